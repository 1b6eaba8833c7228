// The editor in headless Chromium (tests/test_edit_browser.py): type, see the tree change, an inline error on
// its line, a slider, export a .glb, save and reload. Prints one JSON object of what it saw.
// usage: node tests/edit_browser.mjs URL OUTDIR CHROMIUM ARGS_JSON [START TYPED]
// (START: the grammar's text whose last character is typed over with TYPED; default "iterations = 6", "5")
import path from 'node:path';
import { launch } from '../tools/chromium.mjs';

const [url, outdir, executablePath, argsJson, start = 'iterations = 6', typed = '5'] = process.argv.slice(2);
const browser = await launch(executablePath, argsJson);
const out = { errors: [] };
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 }, acceptDownloads: true });
  page.on('pageerror', (e) => out.errors.push(e.message));
  const settled = () =>
    page.waitForFunction(() => {
      const s = window.lsys3d?.state;
      return s && s.shown.seq === s.seq && s.shown.kind === 'full';
    }, null, { timeout: 120000 });
  const triangles = () => page.evaluate(() => window.lsys3d.viewer.triangles);
  const text = () => page.evaluate(() => window.lsys3d.editor.value);
  const select = (needle, offset, length) =>
    page.evaluate(([n, o, l]) => {
      const area = document.querySelector('[data-testid=editor]');
      const at = area.value.indexOf(n) + o;
      area.focus();
      area.setSelectionRange(at, at + l);
    }, [needle, offset, length]);

  await page.goto(url);
  await settled();
  out.trianglesBefore = await triangles();

  // type into the editor: the iterations' digit (6 -> 5 by default; real key presses)
  await select(start, start.length - 1, 1);
  await page.keyboard.type(typed);
  await page.waitForFunction((n) => window.lsys3d.viewer.triangles !== n, out.trianglesBefore, { timeout: 60000 });
  out.trianglesSoup = await triangles();
  out.kindAfterTyping = await page.evaluate(() => window.lsys3d.state.shown.kind);
  await settled();
  out.trianglesAfter = await triangles();

  // a bad rule: its inline error sits on its line
  const lines = (await text()).split('\n');
  out.badLine = lines.findIndex((l) => l.includes('F(l*lr)')) + 1;
  await select('F(l*lr)', 'F(l*lr'.length, 1);
  await page.keyboard.press('Backspace');
  const error = page.locator('[data-testid=inline-error]');
  await error.waitFor({ timeout: 60000 });
  out.errorLine = Number(await error.getAttribute('data-line'));
  out.errorText = await error.textContent();
  out.errorGutter = await page.locator('.error-gutter').textContent();
  await page.keyboard.type(')');
  await error.waitFor({ state: 'detached', timeout: 60000 });
  await settled();

  // a symbol with no meaning: the CLI's warning, listed and the symbol marked where it is written
  await select('(45)A"', '(45)A'.length, 0);
  await page.keyboard.type('X');
  const marked = page.locator('[data-testid=warned-symbol]');
  await marked.first().waitFor({ timeout: 60000 });
  out.warnedSymbol = await marked.first().textContent();
  out.warning = await page.locator('[data-testid=warning]').first().textContent();
  out.warningGutter = await page.locator('.warning-gutter').first().textContent();
  await page.keyboard.press('Backspace');
  await marked.first().waitFor({ state: 'detached', timeout: 60000 });
  await settled();

  // a slider: the define `a` (the branch angle) is written into the text and the tree changes shape
  const boundsBefore = await page.evaluate(() => window.lsys3d.viewer.bounds());
  await page.locator('[data-testid=slider-define-a]').fill('30');
  out.sliderValue = Number(await page.locator('[data-testid=slider-define-a]').inputValue());
  await page.waitForFunction(() => !/\ba = 18\.95\b/.test(window.lsys3d.editor.value), null, { timeout: 10000 });
  await settled();
  const boundsAfter = await page.evaluate(() => window.lsys3d.viewer.bounds());
  out.boundsChanged = JSON.stringify(boundsBefore) !== JSON.stringify(boundsAfter);

  // a turtle setting's slider writes it into the grammar's [turtle] table
  await page.locator('[data-testid=slider-elasticity]').fill('0.5');
  await page.waitForFunction(() => /\nelasticity = 0\.5\n/.test(window.lsys3d.editor.value), null, { timeout: 10000 });
  await settled();

  // the view menu: wireframe, skeleton, UV checker and leaves off change what is drawn
  out.views = {};
  for (const view of ['wireframe', 'skeleton', 'uv', 'shaded']) {
    await page.locator('[data-testid=view]').selectOption(view);
    out.views[view] = await triangles();
  }
  await page.locator('[data-testid=leaves]').uncheck();
  out.trianglesWithoutLeaves = await triangles();
  await page.locator('[data-testid=leaves]').check();

  // levels of detail: the union grown with LOD1..3, each one fewer triangles
  await page.locator('[data-testid=lods]').check();
  await page.waitForFunction(() => document.querySelectorAll('[data-testid=lod] option').length === 4, null, {
    timeout: 120000,
  });
  await settled();
  out.lodTriangles = [];
  for (const level of ['0', '1', '2', '3']) {
    await page.locator('[data-testid=lod]').selectOption(level);
    out.lodTriangles.push(await triangles());
  }
  await page.locator('[data-testid=lod]').selectOption('0');
  await page.locator('[data-testid=lods]').uncheck();
  await settled();

  // export the .glb shown
  const [download] = await Promise.all([
    page.waitForEvent('download', { timeout: 60000 }),
    page.locator('[data-testid=export-glb]').click(),
  ]);
  out.glb = path.join(outdir, 'exported.glb');
  await download.saveAs(out.glb);

  // save, then reload: the page reads the file back
  out.textSaved = await text();
  await page.locator('[data-testid=save]').click();
  await page.waitForFunction(() => document.querySelector('[data-testid=save-status]').dataset.saved === '1', null, {
    timeout: 30000,
  });
  await page.reload();
  await settled();
  out.textReloaded = await text();
  out.trianglesReloaded = await triangles();
  out.timings = await page.evaluate(() => window.lsys3d.state.timings);
  await page.screenshot({ path: path.join(outdir, 'editor.png') });
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

// The picture of docs/edit.md: the editor on tree3d with an angle jitter, its seed variants, and a bad rule's
// inline error (docs/make_edit_screenshot.py runs it). usage: node docs/edit_screenshot.mjs URL OUT.png CHROMIUM ARGS_JSON
import { launch } from '../tools/chromium.mjs';

const [url, out, executablePath, argsJson] = process.argv.slice(2);
const browser = await launch(executablePath, argsJson);
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 860 } });
  const settled = () =>
    page.waitForFunction(() => {
      const s = window.lsys3d?.state;
      return s && s.shown.seq === s.seq && s.shown.kind === 'full';
    }, null, { timeout: 300000 });
  await page.goto(url);
  await settled();
  await page.locator('[data-testid="slider-angle_jitter"]').fill('12');
  await settled();
  await page.locator('[data-testid=variants-button]').click();
  await page.waitForFunction(() => document.querySelectorAll('[data-testid=variant]').length === 5, null, {
    timeout: 120000,
  });
  // a typo in a rule: the error sits on its line, the last good tree stays on screen
  await page.evaluate(() => {
    const area = document.querySelector('[data-testid=editor]');
    const at = area.value.indexOf('F(l*lr)') + 'F(l*lr'.length;
    area.focus();
    area.setSelectionRange(at, at + 1);
  });
  await page.keyboard.press('Backspace');
  await page.locator('[data-testid=inline-error]').waitFor({ timeout: 60000 });
  await page.evaluate(() => document.querySelector('[data-testid=editor]').blur());
  await page.screenshot({ path: out });
} finally {
  await browser.close();
}

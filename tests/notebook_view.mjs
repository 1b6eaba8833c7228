// Opens an HTML file holding lsys3d's notebook viewer (Tree._repr_html_) in headless Chromium, offline, and prints
// the triangles it draws and whether it asked the network for anything (tests/test_notebook.py).
// usage: node tests/notebook_view.mjs FILE CHROMIUM ARGS_JSON
import { pathToFileURL } from 'node:url';
import { launch } from '../tools/chromium.mjs';

const [file, executablePath, argsJson] = process.argv.slice(2);
const browser = await launch(executablePath, argsJson);
const out = { errors: [], requests: [] };
try {
  const page = await browser.newPage({ viewport: { width: 900, height: 700 } });
  page.on('pageerror', (e) => out.errors.push(e.message));
  page.on('request', (r) => {
    if (!r.url().startsWith('file:') && !r.url().startsWith('blob:') && !r.url().startsWith('data:')) out.requests.push(r.url());
  });
  await page.goto(pathToFileURL(file).href);
  await page.waitForSelector('[data-ready=true]', { timeout: 120000 });
  out.triangles = await page.evaluate(() => Number(document.querySelector('.lsys3d-viewer').dataset.triangles));
  out.views = await page.evaluate(() => [...document.querySelector('[data-testid=view]').options].map((o) => o.value));
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

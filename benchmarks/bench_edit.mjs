// Keypress to tree on screen in `lsys3d edit` (benchmarks/bench_edit.py): headless Chromium types one digit
// into the grammar N times (changing the define lr), each after the previous edit's union is shown, and reads
// the page's own timings (the input event to the frame that draws the soup, then the union).
// usage: node benchmarks/bench_edit.mjs URL EDITS CHROMIUM ARGS_JSON
import { launch } from '../tools/chromium.mjs';

const [url, edits, executablePath, argsJson] = process.argv.slice(2);
const browser = await launch(executablePath, argsJson);
const out = { soup: [], full: [], soupFetched: [], soupWorker: [], burst: [] };
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 800 } });
  const settled = () =>
    page.waitForFunction(() => {
      const s = window.lsys3d?.state;
      return s && s.shown.seq === s.seq && s.shown.kind === 'full';
    }, null, { timeout: 300000 });
  const digit = async (d) => {
    await page.evaluate(() => {
      const area = document.querySelector('[data-testid=editor]');
      const at = area.value.search(/lr = 1\.10\d/) + 'lr = 1.10'.length;
      area.focus();
      area.setSelectionRange(at, at + 1);
    });
    await page.keyboard.type(String(d));
  };
  await page.goto(url);
  await settled();
  for (let i = 0; i < Number(edits); i++) {
    await digit(i % 10);
    await settled();
    const t = await page.evaluate(() => window.lsys3d.state.timings.filter((x) => x.seq === window.lsys3d.state.seq));
    for (const x of t) {
      out[x.kind === 'soup' ? 'soup' : 'full'].push(x.ms);
      if (x.kind === 'soup') {
        out.soupFetched.push(x.fetched);
        out.soupWorker.push(x.worker);
      }
    }
  }
  // a burst: five digits 60 ms apart, then the last edit's soup and union (the older work cancelled)
  for (let i = 0; i < 5; i++) {
    await digit((i + 3) % 10);
    await page.waitForTimeout(60);
  }
  await settled();
  out.burst = await page.evaluate(() => window.lsys3d.state.timings.filter((x) => x.seq === window.lsys3d.state.seq));
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));

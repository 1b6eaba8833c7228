// Play a .glb's growth animation with three.js in headless Chromium; print what its skinned meshes look like.
//
//   node tools/three_growth.mjs URL CHROMIUM [ARGS_JSON]
//   node tools/three_growth.mjs '["URL", "URL", ...]' CHROMIUM [ARGS_JSON]
//
// URL is a page served from 127.0.0.1 (tests/test_growth.py serves tools/three_growth.html beside the .glb,
// with three.js from node_modules/three).  The page loads the .glb with GLTFLoader, plays the animation named
// "growth" on an AnimationMixer, steps it to each time the page asks for, and reads every skinned mesh's
// vertices with SkinnedMesh.getVertexPosition (three.js's own skinning, on the CPU).  Prints one JSON line per
// URL (several: a JSON list, each in a page of its own, in one Chromium), in their order.
import { launch } from "./chromium.mjs";

const [urls, executablePath, argsJson] = process.argv.slice(2);
const browser = await launch(executablePath, argsJson);
try {
  for (const url of urls.startsWith("[") ? JSON.parse(urls) : [urls]) {
    const page = await browser.newPage();
    const errors = [];
    page.on("pageerror", (e) => errors.push(String(e)));
    page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
    await page.goto(url);
    await page.waitForFunction(() => window.result !== undefined || window.failure !== undefined, null, { timeout: 120000 });
    const out = await page.evaluate(() => window.result ?? { failure: window.failure });
    out.errors = errors;
    out.userAgent = await page.evaluate(() => navigator.userAgent);
    process.stdout.write(JSON.stringify(out) + "\n");
    await page.close();
  }
} finally {
  await browser.close();
}

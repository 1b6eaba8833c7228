// Headless Chromium through playwright-core from the repository's node_modules: the one launcher of the browser
// tests (tests/*.mjs), tools/three_growth.mjs, the editor's benchmark and the docs' screenshot. The binary and its
// flags come from the Python side (tests/browser.py: CHROMIUM, CHROMIUM_ARGS), passed as the script's arguments.
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const repo = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const { chromium } = createRequire(path.join(repo, 'node_modules/'))('playwright-core');

// executablePath: the Chromium binary; argsJson: its flags as a JSON list (or empty).
export function launch(executablePath, argsJson) {
  return chromium.launch({ executablePath, args: JSON.parse(argsJson || '[]'), headless: true });
}

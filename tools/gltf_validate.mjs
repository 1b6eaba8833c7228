// Validate a .glb or .gltf with the Khronos glTF-Validator (npm "gltf-validator", pinned in package.json).
// Usage: node tools/gltf_validate.mjs FILE
// Prints the validator's report as JSON on stdout; exit 0 when the file was validated (whatever it found),
// 2 when it could not be read, the validator rejected it or is not installed (run `npm ci` first).
// tests/validators.py reads the report.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';

const require = createRequire(import.meta.url);
let validator;
try {
  validator = require('gltf-validator');
} catch (err) {
  if (err.code !== 'MODULE_NOT_FOUND') throw err;
  // one line, not a stack trace: the package is installed by `npm ci` (pinned in package-lock.json)
  console.error(
    "gltf_validate.mjs: the Khronos glTF-Validator (npm package 'gltf-validator') is not installed: " +
      "run 'npm ci' in the repository first (or 'make validators')",
  );
  process.exit(2);
}

const file = process.argv[2];
if (!file) {
  console.error('usage: node tools/gltf_validate.mjs FILE.glb|FILE.gltf');
  process.exit(2);
}
const full = path.resolve(file);
try {
  const bytes = new Uint8Array(await readFile(full));
  const ext = path.extname(full).toLowerCase();
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(full),
    format: ext === '.glb' ? 'glb' : 'gltf',
    maxIssues: 0, // no limit
    writeTimestamp: false,
    externalResourceFunction: async (uri) =>
      new Uint8Array(await readFile(path.resolve(path.dirname(full), decodeURIComponent(uri)))),
  });
  process.stdout.write(JSON.stringify(report) + '\n');
} catch (err) {
  console.error(`${file}: ${err}`);
  process.exit(2);
}

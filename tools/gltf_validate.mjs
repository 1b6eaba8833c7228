// Validate a .glb or .gltf with the Khronos glTF-Validator (npm "gltf-validator", pinned in package.json).
// Usage: node tools/gltf_validate.mjs FILE
// Prints the validator's report as JSON on stdout; exit 0 when the file was validated (whatever it found),
// 2 when it could not be read or the validator rejected it. tests/validators.py reads the report.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

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

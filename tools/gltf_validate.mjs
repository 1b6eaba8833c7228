// Validate a .glb or .gltf with the Khronos glTF-Validator (npm "gltf-validator", pinned in package.json).
// Usage: node tools/gltf_validate.mjs FILE
// Prints the validator's report as JSON on stdout; exit 0 when the file was validated (whatever it found),
// 2 when it could not be read, the validator rejected it or is not installed (run `npm ci` first).
// node tools/gltf_validate.mjs --serve: one file name a line on stdin (a JSON string), one line of JSON back for
// each ({"report": ...} or {"error": "..."}), until stdin ends: tests/validators.py keeps one such process, so
// the suite's hundred files pay node's start and the validator's warm-up once.
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

async function validate(file) {
  const full = path.resolve(file);
  const bytes = new Uint8Array(await readFile(full));
  const ext = path.extname(full).toLowerCase();
  return validator.validateBytes(bytes, {
    uri: path.basename(full),
    format: ext === '.glb' ? 'glb' : 'gltf',
    maxIssues: 0, // no limit
    writeTimestamp: false,
    externalResourceFunction: async (uri) =>
      new Uint8Array(await readFile(path.resolve(path.dirname(full), decodeURIComponent(uri)))),
  });
}

const file = process.argv[2];
if (!file) {
  console.error('usage: node tools/gltf_validate.mjs FILE.glb|FILE.gltf (or --serve)');
  process.exit(2);
}
if (file === '--serve') {
  const { createInterface } = await import('node:readline');
  for await (const line of createInterface({ input: process.stdin, crlfDelay: Infinity })) {
    let name = line;
    let answer;
    try {
      name = JSON.parse(line);
      answer = { report: await validate(name) };
    } catch (err) {
      answer = { error: `${name}: ${err}` };
    }
    process.stdout.write(JSON.stringify(answer) + '\n');
  }
} else {
  try {
    process.stdout.write(JSON.stringify(await validate(file)) + '\n');
  } catch (err) {
    console.error(`${file}: ${err}`);
    process.exit(2);
  }
}

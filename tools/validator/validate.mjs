#!/usr/bin/env node
// Runs the Khronos glTF validator (npm package gltf-validator) over .gltf and
// .glb files, loading their external resources (.bin, images) from disk.
//
// Usage: node tools/validator/validate.mjs [--json] FILE...
// Prints one line per file:
//   <file>: <E> errors, <W> warnings, <I> infos, <H> hints
// followed by the error messages (pointer and code) when there are any.
// --json prints each full report as JSON after its summary line.
// Exit status: 0 when no file has errors, 1 when any file has an error or
// cannot be read, 2 on bad usage. Install once with `npm ci` in this folder.
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

const args = process.argv.slice(2);
const json = args.includes('--json');
const files = args.filter((a) => a !== '--json');
if (files.length === 0) {
  console.error('usage: node validate.mjs [--json] FILE.gltf|FILE.glb ...');
  process.exit(2);
}

let failed = false;
for (const file of files) {
  let report;
  try {
    const bytes = await readFile(file);
    report = await validator.validateBytes(new Uint8Array(bytes), {
      uri: path.basename(file),
      maxIssues: 0,
      writeTimestamp: false,
      externalResourceFunction: async (uri) => {
        const resolved = path.resolve(path.dirname(file), decodeURIComponent(uri));
        return new Uint8Array(await readFile(resolved));
      },
    });
  } catch (error) {
    console.log(`${file}: cannot validate: ${String(error).split('\n')[0]}`);
    failed = true;
    continue;
  }
  const issues = report.issues;
  console.log(
    `${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
      `${issues.numInfos} infos, ${issues.numHints} hints`
  );
  for (const m of issues.messages) {
    if (m.severity === 0) console.log(`  error ${m.code} at ${m.pointer ?? '?'}: ${m.message}`);
  }
  if (json) console.log(JSON.stringify(report, null, 2));
  if (issues.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);

#!/usr/bin/env node
// Runs the Khronos glTF validator (npm gltf-validator) on every .glb under the
// given files/directories. Prints one line per file and a JSON summary on the
// last line; exits 1 if any file has errors (warnings and infos are reported,
// not failed), 2 on bad usage.
//
//   node tests/node/validate-glb.mjs TILESET_DIR [MORE...] [--report out.json] [--max-warnings N]
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

const args = process.argv.slice(2);
let reportPath = null;
let maxWarnings = Infinity;
const inputs = [];
for (let i = 0; i < args.length; ++i) {
  if (args[i] === '--report') reportPath = args[++i];
  else if (args[i] === '--max-warnings') maxWarnings = Number(args[++i]);
  else inputs.push(args[i]);
}
if (inputs.length === 0) {
  console.error('usage: validate-glb.mjs DIR|FILE... [--report out.json] [--max-warnings N]');
  process.exit(2);
}

function collect(p, out) {
  const st = fs.statSync(p);
  if (st.isDirectory()) {
    for (const e of fs.readdirSync(p).sort()) collect(path.join(p, e), out);
  } else if (p.endsWith('.glb')) {
    out.push(p);
  }
}
const files = [];
for (const p of inputs) collect(p, files);
if (files.length === 0) {
  console.error('validate-glb: no .glb files found in ' + inputs.join(' '));
  process.exit(1);
}

const summary = { files: files.length, errors: 0, warnings: 0, infos: 0, hints: 0, failed: [], codes: {} };
const perFile = [];
for (const f of files) {
  const bytes = new Uint8Array(fs.readFileSync(f));
  let report;
  try {
    report = await validator.validateBytes(bytes, { uri: path.basename(f), maxIssues: 100 });
  } catch (e) {
    report = { issues: { numErrors: 1, numWarnings: 0, numInfos: 0, numHints: 0, messages: [{ code: 'VALIDATOR_REJECTED', message: String(e), severity: 0 }] } };
  }
  const is = report.issues;
  summary.errors += is.numErrors;
  summary.warnings += is.numWarnings;
  summary.infos += is.numInfos;
  summary.hints += is.numHints;
  for (const m of is.messages) {
    const key = `${['error', 'warning', 'info', 'hint'][m.severity]}:${m.code}`;
    summary.codes[key] = (summary.codes[key] || 0) + 1;
  }
  if (is.numErrors > 0) {
    summary.failed.push(f);
    console.log(`FAIL ${f}: ${is.numErrors} errors`);
    for (const m of is.messages.filter((m) => m.severity === 0).slice(0, 10))
      console.log(`  ${m.code} ${m.pointer || ''} ${m.message}`);
  }
  perFile.push({ file: f, errors: is.numErrors, warnings: is.numWarnings, infos: is.numInfos, messages: is.messages.slice(0, 20) });
}
if (reportPath) fs.writeFileSync(reportPath, JSON.stringify({ summary, files: perFile }, null, 1));
console.log(`validated ${summary.files} glb: ${summary.errors} errors, ${summary.warnings} warnings, ${summary.infos} infos`);
console.log(JSON.stringify(summary));
process.exit(summary.errors > 0 || summary.warnings > maxWarnings ? 1 : 0);

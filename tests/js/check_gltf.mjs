// Validates a glTF 2.0 file (.glb or .gltf) with the Khronos glTF-Validator
// (npm gltf-validator), written independently of our exporter, and prints
// the report's summary as JSON on stdout:
//   {"uri", "mime_type", "validator_version", "num_errors", "num_warnings",
//    "num_infos", "num_hints", "issues": [{code, severity, pointer, message}],
//    "info": {version, generator, animationCount, materialCount, ...},
//    "problems": [...]}
// `issues` lists every error and warning (infos and hints are only counted).
// Usage: node check_gltf.mjs FILE
// Exit status 0 when the validator found no error, 1 otherwise (or when the
// file could not be validated at all), 2 on bad usage.
// Setup: npm ci --prefix tests/js   (or npm install --prefix tests/js)
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");

// Severity codes of the validator's report.
const SEVERITY = ["error", "warning", "info", "hint"];

async function check(path) {
  const bytes = new Uint8Array(await readFile(path));
  const report = await validator.validateBytes(bytes, {
    uri: path,
    maxIssues: 0,
    writeTimestamp: false,
  });
  const issues = report.issues;
  return {
    uri: path,
    mime_type: report.mimeType,
    validator_version: report.validatorVersion,
    num_errors: issues.numErrors,
    num_warnings: issues.numWarnings,
    num_infos: issues.numInfos,
    num_hints: issues.numHints,
    issues: issues.messages
      .filter((m) => m.severity <= 1)
      .map((m) => ({
        code: m.code,
        severity: SEVERITY[m.severity] ?? String(m.severity),
        pointer: m.pointer ?? "",
        message: m.message,
      })),
    info: report.info ?? {},
    problems: [],
  };
}

const path = process.argv[2];
if (!path || process.argv.length > 3) {
  console.error("usage: node check_gltf.mjs FILE.glb|FILE.gltf");
  process.exit(2);
}
try {
  const result = await check(path);
  console.log(JSON.stringify(result));
  process.exit(result.num_errors === 0 ? 0 : 1);
} catch (error) {
  console.log(JSON.stringify({ uri: path, num_errors: -1, problems: [String(error)] }));
  process.exit(1);
}

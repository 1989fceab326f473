// Validate glTF 2.0 files with the Khronos glTF validator (npm package gltf-validator, installed
// into .ci/node_modules by .ci/setup). Prints one JSON report per file on stdout:
// {"file", "errors", "warnings", "infos", "hints", "messages": [{code, severity, pointer, message}]}
// Exit status: 0 when no file has errors, 1 otherwise, 2 when a file cannot be read.
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

const files = process.argv.slice(2);
let status = 0;
for (const file of files) {
  let bytes;
  try {
    bytes = new Uint8Array(await readFile(file));
  } catch (error) {
    console.error(`error: ${file}: ${error.message}`);
    process.exit(2);
  }
  const report = await validator.validateBytes(bytes, { maxIssues: 0 });
  const issues = report.issues;
  const severities = ["error", "warning", "info", "hint"];
  console.log(JSON.stringify({
    file,
    validator: `${report.validatorVersion}`,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    hints: issues.numHints,
    extensionsUsed: report.info ? report.info.extensionsUsed || [] : [],
    messages: issues.messages.map((m) => ({
      code: m.code, severity: severities[m.severity], pointer: m.pointer || "", message: m.message,
    })),
  }));
  if (issues.numErrors > 0) status = Math.max(status, 1);
}
process.exit(status);

// Runs the Khronos glTF-Validator (npm gltf-validator, pinned in package.json) on one .gltf file and its external
// resources (textures, buffers beside it). Prints the report's issue counts and messages as JSON on stdout; exits 0
// when it has no errors and no warnings, 1 otherwise, 2 when the file could not be read or parsed.
// Usage: node validate.js FILE.gltf   (tests/pipeline/test_gltf_export.cpp runs it)
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

const file = process.argv[2];
if (!file) {
  console.error('usage: node validate.js FILE.gltf');
  process.exit(2);
}
let bytes;
try {
  bytes = new Uint8Array(fs.readFileSync(file));
} catch (e) {
  console.error(String(e));
  process.exit(2);
}
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 100,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          err ? reject(String(err)) : resolve(new Uint8Array(data)));
      }),
  })
  .then(
    (report) => {
      const issues = report.issues;
      console.log(JSON.stringify({
        validator: report.validatorVersion,
        errors: issues.numErrors,
        warnings: issues.numWarnings,
        infos: issues.numInfos,
        hints: issues.numHints,
        messages: issues.messages,
        resources: (report.info && report.info.resources) || [],
      }, null, 1));
      process.exit(issues.numErrors === 0 && issues.numWarnings === 0 ? 0 : 1);
    },
    (error) => {
      console.error(String(error));
      process.exit(2);
    });

// Validates a .glb with the Khronos glTF validator (npm package gltf-validator) and prints
// "errors warnings"; exit status 1 on any error. Used by tests/io.rs when
// KNOTWORK_GLTF_VALIDATOR names the folder holding node_modules/gltf-validator.
const path = require('path');
const fs = require('fs');
const validator = require(path.join(process.env.KNOTWORK_GLTF_VALIDATOR, 'node_modules', 'gltf-validator'));
const file = process.argv[2];
validator.validateBytes(new Uint8Array(fs.readFileSync(file)), { maxIssues: 100 }).then((report) => {
  const issues = report.issues;
  console.log(`${issues.numErrors} ${issues.numWarnings}`);
  for (const message of issues.messages) {
    if (message.severity === 0) console.error(`${message.code} ${message.pointer || ''}: ${message.message}`);
  }
  process.exit(issues.numErrors > 0 ? 1 : 0);
}, (error) => {
  console.error(String(error));
  process.exit(1);
});

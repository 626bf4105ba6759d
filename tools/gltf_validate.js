#!/usr/bin/env node
// Validates a .gltf file (and the buffers and images it names) with the Khronos glTF
// validator, the npm package `gltf-validator` (a library, so this script is its command line).
//
// Usage: node tools/gltf_validate.js scene.gltf
// Finds the package through NODE_PATH or the project's .ci/node_modules
// (`npm install --prefix .ci gltf-validator`). Prints the report's counts and every error and
// warning; exit 0 when the report has no errors, 1 when it has, 2 when it cannot run.
"use strict";
const fs = require("fs");
const path = require("path");

let validator;
try {
    validator = require("gltf-validator");
} catch (e) {
    try {
        validator = require(path.join(__dirname, "..", ".ci", "node_modules", "gltf-validator"));
    } catch (e2) {
        console.error("gltf-validator is not installed: npm install --prefix .ci gltf-validator");
        process.exit(2);
    }
}

const file = process.argv[2];
if (!file) {
    console.error("usage: node tools/gltf_validate.js scene.gltf");
    process.exit(2);
}
const full = path.resolve(file);
const bytes = fs.readFileSync(full);
validator
    .validateBytes(new Uint8Array(bytes), {
        uri: path.basename(full),
        format: "gltf",
        maxIssues: 1000,
        externalResourceFunction: (uri) =>
            new Promise((resolve, reject) => {
                fs.readFile(path.resolve(path.dirname(full), decodeURIComponent(uri)), (err, data) =>
                    err ? reject(err.toString()) : resolve(new Uint8Array(data)));
            }),
    })
    .then(
        (report) => {
            const i = report.issues;
            console.log(`validator ${report.validatorVersion}: ${i.numErrors} errors, ${i.numWarnings} warnings, ` +
                `${i.numInfos} infos, ${i.numHints} hints`);
            for (const m of i.messages) {
                if (m.severity <= 1) {
                    console.log(`  ${m.severity === 0 ? "error" : "warning"} ${m.code} at ${m.pointer || "-"}: ${m.message}`);
                }
            }
            process.exit(i.numErrors === 0 ? 0 : 1);
        },
        (err) => {
            console.error(`the validator could not read ${file}: ${err}`);
            process.exit(2);
        }
    );

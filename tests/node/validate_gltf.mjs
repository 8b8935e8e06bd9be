// Runs the Khronos glTF validator (npm gltf-validator) on .glb/.gltf files:
//   node tests/node/validate_gltf.mjs FILE...
// Prints one summary per file and the validator's messages. Exits 0 when no file has any issue
// except the info that our own extension STRATA_progressive_mesh is unknown to the validator,
// 1 when some file has another error, warning, info or hint (or cannot be read), and 2 for
// usage errors or a missing node_modules (run `npm ci` in tests/node; scripts/test.sh does).
import { readFile } from 'node:fs/promises';
import { basename, dirname, resolve } from 'node:path';

const kAllowedExtension = 'STRATA_progressive_mesh';
const kSeverities = ['error', 'warning', 'info', 'hint'];

/// True for the one issue we accept: the validator does not know our extension.
function isAllowed(message) {
    return message.code === 'UNSUPPORTED_EXTENSION' && message.message.includes(kAllowedExtension);
}

async function loadValidator() {
    try {
        return await import('gltf-validator');
    } catch (error) {
        console.error(`validate_gltf: cannot load the npm package gltf-validator (${error.message})`);
        console.error(`validate_gltf: run \`npm ci\` in ${dirname(new URL(import.meta.url).pathname)}`);
        process.exit(2);
    }
}

function asBytes(buffer) {
    return new Uint8Array(buffer.buffer, buffer.byteOffset, buffer.byteLength);
}

/// Validates one file; returns true when it passes.
async function validateFile(validator, file) {
    let bytes;
    try {
        bytes = asBytes(await readFile(file));
    } catch (error) {
        console.log(`${file}: FAIL: cannot read: ${error.message}`);
        return false;
    }
    const report = await validator.validateBytes(bytes, {
        uri: basename(file),
        maxIssues: 0,  // unlimited
        writeTimestamp: false,
        externalResourceFunction: async (uri) =>
            asBytes(await readFile(resolve(dirname(file), decodeURIComponent(uri)))),
    });
    const issues = report.issues;
    const failing = issues.messages.filter((message) => !isAllowed(message));
    const info = report.info ?? {};
    const external = (info.resources ?? []).filter((r) => r.storage === 'external').length;
    console.log(
        `${file}: ${failing.length === 0 ? 'ok' : 'FAIL'}: ${issues.numErrors} errors, ` +
            `${issues.numWarnings} warnings, ${issues.numInfos} infos, ${issues.numHints} hints; ` +
            `${info.drawCallCount ?? 0} draw calls, ${info.totalTriangleCount ?? 0} triangles, ` +
            `${info.totalVertexCount ?? 0} vertices, ${external} external resources, ` +
            `generator '${info.generator ?? ''}'`);
    for (const message of issues.messages) {
        const where = message.pointer ?? (message.offset !== undefined ? `@${message.offset}` : '');
        const allowed = isAllowed(message) ? ' (allowed)' : '';
        console.log(
            `  ${kSeverities[message.severity] ?? message.severity} ${message.code} ${where}: ` +
                `${message.message}${allowed}`);
    }
    return failing.length === 0;
}

async function main(files) {
    if (files.length === 0) {
        console.error('usage: node validate_gltf.mjs FILE.glb|FILE.gltf...');
        return 2;
    }
    const validator = await loadValidator();
    console.log(`validate_gltf: Khronos glTF validator ${validator.version()}`);
    let failed = 0;
    for (const file of files) {
        try {
            if (!(await validateFile(validator, file))) {
                ++failed;
            }
        } catch (error) {
            // note: the validator rejects when it cannot even detect the format
            console.log(`${file}: FAIL: ${error}`);
            ++failed;
        }
    }
    console.log(`validate_gltf: ${files.length - failed} of ${files.length} files pass`);
    return failed === 0 ? 0 : 1;
}

process.exitCode = await main(process.argv.slice(2));

// Runs the Khronos glTF validator (npm gltf-validator) on .glb/.gltf files:
//   node tests/node/validate_gltf.mjs FILE...
// Prints one summary per file and the validator's messages. Exits 0 when no file has any issue
// but the infos our own extension causes (see allowedIssues: STRATA_progressive_mesh and, in
// files using it, KHR_draco_mesh_compression unknown to the validator, and the buffer views it
// reaches only through our extension or Draco reported as maybe unused), 1 when some file has another error, warning, info or hint (or cannot be read), and 2 for
// usage errors or a missing node_modules (run `npm ci` in tests/node; scripts/test.sh does).
import { readFile } from 'node:fs/promises';
import { basename, dirname, resolve } from 'node:path';

import { kDraco, kExtension as kAllowedExtension } from '../../web-viewer/strata-format.js';
const kSeverities = ['error', 'warning', 'info', 'hint'];

/// The glTF JSON of a .glb or .gltf file's bytes (null when it cannot be parsed).
function gltfJson(bytes) {
    try {
        const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
        if (bytes.byteLength >= 20 && view.getUint32(0, true) === 0x46546c67) {
            const length = view.getUint32(12, true);
            return JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
        }
        return JSON.parse(new TextDecoder().decode(bytes));
    } catch {
        return null;
    }
}

/// The issues we accept, as JSON pointers per code: the validator does not know our extension;
/// in files that use it, it does not decode KHR_draco_mesh_compression either, so it reports the
/// extension as unsupported and the buffer views only our extension or Draco name (the DAG table,
/// the chunks, the base meshes' Draco data) as maybe unused.
/// The same for the Draco primitives of a plain scene (extension and their buffer views).
/// Nothing else is accepted, and these only for exactly those objects.
function allowedIssues(json) {
    const allowed = { UNSUPPORTED_EXTENSION: new Set(), UNUSED_OBJECT: new Set() };
    const used = json?.extensionsUsed ?? [];
    const progressive = used.includes(kAllowedExtension);
    used.forEach((name, i) => {
        if (name === kAllowedExtension || name === kDraco) {
            allowed.UNSUPPORTED_EXTENSION.add(`/extensionsUsed/${i}`);
        }
    });
    allowLodIssues(json, allowed);
    // Draco primitives (scene.glb by default): the validator does not decode them, so their
    // buffer views look unused.
    for (const mesh of json?.meshes ?? []) {
        for (const primitive of mesh.primitives ?? []) {
            const draco = primitive.extensions?.[kDraco];
            if (draco !== undefined) {
                allowed.UNUSED_OBJECT.add(`/bufferViews/${draco.bufferView}`);
            }
        }
    }
    if (!progressive) {
        return allowed;
    }
    // version 2 and 3: the DAG table and chunks views are named only by the extension, and the base
    // meshes' Draco views only by KHR_draco_mesh_compression, which the validator does not read
    const fileExt = json.extensions?.[kAllowedExtension] ?? {};
    for (const view of [fileExt.dag, fileExt.chunks].filter((v) => v !== undefined)) {
        allowed.UNUSED_OBJECT.add(`/bufferViews/${view}`);
    }
    for (const node of json.nodes ?? []) {
        const ext = node.extensions?.[kAllowedExtension];
        if (ext === undefined) {
            continue;
        }
        for (const primitive of json.meshes?.[node.mesh]?.primitives ?? []) {
            const draco = primitive.extensions?.[kDraco];
            if (draco !== undefined) {
                allowed.UNUSED_OBJECT.add(`/bufferViews/${draco.bufferView}`);
            }
        }
    }
    return allowed;
}

/// LOD files (exporters/lod_gltf.h, issue 23): the validator knows neither MSFT_lod nor the
/// compression extensions, so it reports them as unsupported, the coarser level nodes (reached
/// only through MSFT_lod ids), the Draco data's buffer views and the buffer holding the
/// EXT_meshopt_compression streams (named only by the extension) as maybe unused.
function allowLodIssues(json, allowed) {
    const used = json?.extensionsUsed ?? [];
    // also the meshopt scene (scene_gltf's meshopt option): the same compressed data
    if (!used.includes('MSFT_lod') && !used.includes('EXT_meshopt_compression')) {
        return;
    }
    used.forEach((name, i) => {
        if (['MSFT_lod', kDraco, 'EXT_meshopt_compression'].includes(name)) {
            allowed.UNSUPPORTED_EXTENSION.add(`/extensionsUsed/${i}`);
        }
    });
    for (const node of json.nodes ?? []) {
        for (const id of node.extensions?.MSFT_lod?.ids ?? []) {
            allowed.UNUSED_OBJECT.add(`/nodes/${id}`);
        }
    }
    for (const mesh of json.meshes ?? []) {
        for (const primitive of mesh.primitives ?? []) {
            const draco = primitive.extensions?.[kDraco];
            if (draco !== undefined) {
                allowed.UNUSED_OBJECT.add(`/bufferViews/${draco.bufferView}`);
            }
        }
    }
    for (const view of json.bufferViews ?? []) {
        const meshopt = view.extensions?.EXT_meshopt_compression;
        if (meshopt !== undefined) {
            allowed.UNUSED_OBJECT.add(`/buffers/${meshopt.buffer}`);
        }
    }
}

function isAllowed(allowed, message) {
    return allowed[message.code]?.has(message.pointer) ?? false;
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
        maxIssues: 0, // unlimited
        writeTimestamp: false,
        externalResourceFunction: async (uri) =>
            asBytes(await readFile(resolve(dirname(file), decodeURIComponent(uri)))),
    });
    const issues = report.issues;
    const allowed = allowedIssues(gltfJson(bytes));
    const failing = issues.messages.filter((message) => !isAllowed(allowed, message));
    const info = report.info ?? {};
    const external = (info.resources ?? []).filter((r) => r.storage === 'external').length;
    console.log(
        `${file}: ${failing.length === 0 ? 'ok' : 'FAIL'}: ${issues.numErrors} errors, ` +
            `${issues.numWarnings} warnings, ${issues.numInfos} infos, ${issues.numHints} hints; ` +
            `${info.drawCallCount ?? 0} draw calls, ${info.totalTriangleCount ?? 0} triangles, ` +
            `${info.totalVertexCount ?? 0} vertices, ${external} external resources, ` +
            `generator '${info.generator ?? ''}'`,
    );
    for (const message of issues.messages) {
        const where = message.pointer ?? (message.offset !== undefined ? `@${message.offset}` : '');
        const note = isAllowed(allowed, message) ? ' (allowed)' : '';
        console.log(
            `  ${kSeverities[message.severity] ?? message.severity} ${message.code} ${where}: ` +
                `${message.message}${note}`,
        );
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

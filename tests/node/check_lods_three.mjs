// Loads strata's LOD glTF (lods.glb, exporters/lod_gltf.h) with three.js's GLTFLoader in Node:
//   node tests/node/check_lods_three.mjs FILE.glb...
// three.js does not implement MSFT_lod, so the scene shows the finest level; a pipeline reaches
// the coarser levels by node (the `_LOD<i>` names). Checks, per object: the scene holds the
// `_LOD0` node under "patient"; every level node in MSFT_lod.ids loads through GLTFLoader
// (parser.getDependency('node', i)) as one Mesh whose triangles and name match the node's extras;
// no triangle is degenerate; and every level's world box lies within the level's error bound of
// the finest level's box (so the node matrices and the dequantization place the levels where the
// finest is) and the finest level's box has the half diagonal the file states (bounding_radius_mm,
// which its MSFT_screencoverage is computed from). EXT_meshopt_compression decodes with three's MeshoptDecoder; Draco with the npm
// draco3d decoder through a minimal in-process stand-in for DRACOLoader (Node has no Web
// Workers). Exits 0 when every check passes, 1 otherwise, 2 for usage errors.
import { readFileSync } from 'node:fs';
import { dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const kHere = dirname(fileURLToPath(import.meta.url));

async function loadDeps() {
    try {
        const THREE = await import('three');
        const { GLTFLoader } = await import('three/examples/jsm/loaders/GLTFLoader.js');
        const { MeshoptDecoder } = await import('three/examples/jsm/libs/meshopt_decoder.module.js');
        const draco3d = (await import('draco3d')).default;
        return { THREE, GLTFLoader, MeshoptDecoder, draco: await draco3d.createDecoderModule({}) };
    } catch (error) {
        console.error(`check_lods_three: cannot load the npm packages (${error.message})`);
        console.error(`check_lods_three: run \`npm ci\` in ${kHere}`);
        process.exit(2);
    }
}

/// What GLTFLoader asks of a DRACOLoader: decodeDracoFile(buffer, callback, attributeIds,
/// attributeTypes). Decodes with draco3d (float attributes, 32-bit indices).
class DracoStandIn {
    constructor(THREE, draco) {
        this.THREE = THREE;
        this.draco = draco;
    }

    preload() {
        return this;
    }

    decodeDracoFile(buffer, callback, attributeIds, _attributeTypes, _colorSpace, onError = () => {}) {
        const { draco, THREE } = this;
        const decoder = new draco.Decoder();
        const mesh = new draco.Mesh();
        try {
            const bytes = new Int8Array(buffer);
            const status = decoder.DecodeArrayToMesh(bytes, bytes.byteLength, mesh);
            if (!status.ok()) {
                throw new Error(`Draco: ${status.error_msg()}`);
            }
            const geometry = new THREE.BufferGeometry();
            const points = mesh.num_points();
            for (const [name, id] of Object.entries(attributeIds)) {
                const attribute = decoder.GetAttributeByUniqueId(mesh, id);
                const size = attribute.num_components();
                const byteLength = points * size * 4;
                const ptr = draco._malloc(byteLength);
                decoder.GetAttributeDataArrayForAllPoints(mesh, attribute, draco.DT_FLOAT32, byteLength, ptr);
                const values = new Float32Array(draco.HEAPF32.buffer, ptr, points * size).slice();
                draco._free(ptr);
                geometry.setAttribute(name, new THREE.BufferAttribute(values, size));
            }
            const indexBytes = mesh.num_faces() * 12;
            const ptr = draco._malloc(indexBytes);
            decoder.GetTrianglesUInt32Array(mesh, indexBytes, ptr);
            geometry.setIndex(
                new THREE.BufferAttribute(new Uint32Array(draco.HEAPU32.buffer, ptr, mesh.num_faces() * 3).slice(), 1),
            );
            draco._free(ptr);
            callback(geometry);
        } catch (error) {
            onError(error);
        } finally {
            draco.destroy(mesh);
            draco.destroy(decoder);
        }
    }

    dispose() {}
}

function glbJson(bytes) {
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    if (bytes.byteLength < 20 || view.getUint32(0, true) !== 0x46546c67) {
        throw new Error('not a .glb file');
    }
    return JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + view.getUint32(12, true))));
}

async function checkFile(deps, file) {
    const { THREE, GLTFLoader, MeshoptDecoder } = deps;
    const failures = [];
    const expect = (ok, message) => {
        if (!ok) {
            failures.push(message);
        }
    };
    const bytes = new Uint8Array(readFileSync(file));
    const json = glbJson(bytes);
    const loader = new GLTFLoader();
    loader.setDRACOLoader(new DracoStandIn(THREE, deps.draco));
    loader.setMeshoptDecoder(MeshoptDecoder);
    const gltf = await new Promise((resolve, reject) =>
        loader.parse(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength), '', resolve, reject),
    );
    const patient = gltf.scene.children[0];
    expect(patient?.name === 'patient', `${file}: the scene's root is ${patient?.name}, expected patient`);
    let levels = 0;
    for (const index of json.nodes[0].children ?? []) {
        const lod0 = json.nodes[index];
        // A plain scene (scene.glb) has one level per object, without the _LOD0 suffix.
        const name = lod0.name.endsWith('_LOD0') ? lod0.name.replace(/_LOD0$/, '') : null;
        expect(
            patient.children.some((child) => child.name === lod0.name),
            `${file}: ${lod0.name} is not in three's scene`,
        );
        const ids = [index, ...(lod0.extensions?.MSFT_lod?.ids ?? [])];
        let finestBox = null;
        for (const [i, id] of ids.entries()) {
            const node = json.nodes[id];
            expect(
                name === null || node.name === `${name}_LOD${i}`,
                `${file}: node ${id} is ${node.name}, expected ${name}_LOD${i}`,
            );
            const object = await gltf.parser.getDependency('node', id);
            const mesh = object.isMesh ? object : object.children.find((c) => c.isMesh);
            if (!mesh) {
                expect(false, `${file}: ${node.name}: three made no Mesh`);
                continue;
            }
            ++levels;
            const geometry = mesh.geometry;
            const index = geometry.index;
            expect(
                name === null || index.count / 3 === node.extras.triangles,
                `${file}: ${node.name}: ${index.count / 3} triangles in three, the file states ${node.extras.triangles}`,
            );
            expect(geometry.getAttribute('normal') !== undefined, `${file}: ${node.name}: no normals`);
            // World positions (the node's matrix under the patient root's).
            patient.updateMatrixWorld(true);
            object.matrixWorld.multiplyMatrices(patient.matrixWorld, object.matrix);
            const position = geometry.getAttribute('position');
            const p = new THREE.Vector3();
            const world = [];
            for (let v = 0; v < position.count; ++v) {
                world.push(p.fromBufferAttribute(position, v).applyMatrix4(object.matrixWorld).clone());
            }
            let degenerate = 0;
            for (let t = 0; t < index.count; t += 3) {
                const [a, b, c] = [0, 1, 2].map((k) => world[index.getX(t + k)]);
                if (new THREE.Vector3().subVectors(b, a).cross(new THREE.Vector3().subVectors(c, a)).length() === 0) {
                    ++degenerate;
                }
            }
            expect(degenerate === 0, `${file}: ${node.name}: ${degenerate} degenerate triangles`);
            const box = new THREE.Box3().setFromPoints(world);
            if (i === 0 && name === null) {
                finestBox = box;
            } else if (i === 0) {
                finestBox = box;
                // The file's bounding radius (for MSFT_screencoverage) is this box's half diagonal.
                const radius = box.getSize(new THREE.Vector3()).length() / 2;
                expect(
                    Math.abs(radius - node.extras.bounding_radius_mm / 1000) < 1e-6,
                    `${file}: ${node.name}: three's box has half diagonal ${(radius * 1000).toFixed(4)} mm, the ` +
                        `file states ${node.extras.bounding_radius_mm} mm`,
                );
            } else {
                const slack = node.extras.error_mm / 1000 + 1e-9;
                const off = Math.max(
                    ...['x', 'y', 'z'].flatMap((k) => [
                        Math.abs(box.min[k] - finestBox.min[k]),
                        Math.abs(box.max[k] - finestBox.max[k]),
                    ]),
                );
                expect(
                    off <= slack,
                    `${file}: ${node.name}'s box is ${(off * 1000).toFixed(3)} mm off the finest level's, ` +
                        `more than its bound ${node.extras.error_mm} mm`,
                );
            }
        }
    }
    for (const f of failures) {
        console.error(`  FAIL ${f}`);
    }
    console.log(`${file}: three.js loaded ${levels} level meshes; ${failures.length === 0 ? 'ok' : 'FAIL'}`);
    return failures.length === 0;
}

const files = process.argv.slice(2);
if (files.length === 0) {
    console.error('usage: node check_lods_three.mjs FILE.glb...');
    process.exit(2);
}
const deps = await loadDeps();
let ok = true;
for (const file of files) {
    try {
        ok = (await checkFile(deps, file)) && ok;
    } catch (error) {
        console.error(`  FAIL ${file}: ${error.stack ?? error}`);
        ok = false;
    }
}
process.exit(ok ? 0 : 1);

// Checks strata's progressive glTF files (STRATA_progressive_mesh + KHR_draco_mesh_compression)
// with real clients from npm:
//   node tests/node/check_progressive.mjs FILE.glb|FILE.gltf...
// For each file (format version 3, schema/README.md; the reading code is web-viewer/strata-decode.js,
// the plugin's own):
//   [three]  three.js's GLTFLoader loads the file (Draco through a small in-process adapter on the
//            draco3d decoder, see DracoAdapter): the "patient" root, one child per object, its base
//            one mesh with position, normal and _cluster per point, closed (every edge, by position
//            value, used exactly twice, once in each direction).
//   [draco]  every group's chunk decodes as an Edgebreaker triangle mesh with the glTF-only Draco
//            decoder that three ships (examples/jsm/libs/draco/gltf/, the build real viewers load)
//            and with the draco3d decoder, bit-identically; POSITION, _CLUSTER, _SLOT by unique id;
//            every triangle in one consumed cluster, every consumed cluster with triangles; slots
//            resolve (no rank beyond the neighbours, no cycle); positions on the gridStep grid.
//   [base]   the base primitive likewise (POSITION, NORMAL, _CLUSTER by its attribute map): counts
//            as its accessors say, positions within min/max and on the grid, unit normals.
//   [transform] @gltf-transform/core's NodeIO reads the file (Draco through draco3d): all meshes
//            and node names, per primitive the accessors' counts.
//   [schema] the extension object of every node validates against
//            schema/node.STRATA_progressive_mesh.schema.json (ajv, draft-04).
//   [dag]    the JSON types and buffer views, the binary DAG table and its rules (schema/README.md
//            "Validation" 1-9), and with the decoded geometry: every group's sphere contains the
//            vertices of its consumed and produced clusters (scene frame).
//   [cut]    geometry across clusters: every level cut (refine exactly the groups of level > L)
//            is a closed, consistently oriented surface (all positions bit-identical where shared),
//            and every group's consumed clusters at their slot-decoded coarse positions give
//            exactly its produced clusters' triangles (collapsed triangles dropped).
// Failures in one section do not stop the others; [cut] needs a consistent [dag] and every
// cluster's geometry.
// Prints FAIL lines and one summary line per file. Exits 0 when every file passes every check,
// 1 when some check fails (or a file cannot be read), and 2 for usage errors or a missing
// node_modules (run `npm ci` in tests/node; scripts/test.sh does).
import { readFile } from 'node:fs/promises';
import { readFileSync, readdirSync } from 'node:fs';
import { createRequire } from 'node:module';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import {
    kAttributes,
    kChunkAttributeIds,
    kClusterAttribute,
    kSlotAttribute,
    kThreeClusterAttribute,
    kComponentReaders,
    kComponentType,
    kDraco,
    kExtension,
    kGlb,
    kPatientNode,
    kSchemaFile,
    kStorageNode,
    kThreeAttributes,
    kTypeComponents,
} from '../../web-viewer/strata-format.js';
import {
    chunksByteLength,
    parseDagTable,
    readExtension,
    resolveSlots,
    splitByCluster,
} from '../../web-viewer/strata-decode.js';

const kHere = dirname(fileURLToPath(import.meta.url));
const kSchemaDir = resolve(kHere, '../../schema');
const kRootSchema = kSchemaFile;
const kFileSchema = `glTF.${kExtension}.schema.json`;
const kMaxFailLinesPerFile = 60;

// ------------------------------------------------------------------------------------------------
// dependencies

async function loadDependencies() {
    try {
        const THREE = await import('three');
        const { GLTFLoader } = await import('three/examples/jsm/loaders/GLTFLoader.js');
        const draco3d = (await import('draco3d')).default;
        const { NodeIO } = await import('@gltf-transform/core');
        const { KHRONOS_EXTENSIONS } = await import('@gltf-transform/extensions');
        const Ajv = (await import('ajv-draft-04')).default;
        const threeDir = dirname(createRequire(import.meta.url).resolve('three'));
        return { THREE, GLTFLoader, draco3d, NodeIO, KHRONOS_EXTENSIONS, Ajv, threeDir };
    } catch (error) {
        console.error(`check_progressive: cannot load the npm packages (${error.message})`);
        console.error(`check_progressive: run \`npm ci\` in ${kHere}`);
        process.exit(2);
    }
}

/// three's glTF-only Draco decoder (examples/jsm/libs/draco/gltf/: draco_wasm_wrapper.js +
/// draco_decoder.wasm), the build DRACOLoader.setDecoderPath('.../draco/gltf/') loads in browsers.
/// DRACOLoader evaluates the wrapper's text inside a Web Worker; Node has no such worker, so we
/// evaluate the same text here with `new Function` (the file is a classic script defining
/// DracoDecoderModule; the package is "type": "module", so it cannot be require()d) and hand it the
/// wasm bytes, as DRACOLoader does.
async function loadThreeGltfDracoDecoder(threeDir) {
    const dir = join(threeDir, '..', 'examples', 'jsm', 'libs', 'draco', 'gltf');
    const wrapper = join(dir, 'draco_wasm_wrapper.js');
    const source = readFileSync(wrapper, 'utf8');
    const module = { exports: {} };
    const factory = new Function(
        'module',
        'exports',
        'require',
        '__filename',
        '__dirname',
        `${source}\nreturn DracoDecoderModule;`,
    )(module, module.exports, createRequire(wrapper), wrapper, dir);
    return await factory({ wasmBinary: readFileSync(join(dir, 'draco_decoder.wasm')) });
}

// ------------------------------------------------------------------------------------------------
// the file itself: JSON and buffers as bytes

function asBytes(buffer) {
    return new Uint8Array(buffer.buffer, buffer.byteOffset, buffer.byteLength);
}

function dataUriBytes(uri) {
    const comma = uri.indexOf(',');
    const header = uri.slice(0, comma);
    const payload = uri.slice(comma + 1);
    return header.endsWith(';base64')
        ? asBytes(Buffer.from(payload, 'base64'))
        : asBytes(Buffer.from(decodeURIComponent(payload), 'latin1'));
}

/// Reads a .glb or .gltf file: { file, dir, bytes, isGlb, json, buffers: Uint8Array[] }.
async function readGltf(file) {
    const bytes = asBytes(await readFile(file));
    const dir = dirname(resolve(file));
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    let json;
    let bin = null;
    const isGlb = bytes.byteLength >= 12 && view.getUint32(0, true) === kGlb.magic;
    if (isGlb) {
        if (view.getUint32(4, true) !== kGlb.version) {
            throw new Error(`GLB version ${view.getUint32(4, true)}, not 2`);
        }
        let offset = 12;
        while (offset + 8 <= bytes.byteLength) {
            const length = view.getUint32(offset, true);
            const type = view.getUint32(offset + 4, true);
            const data = bytes.subarray(offset + 8, offset + 8 + length);
            if (type === kGlb.chunkJson && json === undefined) {
                json = JSON.parse(new TextDecoder().decode(data));
            } else if (type === kGlb.chunkBin && bin === null) {
                bin = data;
            }
            offset += 8 + length;
        }
        if (json === undefined) {
            throw new Error('GLB without a JSON chunk');
        }
    } else {
        json = JSON.parse(new TextDecoder().decode(bytes));
    }
    const buffers = [];
    for (const [i, buffer] of (json.buffers ?? []).entries()) {
        let data;
        if (buffer.uri === undefined) {
            if (!isGlb || i !== 0 || bin === null) {
                throw new Error(`buffer ${i} has no uri and is not a GLB's BIN chunk`);
            }
            data = bin;
        } else if (buffer.uri.startsWith('data:')) {
            data = dataUriBytes(buffer.uri);
        } else {
            data = asBytes(await readFile(resolve(dir, decodeURIComponent(buffer.uri))));
        }
        if (data.byteLength < buffer.byteLength) {
            throw new Error(`buffer ${i}: ${data.byteLength} bytes, byteLength says ${buffer.byteLength}`);
        }
        buffers.push(data);
    }
    return { file, dir, bytes, isGlb, json, buffers };
}

function bufferViewBytes(doc, index) {
    const view = doc.json.bufferViews?.[index];
    if (view === undefined) {
        throw new Error(`no bufferView ${index}`);
    }
    const buffer = doc.buffers[view.buffer];
    if (buffer === undefined) {
        throw new Error(`bufferView ${index}: no buffer ${view.buffer}`);
    }
    const start = view.byteOffset ?? 0;
    if (start + view.byteLength > buffer.byteLength) {
        throw new Error(`bufferView ${index} runs past the end of buffer ${view.buffer}`);
    }
    return buffer.subarray(start, start + view.byteLength);
}

const kComponents = kTypeComponents;

/// An uncompressed accessor's values, as Float32Array (floats) or Uint32Array (integers).
function readAccessor(doc, index) {
    const accessor = doc.json.accessors?.[index];
    if (accessor === undefined) {
        throw new Error(`no accessor ${index}`);
    }
    if (accessor.bufferView === undefined || accessor.sparse !== undefined) {
        throw new Error(`accessor ${index} has no plain bufferView`);
    }
    const n = kComponents[accessor.type];
    const [size, get] = kComponentReaders[accessor.componentType] ?? [];
    if (n === undefined || size === undefined) {
        throw new Error(`accessor ${index}: unknown type ${accessor.type}/${accessor.componentType}`);
    }
    const bytes = bufferViewBytes(doc, accessor.bufferView);
    const stride = doc.json.bufferViews[accessor.bufferView].byteStride ?? n * size;
    const start = accessor.byteOffset ?? 0;
    if (accessor.count > 0 && start + (accessor.count - 1) * stride + n * size > bytes.byteLength) {
        throw new Error(`accessor ${index} runs past the end of its bufferView`);
    }
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const out =
        accessor.componentType === kComponentType.float32
            ? new Float32Array(accessor.count * n)
            : new Uint32Array(accessor.count * n);
    for (let i = 0; i < accessor.count; ++i) {
        for (let j = 0; j < n; ++j) {
            out[i * n + j] = get(view, start + i * stride + j * size);
        }
    }
    return out;
}

// ------------------------------------------------------------------------------------------------
// Draco

const kDracoTypes = {
    Float32Array: 'DT_FLOAT32',
    Int8Array: 'DT_INT8',
    Int16Array: 'DT_INT16',
    Int32Array: 'DT_INT32',
    Uint8Array: 'DT_UINT8',
    Uint16Array: 'DT_UINT16',
    Uint32Array: 'DT_UINT32',
};

/// Decodes a KHR_draco_mesh_compression bufferView the way three's DRACOLoader worker does
/// (decodeGeometry with useUniqueIDs: GetAttributeByUniqueId, GetAttributeDataArrayForAllPoints,
/// GetTrianglesUInt32Array). attributeIds: name -> Draco unique id; attributeTypes: name ->
/// typed array name (default Float32Array). Returns { numPoints, numFaces, index: Uint32Array,
/// attributes: { name: { itemSize, array } | null } } (null: no attribute with that id).
function dracoDecode(draco, bytes, attributeIds, attributeTypes = {}) {
    const array = new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const decoder = new draco.Decoder();
    const mesh = new draco.Mesh();
    try {
        const type = decoder.GetEncodedGeometryType(array);
        if (type !== draco.TRIANGULAR_MESH) {
            throw new Error(`encoded geometry type ${type}, not TRIANGULAR_MESH`);
        }
        const status = decoder.DecodeArrayToMesh(array, array.byteLength, mesh);
        if (!status.ok() || mesh.ptr === 0) {
            throw new Error(`decoding failed: ${status.error_msg()}`);
        }
        const numPoints = mesh.num_points();
        const numFaces = mesh.num_faces();
        const attributes = {};
        for (const [name, id] of Object.entries(attributeIds)) {
            const attribute = decoder.GetAttributeByUniqueId(mesh, id);
            if (!attribute || attribute.ptr === 0) {
                attributes[name] = null;
                continue;
            }
            const typeName = attributeTypes[name] ?? 'Float32Array';
            const TypedArray = globalThis[typeName];
            const itemSize = attribute.num_components();
            const byteLength = numPoints * itemSize * TypedArray.BYTES_PER_ELEMENT;
            const ptr = draco._malloc(byteLength);
            const ok = decoder.GetAttributeDataArrayForAllPoints(
                mesh,
                attribute,
                draco[kDracoTypes[typeName]],
                byteLength,
                ptr,
            );
            const values = new TypedArray(draco.HEAPU8.buffer, ptr, numPoints * itemSize).slice();
            draco._free(ptr);
            if (!ok) {
                throw new Error(`cannot read attribute ${name} (unique id ${id})`);
            }
            attributes[name] = { itemSize, array: values };
        }
        const byteLength = numFaces * 3 * 4;
        const ptr = draco._malloc(byteLength);
        decoder.GetTrianglesUInt32Array(mesh, byteLength, ptr);
        const index = new Uint32Array(draco.HEAPU8.buffer, ptr, numFaces * 3).slice();
        draco._free(ptr);
        return { numPoints, numFaces, index, attributes };
    } finally {
        draco.destroy(mesh);
        draco.destroy(decoder);
    }
}

/// What GLTFLoader needs of a DRACOLoader (three r187, GLTFDracoMeshCompressionExtension):
/// preload() in its constructor, then per primitive
/// decodeDracoFile(bufferView, callback, threeAttributeMap, attributeTypeMap, colorSpace, onError)
/// with threeAttributeMap: three attribute name ('position', 'normal', '_coarse_position') ->
/// Draco unique id. three's DRACOLoader decodes in Web Workers, which Node lacks; this decodes
/// in-process with draco3d and builds the BufferGeometry as DRACOLoader._createGeometry does
/// (our attributes are float, so no interleaving is needed).
class DracoAdapter {
    constructor(THREE, draco) {
        this.THREE = THREE;
        this.draco = draco;
        this.decoded = 0;
    }

    preload() {
        return this;
    }

    decodeDracoFile(buffer, callback, attributeIDs, attributeTypes, _colorSpace, onError = () => {}) {
        try {
            const data = dracoDecode(this.draco, new Uint8Array(buffer), attributeIDs ?? {}, attributeTypes ?? {});
            const geometry = new this.THREE.BufferGeometry();
            geometry.setIndex(new this.THREE.BufferAttribute(data.index, 1));
            for (const [name, attribute] of Object.entries(data.attributes)) {
                if (attribute === null) {
                    throw new Error(`no Draco attribute with unique id ${attributeIDs[name]} (${name})`);
                }
                geometry.setAttribute(name, new this.THREE.BufferAttribute(attribute.array, attribute.itemSize));
            }
            ++this.decoded;
            callback(geometry);
        } catch (error) {
            onError(error);
        }
        return Promise.resolve();
    }

    dispose() {
        return this;
    }
}

// ------------------------------------------------------------------------------------------------
// helpers

/// A vertex key by exact float value (-0 and 0 alike, as a GPU would weld them).
function positionKey(p, i) {
    return `${p[3 * i] + 0},${p[3 * i + 1] + 0},${p[3 * i + 2] + 0}`;
}

/// Checks that triangles (list of [keyA, keyB, keyC], oriented) form a closed, consistently
/// oriented surface: every directed edge used once and its reverse once. Returns a list of
/// problems (empty when fine).
function closedSurfaceProblems(triangles) {
    const directed = new Map();
    let degenerate = 0;
    for (const [a, b, c] of triangles) {
        if (a === b || b === c || c === a) {
            ++degenerate;
        }
        for (const [u, v] of [
            [a, b],
            [b, c],
            [c, a],
        ]) {
            const key = `${u}|${v}`;
            directed.set(key, (directed.get(key) ?? 0) + 1);
        }
    }
    const problems = [];
    if (degenerate > 0) {
        problems.push(`${degenerate} degenerate triangles`);
    }
    let badCount = 0;
    let example = '';
    const undirected = new Map();
    for (const [key, count] of directed) {
        const [u, v] = key.split('|');
        const reverse = directed.get(`${v}|${u}`) ?? 0;
        const edge = u < v ? `${u}|${v}` : `${v}|${u}`;
        undirected.set(edge, (undirected.get(edge) ?? 0) + count);
        if (count !== 1 || reverse !== 1) {
            ++badCount;
            example ||= `(${u})->(${v}) used ${count}x, reverse ${reverse}x`;
        }
    }
    const notTwice = [...undirected.entries()].filter(([, count]) => count !== 2);
    if (notTwice.length > 0) {
        problems.push(
            `${notTwice.length} of ${undirected.size} edges not used exactly twice, e.g. ` +
                `(${notTwice[0][0].replace('|', ')-(')}) used ${notTwice[0][1]}x`,
        );
    } else if (badCount > 0) {
        problems.push(
            `${badCount} directed edges without exactly one reverse (inconsistent ` + `orientation), e.g. ${example}`,
        );
    }
    return problems;
}

function trianglesOf(positions, index) {
    const keys = [];
    for (let i = 0; i < positions.length / 3; ++i) {
        keys.push(positionKey(positions, i));
    }
    const triangles = [];
    const count = index ? index.length : positions.length / 3;
    for (let t = 0; t + 2 < count; t += 3) {
        const at = (k) => keys[index ? index[t + k] : t + k];
        triangles.push([at(0), at(1), at(2)]);
    }
    return triangles;
}

/// A triangle's key independent of which vertex is listed first (orientation kept).
function triangleKey([a, b, c]) {
    const rotations = [`${a}/${b}/${c}`, `${b}/${c}/${a}`, `${c}/${a}/${b}`];
    return rotations.sort()[0];
}

function bitsEqual(a, b) {
    if (a.length !== b.length) {
        return false;
    }
    const ua = new Uint32Array(a.buffer, a.byteOffset, a.length);
    const ub = new Uint32Array(b.buffer, b.byteOffset, b.length);
    return ua.every((v, i) => v === ub[i]);
}

function meshLabel(json, index) {
    const name = json.meshes?.[index]?.name;
    return name === undefined ? `mesh ${index}` : `mesh ${index} '${name}'`;
}

/// World (scene-frame) matrices of the nodes, from the JSON.
function nodeWorldMatrices(THREE, json) {
    const nodes = json.nodes ?? [];
    const parent = new Array(nodes.length).fill(-1);
    nodes.forEach((node, i) => (node.children ?? []).forEach((c) => (parent[c] = i)));
    const local = nodes.map((node) => {
        const m = new THREE.Matrix4();
        if (node.matrix !== undefined) {
            m.fromArray(node.matrix);
        } else {
            m.compose(
                new THREE.Vector3(...(node.translation ?? [0, 0, 0])),
                new THREE.Quaternion(...(node.rotation ?? [0, 0, 0, 1])),
                new THREE.Vector3(...(node.scale ?? [1, 1, 1])),
            );
        }
        return m;
    });
    const world = new Array(nodes.length).fill(null);
    const worldOf = (i, depth = 0) => {
        if (world[i] === null) {
            if (depth > nodes.length) {
                throw new Error('node hierarchy has a cycle');
            }
            world[i] =
                parent[i] < 0
                    ? local[i].clone()
                    : worldOf(parent[i], depth + 1)
                          .clone()
                          .multiply(local[i]);
        }
        return world[i];
    };
    return nodes.map((_, i) => worldOf(i));
}

// ------------------------------------------------------------------------------------------------
// the checks of one file

class FileCheck {
    constructor(deps, decoders, validateExtension, file) {
        this.deps = deps;
        this.decoders = decoders;
        this.validateExtension = validateExtension;
        this.file = file;
        this.failures = [];
        this.stats = {
            objects: 0,
            clusters: 0,
            groups: 0,
            chunks: 0,
            baseTriangles: 0,
            totalTriangles: 0,
            cuts: 0,
        };
    }

    fail(section, message) {
        this.failures.push(`[${section}] ${message}`);
    }

    async run() {
        let doc;
        try {
            doc = await readGltf(this.file);
        } catch (error) {
            this.fail('read', `cannot read: ${error.message}`);
            return;
        }
        this.doc = doc;
        const json = doc.json;
        this.objects = (json.nodes ?? [])
            .map((node, i) => ({ node, index: i, ext: node.extensions?.[kExtension] }))
            .filter((o) => o.ext !== undefined);
        this.stats.objects = this.objects.length;
        if (this.objects.length === 0) {
            this.fail('dag', `no node has the extension ${kExtension}`);
        }
        for (const [section, step] of [
            ['schema', () => this.checkSchema()],
            ['dag', () => this.checkDag()],
            ['draco', () => this.checkDraco()],
            ['cut', () => this.checkCuts()],
            ['three', () => this.checkThree()],
            ['transform', () => this.checkTransform()],
        ]) {
            try {
                await step();
            } catch (error) {
                this.fail(section, `${error.message ?? error}`);
            }
        }
    }

    // [schema] -----------------------------------------------------------------------------------
    checkSchema() {
        const file = this.validateExtension.file;
        if (!file(this.doc.json.extensions?.[kExtension])) {
            for (const e of file.errors) {
                this.fail('schema', `/extensions/${kExtension}${e.instancePath} ${e.message} (${e.schemaPath})`);
            }
        }
        for (const { node, index, ext } of this.objects) {
            if (!this.validateExtension(ext)) {
                for (const e of this.validateExtension.errors) {
                    this.fail(
                        'schema',
                        `node ${index} '${node.name}': ${kExtension}${e.instancePath} ` +
                            `${e.message} (${e.schemaPath})`,
                    );
                }
            }
        }
    }

    // [dag] --------------------------------------------------------------------------------------
    // The JSON extension object (types, buffer views) and the binary DAG table (strata-decode.js:
    // validation points 1-8 of schema/README.md), and the base mesh's glTF form (point 9).
    checkDag() {
        const json = this.doc.json;
        const accessors = json.accessors ?? [];
        this.tables = new Map(); // node index -> parseDagTable's result
        const usedViews = new Set(accessors.map((a) => a.bufferView).filter((v) => v !== undefined));
        for (const { node, index, ext } of this.objects) {
            const where = `node ${index} '${node.name}'`;
            const fail = (message) => this.fail('dag', `${where}: ${message}`);
            let table;
            try {
                const info = readExtension(ext, json, `${where}/extensions/${kExtension}`);
                const bytes = bufferViewBytes(this.doc, info.dag);
                table = parseDagTable(bytes, info, chunksByteLength(info, json), `${where} DAG table`);
                for (const view of [info.dag, info.chunks].filter((v) => v !== undefined)) {
                    if (usedViews.has(view)) fail(`buffer view ${view} (DAG table or chunks) is used by an accessor`);
                    const def = json.bufferViews[view];
                    if (def.byteStride !== undefined || def.target !== undefined) {
                        fail(`buffer view ${view} has a byteStride or target`);
                    }
                }
                if ((json.bufferViews[info.dag].byteOffset ?? 0) % 4 !== 0) fail('the DAG table is not 4-byte aligned');
            } catch (error) {
                fail(error.message);
                continue;
            }
            this.stats.clusters += table.clusters.length;
            this.stats.groups += table.groups.length;
            // the base: one Draco primitive with POSITION, NORMAL, _CLUSTER
            const primitives = json.meshes?.[node.mesh]?.primitives;
            const primitive = primitives?.[0];
            const draco = primitive?.extensions?.[kDraco];
            const roots = table.clusters.filter((c) => c.consumer === undefined).length;
            if (primitives?.length !== 1 || (primitive.mode ?? 4) !== 4 || draco === undefined) {
                fail(`the base ${meshLabel(json, node.mesh)} is not one TRIANGLES primitive with ${kDraco}`);
                continue;
            }
            const expect = {
                [kAttributes.position]: ['VEC3', [kComponentType.float32]],
                [kAttributes.normal]: ['VEC3', [kComponentType.float32]],
                [kClusterAttribute]: ['SCALAR', [roots > 256 ? kComponentType.uint16 : kComponentType.uint8]],
            };
            // one root: _CLUSTER may be absent (every base triangle is root 0)
            if (roots === 1 && primitive.attributes?.[kClusterAttribute] === undefined)
                delete expect[kClusterAttribute];
            let ok = true;
            for (const [name, [type, componentTypes]] of Object.entries(expect)) {
                const accessor = accessors[primitive.attributes?.[name]];
                if (
                    accessor === undefined ||
                    draco.attributes?.[name] === undefined ||
                    accessor.type !== type ||
                    !componentTypes.includes(accessor.componentType) ||
                    accessor.bufferView !== undefined
                ) {
                    fail(`base ${name}: accessor ${JSON.stringify(accessor)}, Draco id ${draco.attributes?.[name]}`);
                    ok = false;
                }
            }
            if (accessors[primitive.attributes?.[kAttributes.position]]?.min === undefined) {
                fail('base POSITION has no min/max');
            }
            if (ok) this.tables.set(index, table);
        }
    }

    // [draco] / [base] -----------------------------------------------------------------------------
    // Every chunk and every base decodes with both decoders bit-identically; attributes, counts,
    // clusters and slots as specified; positions on the grid; spheres contain the vertices.
    checkDraco() {
        const json = this.doc.json;
        const accessors = json.accessors ?? [];
        const worlds = nodeWorldMatrices(this.deps.THREE, json);
        this.geometry = new Map(); // node index -> per cluster { position, coarse, index }
        for (const { node, index } of this.objects) {
            const table = this.tables.get(index);
            if (table === undefined) continue;
            const where = `node ${index} '${node.name}'`;
            const ext = node.extensions[kExtension];
            const geometry = new Array(table.clusters.length);
            const world = worlds[index];
            const v = new this.deps.THREE.Vector3();
            // the farthest of the points (all, or those an index uses) from a sphere's centre
            const farthest = (position, sphere, index = null) => {
                let worst = 0;
                const n = index === null ? position.length / 3 : index.length;
                for (let k = 0; k < n; ++k) {
                    const i = 3 * (index === null ? k : index[k]);
                    v.set(position[i], position[i + 1], position[i + 2]).applyMatrix4(world);
                    worst = Math.max(worst, Math.hypot(v.x - sphere[0], v.y - sphere[1], v.z - sphere[2]));
                }
                return worst;
            };
            // decodes with both decoders; null (reported) when they fail or disagree
            const decodeBoth = (label, bytes, ids, types) => {
                const decoded = {};
                for (const [name, module] of Object.entries(this.decoders)) {
                    try {
                        decoded[name] = dracoDecode(module, bytes, ids, types);
                    } catch (error) {
                        this.fail('draco', `${label}: the ${name} decoder fails: ${error.message}`);
                        return null;
                    }
                }
                const [first, second] = Object.values(decoded);
                const same =
                    first.numPoints === second.numPoints &&
                    bitsEqual(first.index, second.index) &&
                    Object.keys(ids).every(
                        (a) =>
                            (first.attributes[a] === null) === (second.attributes[a] === null) &&
                            (first.attributes[a] === null ||
                                bitsEqual(first.attributes[a].array, second.attributes[a].array)),
                    );
                if (!same) {
                    this.fail('draco', `${label}: the decoders (${Object.keys(decoded)}) disagree`);
                    return null;
                }
                for (const [name, attribute] of Object.entries(first.attributes)) {
                    if (attribute === null) {
                        this.fail('draco', `${label}: no Draco attribute ${name} (unique id ${ids[name]})`);
                        return null;
                    }
                }
                if (first.numPoints > 3 * first.numFaces) {
                    this.fail('draco', `${label}: ${first.numPoints} points for ${first.numFaces} triangles`);
                }
                return first;
            };
            const addClusters = (label, clusters, d, coarse) => {
                const { order, start } = splitByCluster(
                    d.index,
                    d.attributes[kClusterAttribute].array,
                    clusters.length,
                    label,
                );
                clusters.forEach((c, k) => {
                    geometry[c] = {
                        position: d.attributes.POSITION.array,
                        coarse,
                        index: order.subarray(start[k], start[k + 1]),
                    };
                    this.stats.totalTriangles += (start[k + 1] - start[k]) / 3;
                });
            };
            // the base
            const roots = [];
            table.clusters.forEach((c, ci) => c.consumer === undefined && roots.push(ci));
            const primitive = json.meshes[node.mesh].primitives[0];
            const draco = primitive.extensions[kDraco];
            const baseLabel = `${where} base`;
            try {
                const ids = { POSITION: draco.attributes.POSITION, NORMAL: draco.attributes.NORMAL };
                if (draco.attributes[kClusterAttribute] !== undefined)
                    ids[kClusterAttribute] = draco.attributes[kClusterAttribute];
                const d = decodeBoth(baseLabel, bufferViewBytes(this.doc, draco.bufferView), ids, {
                    [kClusterAttribute]: 'Uint32Array',
                });
                if (d !== null && d.attributes[kClusterAttribute] === undefined) {
                    d.attributes[kClusterAttribute] = { itemSize: 1, array: new Uint32Array(d.numPoints) };
                }
                if (d !== null) {
                    const positionAccessor = accessors[primitive.attributes.POSITION];
                    if (
                        d.numPoints !== positionAccessor.count ||
                        3 * d.numFaces !== accessors[primitive.indices]?.count
                    ) {
                        this.fail(
                            'base',
                            `${baseLabel}: ${d.numPoints} points, ${d.numFaces} triangles decoded; accessors say ${positionAccessor.count}, ${accessors[primitive.indices]?.count / 3}`,
                        );
                    }
                    this.checkPositions(
                        'base',
                        baseLabel,
                        'POSITION',
                        d.attributes.POSITION.array,
                        positionAccessor,
                        table.gridStep,
                    );
                    const normal = d.attributes.NORMAL.array;
                    for (let i = 0; i < normal.length; i += 3) {
                        const length = Math.hypot(normal[i], normal[i + 1], normal[i + 2]);
                        if (!(Math.abs(length - 1) < 0.01)) {
                            this.fail('base', `${baseLabel}: NORMAL ${i / 3} has length ${length}`);
                            break;
                        }
                    }
                    addClusters(baseLabel, roots, d, d.attributes.POSITION.array);
                    this.stats.baseTriangles += d.numFaces;
                }
            } catch (error) {
                this.fail('base', `${baseLabel}: ${error.message}`);
            }
            // the chunks
            const fileChunks = this.doc.json.extensions?.[kExtension]?.chunks; // one view for every object
            const chunks = fileChunks === undefined ? new Uint8Array(0) : bufferViewBytes(this.doc, fileChunks);
            table.groups.forEach((group, g) => {
                const label = `${where} group ${g}`;
                try {
                    const bytes = chunks.subarray(group.chunkOffset, group.chunkOffset + group.chunkLength);
                    const ids = {
                        POSITION: kChunkAttributeIds.position,
                        [kClusterAttribute]: kChunkAttributeIds.cluster,
                        [kSlotAttribute]: kChunkAttributeIds.slot,
                    };
                    const d = decodeBoth(label, bytes, ids, {
                        [kClusterAttribute]: 'Uint32Array',
                        [kSlotAttribute]: 'Uint32Array',
                    });
                    if (d === null) return;
                    ++this.stats.chunks;
                    const position = d.attributes.POSITION.array;
                    this.checkPositions('draco', label, 'POSITION', position, null, table.gridStep);
                    const coarse = resolveSlots(position, d.index, d.attributes[kSlotAttribute].array, label);
                    addClusters(label, group.consumed, d, coarse);
                    const worst = farthest(position, group.sphere);
                    if (worst > group.sphere[3] * (1 + 1e-6) + 1e-9) {
                        this.fail(
                            'dag',
                            `${label}: a consumed vertex lies ${worst} m from the sphere's centre, radius ${group.sphere[3]}`,
                        );
                    }
                } catch (error) {
                    this.fail('draco', `${label}: ${error.message}`);
                }
            });
            // produced clusters lie in their producer's sphere too
            table.groups.forEach((group, g) => {
                for (const c of group.produced) {
                    if (geometry[c] === undefined) continue;
                    const worst = farthest(geometry[c].position, group.sphere, geometry[c].index);
                    if (worst > group.sphere[3] * (1 + 1e-6) + 1e-9) {
                        this.fail(
                            'dag',
                            `${where} group ${g}: a vertex of produced cluster ${c} lies ${worst} m from the sphere's centre, radius ${group.sphere[3]}`,
                        );
                    }
                }
            });
            this.geometry.set(index, geometry);
        }
    }

    /// Finite, within the accessor's min/max (when given), on the grid (value / gridStep integer).
    checkPositions(section, label, name, values, accessor, gridStep) {
        const fail = (message) => this.fail(section, `${label}: ${name} ${message}`);
        let offGrid = -1;
        let outside = -1;
        for (let i = 0; i < values.length; ++i) {
            const x = values[i];
            if (!Number.isFinite(x)) {
                fail(`value ${i} is ${x}`);
                return;
            }
            if (offGrid < 0 && gridStep !== null && !Number.isInteger(x / gridStep)) {
                offGrid = i;
            }
            if (outside < 0 && accessor?.min !== undefined && !(x >= accessor.min[i % 3] && x <= accessor.max[i % 3])) {
                outside = i;
            }
        }
        if (offGrid >= 0) {
            fail(
                `value ${values[offGrid]} (vertex ${Math.floor(offGrid / 3)}) is not on the grid, gridStep ${gridStep}`,
            );
        }
        if (outside >= 0) {
            const axis = outside % 3;
            fail(
                `value ${values[outside]} (vertex ${Math.floor(outside / 3)}, axis ${axis}) outside the accessor's ` +
                    `[${accessor.min[axis]}, ${accessor.max[axis]}]`,
            );
        }
    }

    // [cut] --------------------------------------------------------------------------------------
    // Every level cut (refine exactly the groups of level > L) is a closed, consistently oriented
    // surface (positions bit-identical where shared), and every group's consumed clusters at their
    // coarse positions (decoded from _SLOT) give exactly its produced clusters' triangles.
    checkCuts() {
        for (const { node, index } of this.objects) {
            const table = this.tables?.get(index);
            const geometry = this.geometry?.get(index);
            if (
                table === undefined ||
                geometry === undefined ||
                table.clusters.some((_, c) => geometry[c] === undefined)
            ) {
                continue; // reported already
            }
            const where = `node ${index} '${node.name}'`;
            const { clusters, groups } = table;
            const triangles = (c, coarse = false) => {
                const g = geometry[c];
                return trianglesOf(coarse ? g.coarse : g.position, g.index);
            };
            const maxLevel = Math.max(0, ...groups.map((g) => g.level));
            for (let level = 0; level <= maxLevel; ++level) {
                const refined = groups.map((g) => g.level > level);
                const drawn = clusters
                    .map((_, c) => c)
                    .filter((c) => {
                        const { producer, consumer } = clusters[c];
                        return (
                            (producer === undefined || !refined[producer]) &&
                            (consumer === undefined || refined[consumer])
                        );
                    });
                ++this.stats.cuts;
                for (const problem of closedSurfaceProblems(drawn.flatMap((c) => triangles(c)))) {
                    this.fail('cut', `${where}: level ${level} cut (${drawn.length} clusters): ${problem}`);
                }
            }
            groups.forEach((g, gi) => {
                const count = (list) => {
                    const m = new Map();
                    for (const t of list) {
                        if (t[0] !== t[1] && t[1] !== t[2] && t[2] !== t[0]) {
                            const key = triangleKey(t);
                            m.set(key, (m.get(key) ?? 0) + 1);
                        }
                    }
                    return m;
                };
                const morphed = count(g.consumed.flatMap((c) => triangles(c, true)));
                const produced = count(g.produced.flatMap((c) => triangles(c)));
                let differ = 0;
                let example = '';
                for (const key of new Set([...morphed.keys(), ...produced.keys()])) {
                    if ((morphed.get(key) ?? 0) !== (produced.get(key) ?? 0)) {
                        ++differ;
                        example ||= `${key}: ${morphed.get(key) ?? 0}x morphed, ${produced.get(key) ?? 0}x produced`;
                    }
                }
                if (differ > 0) {
                    this.fail(
                        'cut',
                        `${where}: group ${gi}: its consumed clusters at their slot-decoded coarse positions differ from ` +
                            `its produced clusters in ${differ} triangles, e.g. ${example}`,
                    );
                }
            });
        }
    }

    // [three] ------------------------------------------------------------------------------------
    async checkThree() {
        const { THREE, GLTFLoader } = this.deps;
        const doc = this.doc;
        const json = doc.json;
        // External buffers: GLTFLoader resolves each buffer's uri against the path given to parse()
        // (LoaderUtils.resolveURL) and loads it with a FileLoader, which uses fetch(); Node's fetch
        // reads neither plain paths nor (in Node 20) file: URLs. The URL modifier of the loader's
        // LoadingManager turns each resolved path into a data: URL of the file's bytes, which
        // Node's fetch does read. So GLTFLoader's own code still resolves the uris and requests
        // each buffer; we only supply the bytes (no rewriting of the glTF into a GLB).
        // FileLoader reports download progress with the DOM's ProgressEvent, which Node (20) lacks:
        // a minimal stand-in (FileLoader only constructs it and passes it to onProgress).
        globalThis.ProgressEvent ??= class ProgressEvent extends Event {
            constructor(type, { lengthComputable = false, loaded = 0, total = 0 } = {}) {
                super(type);
                Object.assign(this, { lengthComputable, loaded, total });
            }
        };
        const manager = new THREE.LoadingManager();
        const requested = [];
        manager.setURLModifier((url) => {
            if (/^(data|blob):/i.test(url)) {
                return url;
            }
            requested.push(url);
            const bytes = readFileSync(decodeURIComponent(url));
            return `data:application/octet-stream;base64,${bytes.toString('base64')}`;
        });
        const loader = new GLTFLoader(manager);
        const adapter = new DracoAdapter(THREE, this.decoders.draco3d);
        loader.setDRACOLoader(adapter);
        const data = doc.bytes.buffer.slice(doc.bytes.byteOffset, doc.bytes.byteOffset + doc.bytes.byteLength);
        const gltf = await new Promise((resolveLoad, rejectLoad) =>
            loader.parse(data, `${doc.dir}/`, resolveLoad, rejectLoad),
        );
        const fail = (message) => this.fail('three', message);
        const expectedRequests = (json.buffers ?? []).filter(
            (b) => b.uri !== undefined && !b.uri.startsWith('data:'),
        ).length;
        // Buffers load lazily, when a bufferView in them is needed; the chunks below need the rest.
        const associations = gltf.parser.associations;
        const nodeOf = (object) => associations.get(object)?.nodes;
        // the scene: root "patient", its one child "storage" (the shared storage frame), one
        // child of that per object
        const roots = gltf.scene.children;
        const patient = roots.find((o) => json.nodes[nodeOf(o)]?.name === kPatientNode);
        if (roots.length !== 1 || patient === undefined || patient.name !== kPatientNode) {
            fail(`the scene's roots are [${roots.map((o) => o.name)}], not one node "patient"`);
        }
        const storage = patient?.children.length === 1 ? patient.children[0] : undefined;
        if (storage === undefined || json.nodes[nodeOf(storage)]?.name !== kStorageNode) {
            fail(`"patient" has children [${(patient?.children ?? []).map((o) => o.name)}], not one node "storage"`);
        }
        const objectNodes = new Set(this.objects.map((o) => o.index));
        const children = storage?.children ?? [];
        const childNodes = children.map(nodeOf);
        if (children.length !== objectNodes.size || !childNodes.every((i) => objectNodes.has(i))) {
            fail(
                `"storage" has children [${children.map((o) => o.name)}] (nodes ${childNodes}), ` +
                    `not the ${objectNodes.size} nodes with ${kExtension} (${[...objectNodes]})`,
            );
        }
        gltf.scene.updateMatrixWorld(true);
        for (const object of children) {
            const nodeIndex = nodeOf(object);
            const node = json.nodes[nodeIndex];
            const ext = node?.extensions?.[kExtension];
            if (ext === undefined) {
                continue;
            }
            const where = `node ${nodeIndex} '${node.name}'`;
            if (object.name !== THREE.PropertyBinding.sanitizeNodeName(node.name ?? '')) {
                fail(`${where}: three named it '${object.name}'`);
            }
            if (object.userData?.gltfExtensions?.[kExtension] === undefined) {
                fail(`${where}: the extension is missing from userData.gltfExtensions`);
            }
            if (!object.matrixWorld.elements.every(Number.isFinite) || object.matrixWorld.determinant() <= 0) {
                fail(
                    `${where}: world matrix not finite or not positive (determinant ${object.matrixWorld.determinant()})`,
                );
            }
            // the base: the node's object is the Mesh (one primitive) or a Group of Meshes
            const meshes = [];
            object.traverse((o) => {
                if (o.isMesh && associations.get(o)?.meshes === node.mesh) {
                    meshes.push(o);
                }
            });
            const primitives = json.meshes?.[node.mesh]?.primitives ?? [];
            if (meshes.length !== 1 || primitives.length !== 1) {
                fail(
                    `${where}: three made ${meshes.length} meshes of the base ${meshLabel(json, node.mesh)}, ` +
                        `which has ${primitives.length} primitives (expected one)`,
                );
            }
            const hasCluster = primitives[0]?.attributes?.[kClusterAttribute] !== undefined;
            for (const mesh of meshes) {
                if (
                    hasCluster &&
                    mesh.geometry.getAttribute(kThreeClusterAttribute)?.count !==
                        mesh.geometry.getAttribute('position')?.count
                ) {
                    fail(`${where}: the base as loaded by three has no ${kThreeClusterAttribute} per point`);
                }
                if (mesh.geometry.getAttribute('normal') === undefined)
                    fail(`${where}: the base has no normals in three`);
            }
            const triangles = [];
            for (const mesh of meshes) {
                const p = associations.get(mesh).primitives;
                const primitive = primitives[p];
                const label = `${where} base primitive ${p}`;
                this.checkThreeGeometry(label, mesh.geometry, primitive);
                const position = mesh.geometry.getAttribute('position');
                if (position !== undefined) {
                    triangles.push(...trianglesOf(position.array, mesh.geometry.index?.array ?? null));
                }
            }
            for (const problem of closedSurfaceProblems(triangles)) {
                fail(`${where}: the base mesh as loaded by three is not closed: ${problem}`);
            }
        }
        if (requested.length !== expectedRequests) {
            fail(`GLTFLoader requested ${requested.length} external buffers, the file has ${expectedRequests}`);
        }
        if (adapter.decoded !== this.objects.length) {
            fail(`the Draco adapter decoded ${adapter.decoded} primitives for ${this.objects.length} objects' bases`);
        }
    }

    checkThreeGeometry(label, geometry, primitive) {
        const fail = (message) => this.fail('three', `${label}: ${message}`);
        const accessors = this.doc.json.accessors ?? [];
        const position = geometry.getAttribute('position');
        if (position === undefined) {
            fail('no position attribute');
            return;
        }
        const positionAccessor = accessors[primitive?.attributes?.POSITION];
        if (position.count !== positionAccessor?.count) {
            fail(`${position.count} positions, POSITION accessor count ${positionAccessor?.count}`);
        }
        const values = position.array;
        const bad = values.findIndex((x) => !Number.isFinite(x));
        if (bad >= 0) {
            fail(`position value ${bad} is ${values[bad]}`);
        }
        const indexAccessor = accessors[primitive?.indices];
        const indexCount = geometry.index ? geometry.index.count : position.count;
        if (indexCount !== indexAccessor?.count || indexCount % 3 !== 0) {
            fail(
                `${indexCount / 3} triangles, indices accessor count ${indexAccessor?.count} ` +
                    `(${indexAccessor?.count / 3} triangles)`,
            );
        }
    }

    // [transform] --------------------------------------------------------------------------------
    async checkTransform() {
        const { NodeIO, KHRONOS_EXTENSIONS } = this.deps;
        const json = this.doc.json;
        const messages = [];
        const logger = {
            debug: () => {},
            info: () => {},
            warn: (m) => messages.push(m),
            error: (m) => messages.push(m),
        };
        const io = new NodeIO()
            .setLogger(logger)
            .registerExtensions(KHRONOS_EXTENSIONS)
            .registerDependencies({ 'draco3d.decoder': this.decoders.draco3d });
        const document = this.doc.isGlb ? await io.readBinary(this.doc.bytes) : await io.read(this.file);
        const fail = (message) => this.fail('transform', message);
        for (const message of messages) {
            // gltf-transform has no handler for our extension and says so; anything else fails
            if (message !== `Missing optional extension, "${kExtension}".`) {
                fail(`NodeIO: ${message}`);
            }
        }
        const root = document.getRoot();
        const meshes = root.listMeshes();
        if (meshes.length !== (json.meshes ?? []).length) {
            fail(`${meshes.length} meshes read, the file has ${(json.meshes ?? []).length}`);
        }
        const names = root.listNodes().map((n) => n.getName());
        const expected = (json.nodes ?? []).map((n) => n.name ?? '');
        if (JSON.stringify(names) !== JSON.stringify(expected)) {
            fail(`node names [${names}], the file has [${expected}]`);
        }
        const accessors = json.accessors ?? [];
        meshes.forEach((mesh, mi) => {
            const primitives = mesh.listPrimitives();
            const defs = json.meshes?.[mi]?.primitives ?? [];
            if (primitives.length !== defs.length) {
                fail(`${meshLabel(json, mi)}: ${primitives.length} primitives read, the file has ${defs.length}`);
                return;
            }
            primitives.forEach((p, pi) => {
                for (const [semantic, accessor] of Object.entries(defs[pi].attributes ?? {})) {
                    const count = p.getAttribute(semantic)?.getCount();
                    if (count !== accessors[accessor]?.count) {
                        fail(
                            `${meshLabel(json, mi)} primitive ${pi}: ${semantic} count ${count}, accessor ${accessors[accessor]?.count}`,
                        );
                    }
                }
                const count = p.getIndices()?.getCount();
                if (count !== accessors[defs[pi].indices]?.count) {
                    fail(
                        `${meshLabel(json, mi)} primitive ${pi}: ${count} indices, accessor ${accessors[defs[pi].indices]?.count}`,
                    );
                }
            });
        });
    }
}

// ------------------------------------------------------------------------------------------------

/// The validator of the extension object: every schema of schema/ added under its file name, so
/// the relative $refs ("glTFid.schema.json", ...) resolve. The schemas say
/// "$schema": "http://json-schema.org/draft-04/schema" (no '#', as the Khronos glTF schemas);
/// ajv-draft-04 registers its meta-schema as ".../draft-04/schema#" and normalizes ids by
/// dropping an empty fragment, so both spellings name the same meta-schema; we check that
/// explicitly and validate each schema against it (a strict ajv would otherwise also reject the
/// Khronos annotation keyword gltf_detailedDescription, which we declare).
function makeExtensionValidator(Ajv) {
    const ajv = new Ajv({ allErrors: true, strict: true });
    ajv.addKeyword({ keyword: 'gltf_detailedDescription', schemaType: 'string' });
    const names = readdirSync(kSchemaDir)
        .filter((f) => f.endsWith('.schema.json'))
        .sort();
    for (const name of names) {
        const schema = JSON.parse(readFileSync(join(kSchemaDir, name), 'utf8'));
        const meta = schema.$schema;
        if (meta !== undefined && ajv.getSchema(meta) === undefined) {
            throw new Error(`${name}: unknown $schema ${meta}`);
        }
        if (!ajv.validateSchema(schema)) {
            throw new Error(`${name} is not a valid draft-04 schema: ${ajv.errorsText(ajv.errors)}`);
        }
        ajv.addSchema(schema, name);
    }
    const validate = ajv.getSchema(kRootSchema);
    const file = ajv.getSchema(kFileSchema); // the top-level extension object
    if (validate === undefined || file === undefined) {
        throw new Error(`no ${kRootSchema} or ${kFileSchema} in ${kSchemaDir}`);
    }
    validate.file = file;
    return validate;
}

async function main(files) {
    if (files.length === 0 || files.some((f) => f.startsWith('-'))) {
        console.error('usage: node check_progressive.mjs FILE.glb|FILE.gltf...');
        return 2;
    }
    const deps = await loadDependencies();
    let validateExtension;
    try {
        validateExtension = makeExtensionValidator(deps.Ajv);
    } catch (error) {
        console.error(`check_progressive: the schemas in ${kSchemaDir}: ${error.message}`);
        return 2;
    }
    const decoders = {
        draco3d: await deps.draco3d.createDecoderModule({}),
        'three gltf': await loadThreeGltfDracoDecoder(deps.threeDir),
    };
    const threeVersion = deps.THREE.REVISION;
    console.log(
        `check_progressive: three r${threeVersion} GLTFLoader, draco3d and three's glTF Draco ` +
            `decoder, @gltf-transform/core NodeIO, ajv-draft-04; schema ${kSchemaDir}`,
    );
    let failed = 0;
    for (const file of files) {
        const check = new FileCheck(deps, decoders, validateExtension, file);
        await check.run();
        const s = check.stats;
        const shown = check.failures.slice(0, kMaxFailLinesPerFile);
        for (const failure of shown) {
            console.log(`${file}: FAIL ${failure}`);
        }
        if (check.failures.length > shown.length) {
            console.log(`${file}: FAIL ... and ${check.failures.length - shown.length} more failures`);
        }
        console.log(
            `${file}: ${check.failures.length === 0 ? 'ok' : 'FAIL'}: ${s.objects} objects, ` +
                `${s.clusters} clusters, ${s.groups} groups, ${s.chunks} chunks decoded (2 decoders, slots resolved), ` +
                `${s.cuts} level cuts closed-checked, triangles base ${s.baseTriangles} / total ${s.totalTriangles}` +
                (check.failures.length === 0 ? '' : `; ${check.failures.length} failures`),
        );
        if (check.failures.length > 0) {
            ++failed;
        }
    }
    console.log(`check_progressive: ${files.length - failed} of ${files.length} files pass`);
    return failed === 0 ? 0 : 1;
}

// An exception thrown in a loader's callback escapes every promise: report it as a failure.
process.on('uncaughtException', (error) => {
    console.log(`check_progressive: FAIL uncaught exception: ${error?.stack ?? error}`);
    process.exit(1);
});
process.exitCode = await main(process.argv.slice(2));

// Reading STRATA_progressive_mesh version 2 (schema/README.md) without three.js or the DOM: the
// extension object, the binary DAG table, a decoded chunk's clusters and its geomorph slots, and
// the normals of a drawn cut. Used by the plugin (strata-progressive.js), the viewer's tests and
// tests/node/check_progressive.mjs. Every function validates what it reads and throws an Error
// that says what, where and what was expected.
import { fineError, kChunkAttributeIds, kDagTable, kExtension, kVersion } from './strata-format.js';

const isIndex = (v) => Number.isInteger(v) && v >= 0;
const isNumber = (v) => typeof v === 'number' && Number.isFinite(v);

/// Byte length of the file's `chunks` buffer view (0 when it has none: no object has groups).
export function chunksByteLength(info, json) {
    return info.chunks === undefined ? 0 : json.bufferViews[info.chunks].byteLength;
}

/// Checks the JSON extension object of a node and the file's (top-level `extensions`: version and
/// the two buffer views every object shares; validation point 1 and the buffer views' ranges).
/// Returns { dag, dagOffset, chunks, errors, fullResolutionError, gridStep }: dag and chunks are
/// the file's buffer views (chunks undefined when no object has groups), dagOffset the byte
/// offset of the node's table in the dag view.
export function readExtension(ext, json, where = 'extension') {
    const fileWhere = `/extensions/${kExtension}`;
    const file = json.extensions?.[kExtension];
    if (typeof file !== 'object' || file === null || Array.isArray(file)) {
        throw new Error(
            `${fileWhere}: absent, expected an object (a file of an earlier strata: rebuild it with this strata)`,
        );
    }
    if (file.version !== kVersion) {
        throw new Error(
            `${fileWhere}/version: ${JSON.stringify(file.version)}, expected ${kVersion} (a version 1 file: rebuild it with this strata)`,
        );
    }
    if (typeof ext !== 'object' || ext === null || Array.isArray(ext)) throw new Error(`${where}: not an object`);
    if (!Array.isArray(ext.errors) || !ext.errors.every((e) => isNumber(e) && e >= 0)) {
        throw new Error(`${where}/errors: expected an array of finite numbers >= 0`);
    }
    // `chunks` is absent when no object has groups (a glTF buffer view cannot be empty)
    const keys = file.chunks === undefined && ext.errors.length === 0 ? ['dag'] : ['dag', 'chunks'];
    for (const key of keys) {
        const v = file[key];
        const view = isIndex(v) ? json.bufferViews?.[v] : undefined;
        if (view === undefined) throw new Error(`${fileWhere}/${key}: ${JSON.stringify(v)} is not a buffer view index`);
        const buffer = json.buffers?.[view.buffer];
        if (buffer === undefined || !((view.byteOffset ?? 0) + view.byteLength <= buffer.byteLength)) {
            throw new Error(`${fileWhere}/${key}: buffer view ${v} does not lie inside its buffer`);
        }
    }
    if (!isIndex(ext.dag) || ext.dag % 4 !== 0 || ext.dag >= json.bufferViews[file.dag].byteLength) {
        throw new Error(
            `${where}/dag: ${JSON.stringify(ext.dag)}, expected a byte offset in the dag buffer view, a multiple of 4`,
        );
    }
    if (!isNumber(ext.fullResolutionError) || ext.fullResolutionError < 0) {
        throw new Error(`${where}/fullResolutionError: ${ext.fullResolutionError}, expected a number >= 0`);
    }
    if (!isNumber(ext.gridStep) || !(ext.gridStep > 0)) {
        throw new Error(`${where}/gridStep: ${ext.gridStep}, expected a number > 0`);
    }
    return {
        dag: file.dag,
        dagOffset: ext.dag,
        chunks: file.chunks,
        errors: ext.errors,
        fullResolutionError: ext.fullResolutionError,
        gridStep: ext.gridStep,
    };
}

/// Parses and validates the DAG table (validation points 2-8) of one object. bytes: the `dag`
/// buffer view (Uint8Array; the table starts at info.dagOffset and its counts give its length;
/// without info.dagOffset, bytes are exactly one table); info: readExtension's result;
/// chunksLength: byteLength of the `chunks` buffer view. Returns the DAG in the shape selection.js's buildDag reads:
///   { clusters: [{ level, producer?, consumer?, sphere }], groups: [{ level, error, sphere,
///     consumed, produced, chunkOffset, chunkLength }], fullResolutionError, gridStep }
/// A cluster's sphere is its producer's, else its consumer's; a cluster in no list (a root that
/// was never simplified) gets null (the caller takes it from the base mesh).
export function parseDagTable(bytes, info, chunksLength, where = 'DAG table') {
    const T = kDagTable;
    const shared = info.dagOffset !== undefined;
    if (shared) {
        if (!isIndex(info.dagOffset) || info.dagOffset > bytes.byteLength) {
            throw new Error(`${where}: offset ${info.dagOffset} outside the dag view (${bytes.byteLength} bytes)`);
        }
        bytes = bytes.subarray(info.dagOffset);
    }
    if (bytes.byteLength < T.headerBytes) throw new Error(`${where}: ${bytes.byteLength} bytes, expected >= 16`);
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const magic = String.fromCharCode(...bytes.subarray(0, 4));
    if (magic !== T.magic) throw new Error(`${where}: magic ${JSON.stringify(magic)}, expected "${T.magic}"`);
    const C = view.getUint32(T.clusterCountOffset, true);
    const G = view.getUint32(T.groupCountOffset, true);
    const idBytes = view.getUint32(T.idBytesOffset, true);
    if (C < 1) throw new Error(`${where}: cluster count 0, expected >= 1`);
    if (!T.idBytesAllowed.includes(idBytes)) throw new Error(`${where}: idBytes ${idBytes}, expected 2 or 4`);
    if (G !== info.errors.length) throw new Error(`${where}: ${G} groups but ${info.errors.length} errors`);
    if (T.headerBytes + T.recordBytes * G > bytes.byteLength) {
        throw new Error(`${where}: ${G} group records do not fit in ${bytes.byteLength} bytes`);
    }
    const groups = [];
    let idCount = 0;
    for (let g = 0; g < G; ++g) {
        const r = T.headerBytes + T.recordBytes * g;
        const sphere = [0, 4, 8, 12].map((o) => view.getFloat32(r + T.centerOffset + o, true));
        const group = {
            sphere,
            chunkOffset: view.getUint32(r + T.chunkOffsetOffset, true),
            chunkLength: view.getUint32(r + T.chunkLengthOffset, true),
            consumedCount: view.getUint16(r + T.consumedCountOffset, true),
            producedCount: view.getUint16(r + T.producedCountOffset, true),
            level: view.getUint16(r + T.levelOffset, true),
            error: info.errors[g],
            fineError: fineError(info.errors[g], view.getUint16(r + T.fineOffset, true)),
        };
        const at = `${where}: group ${g} (record at byte ${r})`;
        if (!sphere.every(Number.isFinite) || !(sphere[3] >= 0)) throw new Error(`${at}: sphere ${sphere}`);
        if (group.consumedCount < 1 || group.producedCount < 1) throw new Error(`${at}: a count is 0`);
        if (group.level < 1) throw new Error(`${at}: level 0, expected >= 1`);
        if (group.chunkLength < 1 || group.chunkOffset + group.chunkLength > chunksLength) {
            throw new Error(
                `${at}: chunk [${group.chunkOffset}, +${group.chunkLength}) outside the chunks view (${chunksLength} bytes)`,
            );
        }
        idCount += group.consumedCount + group.producedCount;
        groups.push(group);
    }
    const listStart = T.headerBytes + T.recordBytes * G;
    const expected = Math.ceil((listStart + idBytes * idCount) / 4) * 4;
    if (shared ? bytes.byteLength < expected : bytes.byteLength !== expected) {
        throw new Error(`${where}: ${bytes.byteLength} bytes, expected ${shared ? 'at least ' : ''}${expected}`);
    }
    if (shared) bytes = bytes.subarray(0, expected);
    const clusters = Array.from({ length: C }, () => ({ level: 0, sphere: null }));
    let offset = listStart;
    const readId = () => {
        const id = idBytes === 2 ? view.getUint16(offset, true) : view.getUint32(offset, true);
        if (id >= C) throw new Error(`${where}: cluster id ${id} at byte ${offset}, expected < ${C}`);
        offset += idBytes;
        return id;
    };
    groups.forEach((group, g) => {
        group.consumed = Array.from({ length: group.consumedCount }, readId);
        group.produced = Array.from({ length: group.producedCount }, readId);
        for (const c of group.consumed) {
            if (clusters[c].consumer !== undefined)
                throw new Error(`${where}: cluster ${c} consumed by groups ${clusters[c].consumer} and ${g}`);
            clusters[c].consumer = g;
        }
        for (const c of group.produced) {
            if (clusters[c].producer !== undefined)
                throw new Error(`${where}: cluster ${c} produced by groups ${clusters[c].producer} and ${g}`);
            clusters[c].producer = g;
            clusters[c].level = group.level;
        }
    });
    for (let o = offset; o < bytes.byteLength; ++o) {
        if (bytes[o] !== 0) throw new Error(`${where}: padding byte ${o} is not 0`);
    }
    groups.forEach((group, g) => {
        for (const c of group.consumed) {
            const p = clusters[c].producer;
            if (clusters[c].level >= group.level)
                throw new Error(
                    `${where}: group ${g} consumes cluster ${c} of level ${clusters[c].level} >= ${group.level}`,
                );
            if (p === undefined) continue;
            if (p >= g)
                throw new Error(
                    `${where}: group ${g} consumes cluster ${c} of the later group ${p} (not children first)`,
                );
            if (groups[p].error > group.error)
                throw new Error(`${where}: group ${g}: error ${group.error} below its child ${p}'s ${groups[p].error}`);
            if (groups[p].fineError > group.fineError)
                throw new Error(
                    `${where}: group ${g}: bound against the finest level ${group.fineError} below its child ${p}'s ${groups[p].fineError}`,
                );
            if (!sphereContains(group.sphere, groups[p].sphere))
                throw new Error(`${where}: group ${g}'s sphere does not contain its child ${p}'s`);
        }
        if (group.error < info.fullResolutionError)
            throw new Error(`${where}: group ${g}: error below fullResolutionError`);
    });
    // chunk ranges do not overlap
    const ranges = groups
        .map((group, g) => [group.chunkOffset, group.chunkOffset + group.chunkLength, g])
        .sort((a, b) => a[0] - b[0]);
    for (let i = 1; i < ranges.length; ++i) {
        if (ranges[i][0] < ranges[i - 1][1])
            throw new Error(`${where}: the chunks of groups ${ranges[i - 1][2]} and ${ranges[i][2]} overlap`);
    }
    clusters.forEach((cluster) => {
        const g = cluster.producer ?? cluster.consumer;
        cluster.sphere = g === undefined ? null : groups[g].sphere;
    });
    return { clusters, groups, fullResolutionError: info.fullResolutionError, gridStep: info.gridStep };
}

/// Does sphere a contain sphere b (relative tolerance 1e-6 of a's radius, for float32 rounding)?
function sphereContains(a, b) {
    const d = Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
    return d + b[3] <= a[3] * (1 + 1e-6) + 1e-9;
}

// ------------------------------------------------------------------------------------------------
// chunks

/// Decodes one Draco bitstream with a draco3d-style decoder module (draco3d's in Node, or three's
/// glTF decoder): { positions: Float32Array (3 per point), cluster: Uint32Array, slot: Uint32Array
/// | null, index: Uint32Array }. ids: unique ids { position, cluster, slot } (slot may be absent:
/// the base mesh; cluster too: a base mesh of one root, all zeros then). Checks the attributes'
/// presence, component counts and types.
export function decodeDraco(draco, bytes, ids = kChunkAttributeIds, where = 'chunk') {
    const decoder = new draco.Decoder();
    const mesh = new draco.Mesh();
    try {
        const array = new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength);
        const status = decoder.DecodeArrayToMesh(array, array.byteLength, mesh);
        if (!status.ok() || mesh.ptr === 0) throw new Error(`${where}: Draco: ${status.error_msg()}`);
        const points = mesh.num_points();
        const faces = mesh.num_faces();
        if (points > 3 * faces) throw new Error(`${where}: ${points} points for ${faces} triangles`);
        const read = (name, id, components, types, Type, dracoType) => {
            const attribute = decoder.GetAttributeByUniqueId(mesh, id);
            if (attribute.ptr === 0) throw new Error(`${where}: no attribute with unique id ${id} (${name})`);
            if (attribute.num_components() !== components || !types.includes(attribute.data_type())) {
                throw new Error(
                    `${where}: attribute ${name}: ${attribute.num_components()} components of Draco type ${attribute.data_type()}`,
                );
            }
            const bytesLength = points * components * Type.BYTES_PER_ELEMENT;
            const ptr = draco._malloc(bytesLength);
            try {
                decoder.GetAttributeDataArrayForAllPoints(mesh, attribute, dracoType, bytesLength, ptr);
                return new Type(draco.HEAPF32.buffer, ptr, points * components).slice();
            } finally {
                draco._free(ptr);
            }
        };
        const positions = read('POSITION', ids.position, 3, [draco.DT_FLOAT32], Float32Array, draco.DT_FLOAT32);
        const unsigned = [draco.DT_UINT8, draco.DT_UINT16];
        // a base mesh with a single root has no _CLUSTER: every triangle is root 0
        const cluster =
            ids.cluster === undefined
                ? new Uint32Array(points)
                : read('_CLUSTER', ids.cluster, 1, unsigned, Uint32Array, draco.DT_UINT32);
        const slot =
            ids.slot === undefined ? null : read('_SLOT', ids.slot, 1, [draco.DT_UINT8], Uint32Array, draco.DT_UINT32);
        const indexBytes = faces * 3 * 4;
        const ptr = draco._malloc(indexBytes);
        let index;
        try {
            decoder.GetTrianglesUInt32Array(mesh, indexBytes, ptr);
            index = new Uint32Array(draco.HEAPF32.buffer, ptr, faces * 3).slice();
        } finally {
            draco._free(ptr);
        }
        return { positions, cluster, slot, index };
    } finally {
        draco.destroy(mesh);
        draco.destroy(decoder);
    }
}

/// Orders a decoded mesh's triangles by cluster: { order: Uint32Array (the index, triangles of
/// cluster 0 first, ...), start: Uint32Array(count + 1) (cluster k: order[start[k] .. start[k+1]),
/// in indices) }. Checks that every triangle's points carry one cluster value < count and that
/// every cluster has a triangle.
export function splitByCluster(index, cluster, count, where = 'chunk') {
    const triangles = index.length / 3;
    const start = new Uint32Array(count + 1);
    for (let t = 0; t < triangles; ++t) {
        const k = cluster[index[3 * t]];
        if (k >= count || cluster[index[3 * t + 1]] !== k || cluster[index[3 * t + 2]] !== k) {
            throw new Error(
                `${where}: triangle ${t} has cluster values ${cluster[index[3 * t]]}, ${cluster[index[3 * t + 1]]}, ${cluster[index[3 * t + 2]]} (expected one value < ${count})`,
            );
        }
        start[k + 1] += 3;
    }
    for (let k = 0; k < count; ++k) {
        if (start[k + 1] === 0) throw new Error(`${where}: cluster ${k} has no triangle`);
        start[k + 1] += start[k];
    }
    const fill = start.slice(0, count);
    const order = new Uint32Array(index.length);
    for (let t = 0; t < triangles; ++t) {
        const k = cluster[index[3 * t]];
        order.set(index.subarray(3 * t, 3 * t + 3), fill[k]);
        fill[k] += 3;
    }
    return { order, start };
}

/// Vertex ids of a decoded mesh's points: points with the same position (the three float32 values
/// compared exactly; -0 as +0) share an id, numbered in the order of their first point. Returns
/// { vertexOf: Uint32Array per point, count, first: Uint32Array (a point of each vertex) }.
/// A Float32Array is welded on its bit patterns in an open-addressing table (string keys in a Map,
/// as for other arrays, took 0.7-1.0 s of FreeSurfer's settling).
export function weldPoints(positions) {
    const points = positions.length / 3;
    const vertexOf = new Uint32Array(points);
    const first = [];
    if (positions instanceof Float32Array) {
        const bits = new Uint32Array(positions.buffer, positions.byteOffset, positions.length);
        let capacity = 16;
        while (capacity < 2 * points) capacity *= 2;
        const mask = capacity - 1;
        const table = new Int32Array(capacity).fill(-1); // slot -> vertex id
        const key = (p, k) => (bits[3 * p + k] === 0x80000000 ? 0 : bits[3 * p + k]);
        for (let p = 0; p < points; ++p) {
            const x = key(p, 0);
            const y = key(p, 1);
            const z = key(p, 2);
            let h =
                Math.imul(x, 0x9e3779b1) ^
                Math.imul(y ^ (y >>> 16), 0x85ebca77) ^
                Math.imul(z ^ (z >>> 13), 0xc2b2ae3d);
            h ^= h >>> 15;
            h = Math.imul(h, 0x2c1b3c6d);
            h ^= h >>> 12;
            let i = h & mask;
            for (;;) {
                const id = table[i];
                if (id < 0) {
                    table[i] = first.length;
                    vertexOf[p] = first.length;
                    first.push(p);
                    break;
                }
                const q = first[id];
                if (key(q, 0) === x && key(q, 1) === y && key(q, 2) === z) {
                    vertexOf[p] = id;
                    break;
                }
                i = (i + 1) & mask;
            }
        }
        return { vertexOf, count: first.length, first: Uint32Array.from(first) };
    }
    const ids = new Map();
    for (let p = 0; p < points; ++p) {
        const key = `${positions[3 * p]},${positions[3 * p + 1]},${positions[3 * p + 2]}`;
        let id = ids.get(key);
        if (id === undefined) {
            id = first.length;
            ids.set(key, id);
            first.push(p);
        }
        vertexOf[p] = id;
    }
    return { vertexOf, count: first.length, first: Uint32Array.from(first) };
}

/// The geomorph target of every point of a chunk, from its `_SLOT` values (schema/README.md,
/// "Geomorphs: the slot encoding"): Float32Array, 3 per point. Throws when a vertex's points
/// disagree on the slot, a slot exceeds the neighbour count, or slots form a cycle.
export function resolveSlots(positions, index, slot, where = 'chunk') {
    const { vertexOf, count, first } = weldPoints(positions);
    const vslot = new Uint32Array(count);
    for (let v = 0; v < count; ++v) vslot[v] = slot[first[v]];
    for (let p = 0; p < vertexOf.length; ++p) {
        if (slot[p] !== vslot[vertexOf[p]])
            throw new Error(`${where}: the points of one vertex have slots ${slot[p]} and ${vslot[vertexOf[p]]}`);
    }
    // neighbours (compressed rows; duplicates removed after sorting)
    const degree = new Uint32Array(count + 1);
    for (let i = 0; i < index.length; i += 3) {
        for (let j = 0; j < 3; ++j) degree[vertexOf[index[i + j]] + 1] += 2;
    }
    for (let v = 0; v < count; ++v) degree[v + 1] += degree[v];
    const fill = degree.slice(0, count);
    const adjacent = new Uint32Array(degree[count]);
    for (let i = 0; i < index.length; i += 3) {
        const a = vertexOf[index[i]];
        const b = vertexOf[index[i + 1]];
        const c = vertexOf[index[i + 2]];
        adjacent[fill[a]++] = b;
        adjacent[fill[a]++] = c;
        adjacent[fill[b]++] = c;
        adjacent[fill[b]++] = a;
        adjacent[fill[c]++] = a;
        adjacent[fill[c]++] = b;
    }
    // each vertex's coordinates (float32 values as binary64, read once)
    const xyz = new Float64Array(3 * count);
    for (let v = 0; v < count; ++v) {
        xyz[3 * v] = positions[3 * first[v]];
        xyz[3 * v + 1] = positions[3 * first[v] + 1];
        xyz[3 * v + 2] = positions[3 * first[v] + 2];
    }
    // before(a, b) around v at (vx, vy, vz): a comes first (survivors, then shorter edges, then
    // smaller x, y, z)
    const before = (a, b, vx, vy, vz) => {
        const sa = vslot[a] === 0 ? 0 : 1;
        const sb = vslot[b] === 0 ? 0 : 1;
        if (sa !== sb) return sa < sb;
        const ax = xyz[3 * a] - vx;
        const ay = xyz[3 * a + 1] - vy;
        const az = xyz[3 * a + 2] - vz;
        const bx = xyz[3 * b] - vx;
        const by = xyz[3 * b + 1] - vy;
        const bz = xyz[3 * b + 2] - vz;
        const la = ax * ax + ay * ay + az * az;
        const lb = bx * bx + by * by + bz * bz;
        if (la !== lb) return la < lb;
        if (xyz[3 * a] !== xyz[3 * b]) return xyz[3 * a] < xyz[3 * b];
        if (xyz[3 * a + 1] !== xyz[3 * b + 1]) return xyz[3 * a + 1] < xyz[3 * b + 1];
        return xyz[3 * a + 2] < xyz[3 * b + 2];
    };
    // target[v]: the neighbour a collapsed vertex points to. note: the hot loop of attaching a
    // chunk (most vertices collapse), so each neighbour list is deduplicated and ordered in place
    // in one scratch array, by insertion (lists are short), without allocating
    const target = new Int32Array(count).fill(-1);
    let list = new Uint32Array(64);
    for (let v = 0; v < count; ++v) {
        const s = vslot[v];
        if (s === 0) continue;
        const vx = xyz[3 * v];
        const vy = xyz[3 * v + 1];
        const vz = xyz[3 * v + 2];
        if (degree[v + 1] - degree[v] > list.length) list = new Uint32Array(2 * (degree[v + 1] - degree[v]));
        let n = 0;
        for (let i = degree[v]; i < degree[v + 1]; ++i) {
            const u = adjacent[i];
            let j = 0;
            while (j < n && list[j] !== u) ++j;
            if (j < n) continue; // a duplicate
            j = n++;
            while (j > 0 && before(u, list[j - 1], vx, vy, vz)) {
                list[j] = list[j - 1];
                --j;
            }
            list[j] = u;
        }
        if (s > n) throw new Error(`${where}: slot ${s} of a vertex with ${n} neighbours`);
        target[v] = list[s - 1];
    }
    // follow the chains to a survivor (state: 0 unknown, 1 on the current chain, 2 resolved)
    const survivor = new Int32Array(count).fill(-1);
    const state = new Uint8Array(count);
    const chain = [];
    for (let v = 0; v < count; ++v) {
        let u = v;
        while (state[u] === 0 && target[u] >= 0) {
            state[u] = 1;
            chain.push(u);
            u = target[u];
        }
        if (state[u] === 1) throw new Error(`${where}: the slots form a cycle`);
        const end = target[u] < 0 ? u : survivor[u];
        state[u] = 2;
        survivor[u] = end;
        for (const w of chain) {
            survivor[w] = end;
            state[w] = 2;
        }
        chain.length = 0;
    }
    const coarse = new Float32Array(positions.length);
    for (let p = 0; p < vertexOf.length; ++p) {
        const s = first[survivor[vertexOf[p]]];
        coarse[3 * p] = positions[3 * s];
        coarse[3 * p + 1] = positions[3 * s + 1];
        coarse[3 * p + 2] = positions[3 * s + 2];
    }
    return coarse;
}

// ------------------------------------------------------------------------------------------------
// shading normals of a drawn cut

/// Unit shading normals with the definition of strata's C++ shading_normals (src/mesh/
/// shading_normals.h; keep both in step): face normals n_f = normalize((p1 - p0) x (p2 - p0))
/// (zero cross product: no contribution); a(v) = sum of theta_f(v) n_f over the faces at v
/// (theta the interior angle, acos of the clamped dot product of the unit edges; 0 for a
/// zero-length edge), normalized (or zero); n(v) = normalize(sum of a(u) over the `rings`-ring of
/// v, v included, each u weighted clamp((a(u) . a(v) + 1/2) / 0.1, 0, 1)), else a(v), else
/// (0, 0, 1).
/// positions: Float64Array (3 per vertex, in a frame where angles are true, e.g. patient mm);
/// triangles: Uint32Array of vertex ids (the drawn cut, welded: one id per position); vertexCount.
/// Returns Float32Array, 3 per vertex (vertices in no triangle get (0, 0, 1)).
export function shadingNormals(positions, triangles, vertexCount, rings = 3) {
    const a = new Float64Array(3 * vertexCount);
    const unitEdge = (from, to, out) => {
        const dx = positions[3 * to] - positions[3 * from];
        const dy = positions[3 * to + 1] - positions[3 * from + 1];
        const dz = positions[3 * to + 2] - positions[3 * from + 2];
        const n = Math.sqrt(dx * dx + dy * dy + dz * dz);
        if (!(n > 0)) return false;
        out[0] = dx / n;
        out[1] = dy / n;
        out[2] = dz / n;
        return true;
    };
    const u = [0, 0, 0];
    const w = [0, 0, 0];
    const angle = (v, p, q) => {
        if (!unitEdge(v, p, u) || !unitEdge(v, q, w)) return 0;
        return Math.acos(Math.min(1, Math.max(-1, u[0] * w[0] + u[1] * w[1] + u[2] * w[2])));
    };
    // adds face normal (cx, cy, cz) / n weighted by its angle at v (no array per corner: the
    // garbage of three per triangle was a tenth of a viewer's main thread while chunks arrived)
    const addCorner = (v, p, q, cx, cy, cz, n) => {
        const theta = angle(v, p, q) / n;
        a[3 * v] += theta * cx;
        a[3 * v + 1] += theta * cy;
        a[3 * v + 2] += theta * cz;
    };
    for (let t = 0; t < triangles.length; t += 3) {
        const i0 = triangles[t];
        const i1 = triangles[t + 1];
        const i2 = triangles[t + 2];
        const ax = positions[3 * i1] - positions[3 * i0];
        const ay = positions[3 * i1 + 1] - positions[3 * i0 + 1];
        const az = positions[3 * i1 + 2] - positions[3 * i0 + 2];
        const bx = positions[3 * i2] - positions[3 * i0];
        const by = positions[3 * i2 + 1] - positions[3 * i0 + 1];
        const bz = positions[3 * i2 + 2] - positions[3 * i0 + 2];
        const cx = ay * bz - az * by;
        const cy = az * bx - ax * bz;
        const cz = ax * by - ay * bx;
        const n = Math.sqrt(cx * cx + cy * cy + cz * cz);
        if (!(n > 0)) continue;
        addCorner(i0, i1, i2, cx, cy, cz, n);
        addCorner(i1, i2, i0, cx, cy, cz, n);
        addCorner(i2, i0, i1, cx, cy, cz, n);
    }
    for (let v = 0; v < vertexCount; ++v) {
        const n = Math.hypot(a[3 * v], a[3 * v + 1], a[3 * v + 2]);
        if (n > 0) for (let k = 0; k < 3; ++k) a[3 * v + k] /= n;
    }
    const out = new Float32Array(3 * vertexCount);
    const put = (v, x, y, z) => {
        out[3 * v] = x;
        out[3 * v + 1] = y;
        out[3 * v + 2] = z;
    };
    if (rings === 0) {
        for (let v = 0; v < vertexCount; ++v) {
            const zero = a[3 * v] === 0 && a[3 * v + 1] === 0 && a[3 * v + 2] === 0;
            if (zero) put(v, 0, 0, 1);
            else put(v, a[3 * v], a[3 * v + 1], a[3 * v + 2]);
        }
        return out;
    }
    // neighbours (compressed rows)
    const start = new Uint32Array(vertexCount + 1);
    for (let t = 0; t < triangles.length; ++t) start[triangles[t] + 1] += 2;
    for (let v = 0; v < vertexCount; ++v) start[v + 1] += start[v];
    const fill = start.slice(0, vertexCount);
    const adjacent = new Uint32Array(start[vertexCount]);
    for (let t = 0; t < triangles.length; t += 3) {
        for (let i = 0; i < 3; ++i) {
            const v = triangles[t + i];
            adjacent[fill[v]++] = triangles[t + ((i + 1) % 3)];
            adjacent[fill[v]++] = triangles[t + ((i + 2) % 3)];
        }
    }
    const stamp = new Int32Array(vertexCount).fill(-1);
    const ring = new Int32Array(vertexCount); // the rings of v, ring[0, size)
    for (let v = 0; v < vertexCount; ++v) {
        if (start[v + 1] === start[v]) {
            put(v, 0, 0, 1);
            continue;
        }
        let size = 0;
        ring[size++] = v;
        stamp[v] = v;
        let layerBegin = 0;
        for (let depth = 0; depth < rings; ++depth) {
            const layerEnd = size;
            for (let r = layerBegin; r < layerEnd; ++r) {
                const x = ring[r];
                for (let e = start[x]; e < start[x + 1]; ++e) {
                    const y = adjacent[e];
                    if (stamp[y] !== v) {
                        stamp[y] = v;
                        ring[size++] = y;
                    }
                }
            }
            layerBegin = layerEnd;
        }
        let sx = 0;
        let sy = 0;
        let sz = 0;
        for (let r = 0; r < size; ++r) {
            const x = ring[r];
            // fade out normals 114-120 degrees from v's own (the other side of a thin part)
            const d = a[3 * x] * a[3 * v] + a[3 * x + 1] * a[3 * v + 1] + a[3 * x + 2] * a[3 * v + 2];
            const weight = Math.min(1, Math.max(0, (d + 0.5) / 0.1));
            if (!(weight > 0)) continue;
            sx += weight * a[3 * x];
            sy += weight * a[3 * x + 1];
            sz += weight * a[3 * x + 2];
        }
        let n = Math.hypot(sx, sy, sz);
        if (!(n > 0)) {
            sx = a[3 * v];
            sy = a[3 * v + 1];
            sz = a[3 * v + 2];
            n = Math.hypot(sx, sy, sz);
        }
        if (n > 0) put(v, sx / n, sy / n, sz / n);
        else put(v, 0, 0, 1);
    }
    return out;
}

// node --test web-viewer/test/
// strata-decode.js on hand-made data (no model file): the DAG table as schema/README.md lays it
// out byte by byte (encoded here, independently of the C++ writer), each validation rule, the
// geomorph slot order worked out by hand, and the shading normals on shapes whose normals are
// known by symmetry.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { parseDagTable, resolveSlots, shadingNormals, splitByCluster, weldPoints } from '../strata-decode.js';

/// The DAG table of schema/README.md: 16-byte header, 32-byte records, id lists, zero padding.
function encodeTable({ clusterCount, idBytes = 2, groups, magic = 'SDAG', padding = 0 }) {
    const ids = groups.reduce((s, g) => s + g.consumed.length + g.produced.length, 0);
    const length = Math.ceil((16 + 32 * groups.length + idBytes * ids) / 4) * 4 + padding;
    const bytes = new Uint8Array(length);
    const view = new DataView(bytes.buffer);
    for (let i = 0; i < 4; ++i) bytes[i] = magic.charCodeAt(i);
    view.setUint32(4, clusterCount, true);
    view.setUint32(8, groups.length, true);
    view.setUint32(12, idBytes, true);
    groups.forEach((g, i) => {
        const r = 16 + 32 * i;
        g.sphere.forEach((v, k) => view.setFloat32(r + 4 * k, v, true));
        view.setUint32(r + 16, g.chunkOffset, true);
        view.setUint32(r + 20, g.chunkLength, true);
        view.setUint16(r + 24, g.consumedCount ?? g.consumed.length, true);
        view.setUint16(r + 26, g.producedCount ?? g.produced.length, true);
        view.setUint16(r + 28, g.level, true);
        view.setUint16(r + 30, g.fine ?? 0, true);
    });
    let o = 16 + 32 * groups.length;
    for (const g of groups) {
        for (const c of [...g.consumed, ...g.produced]) {
            if (idBytes === 2) view.setUint16(o, c, true);
            else view.setUint32(o, c, true);
            o += idBytes;
        }
    }
    return bytes;
}

/// The schema's example: clusters 0 and 1 consumed by group 0, which produced root cluster 2.
const kExample = {
    clusterCount: 3,
    groups: [
        {
            sphere: [0, 0, 0, 1],
            chunkOffset: 0,
            chunkLength: 100,
            consumed: [0, 1],
            produced: [2],
            level: 1,
            fine: 21845,
        },
    ],
};
const kInfo = { errors: [0.0009], fullResolutionError: 0.00035, gridStep: 0.0078125 };

test('DAG table: the schema example decodes to the links, levels and spheres it describes', () => {
    for (const idBytes of [2, 4]) {
        const table = parseDagTable(encodeTable({ ...kExample, idBytes }), kInfo, 100);
        assert.equal(table.clusters.length, 3);
        assert.deepEqual(
            table.clusters.map((c) => [c.producer, c.consumer, c.level]),
            [
                [undefined, 0, 0],
                [undefined, 0, 0],
                [0, undefined, 1],
            ],
        );
        assert.deepEqual(table.groups[0].consumed, [0, 1]);
        assert.deepEqual(table.groups[0].produced, [2]);
        assert.equal(table.groups[0].error, 0.0009);
        // fine 21845 of 65535: a third of the error (0.3 mm) against the finest level
        assert.ok(Math.abs(table.groups[0].fineError - 0.0003) < 1e-15, `${table.groups[0].fineError}`);
        assert.deepEqual(table.clusters[0].sphere, [0, 0, 0, 1]);
        assert.equal(table.fullResolutionError, 0.00035);
    }
});

test('DAG table: every validation rule rejects its violation', () => {
    const chain = {
        clusterCount: 4,
        groups: [
            { sphere: [0, 0, 0, 1], chunkOffset: 0, chunkLength: 10, consumed: [0, 1], produced: [2], level: 1 },
            { sphere: [0, 0, 0, 2], chunkOffset: 10, chunkLength: 10, consumed: [2], produced: [3], level: 2 },
        ],
    };
    const info = { errors: [0.001, 0.002], fullResolutionError: 0.0005, gridStep: 1 };
    assert.doesNotThrow(() => parseDagTable(encodeTable(chain), info, 20));
    const bad = (change, message, { infoChange = {}, viewLength = 20 } = {}) => {
        const spec = structuredClone(chain);
        const bytes = change(spec) ?? encodeTable(spec);
        assert.throws(() => parseDagTable(bytes, { ...info, ...infoChange }, viewLength), message);
    };
    bad((s) => encodeTable({ ...s, magic: 'SDAX' }), /magic/);
    bad((s) => encodeTable({ ...s, idBytes: 3 }), /idBytes 3/);
    bad(() => null, /2 groups but 1 errors/, { infoChange: { errors: [0.001] } });
    bad((s) => encodeTable({ ...s, padding: 4 }), /bytes, expected/);
    bad((s) => void (s.groups[0].level = 0), /level 0/);
    bad((s) => void (s.groups[0].fine = 65535), /bound against the finest level .* below its child/);
    bad((s) => void (s.groups[1].produced = [4]), /cluster id 4 .* expected < 4/);
    bad((s) => void (s.groups[1].consumed = [1]), /cluster 1 consumed by groups 0 and 1/);
    bad((s) => void (s.groups[1].produced = [2]), /cluster 2 produced by groups 0 and 1/);
    bad((s) => void (s.groups[1].level = 1), /level 1 >= 1/);
    bad(() => null, /below its child/, { infoChange: { errors: [0.003, 0.002] } });
    bad(() => null, /below fullResolutionError/, { infoChange: { fullResolutionError: 0.0015 } });
    bad((s) => void (s.groups[1].sphere = [3, 0, 0, 2]), /does not contain its child/);
    bad((s) => void (s.groups[1].chunkOffset = 5), /overlap/);
    bad(() => null, /outside the chunks view/, { viewLength: 19 });
    bad((s) => void (s.groups[0].chunkLength = 0), /outside the chunks view/);
    bad((s) => void (s.groups[0].sphere = [0, 0, 0, -1]), /sphere/);
    // children first: the group producing 2 must come before its consumer
    bad(
        (s) =>
            encodeTable({
                ...s,
                groups: [
                    { ...s.groups[1], level: 2, chunkOffset: 0 },
                    { ...s.groups[0], chunkOffset: 10 },
                ],
            }),
        /not children first/,
    );
});

test('DAG table: tables of several objects in one dag view, each at its byte offset', () => {
    // the file's dag view: the example's table, then a one-group table with other ids and sphere
    const first = encodeTable(kExample);
    const other = {
        clusterCount: 5,
        groups: [
            { sphere: [1, 2, 3, 4], chunkOffset: 100, chunkLength: 8, consumed: [3, 1, 0], produced: [4], level: 1 },
        ],
    };
    const second = encodeTable(other);
    const view = new Uint8Array(first.byteLength + second.byteLength);
    view.set(first, 0);
    view.set(second, first.byteLength);
    const a = parseDagTable(view, { ...kInfo, dagOffset: 0 }, 108);
    assert.equal(a.clusters.length, 3);
    assert.deepEqual(a.groups[0].consumed, [0, 1]);
    const b = parseDagTable(view, { ...kInfo, dagOffset: first.byteLength }, 108);
    assert.equal(b.clusters.length, 5);
    assert.deepEqual(b.groups[0].consumed, [3, 1, 0]);
    assert.deepEqual(b.groups[0].sphere, [1, 2, 3, 4]);
    assert.equal(b.groups[0].chunkOffset, 100);
    // a table that would run past the view, an offset beyond it
    assert.throws(
        () => parseDagTable(view.subarray(0, view.byteLength - 4), { ...kInfo, dagOffset: first.byteLength }, 108),
        /expected at least/,
    );
    assert.throws(() => parseDagTable(view, { ...kInfo, dagOffset: view.byteLength + 4 }, 108), /outside the dag view/);
});

test('slots: the neighbour order of the spec (survivors, squared length, x, y, z), chains and refusals', () => {
    // a fan: centre 0 at the origin, ring 1..6; squared lengths 4, 5, 5, 4, 5, 5
    const ring = [
        [2, 0, 0],
        [1, 2, 0],
        [-1, 2, 0],
        [-2, 0, 0],
        [-1, -2, 0],
        [1, -2, 0],
    ];
    const positions = Float32Array.from([0, 0, 0, ...ring.flat()]);
    const index = Uint32Array.from(ring.flatMap((_, i) => [0, 1 + i, 1 + ((i + 1) % 6)]));
    const at = (coarse, v) => [...coarse.subarray(3 * v, 3 * v + 3)];
    // order of the centre's neighbours (all survivors): length 4 first, x smaller first: (-2,0,0),
    // (2,0,0); then length 5: x -1 (y -2 before y 2), x 1 (y -2 before y 2)
    const order = [ring[3], ring[0], ring[4], ring[2], ring[5], ring[1]];
    order.forEach((expected, k) => {
        const slot = Uint32Array.from([k + 1, 0, 0, 0, 0, 0, 0]);
        const coarse = resolveSlots(positions, index, slot);
        assert.deepEqual(at(coarse, 0), expected, `slot ${k + 1}`);
        for (let v = 1; v <= 6; ++v) assert.deepEqual(at(coarse, v), ring[v - 1], 'a survivor stays');
    });
    // survivors come before collapsed neighbours: ring vertex 4 (-2,0,0) collapsed: the centre's
    // slot 1 is then (2,0,0), and a chain 0 -> 4 -> 3 resolves to 3's position
    {
        const slot = Uint32Array.from([6, 0, 0, 0, 0, 0, 0]); // the last: the collapsed (-2,0,0)
        // vertex 4 = (-2, 0, 0): neighbours 0 (collapsed), 3 (-1,2,0), 5 (-1,-2,0); its slot 1 =
        // the nearer survivor: |(-1,2)-(-2,0)|^2 = 5 for both; x equal; y -2 first: vertex 5
        slot[4] = 1;
        const coarse = resolveSlots(positions, index, slot);
        assert.deepEqual(at(coarse, 4), ring[4]);
        assert.deepEqual(at(coarse, 0), ring[4], 'the chain 0 -> 4 -> 5');
    }
    // the points of one vertex may be split (Draco does at cluster borders): same result
    {
        const split = Float32Array.from([...positions, 0, 0, 0]);
        const index2 = Uint32Array.from(index);
        index2[0] = 7; // the first triangle uses the copy of the centre
        const slot = Uint32Array.from([2, 0, 0, 0, 0, 0, 0, 2]);
        const coarse = resolveSlots(split, index2, slot);
        assert.deepEqual(at(coarse, 0), ring[0]);
        assert.deepEqual(at(coarse, 7), ring[0]);
        assert.throws(
            () => resolveSlots(split, index2, Uint32Array.from([2, 0, 0, 0, 0, 0, 0, 1])),
            /slots 1 and 2|slots 2 and 1/,
        );
    }
    assert.throws(
        () => resolveSlots(positions, index, Uint32Array.from([7, 0, 0, 0, 0, 0, 0])),
        /slot 7 of a vertex with 6/,
    );
    // a cycle: 1 -> 0 and 0 -> 1 (both collapsed)
    {
        // for vertex 1 = (2,0,0): neighbours 0 (length 4), 2 (1,2: 5), 6 (1,-2: 5); survivors 2, 6 first
        const slot = Uint32Array.from([0, 3, 0, 0, 0, 0, 0]);
        // centre's order with 1 collapsed: survivors by length: (-2,0,0) then the four of length 5, then (2,0,0)
        slot[0] = 6;
        assert.throws(() => resolveSlots(positions, index, slot), /cycle/);
    }
});

test('splitByCluster: triangles ordered by cluster; mixed or missing clusters are refused', () => {
    const index = Uint32Array.from([0, 1, 2, 3, 4, 5, 6, 7, 8]);
    const cluster = Uint32Array.from([1, 1, 1, 0, 0, 0, 1, 1, 1]);
    const { order, start } = splitByCluster(index, cluster, 2);
    assert.deepEqual([...start], [0, 3, 9]);
    assert.deepEqual([...order], [3, 4, 5, 0, 1, 2, 6, 7, 8]);
    assert.throws(() => splitByCluster(index, Uint32Array.from([1, 1, 0, 0, 0, 0, 1, 1, 1]), 2), /triangle 0/);
    assert.throws(() => splitByCluster(index, cluster, 3), /cluster 2 has no triangle/);
    assert.throws(
        () => splitByCluster(index, Uint32Array.from([2, 2, 2, 0, 0, 0, 1, 1, 1]), 2),
        /expected one value < 2/,
    );
});

test('shading normals: a plane, and an octahedron (normals radial by symmetry; the 2-ring sum cancels)', () => {
    // a 3 x 3 grid of vertices in the plane z = 0, counter-clockwise: normals +z everywhere
    const grid = [];
    for (let y = 0; y < 3; ++y) for (let x = 0; x < 3; ++x) grid.push(x, y * 1.7, 0);
    const tris = [];
    for (let y = 0; y < 2; ++y) {
        for (let x = 0; x < 2; ++x) {
            const a = 3 * y + x;
            tris.push(a, a + 1, a + 4, a, a + 4, a + 3);
        }
    }
    const plane = shadingNormals(Float64Array.from(grid), Uint32Array.from(tris), 9);
    for (let v = 0; v < 9; ++v) assert.deepEqual([...plane.subarray(3 * v, 3 * v + 3)], [0, 0, 1]);
    // octahedron: every 2-ring is the whole mesh, whose angle-weighted normals sum to zero, so
    // n(v) falls back to the angle-weighted normal: the direction of the vertex
    const p = [1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1];
    const faces = [0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5];
    for (const rings of [0, 1, 2]) {
        const n = shadingNormals(Float64Array.from(p), Uint32Array.from(faces), 6, rings);
        for (let v = 0; v < 6; ++v) {
            for (let k = 0; k < 3; ++k)
                assert.ok(Math.abs(n[3 * v + k] - p[3 * v + k]) < 1e-6, `rings ${rings} vertex ${v}`);
        }
    }
    // a vertex in no triangle gets (0, 0, 1)
    const lone = shadingNormals(Float64Array.from([...p, 5, 5, 5]), Uint32Array.from(faces), 7);
    assert.deepEqual([...lone.subarray(18, 21)], [0, 0, 1]);
});

test('weldPoints: points of equal float32 positions (-0 as +0) share an id, first-seen order', () => {
    // random points drawn from a small pool (many repeats, some -0), against ids from string keys
    let seed = 3;
    const random = () => ((seed = (seed * 1103515245 + 12345) % 2 ** 31), seed / 2 ** 31);
    for (let round = 0; round < 10; ++round) {
        const n = 1 + Math.floor(random() * 5000);
        const pool = Array.from({ length: 1 + Math.floor(random() * n) }, () =>
            [0, 1, 2].map(() => (random() < 0.1 ? (random() < 0.5 ? -0 : 0) : Math.round(random() * 64) / 8 - 4)),
        );
        const positions = new Float32Array(3 * n);
        for (let p = 0; p < n; ++p) positions.set(pool[Math.floor(random() * pool.length)], 3 * p);
        const ids = new Map();
        const expected = [];
        for (let p = 0; p < n; ++p) {
            const key = [0, 1, 2].map((k) => String(positions[3 * p + k] + 0)).join(',');
            if (!ids.has(key)) ids.set(key, ids.size);
            expected.push(ids.get(key));
        }
        const welded = weldPoints(positions);
        assert.equal(welded.count, ids.size);
        assert.deepEqual([...welded.vertexOf], expected);
        for (let v = 0; v < welded.count; ++v) assert.equal(expected[welded.first[v]], v);
    }
});

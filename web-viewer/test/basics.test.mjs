// node --test web-viewer/test/
// Tests that need no model: the selection rules on the schema's example extension object and on a
// small hand-made DAG, and serve.mjs (ranges, MIME types, paths).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { mkdtempSync, readFileSync, rmSync, writeFileSync, mkdirSync } from 'node:fs';
import { spawn } from 'node:child_process';
import { tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';
import {
    buildDag,
    closeUpward,
    cutForPredicate,
    drawnClusters,
    isClosedUpward,
    restrictToLoaded,
    screenSpaceError,
    selectCut,
    validateExtension,
} from '../selection.js';
import { ByteCoverage, coalesceRanges, glbLayout, parseGlb } from '../gltf-file.js';
import { parseRange, pickEncoding, startServer } from '../serve.mjs';
import { request as httpRequest } from 'node:http';
import { brotliDecompressSync, gunzipSync } from 'node:zlib';

const kHere = dirname(fileURLToPath(import.meta.url));
const kExample = join(kHere, '..', '..', 'schema', 'example.node.STRATA_progressive_mesh.json');

test('the schema example: base, refined, screen-space error', () => {
    // the DAG the example's table describes (decode.test.mjs checks the table itself): clusters 0
    // and 1 consumed by group 0, which produced root cluster 2; the example's numbers
    const example = JSON.parse(readFileSync(kExample, 'utf8'));
    const sphere = [0.1, 0.2, 0.3, 0.05];
    const ext = {
        clusters: [
            { level: 0, consumer: 0, sphere },
            { level: 0, consumer: 0, sphere },
            { level: 1, producer: 0, sphere },
        ],
        groups: [{ level: 1, error: example.errors[0], sphere, consumed: [0, 1], produced: [2] }],
        fullResolutionError: example.fullResolutionError,
        gridStep: example.gridStep,
    };
    assert.deepEqual(validateExtension(ext), []);
    const dag = buildDag(ext, { clusterTriangles: [1000, 1000, 900] });
    assert.deepEqual(drawnClusters(dag, Uint8Array.of(0)), [2]);
    assert.deepEqual(drawnClusters(dag, Uint8Array.of(1)), [0, 1]);
    assert.equal(dag.delta[0], 1100);
    // 3D Tiles formula: error * H / (d * 2 tan(fovy / 2)), d to the sphere, infinite inside
    const [x, y, z, r] = ext.groups[0].sphere;
    const view = { position: [x, y, z + r + 1], fovy: Math.PI / 2, heightPx: 1000 };
    assert.ok(Math.abs(screenSpaceError(0.0009, ext.groups[0].sphere, view) - (0.0009 * 1000) / 2) < 1e-12);
    assert.equal(screenSpaceError(0.0009, ext.groups[0].sphere, { ...view, position: [x, y, z] }), Infinity);
    assert.equal(
        screenSpaceError(0.0009, ext.groups[0].sphere, { orthographic: true, viewHeight: 0.5, heightPx: 1000 }),
        0.0009 * 2000,
    );
    // the projected error is 0.45 px: tau above it keeps the base, below it refines
    assert.deepEqual(selectCut([dag], view, { tauPx: 0.5 }).cuts[0].drawn, [2]);
    assert.deepEqual(selectCut([dag], view, { tauPx: 0.4 }).cuts[0].drawn, [0, 1]);
    // not loaded: stays coarse and wants both chunks
    const waiting = selectCut([dag], view, { tauPx: 0.4, isLoaded: (_, c) => c === 2 });
    assert.deepEqual(waiting.cuts[0].drawn, [2]);
    assert.deepEqual(
        waiting.wanted.map((w) => w.cluster),
        [0, 1],
    );
    // budget: the refinement adds 1100 triangles
    assert.deepEqual(selectCut([dag], view, { tauPx: 0.4, budget: 1999 }).cuts[0].drawn, [2]);
    assert.deepEqual(selectCut([dag], view, { tauPx: 0.4, budget: 2000 }).cuts[0].drawn, [0, 1]);
});

/// A chain of three levels over four level-0 clusters:
///   group 0 consumes 0, 1 -> produces 4;  group 1 consumes 2, 3 -> produces 5;
///   group 2 consumes 4, 5 -> produces 6 (root)
function chain() {
    const s = (x, r) => [x, 0, 0, r];
    return {
        clusters: [
            { mesh: 1, level: 0, consumer: 0, sphere: s(-1.5, 0.5) },
            { mesh: 2, level: 0, consumer: 0, sphere: s(-0.5, 0.5) },
            { mesh: 3, level: 0, consumer: 1, sphere: s(0.5, 0.5) },
            { mesh: 4, level: 0, consumer: 1, sphere: s(1.5, 0.5) },
            { mesh: 5, level: 1, producer: 0, consumer: 2, sphere: s(-1, 1) },
            { mesh: 6, level: 1, producer: 1, consumer: 2, sphere: s(1, 1) },
            { mesh: 0, level: 2, producer: 2, sphere: s(0, 2) },
        ],
        groups: [
            { level: 1, error: 0.01, sphere: s(-1, 1), consumed: [0, 1], produced: [4] },
            { level: 1, error: 0.02, sphere: s(1, 1), consumed: [2, 3], produced: [5] },
            { level: 2, error: 0.05, sphere: s(0, 2), consumed: [4, 5], produced: [6] },
        ],
        fullResolutionError: 0.005,
        gridStep: 1,
    };
}

test('the spec passes: upward closure, loaded restriction, draw rule', () => {
    const dag = buildDag(chain(), { clusterTriangles: [100, 100, 100, 100, 100, 100, 100] });
    assert.deepEqual(dag.children, [[], [], [0, 1]]);
    assert.deepEqual(dag.parents, [[2], [2], []]);
    // refining group 0 alone forces group 2
    const refined = closeUpward(dag, Uint8Array.of(1, 0, 0));
    assert.deepEqual([...refined], [1, 0, 1]);
    assert.ok(isClosedUpward(dag, refined));
    assert.deepEqual(drawnClusters(dag, refined), [0, 1, 5]);
    // cluster 1 missing: group 0 cannot be refined
    restrictToLoaded(dag, refined, (c) => c !== 1);
    assert.deepEqual([...refined], [0, 0, 1]);
    assert.deepEqual(drawnClusters(dag, refined), [4, 5]);
    // cluster 5 missing: group 2 cannot be refined, nor its children
    const r2 = restrictToLoaded(dag, Uint8Array.of(1, 1, 1), (c) => c !== 5);
    assert.deepEqual([...r2], [0, 0, 0]);
    // uniform error
    assert.deepEqual(cutForPredicate(dag, (g) => dag.error[g] > 0.015).drawn, [2, 3, 4]);
});

test('refineOn: the bound against the finest level, or the slice bound above full resolution', () => {
    // chain(): slice bounds 0.01, 0.02, 0.05, full resolution 0.005; with fineError (the bound
    // against the finest level) 0.009, 0.012, 0.03 on groups 0-2
    const ext = chain();
    ext.groups.forEach((g, i) => (g.fineError = [0.009, 0.012, 0.03][i]));
    const triangles = { clusterTriangles: [100, 100, 100, 100, 60, 60, 50] };
    const finest = buildDag(ext, triangles);
    const data = buildDag(ext, { ...triangles, refineOn: 'data' });
    assert.deepEqual([...finest.fine], [0.009, 0.012, 0.03]);
    assert.deepEqual([...data.fine], [0.01 - 0.005, 0.02 - 0.005, 0.05 - 0.005]);
    assert.throws(() => buildDag(ext, { ...triangles, refineOn: 'slices' }), /refineOn/);
    // a view where group 0's finest bound projects above tau and its excess below: g0's sphere at
    // distance 9 (centre x = -1, radius 1, camera at x = -1, z = 10), 1000 px, fovy 90 degrees:
    // 0.009 * 1000 / (9 * 2) = 0.5 px, (0.01 - 0.005) * 1000 / 18 = 0.28 px; tau 0.4
    const view = { position: [-1, 0, 10], fovy: Math.PI / 2, heightPx: 1000 };
    assert.ok(screenSpaceError(finest.fine[0], ext.groups[0].sphere, view) > 0.4);
    assert.ok(screenSpaceError(data.fine[0], ext.groups[0].sphere, view) < 0.4);
    assert.equal(selectCut([finest], view, { tauPx: 0.4, cull: false }).cuts[0].refined[0], 1);
    assert.equal(selectCut([data], view, { tauPx: 0.4, cull: false }).cuts[0].refined[0], 0);
});

test('selectCut: region of interest, frustum, budget order', () => {
    const dag = buildDag(chain(), { clusterTriangles: [100, 100, 100, 100, 60, 60, 50] });
    const view = { position: [0, 0, 100], fovy: Math.PI / 3, heightPx: 1000 };
    // far away: nothing refined at tau 1 (sse of group 2 = 0.05 * 1000 / (98 * 2 tan 30deg) ~ 0.44 px)
    assert.deepEqual(selectCut([dag], view, { tauPx: 1 }).cuts[0].drawn, [6]);
    // region of interest around x = 1.5 with factor 8: groups 2 and 1 refine, group 0 not
    const roi = { center: [1.5, 0, 0], radius: 0.1, factor: 8 };
    const cut = selectCut([dag], view, { tauPx: 1, roi }).cuts[0];
    assert.deepEqual([...cut.refined], [0, 1, 1]);
    assert.deepEqual(cut.drawn, [2, 3, 4]);
    // a frustum that excludes x < 0.2: group 0's sphere (x in [-2, 0]) is culled
    const frustum = [[1, 0, 0, -0.2]];
    const culled = selectCut([dag], { ...view, frustum }, { tauPx: 0.01 }).cuts[0];
    assert.deepEqual([...culled.refined], [0, 1, 1]);
    // the budget refines the larger priority first: group 1 (error 0.02) before group 0
    const budget = 50 + 70 + 140; // base 50, group 2 adds 70, group 1 adds 140, group 0 would add 140 more
    const limited = selectCut([dag], view, { tauPx: 0.01, budget });
    assert.deepEqual([...limited.cuts[0].refined], [0, 1, 1]);
    assert.ok(limited.budgetLimited);
    assert.equal(limited.triangles, 260);
    // geomorph weights: 0 far above the threshold, 1 at it
    const near = selectCut([dag], view, { tauPx: 0.44 * 0.999 }).cuts[0];
    assert.equal(near.refined[2], 1);
    assert.ok(near.weight[2] > 0.99, `weight ${near.weight[2]}`);
    const far = selectCut([dag], view, { tauPx: 0.01 }).cuts[0];
    assert.equal(far.weight[2], 0);
});

test('GLB layout and range coalescing', () => {
    const json = {
        asset: { version: '2.0' },
        bufferViews: [
            { buffer: 0, byteOffset: 0, byteLength: 10 },
            { buffer: 0, byteOffset: 12, byteLength: 8 },
            { buffer: 0, byteOffset: 100, byteLength: 4 },
            { buffer: 1, byteOffset: 0, byteLength: 4 },
        ],
    };
    const text = new TextEncoder().encode(
        JSON.stringify(json).padEnd(Math.ceil(JSON.stringify(json).length / 4) * 4, ' '),
    );
    const bin = new Uint8Array(104).map((_, i) => i);
    const glb = new Uint8Array(12 + 8 + text.length + 8 + bin.length);
    const view = new DataView(glb.buffer);
    view.setUint32(0, 0x46546c67, true);
    view.setUint32(4, 2, true);
    view.setUint32(8, glb.length, true);
    view.setUint32(12, text.length, true);
    view.setUint32(16, 0x4e4f534a, true);
    glb.set(text, 20);
    view.setUint32(20 + text.length, bin.length, true);
    view.setUint32(24 + text.length, 0x004e4942, true);
    glb.set(bin, 28 + text.length);
    const layout = glbLayout(glb);
    assert.equal(layout.binOffset, 28 + text.length);
    const parsed = parseGlb(glb);
    assert.deepEqual(parsed.json, json);
    assert.deepEqual([...parsed.bin.subarray(0, 3)], [0, 1, 2]);
    assert.equal(glbLayout(new TextEncoder().encode('{"asset":{"version":"2.0"}}')), null);
    assert.deepEqual(
        coalesceRanges(json, [0, 1, 2, 3], 4).map((r) => [r.buffer, r.start, r.end, r.views]),
        [
            [0, 0, 20, [0, 1]],
            [0, 100, 104, [2]],
            [1, 0, 4, [3]],
        ],
    );
});

test('ByteCoverage: distinct bytes and the overlap of a range, against a byte map', () => {
    // random ranges over two files; a Uint8Array per file marks the bytes added (the reference)
    let seed = 7;
    const random = (n) => ((seed = (seed * 1103515245 + 12345) % 2 ** 31), seed % n);
    const coverage = new ByteCoverage();
    const marked = { a: new Uint8Array(300), b: new Uint8Array(300) };
    for (let i = 0; i < 200; ++i) {
        const key = random(2) ? 'a' : 'b';
        const start = random(300);
        const end = Math.min(300, start + random(40));
        const before = marked[key].reduce((s, x) => s + x, 0);
        marked[key].fill(1, start, end);
        const added = coverage.add(key, start, end);
        assert.equal(added, marked[key].reduce((s, x) => s + x, 0) - before);
        const qs = random(300);
        const qe = Math.min(300, qs + random(60));
        const other = random(2) ? 'a' : 'b';
        assert.equal(
            coverage.overlap(other, qs, qe),
            marked[other].subarray(qs, qe).reduce((s, x) => s + x, 0),
        );
    }
    assert.equal(coverage.size, marked.a.reduce((s, x) => s + x, 0) + marked.b.reduce((s, x) => s + x, 0));
    assert.equal(coverage.overlap('c', 0, 100), 0);
});

test('serve.mjs: ranges, MIME types, no way out of its folders', async () => {
    assert.deepEqual(parseRange('bytes=0-9', 100), { start: 0, end: 9 });
    assert.deepEqual(parseRange('bytes=90-', 100), { start: 90, end: 99 });
    assert.deepEqual(parseRange('bytes=-10', 100), { start: 90, end: 99 });
    assert.deepEqual(parseRange('bytes=95-200', 100), { start: 95, end: 99 });
    assert.equal(parseRange('bytes=100-', 100), 'invalid');
    assert.equal(parseRange('bytes=5-1', 100), 'invalid');
    assert.equal(parseRange('bytes=0-1,5-6', 100), null);
    assert.equal(parseRange(undefined, 100), null);
    const dir = mkdtempSync(join(tmpdir(), 'strata-serve-test-'));
    try {
        mkdirSync(join(dir, 'models'));
        const bytes = new Uint8Array(1000).map((_, i) => i % 251);
        writeFileSync(join(dir, 'models', 'model.glb'), bytes);
        writeFileSync(join(dir, 'models', 'model.level1.bin'), bytes.subarray(0, 10));
        writeFileSync(join(dir, 'secret.txt'), 'no');
        const server = await startServer({ model: join(dir, 'models', 'model.glb'), port: 0 });
        try {
            assert.match(server.url, /^http:\/\/127\.0\.0\.1:\d+\/\?model=model\/model\.glb$/);
            const base = server.url.replace(/\?.*$/, '');
            let r = await fetch(`${base}model/model.glb`, { headers: { Range: 'bytes=10-19' } });
            assert.equal(r.status, 206);
            assert.equal(r.headers.get('content-range'), 'bytes 10-19/1000');
            assert.equal(r.headers.get('content-type'), 'model/gltf-binary');
            assert.deepEqual([...new Uint8Array(await r.arrayBuffer())], [...bytes.subarray(10, 20)]);
            r = await fetch(`${base}model/model.glb`);
            assert.equal(r.status, 200);
            assert.equal(r.headers.get('accept-ranges'), 'bytes');
            assert.equal((await r.arrayBuffer()).byteLength, 1000);
            r = await fetch(`${base}model/model.glb`, { headers: { Range: 'bytes=1000-' } });
            assert.equal(r.status, 416);
            assert.equal(r.headers.get('content-range'), 'bytes */1000');
            r = await fetch(`${base}model/model.level1.bin`, { method: 'HEAD' });
            assert.equal(r.status, 200);
            assert.equal(r.headers.get('content-length'), '10');
            r = await fetch(`${base}index.html`);
            assert.equal(r.status, 200);
            assert.match(r.headers.get('content-type'), /^text\/html/);
            r = await fetch(`${base}selection.js`);
            assert.match(r.headers.get('content-type'), /^text\/javascript/);
            for (const path of [
                'model/..%2Fsecret.txt',
                'model/%2e%2e/secret.txt',
                '..%2F..%2Fetc%2Fpasswd',
                'model/nothing.bin',
            ]) {
                r = await fetch(`${base}${path}`);
                assert.equal(r.status, 404, path);
            }
            r = await fetch(`${base}model/model.glb`, { method: 'POST' });
            assert.equal(r.status, 405);
        } finally {
            await server.close();
        }
    } finally {
        rmSync(dir, { recursive: true, force: true });
    }
});

/// GET url with the given headers, the body as received (not decoded): { status, headers, body }.
function rawGet(url, headers = {}) {
    return new Promise((resolve, reject) => {
        const req = httpRequest(url, { headers }, (res) => {
            const parts = [];
            res.on('data', (d) => parts.push(d));
            res.on('end', () => resolve({ status: res.statusCode, headers: res.headers, body: Buffer.concat(parts) }));
            res.on('error', reject);
        });
        req.on('error', reject);
        req.end();
    });
}

test('serve.mjs: the viewer files brotli- or gzip-compressed as the browser accepts, models as they are', async () => {
    assert.equal(pickEncoding('gzip, deflate, br'), 'br');
    assert.equal(pickEncoding('gzip;q=1.0, br;q=0'), 'gzip');
    assert.equal(pickEncoding('identity'), null);
    assert.equal(pickEncoding(undefined), null);
    const dir = mkdtempSync(join(tmpdir(), 'strata-serve-test-'));
    try {
        const bytes = new Uint8Array(5000).map((_, i) => (i * 7) % 13);
        writeFileSync(join(dir, 'model.glb'), bytes);
        const viewer = join(kHere, '..');
        const original = readFileSync(join(viewer, 'selection.js'));
        const wasm = readFileSync(join(viewer, 'node_modules/three/examples/jsm/libs/draco/gltf/draco_decoder.wasm'));
        for (const compress of [true, false]) {
            const server = await startServer({ model: join(dir, 'model.glb'), port: 0, compress });
            try {
                const base = server.url.replace(/\?.*$/, '');
                let r = await rawGet(`${base}selection.js`, { 'Accept-Encoding': 'gzip, br' });
                assert.equal(r.status, 200);
                if (compress) {
                    assert.equal(r.headers['content-encoding'], 'br');
                    assert.equal(r.headers.vary, 'Accept-Encoding');
                    assert.equal(Number(r.headers['content-length']), r.body.length);
                    assert.ok(r.body.length < original.length / 2, `${r.body.length} of ${original.length}`);
                    assert.ok(brotliDecompressSync(r.body).equals(original));
                } else {
                    assert.equal(r.headers['content-encoding'], undefined);
                    assert.ok(r.body.equals(original));
                }
                r = await rawGet(`${base}node_modules/three/examples/jsm/libs/draco/gltf/draco_decoder.wasm`, {
                    'Accept-Encoding': 'gzip',
                });
                assert.equal(r.headers['content-type'], 'application/wasm');
                assert.ok((compress ? gunzipSync(r.body) : r.body).equals(wasm));
                assert.equal(r.headers['content-encoding'], compress ? 'gzip' : undefined);
                r = await rawGet(`${base}selection.js`);
                assert.equal(r.headers['content-encoding'], undefined);
                assert.ok(r.body.equals(original));
                // the model: never compressed, ranges as asked
                r = await rawGet(`${base}model/model.glb`, { 'Accept-Encoding': 'br, gzip', Range: 'bytes=100-199' });
                assert.equal(r.status, 206);
                assert.equal(r.headers['content-encoding'], undefined);
                assert.ok(r.body.equals(Buffer.from(bytes.subarray(100, 200))));
            } finally {
                await server.close();
            }
        }
    } finally {
        rmSync(dir, { recursive: true, force: true });
    }
});

/// Runs `node serve.mjs ARGS` until it exits (or kills it after timeoutMs): { code, stdout, stderr }.
function runServe(args, timeoutMs = 10000) {
    return new Promise((resolvePromise) => {
        const child = spawn(process.execPath, [join(kHere, '..', 'serve.mjs'), ...args]);
        let stdout = '';
        let stderr = '';
        child.stdout.on('data', (d) => (stdout += d));
        child.stderr.on('data', (d) => (stderr += d));
        const timer = setTimeout(() => child.kill('SIGKILL'), timeoutMs);
        child.on('close', (code, signal) => {
            clearTimeout(timer);
            resolvePromise({ code, signal, stdout, stderr });
        });
    });
}

test('serve.mjs: a missing model, a folder or a taken port give one clear line and exit 2, no stack trace', async () => {
    const dir = mkdtempSync(join(tmpdir(), 'strata-serve-errors-'));
    try {
        const model = join(dir, 'model.glb');
        writeFileSync(model, new Uint8Array(100));
        const stackTrace = /^\s+at |node:internal|Error: listen/m;
        let r = await runServe([join(dir, 'missing.glb')]);
        assert.equal(r.code, 2, r.stderr);
        assert.match(r.stderr, /missing\.glb: no such file/);
        assert.doesNotMatch(r.stderr, /not a \.glb/);
        assert.doesNotMatch(r.stderr, stackTrace);
        r = await runServe([dir]);
        assert.equal(r.code, 2, r.stderr);
        assert.match(r.stderr, /a folder, expected a \.glb or \.gltf file/);
        writeFileSync(join(dir, 'notes.txt'), 'x');
        r = await runServe([join(dir, 'notes.txt')]);
        assert.equal(r.code, 2, r.stderr);
        assert.match(r.stderr, /not a \.glb or \.gltf file/);
        // a port another server holds
        const other = await startServer({ model, port: 0 });
        try {
            r = await runServe([model, '--port', String(other.port)]);
            assert.equal(r.code, 2, `exit ${r.code} ${r.signal}: ${r.stderr}`);
            assert.match(r.stderr, new RegExp(`port ${other.port} on 127\\.0\\.0\\.1 is already in use`));
            assert.doesNotMatch(r.stderr, stackTrace);
            assert.equal(r.stderr.trim().split('\n').length, 1, r.stderr);
        } finally {
            await other.close();
        }
    } finally {
        rmSync(dir, { recursive: true, force: true });
    }
});

// node --test web-viewer/test/
// The selection logic (selection.js) on real DAGs written by `strata build`: the model file is
// given by the environment variable STRATA_VIEWER_MODEL (a .glb; a .gltf with its buffer files
// works too); without it the tests build one (test-model.mjs), or fail.
// The expected cuts come from an oracle written here from the spec's definitions (sets of
// ancestors on the extension's own lists), not from selection.js's passes.
//
// For many random cameras, thresholds, budgets, regions of interest and loaded-chunk sets:
//   * the refined set is closed upward; the drawn clusters are the stateless rule's;
//   * coverage: no cluster is drawn with an ancestor (or descendant), and every level-0 cluster
//     has an ancestor-or-self drawn;
//   * only loaded clusters are drawn; the budget holds; the triangle count adds up;
//   * with everything loaded and no budget, the cut is exactly the spec's two passes
//     (schema/README.md) for the predicate sse * factor / tau > 1 in the frustum;
//   * monotone: a larger tau refines a subset of the groups and draws no more triangles; a larger
//     budget refines a superset; a region of interest refines a superset;
//   * geometry: for some cuts, the drawn clusters' triangles (decoded with draco3d, positions
//     compared bit-exactly) form a closed, consistently oriented surface: every directed edge
//     once, its reverse once.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { existsSync, readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { buildDag, clusterTriangleCounts, drawnClusters, selectCut, cutStats } from '../selection.js';
import { parseGlb, progressiveNodes } from '../gltf-file.js';
import { kClusterAttribute, kDraco } from '../strata-format.js';
import {
    chunksByteLength,
    decodeDraco,
    parseDagTable,
    readExtension,
    shadingNormals,
    splitByCluster,
} from '../strata-decode.js';
import { testModel } from './test-model.mjs';

const kModel = testModel();
const kTrials = Number(process.env.STRATA_VIEWER_TRIALS ?? 300);

// ------------------------------------------------------------------------------------------------
// the model

/// Reads a model (format version 3) and decodes all of it with draco3d: per object the DAG table
/// (as buildDag reads it), and per cluster its triangles as position keys (exact float values).
async function readModel(file) {
    const bytes = new Uint8Array(readFileSync(file));
    let json;
    const buffers = [];
    if (file.endsWith('.glb')) {
        const glb = parseGlb(bytes);
        json = glb.json;
        buffers.push(glb.bin);
    } else {
        json = JSON.parse(new TextDecoder().decode(bytes));
    }
    (json.buffers ?? []).forEach((b, i) => {
        if (b.uri !== undefined)
            buffers[i] = new Uint8Array(readFileSync(resolve(dirname(file), decodeURIComponent(b.uri))));
    });
    const draco3d = (await import('draco3d')).default;
    const draco = await draco3d.createDecoderModule({});
    const world = nodeWorldMatrices(json);
    const objects = progressiveNodes(json).map(({ nodeIndex, node, ext }) => {
        const info = readExtension(ext, json);
        const table = parseDagTable(bufferViewBytes(json, buffers, info.dag), info, chunksByteLength(info, json));
        const triangles = new Array(table.clusters.length); // cluster -> [[keyA, keyB, keyC], ...]
        const add = (clusters, decoded) => {
            const keys = [];
            const p = decoded.positions;
            for (let i = 0; i < p.length / 3; ++i) keys.push(`${p[3 * i] + 0},${p[3 * i + 1] + 0},${p[3 * i + 2] + 0}`);
            const { order, start } = splitByCluster(decoded.index, decoded.cluster, clusters.length);
            clusters.forEach((c, k) => {
                triangles[c] = [];
                for (let i = start[k]; i < start[k + 1]; i += 3) {
                    triangles[c].push([keys[order[i]], keys[order[i + 1]], keys[order[i + 2]]]);
                }
            });
            return decoded;
        };
        const roots = [];
        table.clusters.forEach((c, ci) => c.consumer === undefined && roots.push(ci));
        const primitive = json.meshes[node.mesh].primitives[0];
        const baseDraco = primitive.extensions[kDraco];
        const base = add(
            roots,
            decodeDraco(draco, bufferViewBytes(json, buffers, baseDraco.bufferView), {
                position: baseDraco.attributes.POSITION,
                cluster: baseDraco.attributes[kClusterAttribute],
            }),
        );
        const chunks = info.chunks === undefined ? new Uint8Array(0) : bufferViewBytes(json, buffers, info.chunks);
        table.groups.forEach((g) =>
            add(g.consumed, decodeDraco(draco, chunks.subarray(g.chunkOffset, g.chunkOffset + g.chunkLength))),
        );
        // roots that were never simplified: a sphere around their vertices (scene frame)
        for (const c of roots) {
            if (table.clusters[c].sphere !== null) continue;
            const m = world[nodeIndex];
            const points = [];
            for (let i = 0; i < base.positions.length; i += 3) {
                const [x, y, z] = [base.positions[i], base.positions[i + 1], base.positions[i + 2]];
                points.push([0, 1, 2].map((r) => m[r] * x + m[4 + r] * y + m[8 + r] * z + m[12 + r]));
            }
            const centre = [0, 1, 2].map((k) => points.reduce((s, q) => s + q[k], 0) / points.length);
            const radius = Math.max(
                ...points.map((q) => Math.hypot(q[0] - centre[0], q[1] - centre[1], q[2] - centre[2])),
            );
            table.clusters[c].sphere = [...centre, radius * (1 + 1e-6)];
        }
        return {
            nodeIndex,
            name: node.name,
            ext: table,
            triangles,
            dag: buildDag(table, { clusterTriangles: triangles.map((t) => t.length) }),
        };
    });
    return { json, buffers, objects };
}

const kIdentity = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];

/// a * b, 4 x 4 column-major arrays.
function multiply(a, b) {
    return Array.from({ length: 16 }, (_, k) => {
        const col = Math.floor(k / 4);
        const row = k % 4;
        let sum = 0;
        for (let i = 0; i < 4; ++i) sum += a[4 * i + row] * b[4 * col + i];
        return sum;
    });
}

/// Parent node index of every node (-1: a root).
function nodeParents(nodes) {
    const parent = new Array(nodes.length).fill(-1);
    nodes.forEach((n, i) => (n.children ?? []).forEach((c) => (parent[c] = i)));
    return parent;
}

/// The product of the matrices of a node and its ancestors below the "patient" node: an object's
/// local frame -> patient mm (its own matrix, absent, and the storage node's).
function localToPatient(json, index) {
    const nodes = json.nodes ?? [];
    const parent = nodeParents(nodes);
    let m = kIdentity;
    for (let i = index; i >= 0 && nodes[i].name !== 'patient'; i = parent[i]) {
        m = multiply(nodes[i].matrix ?? kIdentity, m);
    }
    return m;
}

/// World matrices (column-major arrays) of the nodes.
function nodeWorldMatrices(json) {
    const nodes = json.nodes ?? [];
    const parent = nodeParents(nodes);
    const world = (i) => (i < 0 ? kIdentity : multiply(world(parent[i]), nodes[i].matrix ?? kIdentity));
    return nodes.map((_, i) => world(i));
}

const model = await readModel(kModel);
function getModel() {
    return model;
}

// A deterministic random generator (mulberry32), so failures reproduce.
function random(seed) {
    let a = seed >>> 0;
    return () => {
        a = (a + 0x6d2b79f5) >>> 0;
        let t = a;
        t = Math.imul(t ^ (t >>> 15), t | 1);
        t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
        return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
}

/// The scene's bounding sphere (of the root groups' spheres).
function sceneSphere(objects) {
    const spheres = objects.flatMap(({ dag }) =>
        dag.roots.map((c) => [...dag.clusterSphere.subarray(4 * c, 4 * c + 4)]),
    );
    const centre = [0, 1, 2].map((k) => spheres.reduce((s, sp) => s + sp[k], 0) / spheres.length);
    const radius = Math.max(
        ...spheres.map((sp) => Math.hypot(sp[0] - centre[0], sp[1] - centre[1], sp[2] - centre[2]) + sp[3]),
    );
    return { centre, radius };
}

/// A random perspective view around the scene, sometimes inside it, with its frustum planes.
function randomView(rnd, scene) {
    const dir = normalize([rnd() * 2 - 1, rnd() * 2 - 1, rnd() * 2 - 1]);
    const distance = scene.radius * (rnd() < 0.15 ? rnd() * 0.8 : 0.8 + rnd() * 15);
    const position = scene.centre.map((c, k) => c + dir[k] * distance);
    // look at a random point near the centre
    const target = scene.centre.map((c) => c + (rnd() - 0.5) * scene.radius);
    const fovy = ((15 + rnd() * 75) * Math.PI) / 180;
    const heightPx = Math.round(200 + rnd() * 1800);
    const aspect = 0.5 + rnd() * 1.5;
    return {
        position,
        fovy,
        heightPx,
        frustum: frustumPlanes(position, target, fovy, aspect, scene.radius * 1e-3, scene.radius * 100),
    };
}

function normalize(v) {
    const n = Math.hypot(...v) || 1;
    return v.map((x) => x / n);
}

function cross(a, b) {
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
}

function dot(a, b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/// Six inward planes [n, d] of a perspective frustum.
function frustumPlanes(eye, target, fovy, aspect, near, far) {
    const f = normalize(target.map((t, k) => t - eye[k]));
    let up = Math.abs(f[1]) < 0.99 ? [0, 1, 0] : [1, 0, 0];
    const r = normalize(cross(f, up));
    up = cross(r, f);
    const ty = Math.tan(fovy / 2);
    const tx = ty * aspect;
    const plane = (n, p) => [...n, -dot(n, p)];
    const planes = [
        plane(
            f,
            eye.map((e, k) => e + f[k] * near),
        ),
        plane(
            f.map((x) => -x),
            eye.map((e, k) => e + f[k] * far),
        ),
    ];
    // side planes through the eye: normals from the frustum edges
    for (const [axis, t, other] of [
        [r, tx, up],
        [up, ty, r],
    ]) {
        for (const s of [1, -1]) {
            const edge = normalize(f.map((x, k) => x + s * t * axis[k]));
            let n = normalize(cross(edge, other));
            if (dot(n, f) < 0) n = n.map((x) => -x);
            planes.push(plane(n, eye));
        }
    }
    return planes;
}

// ------------------------------------------------------------------------------------------------
// the oracle: the spec's definitions (schema/README.md, "Selecting a cut", "Streaming") evaluated
// on the extension's own cluster and group lists, as sets, without selection.js

/// Per group, the set of groups above it (ancestors: consumers of its produced clusters, their
/// consumers, ...), from ext.groups[g].produced and the groups' consumed lists.
function ancestorSets(ext) {
    const consumerOf = new Map();
    ext.groups.forEach((group, g) => group.consumed.forEach((c) => consumerOf.set(c, g)));
    const memo = new Array(ext.groups.length);
    const above = (g) => {
        if (memo[g] === undefined) {
            const out = new Set();
            for (const c of ext.groups[g].produced) {
                const p = consumerOf.get(c);
                if (p === undefined) continue;
                out.add(p);
                for (const q of above(p)) out.add(q);
            }
            memo[g] = out;
        }
        return memo[g];
    };
    return ext.groups.map((_, g) => above(g));
}

/// The refined set the spec defines for predicate P (and a loaded set): g is refined iff P holds
/// for g or for some group below g (upward closure), and every group in g's ancestors-or-self has
/// its consumed clusters loaded (the streaming restriction). Returns a Uint8Array.
function oracleRefined(ext, ancestors, predicate, isLoaded = null) {
    const ng = ext.groups.length;
    const wanted = new Uint8Array(ng);
    for (let g = 0; g < ng; ++g) {
        if (!predicate(g)) continue;
        wanted[g] = 1;
        for (const a of ancestors[g]) wanted[a] = 1;
    }
    const loaded = (g) => isLoaded === null || ext.groups[g].consumed.every((c) => isLoaded(c));
    const out = new Uint8Array(ng);
    for (let g = 0; g < ng; ++g) {
        out[g] = wanted[g] && loaded(g) && [...ancestors[g]].every(loaded) ? 1 : 0;
    }
    return out;
}

/// The spec's draw rule on the extension's lists: c is drawn iff (no producer or producer not
/// refined) and (no consumer or consumer refined).
function oracleDrawn(ext, refined) {
    const producer = new Map();
    const consumer = new Map();
    ext.groups.forEach((group, g) => {
        group.produced.forEach((c) => producer.set(c, g));
        group.consumed.forEach((c) => consumer.set(c, g));
    });
    const out = [];
    for (let c = 0; c < ext.clusters.length; ++c) {
        const p = producer.get(c);
        const q = consumer.get(c);
        if ((p === undefined || !refined[p]) && (q === undefined || refined[q])) out.push(c);
    }
    return out;
}

/// The spec's screen-space predicate for one group (its sphere and its bound against the finest
/// level, error * fine / 65535, which the viewer projects): in the frustum (sphere not wholly
/// behind a plane) and sse * factor / tau > 1, sse = e * H / (d * 2 tan(fovy / 2)), d = |camera - centre| - radius (infinite error at d <= 0), factor = roi.factor where the
/// sphere meets the region of interest.
function oracleWants(group, view, tauPx, roi, frustum) {
    const [x, y, z, r] = group.sphere;
    for (const [nx, ny, nz, d] of frustum ?? []) {
        if (nx * x + ny * y + nz * z + d < -r) return false;
    }
    const d = Math.hypot(view.position[0] - x, view.position[1] - y, view.position[2] - z) - r;
    const e = group.fineError;
    assert.ok(e >= 0 && e <= group.error, `bound against the finest level ${e}, error ${group.error}`);
    const sse = d > 0 ? (e * view.heightPx) / (d * 2 * Math.tan(view.fovy / 2)) : e > 0 ? Infinity : 0;
    const inRoi = roi && Math.hypot(x - roi.center[0], y - roi.center[1], z - roi.center[2]) <= r + roi.radius;
    const factor = inRoi && roi.factor > 1 ? roi.factor : 1;
    return (sse * factor) / tauPx > 1;
}

/// True when every group above a refined group is refined (closed upward), on the oracle's sets.
function closedUpward(ancestors, refined) {
    return ancestors.every((above, g) => !refined[g] || [...above].every((a) => refined[a]));
}

// ------------------------------------------------------------------------------------------------
// checks

/// No drawn cluster has a drawn ancestor (a cluster produced by its consumer, or by the consumer
/// of such a cluster, ...), and every level-0 cluster has at least one ancestor-or-self drawn.
/// (Not "exactly one": a group that produces several clusters replaces all its consumed clusters
/// by all its produced ones together, so a level-0 cluster has several ancestors at one level;
/// the decoded-geometry test below checks that the pieces fit exactly.) Returns a problem or null.
function coverageProblem(dag, drawn) {
    const isDrawn = new Uint8Array(dag.nc);
    for (const c of drawn) isDrawn[c] = 1;
    const ancestorsOf = (c) => {
        const out = new Set();
        const stack = [c];
        while (stack.length > 0) {
            const g = dag.consumer[stack.pop()];
            if (g < 0) continue;
            for (const a of dag.groups[g].produced) {
                if (!out.has(a)) {
                    out.add(a);
                    stack.push(a);
                }
            }
        }
        return out;
    };
    for (const c of drawn) {
        for (const a of ancestorsOf(c)) {
            if (isDrawn[a]) return `cluster ${c} is drawn with its ancestor ${a}`;
        }
    }
    for (let c = 0; c < dag.nc; ++c) {
        if (dag.producer[c] < 0 && !isDrawn[c] && ![...ancestorsOf(c)].some((a) => isDrawn[a])) {
            return `level-0 cluster ${c} has no ancestor-or-self drawn (a hole)`;
        }
    }
    return null;
}

function subset(a, b) {
    return a.every((x, i) => !x || b[i]);
}

// ------------------------------------------------------------------------------------------------

test('the model has objects with STRATA_progressive_mesh', () => {
    const { objects } = getModel();
    assert.ok(objects.length > 0, `no node with the extension in ${kModel}`);
    assert.ok(
        objects.some(({ dag }) => dag.ng > 0),
        'no object has refinement groups',
    );
    for (const { name, dag } of objects) {
        // a surface of a single cluster has no groups (schema/README.md)
        assert.ok(
            dag.ng === 0 ? dag.nc === 1 : dag.totalTriangles > dag.baseTriangles,
            `${name}: ${dag.nc} clusters, ${dag.ng} groups`,
        );
        assert.deepEqual(
            drawnClusters(dag, new Uint8Array(dag.ng)),
            dag.roots,
            `${name}: nothing refined must draw the roots`,
        );
        const all = drawnClusters(dag, new Uint8Array(dag.ng).fill(1));
        assert.ok(
            all.every((c) => dag.producer[c] < 0),
            `${name}: everything refined must draw level 0`,
        );
    }
    console.log(`${kModel}: ${objects.map((o) => `${o.name} ${o.dag.nc} clusters/${o.dag.ng} groups`).join(', ')}`);
});

test('level cuts and uniform-error cuts are valid cuts', () => {
    const { objects } = getModel();
    for (const { name, dag, ext } of objects) {
        const ancestors = ancestorSets(ext);
        const levels = Math.max(...dag.groups.map((g) => g.level));
        for (let level = 0; level <= levels; ++level) {
            const refined = oracleRefined(ext, ancestors, (g) => ext.groups[g].level > level);
            const drawn = oracleDrawn(ext, refined);
            assert.ok(closedUpward(ancestors, refined), `${name} level ${level}: not closed upward`);
            assert.deepEqual(
                drawnClusters(dag, refined),
                drawn,
                `${name} level ${level}: selection.js draws other clusters`,
            );
            assert.equal(coverageProblem(dag, drawn), null, `${name} level ${level}`);
        }
        for (const g of dag.groups) {
            const tau = g.error * 0.999;
            const refined = oracleRefined(ext, ancestors, (h) => ext.groups[h].error > tau);
            const drawn = oracleDrawn(ext, refined);
            assert.ok(closedUpward(ancestors, refined));
            assert.equal(coverageProblem(dag, drawn), null, `${name} uniform error ${tau}`);
            assert.ok(
                cutStats(dag, drawn).maxError <= Math.max(tau, dag.fullResolutionError),
                `${name}: bound above tau`,
            );
        }
    }
});

test('random views, taus, budgets, regions and loaded sets: valid, exact, monotone cuts', () => {
    const { objects } = getModel();
    const dags = objects.map((o) => o.dag);
    const ancestors = objects.map((o) => ancestorSets(o.ext));
    const scene = sceneSphere(objects);
    const rnd = random(12345);
    const base = dags.reduce((s, d) => s + d.baseTriangles, 0);
    const total = dags.reduce((s, d) => s + d.totalTriangles, 0);
    let refinedSomething = 0;
    let budgetLimited = 0;
    let partial = 0;
    for (let trial = 0; trial < kTrials; ++trial) {
        const view = randomView(rnd, scene);
        const cull = rnd() < 0.7;
        const roi =
            rnd() < 0.4
                ? {
                      center: scene.centre.map((c) => c + (rnd() - 0.5) * scene.radius),
                      radius: scene.radius * rnd() * 0.3,
                      factor: 1 + rnd() * 8,
                  }
                : null;
        // a random loaded set (roots always loaded), or everything
        let loaded = null;
        if (rnd() < 0.4) {
            const p = rnd();
            loaded = dags.map((d) =>
                Uint8Array.from({ length: d.nc }, (_, c) => (d.consumer[c] < 0 || rnd() < p ? 1 : 0)),
            );
        }
        const isLoaded = loaded === null ? null : (di, c) => loaded[di][c] === 1;
        const budget = rnd() < 0.5 ? Infinity : base + rnd() * (total - base) * 0.5;
        const taus = Array.from({ length: 4 }, () => Math.exp(Math.log(0.25) + rnd() * Math.log(200))).sort(
            (a, b) => a - b,
        );
        let previous = null;
        for (const tauPx of taus) {
            const options = { tauPx, budget, roi, cull, isLoaded };
            const result = selectCut(dags, view, options);
            const where = `trial ${trial} tau ${tauPx.toFixed(3)} budget ${budget} roi ${!!roi} cull ${cull} loaded ${!!loaded}`;
            let triangles = 0;
            result.cuts.forEach((cut, di) => {
                const dag = dags[di];
                assert.ok(closedUpward(ancestors[di], cut.refined), `${where}: ${objects[di].name} not closed upward`);
                assert.deepEqual(cut.drawn, oracleDrawn(objects[di].ext, cut.refined));
                assert.equal(coverageProblem(dag, cut.drawn), null, `${where}: ${objects[di].name}`);
                if (loaded !== null) {
                    for (const c of cut.drawn) assert.ok(loaded[di][c], `${where}: cluster ${c} drawn but not loaded`);
                }
                for (const g of cut.refined.keys()) {
                    if (cut.refined[g]) {
                        assert.ok(cut.weight[g] >= 0 && cut.weight[g] <= 1);
                    }
                }
                triangles += cutStats(dag, cut.drawn).triangles;
                // against the spec's passes, when nothing limits the cut
                if (budget === Infinity) {
                    const ext = objects[di].ext;
                    const spec = oracleRefined(
                        ext,
                        ancestors[di],
                        (g) => oracleWants(ext.groups[g], view, tauPx, roi, cull ? view.frustum : null),
                        loaded === null ? null : (c) => loaded[di][c] === 1,
                    );
                    assert.deepEqual(cut.refined, spec, `${where}: ${objects[di].name} differs from the spec's passes`);
                }
                if (cut.refined.some((x) => x)) ++refinedSomething;
            });
            assert.equal(result.triangles, triangles, `${where}: triangle count`);
            assert.ok(
                triangles <= Math.max(budget, base),
                `${where}: ${triangles} triangles over the budget ${budget}`,
            );
            if (result.budgetLimited) ++budgetLimited;
            if (result.wanted.length > 0) ++partial;
            if (previous !== null) {
                result.cuts.forEach((cut, di) => {
                    assert.ok(
                        subset(cut.refined, previous.cuts[di].refined),
                        `${where}: a larger tau refined a group a smaller one did not (${objects[di].name})`,
                    );
                });
                assert.ok(result.triangles <= previous.triangles, `${where}: a larger tau draws more triangles`);
            }
            previous = result;
        }
        // monotone in the budget and in the region of interest (tau fixed)
        const tauPx = taus[0];
        const small = selectCut(dags, view, { tauPx, budget: base + (total - base) * 0.05, roi, cull, isLoaded });
        const large = selectCut(dags, view, { tauPx, budget: base + (total - base) * 0.3, roi, cull, isLoaded });
        small.cuts.forEach((cut, di) =>
            assert.ok(subset(cut.refined, large.cuts[di].refined), `trial ${trial}: budget not monotone`),
        );
        if (roi !== null) {
            const without = selectCut(dags, view, { tauPx, cull, isLoaded });
            const withRoi = selectCut(dags, view, { tauPx, roi, cull, isLoaded });
            without.cuts.forEach((cut, di) =>
                assert.ok(subset(cut.refined, withRoi.cuts[di].refined), `trial ${trial}: roi not monotone`),
            );
        }
    }
    console.log(
        `${kTrials} views x 4 taus: some refinement in ${refinedSomething} object cuts, ` +
            `budget-limited ${budgetLimited}, waiting for chunks ${partial}`,
    );
    assert.ok(refinedSomething > kTrials, 'the random views hardly ever refine anything: the test is not testing');
    assert.ok(budgetLimited > 0, 'the budget never limited a cut');
});

test('drawn clusters of random cuts form closed, consistently oriented surfaces (decoded with draco3d)', async () => {
    const { objects } = getModel();
    const dags = objects.map((o) => o.dag);
    const scene = sceneSphere(objects);
    const rnd = random(777);
    let checked = 0;
    for (let trial = 0; trial < 16; ++trial) {
        const view = randomView(rnd, scene);
        const roi = {
            center: scene.centre.map((c) => c + (rnd() - 0.5) * scene.radius),
            radius: scene.radius * 0.2,
            factor: 4,
        };
        const base = dags.reduce((s, d) => s + d.baseTriangles, 0);
        const budget = trial % 4 === 1 ? base * (1 + rnd() * 3) : Infinity;
        const loaded = dags.map((d) =>
            Uint8Array.from({ length: d.nc }, (_, c) => (d.consumer[c] < 0 || rnd() < 0.7 ? 1 : 0)),
        );
        const isLoaded = trial % 4 === 2 ? (di, c) => loaded[di][c] === 1 : null;
        const result = selectCut(dags, view, {
            tauPx: Math.exp(rnd() * 4) * 0.3,
            roi: trial % 2 ? roi : null,
            cull: trial % 3 !== 0,
            budget,
            isLoaded,
        });
        result.cuts.forEach((cut, di) => {
            const triangles = cut.drawn.flatMap((c) => objects[di].triangles[c]);
            const problem = closedProblem(triangles);
            assert.equal(
                problem,
                null,
                `trial ${trial}: ${objects[di].name}, ${cut.drawn.length} clusters: ${problem}`,
            );
            ++checked;
        });
    }
    console.log(`${checked} cuts closed and consistently oriented`);
});

// ------------------------------------------------------------------------------------------------
// geometry helpers

function closedProblem(triangles) {
    const directed = new Map();
    for (const [a, b, c] of triangles) {
        if (a === b || b === c || c === a) return 'degenerate triangle';
        for (const [u, v] of [
            [a, b],
            [b, c],
            [c, a],
        ]) {
            const key = `${u}|${v}`;
            if (directed.has(key)) return `directed edge ${key} used twice`;
            directed.set(key, 1);
        }
    }
    for (const key of directed.keys()) {
        const [u, v] = key.split('|');
        if (!directed.has(`${v}|${u}`)) return `edge ${key} has no reverse (hole or crack)`;
    }
    return null;
}

function bufferViewBytes(json, buffers, index) {
    const view = json.bufferViews[index];
    const start = view.byteOffset ?? 0;
    return buffers[view.buffer].subarray(start, start + view.byteLength);
}

test("the plugin's normals over the full-resolution cut are the C++ shading normals of scene.glb", async () => {
    // scene.glb (written beside the model by `strata build`): the full-resolution meshes in patient
    // mm with strata's C++ shading_normals; the plugin computes its normals with
    // strata-decode.js's shadingNormals over the drawn cut: over the level-0 cut they must agree
    const scenePath = join(dirname(kModel), 'scene.glb');
    assert.ok(existsSync(scenePath), `${scenePath}: missing (strata build writes it beside model.glb)`);
    const scene = parseGlb(new Uint8Array(readFileSync(scenePath)));
    const draco = await (await import('draco3d')).default.createDecoderModule({});
    const { json, objects } = getModel();
    let compared = 0;
    let worst = 0;
    for (const object of objects) {
        const M = localToPatient(json, object.nodeIndex); // local -> patient mm
        const ids = new Map();
        const positions = [];
        const triangles = [];
        const idOf = (key) => {
            const [x, y, z] = key.split(',').map(Number);
            const mm = [0, 1, 2].map((r) => M[r] * x + M[4 + r] * y + M[8 + r] * z + M[12 + r]);
            const k = mm.map((v) => Math.round(v * 1024)).join(',');
            if (!ids.has(k)) {
                ids.set(k, positions.length / 3);
                positions.push(...mm);
            }
            return ids.get(k);
        };
        object.ext.clusters.forEach((cluster, c) => {
            if (cluster.level !== 0) return;
            for (const t of object.triangles[c]) triangles.push(...t.map(idOf));
        });
        const normals = shadingNormals(Float64Array.from(positions), Uint32Array.from(triangles), positions.length / 3);
        const node = scene.json.nodes.find((n) => n.name === object.name && n.mesh !== undefined);
        assert.ok(node !== undefined, `scene.glb has no node ${object.name}`);
        const primitive = scene.json.meshes[node.mesh].primitives[0];
        let P;
        let N;
        let tolerance = 0.1; // degrees: float32 storage
        const compressed = primitive.extensions?.[kDraco];
        if (compressed !== undefined) {
            const bytes = bufferViewBytes(scene.json, [scene.bin], compressed.bufferView);
            const decoder = new draco.Decoder();
            const mesh = new draco.Mesh();
            decoder.DecodeArrayToMesh(
                new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength),
                bytes.byteLength,
                mesh,
            );
            const read = (id) => {
                const values = new draco.DracoFloat32Array();
                decoder.GetAttributeFloatForAllPoints(mesh, decoder.GetAttributeByUniqueId(mesh, id), values);
                const out = Float32Array.from({ length: values.size() }, (_, i) => values.GetValue(i));
                draco.destroy(values);
                return out;
            };
            P = read(compressed.attributes.POSITION);
            N = read(compressed.attributes.NORMAL);
            draco.destroy(mesh);
            draco.destroy(decoder);
            tolerance = 1; // Draco's normal quantization
        } else {
            const read = (index) => {
                const a = scene.json.accessors[index];
                const bytes = bufferViewBytes(scene.json, [scene.bin], a.bufferView);
                return new Float32Array(bytes.slice(a.byteOffset ?? 0).buffer, 0, 3 * a.count);
            };
            P = read(primitive.attributes.POSITION);
            N = read(primitive.attributes.NORMAL);
        }
        // Draco-compressed positions are quantized: match each scene vertex to the nearest model
        // vertex (within 0.01 mm; distinct vertices are far further apart)
        const cell = (v) => Math.floor(v / 0.05);
        const grid = new Map();
        for (let id = 0; id < positions.length / 3; ++id) {
            const key = [0, 1, 2].map((k) => cell(positions[3 * id + k])).join(',');
            if (!grid.has(key)) grid.set(key, []);
            grid.get(key).push(id);
        }
        const nearest = (x, y, z) => {
            let best;
            let bestD = 0.01;
            for (let dx = -1; dx <= 1; ++dx)
                for (let dy = -1; dy <= 1; ++dy)
                    for (let dz = -1; dz <= 1; ++dz) {
                        for (const id of grid.get(`${cell(x) + dx},${cell(y) + dy},${cell(z) + dz}`) ?? []) {
                            const d = Math.hypot(
                                positions[3 * id] - x,
                                positions[3 * id + 1] - y,
                                positions[3 * id + 2] - z,
                            );
                            if (d < bestD) {
                                bestD = d;
                                best = id;
                            }
                        }
                    }
            return best;
        };
        for (let i = 0; i < P.length / 3; ++i) {
            const id = nearest(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
            assert.ok(id !== undefined, `${object.name}: scene.glb vertex ${i} is not a vertex of the level-0 cut`);
            const length = Math.hypot(N[3 * i], N[3 * i + 1], N[3 * i + 2]);
            const dot =
                (normals[3 * id] * N[3 * i] + normals[3 * id + 1] * N[3 * i + 1] + normals[3 * id + 2] * N[3 * i + 2]) /
                length;
            const angle = (Math.acos(Math.min(1, dot)) * 180) / Math.PI;
            worst = Math.max(worst, angle);
            assert.ok(
                angle <= tolerance,
                `${object.name} vertex ${i}: ${angle.toFixed(3)} degrees from scene.glb's normal`,
            );
            ++compared;
        }
        assert.equal(
            P.length / 3,
            positions.length / 3,
            `${object.name}: scene.glb and the level-0 cut have other vertices`,
        );
    }
    console.log(`${compared} normals compared with scene.glb: at most ${worst.toFixed(4)} degrees apart`);
});

// A three.js GLTFLoader plugin for STRATA_progressive_mesh version 2 (schema/README.md): any
// three.js app can register it, independently of this folder's page.
//
//   import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
//   import { StrataProgressivePlugin } from './strata-progressive.js';
//   loader.setDRACOLoader(dracoLoader);
//   loader.register((parser) => new StrataProgressivePlugin(parser, { concurrency: 4 }));
//   const gltf = await loader.loadAsync('model.gltf');
//   const strata = gltf.userData.strata;          // this plugin: update() for all objects
//   // every frame:
//   strata.update(camera, renderer.domElement.height, 1 /* tau px */, 2e6 /* triangles */);
//
// GLTFLoader builds the base (the node's mesh: one Draco primitive holding every root cluster,
// with _CLUSTER) as usual; the plugin then
//   * reads each object's DAG table (strata-decode.js) and splits the base by root cluster (one
//     controller per object: strata.controllers);
//   * per update selects the cut (selection.js: screen-space error with the 3D Tiles formula,
//     region of interest, frustum, triangle budget, chunks not loaded yet), sets each drawn
//     chunk's geomorph weight, computes smooth shading normals over the drawn cut of every object
//     whose cut changed (welded at shared positions across clusters and levels, the definition of
//     strata's C++ shading normals), and draws each object's cut as ONE mesh: one geometry per
//     object holding the drawn clusters' triangles (rebuilt when its cut or normals change, its
//     weights rewritten while it blends), one material per object, so that draw calls grow with
//     the objects, not the clusters (FreeSurfer's 188 objects drew thousands of cluster meshes);
//   * requests the chunks of the wanted groups by priority, a few HTTP range requests at a time
//     (neighbouring chunks in one request), cancels requests no longer wanted, decodes chunks with
//     GLTFLoader's DRACOLoader (Web Workers), resolves their geomorph slots, and unloads chunks
//     that left the cut when the loaded triangles exceed a memory budget.
// Geomorphs: each object's mesh has a clone of its material whose vertex shader draws
// position + (_coarse_position - position) * w, with w a vertex attribute holding, for the points
// of a chunk, the weight of the group that consumes the chunk's clusters (all of them are consumed
// by that group; 1 at the refinement threshold, 0 from k * tau on), a short time blend
// from 1 to 0 after a refinement the threshold did not announce (a chunk arriving late), and from
// 0 to 1 before a coarsening the threshold did not announce (budget, frustum, a jump of the
// camera): the consumed clusters stay drawn while they morph onto the produced ones. Root
// clusters have _coarse_position = position and w = 0, so shared vertices are transformed by
// identical code in every cluster (invariant gl_Position).
import {
    Box3,
    BufferAttribute,
    BufferGeometry,
    Color,
    DynamicDrawUsage,
    Frustum,
    LoaderUtils,
    Matrix4,
    Mesh,
    MeshBasicMaterial,
    Sphere,
    Vector3,
} from 'three';
import {
    buildDag,
    clusterError,
    cutStats,
    selectCut,
    setClusterTriangles,
    sphereMeetsRoi,
    drawnClusters,
} from './selection.js';
import { ByteCoverage, coalesceRanges, glbLayout, meshBufferViews, progressiveNodes } from './gltf-file.js';
import {
    kChunkAttributeIds,
    kDraco,
    kExtension,
    kPatientNode,
    kThreeAttributes,
    kThreeClusterAttribute,
} from './strata-format.js';
import {
    chunksByteLength,
    parseDagTable,
    readExtension,
    resolveSlots,
    shadingNormals,
    splitByCluster,
} from './strata-decode.js';

const kDefaults = {
    concurrency: 4, // HTTP requests in flight
    // chunks fetched or decoding at once (DRACOLoader's workers queue them): 24 split the
    // TotalSegmentator example's ~150 wanted chunks into ten rounds of requests
    maxDecodes: 256,
    morph: true, // geomorphs
    morphK: 2, // w = clamp((k - sse / tau) / (k - 1), 0, 1)
    blendMs: 300, // time blend of a refinement or coarsening the threshold did not announce
    cull: true, // refine only groups whose sphere meets the view frustum
    // what tau bounds (selection.js buildDag): 'finest', each group's bound against full resolution;
    // 'data', how much its bound against the slices exceeds full resolution's
    refineOn: 'finest',
    normals: true, // shading normals over the drawn cut (false: the base's normals, chunks flat)
    // main-thread time per update for recomputing objects' normals (at least one object), or 40 %
    // of the time since the last update when frames are slower (a slow GPU leaves the main thread
    // idle: 8 ms per 150 ms frame of software WebGL made normals the bottleneck of settling)
    normalsMs: 8,
    normalsFullShare: 0.5, // recompute an object's normals over its whole cut when more of it changed
    prefetch: true, // request the chunks of the levels below a missing one at once (selectCut prefetch)
    // main-thread time per task for attaching decoded chunks (at least one chunk): tasks of their
    // own, as chunks arrive, not one slice per frame (which tied loading to the frame rate)
    attachMs: 8,
    // main-thread time per task of the setup (at least one object): the objects' controllers are
    // made in tasks of their own, so that frames and arriving responses are not held up for the
    // whole setup (one task of 100-210 ms on the torso and TotalSegmentator)
    setupSliceMs: 16,
    memoryBudget: 4e6, // triangles of loaded chunks kept; beyond it, chunks off the cut are unloaded
    // merge chunk ranges of one buffer closer than this into one request: 4 kB, less than an
    // average chunk, so that merging saves requests without fetching many chunks the view does
    // not want (32 kB fetched 72 % of the torso's bytes at tau 2 where 4 kB fetched 36 %)
    maxRangeGap: 4096,
    maxRangeBytes: 1 << 20, // ... up to this length
    source: null, // set by loadStrataModel: { kind: 'glb-range', url, binOffset, length, prefix }
    initialBytes: 0, // bytes fetched before GLTFLoader ran (loadStrataModel: the JSON)
    initialRanges: [], // ... as [url, start, end) triples (distinct bytes are counted once)
    totalBytes: 0, // total size of the model's files, when known
    fetch: null, // fetch function (default globalThis.fetch)
    onChange: null, // called when a chunk arrives or the setup is done (an app that renders on demand re-renders)
    deferSetup: true, // the first frame shows the base before the plugin's setup (afterRoot)
};

/// A User Timing mark (for benchmarks: web-viewer/bench/first-frame.mjs reads them).
/// Resolves in a task of its own (after what the event loop has queued: frames, responses).
function nextTask() {
    return new Promise((resolve) => setTimeout(resolve, 0));
}

function mark(name) {
    globalThis.performance?.mark?.(name);
}

// ------------------------------------------------------------------------------------------------
// byte sources

/// Fetches [start, end) of url with a Range request; a server that answers 200 gives the whole
/// file, which is then kept (whole) for later ranges of the same url. stats.bytesFetched counts
/// every byte received, stats.bytesLoaded the distinct bytes of the model's files (so it never
/// exceeds their size).
class RangeFetcher {
    constructor(fetchFn, stats, coverage) {
        this.fetch = fetchFn;
        this.stats = stats;
        this.coverage = coverage;
        this.whole = new Map(); // url -> Promise<ArrayBuffer> when ranges are not supported
    }

    count(url, start, bytes) {
        ++this.stats.requests;
        this.stats.bytesFetched += bytes;
        this.stats.bytesLoaded += this.coverage.add(url, start, start + bytes);
    }

    /// signal: an AbortSignal (the request is dropped when it becomes obsolete).
    async range(url, start, end, signal = undefined) {
        if (this.whole.has(url)) {
            return (await this.whole.get(url)).slice(start, end);
        }
        const response = await this.fetch(url, { headers: { Range: `bytes=${start}-${end - 1}` }, signal });
        if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
        const body = await response.arrayBuffer();
        this.count(url, response.status === 206 ? start : 0, body.byteLength);
        if (response.status === 206) {
            if (body.byteLength !== end - start) {
                throw new Error(`${url}: range ${start}-${end} gave ${body.byteLength} bytes`);
            }
            return body;
        }
        this.whole.set(url, Promise.resolve(body)); // no range support: we have it all now
        return body.slice(start, end);
    }

    async all(url) {
        if (!this.whole.has(url)) {
            this.whole.set(
                url,
                (async () => {
                    const response = await this.fetch(url);
                    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
                    const body = await response.arrayBuffer();
                    this.count(url, 0, body.byteLength);
                    return body;
                })(),
            );
        }
        return this.whole.get(url);
    }
}

// ------------------------------------------------------------------------------------------------
// geomorph material

/// The name of the per-point geomorph weight attribute of the objects' draw geometries.
const kMorphWeight = 'strataMorph';

/// A clone of an object's material that morphs position towards _coarse_position by the per-point
/// weight attribute strataMorph. All objects' clones share one program.
function morphMaterial(base) {
    const material = base.clone();
    material.userData.strataBaseColor = base.color?.clone();
    const coarse = kThreeAttributes.coarsePosition;
    material.onBeforeCompile = (shader) => {
        shader.vertexShader =
            `invariant gl_Position;\nattribute vec3 ${coarse};\nattribute float ${kMorphWeight};\n` +
            shader.vertexShader.replace(
                '#include <begin_vertex>',
                `vec3 transformed = position + ( ${coarse} - position ) * ${kMorphWeight};`,
            );
    };
    material.customProgramCacheKey = () => 'strata-morph-3';
    return material;
}

/// Grows a capacity (elements) to hold at least n: powers of two from 1024.
function capacityFor(n) {
    let c = 1024;
    while (c < n) c *= 2;
    return c;
}

/// The attribute values of a (possibly interleaved) three.js attribute, one component per item.
function scalarValues(attribute) {
    const out = new Uint32Array(attribute.count);
    for (let i = 0; i < attribute.count; ++i) out[i] = attribute.getX(i);
    return out;
}

// ------------------------------------------------------------------------------------------------
// vertex ids

/// Exact positions -> dense ids: an open-addressing hash table on the three float32 bit patterns
/// (the positions of one surface lie on one grid, so equal positions are bit-identical; -0 is
/// taken as +0). A Map keyed by strings did the same at several times the cost.
class VertexTable {
    constructor() {
        this.capacity = 1 << 12;
        this.keys = new Uint32Array(3 * this.capacity);
        this.ids = new Int32Array(this.capacity).fill(-1);
        this.size = 0;
    }

    static slot(x, y, z, mask) {
        let h =
            Math.imul(x, 0x9e3779b1) ^ Math.imul(y ^ (y >>> 16), 0x85ebca77) ^ Math.imul(z ^ (z >>> 13), 0xc2b2ae3d);
        h ^= h >>> 15;
        h = Math.imul(h, 0x2c1b3c6d);
        h ^= h >>> 12;
        return h & mask;
    }

    /// The id of position bits (x, y, z), or `next` (then stored as its id) when new.
    idOf(x, y, z, next) {
        if (x === 0x80000000) x = 0;
        if (y === 0x80000000) y = 0;
        if (z === 0x80000000) z = 0;
        if (2 * (this.size + 1) > this.capacity) this.grow();
        const mask = this.capacity - 1;
        for (let i = VertexTable.slot(x, y, z, mask); ; i = (i + 1) & mask) {
            const id = this.ids[i];
            if (id < 0) {
                this.keys[3 * i] = x;
                this.keys[3 * i + 1] = y;
                this.keys[3 * i + 2] = z;
                this.ids[i] = next;
                ++this.size;
                return next;
            }
            if (this.keys[3 * i] === x && this.keys[3 * i + 1] === y && this.keys[3 * i + 2] === z) return id;
        }
    }

    grow() {
        const { keys, ids } = this;
        this.capacity *= 2;
        this.keys = new Uint32Array(3 * this.capacity);
        this.ids = new Int32Array(this.capacity).fill(-1);
        const mask = this.capacity - 1;
        for (let j = 0; j < ids.length; ++j) {
            if (ids[j] < 0) continue;
            let i = VertexTable.slot(keys[3 * j], keys[3 * j + 1], keys[3 * j + 2], mask);
            while (this.ids[i] >= 0) i = (i + 1) & mask;
            this.keys.set(keys.subarray(3 * j, 3 * j + 3), 3 * i);
            this.ids[i] = ids[j];
        }
    }
}

// ------------------------------------------------------------------------------------------------
// one object

/// The controller of one object node: its DAG, its loaded chunks and clusters, and the one mesh
/// that draws its cut.
export class StrataObjectController {
    /// table: parseDagTable's result; base: the GLTFLoader mesh of the node's mesh.
    constructor(plugin, nodeIndex, object, table, base, json) {
        this.plugin = plugin;
        this.nodeIndex = nodeIndex;
        this.object = object;
        this.name = json.nodes[nodeIndex].name ?? `node ${nodeIndex}`;
        this.extras = json.nodes[nodeIndex].extras ?? {};
        this.table = table;
        this.chunksView = json.extensions[kExtension].chunks; // one view for every object
        this.material = base.material;
        const nc = table.clusters.length;
        // cluster -> { chunk, range: [a, b) of chunk.index } (null until loaded); a chunk (the base,
        // or one group's decoded chunk): { group (-1: the base), positions, coarse, normals (the
        // shading normals of its points, object local frame), index (ordered by cluster), vertexOf
        // (object vertex id per point), count (points) }
        this.parts = new Array(nc).fill(null);
        // vertex ids of the object: one per distinct position (exact), across clusters and levels
        this.vertexIds = new VertexTable();
        this.vertexCount = 0;
        // for the incremental normals: per cluster its border vertices (object ids; kept after an
        // unload), per border vertex the loaded clusters having it on their border, and which
        // clusters were drawn when the normals were last brought up to date (null: never)
        this.border = new Array(nc).fill(null);
        this.clustersAt = new Map();
        this.normalsCut = null;
        this.positionsMm = new Float64Array(3 * 4096);
        // local -> patient mm (linear part): the matrices below the patient node (the shared
        // storage node's, the object's own)
        this.toMm = new Matrix4();
        for (let o = object; o !== null && o.name !== kPatientNode; o = o.parent) {
            o.updateMatrix();
            this.toMm.premultiply(o.matrix);
        }
        this.toMm.setPosition(0, 0, 0);
        // the draw mesh (built by syncDraw): one geometry with the drawn clusters' points and
        // triangles; drawChunks: the chunks in it, { chunk, first point, weight written }
        this.drawMaterial = morphMaterial(this.material);
        this.drawMesh = null;
        this.drawChunks = [];
        this.drawStale = true; // the drawn clusters changed: rebuild the geometry
        this.normalsStale = false; // only the normals of drawn clusters changed
        this.weightsStale = false; // only the weights of drawn chunks changed
        const roots = [];
        for (let c = 0; c < nc; ++c) if (table.clusters[c].consumer === undefined) roots.push(c);
        const rootTriangles = this.splitBase(base, roots);
        this.dag = buildDag(table, {
            refineOn: plugin.options.refineOn,
            clusterTriangles: table.clusters.map((_, c) => rootTriangles.get(c) ?? 0),
        });
        this.groupState = new Uint8Array(this.dag.ng); // 0 not loaded, 1 requested, 2 loaded, 3 failed
        this.groupUsed = new Float64Array(this.dag.ng); // last time a group was drawn refined (ms)
        this.chunkTriangles = 0; // triangles of the loaded chunks
        this.refined = new Uint8Array(this.dag.ng);
        this.weight = new Float64Array(this.dag.ng); // the weight applied last to a group's consumed clusters
        this.refinedAt = new Float64Array(this.dag.ng).fill(-Infinity);
        this.coarsenAt = new Float64Array(this.dag.ng).fill(-Infinity);
        this.coarsenFrom = new Float64Array(this.dag.ng);
        this.shown = new Uint8Array(nc); // the clusters drawn (the cut, and clusters blending out)
        this.drawn = roots;
        this.drawnKey = roots.join(',');
        this.stats = { triangles: this.dag.baseTriangles, maxError: 0, maxErrorPx: 0 };
        this.opacity = 1;
        this.colorByLevel = false;
        for (const c of roots) this.shown[c] = 1;
        this.updateNormals(roots);
        this.syncDraw();
    }

    /// Splits the base mesh (GLTFLoader's, one primitive) by root cluster (its _CLUSTER values:
    /// root k in increasing cluster id) into the base chunk; hides GLTFLoader's mesh. Returns the
    /// triangles per root cluster.
    splitBase(base, roots) {
        const geometry = base.geometry;
        const clusterAttribute = geometry.getAttribute(kThreeClusterAttribute);
        const position = geometry.getAttribute('position');
        if (clusterAttribute === undefined && roots.length !== 1) {
            throw new Error(`${this.name}: the base mesh has no _CLUSTER but ${roots.length} root clusters`);
        }
        // without _CLUSTER (one root) every base triangle is root 0
        const clusterValues = clusterAttribute ? scalarValues(clusterAttribute) : new Uint32Array(position.count);
        const positions = Float32Array.from({ length: 3 * position.count }, (_, i) =>
            position.getComponent(Math.floor(i / 3), i % 3),
        );
        const index = geometry.index
            ? Uint32Array.from(geometry.index.array)
            : Uint32Array.from({ length: position.count }, (_, i) => i);
        const { order, start } = splitByCluster(index, clusterValues, roots.length, `${this.name} base`);
        const rootTriangles = new Map();
        const chunk = this.makeChunk(-1, positions, positions, order);
        roots.forEach((c, k) => {
            rootTriangles.set(c, (start[k + 1] - start[k]) / 3);
            this.adopt(c, chunk, start[k], start[k + 1]);
        });
        // GLTFLoader's mesh stays in the scene graph (it may be the node itself) but draws nothing
        base.material = new MeshBasicMaterial({ visible: false });
        // root clusters that were never simplified have no sphere in the table: take their bounds
        this.object.updateWorldMatrix(true, false);
        const toScene = this.sceneMatrix();
        roots.forEach((c) => {
            if (this.table.clusters[c].sphere !== null) return;
            const box = this.partBox(c).applyMatrix4(toScene);
            const sphere = box.getBoundingSphere(new Sphere());
            this.table.clusters[c].sphere = [sphere.center.x, sphere.center.y, sphere.center.z, sphere.radius];
        });
        return rootTriangles;
    }

    /// The bounding box of cluster c's points, morph targets included (object local frame).
    partBox(c) {
        const { chunk, range } = this.parts[c];
        const box = new Box3();
        const v = new Vector3();
        for (let i = range[0]; i < range[1]; ++i) {
            const k = 3 * chunk.index[i];
            box.expandByPoint(v.fromArray(chunk.positions, k));
            box.expandByPoint(v.fromArray(chunk.coarse, k));
        }
        return box;
    }

    /// The matrix from the object's local frame to the glTF scene frame (the spheres' frame).
    sceneMatrix() {
        const root = this.plugin.sceneRoot;
        const toScene = new Matrix4();
        if (root) toScene.copy(root.matrixWorld).invert();
        return toScene.multiply(this.object.matrixWorld);
    }

    /// A decoded chunk (or the base): its points, their morph targets, their shading normals
    /// (filled over the drawn cut), the index ordered by cluster, and per point its object vertex
    /// id.
    makeChunk(group, positions, coarse, order) {
        return {
            group,
            positions,
            coarse,
            normals: new Float32Array(positions.length),
            index: order,
            vertexOf: this.vertexIdsOf(positions),
            count: positions.length / 3,
        };
    }

    /// Object vertex ids of a chunk's points (new positions get new ids, with their patient-mm
    /// coordinates for the normals).
    vertexIdsOf(positions) {
        const out = new Uint32Array(positions.length / 3);
        const bits = new Uint32Array(positions.buffer, positions.byteOffset, positions.length);
        const e = this.toMm.elements;
        for (let p = 0; p < out.length; ++p) {
            const id = this.vertexIds.idOf(bits[3 * p], bits[3 * p + 1], bits[3 * p + 2], this.vertexCount);
            if (id === this.vertexCount) {
                ++this.vertexCount;
                if (3 * this.vertexCount > this.positionsMm.length) {
                    const grown = new Float64Array(2 * this.positionsMm.length);
                    grown.set(this.positionsMm);
                    this.positionsMm = grown;
                }
                const x = positions[3 * p];
                const y = positions[3 * p + 1];
                const z = positions[3 * p + 2];
                this.positionsMm[3 * id] = e[0] * x + e[4] * y + e[8] * z;
                this.positionsMm[3 * id + 1] = e[1] * x + e[5] * y + e[9] * z;
                this.positionsMm[3 * id + 2] = e[2] * x + e[6] * y + e[10] * z;
            }
            out[p] = id;
        }
        return out;
    }

    /// Makes triangles [a, b) of chunk's index cluster c.
    adopt(c, chunk, a, b) {
        this.parts[c] = { chunk, range: [a, b] };
        this.setBorder(c);
    }

    /// Records the border vertices of cluster c (the ends of edges used by one of its triangles
    /// only): two clusters of a drawn cut touch exactly at shared border vertices.
    setBorder(c) {
        const { chunk, range } = this.parts[c];
        const index = chunk.index;
        const vertexOf = chunk.vertexOf;
        const edges = new Map();
        const kShift = 2 ** 26; // object vertex ids below 2^26: the key is exact
        for (let i = range[0]; i < range[1]; i += 3) {
            for (let k = 0; k < 3; ++k) {
                const u = vertexOf[index[i + k]];
                const v = vertexOf[index[i + ((k + 1) % 3)]];
                const key = u < v ? u * kShift + v : v * kShift + u;
                edges.set(key, (edges.get(key) ?? 0) + 1);
            }
        }
        const vertices = new Set();
        for (const [key, n] of edges) {
            if (n !== 1) continue;
            vertices.add(Math.floor(key / kShift));
            vertices.add(key % kShift);
        }
        if (this.border[c] !== null) this.dropBorder(c);
        this.border[c] = Uint32Array.from(vertices);
        for (const v of this.border[c]) {
            const list = this.clustersAt.get(v);
            if (list === undefined) this.clustersAt.set(v, [c]);
            else list.push(c);
        }
    }

    /// Forgets cluster c in clustersAt (its border is kept: a cluster unloaded after the normals
    /// were computed still tells which neighbours its disappearance touches).
    dropBorder(c) {
        for (const v of this.border[c]) {
            const list = this.clustersAt.get(v);
            const i = list?.indexOf(c) ?? -1;
            if (i >= 0) list.splice(i, 1);
            if (list?.length === 0) this.clustersAt.delete(v);
        }
    }

    /// The chunk of group g arrived, decoded: { positions, cluster, slot, index } (typed arrays).
    attachChunk(g, decoded) {
        const group = this.dag.groups[g];
        const where = `${this.name} group ${g}`;
        const coarse = resolveSlots(decoded.positions, decoded.index, decoded.slot, where);
        const { order, start } = splitByCluster(decoded.index, decoded.cluster, group.consumed.length, where);
        const chunk = this.makeChunk(g, decoded.positions, coarse, order);
        group.consumed.forEach((c, k) => {
            const triangles = (start[k + 1] - start[k]) / 3;
            setClusterTriangles(this.dag, c, triangles);
            this.chunkTriangles += triangles;
            this.adopt(c, chunk, start[k], start[k + 1]);
        });
        // the chunk's own normals until the welded ones over the drawn cut are computed
        // (angle-weighted only: a cheap stand-in, replaced when the clusters are drawn)
        if (this.plugin.options.normals) this.computeNormals(group.consumed, null, null, 0);
        this.groupState[g] = 2;
    }

    /// Unloads the chunk of group g (its consumed clusters; none of them is drawn).
    evict(g) {
        for (const c of this.dag.groups[g].consumed) {
            if (this.parts[c] === null) continue;
            this.dropBorder(c);
            this.chunkTriangles -= this.dag.triangles[c];
            this.parts[c] = null;
            if (this.shown[c]) this.drawStale = true;
            this.shown[c] = 0;
        }
        this.groupState[g] = 0;
    }

    isLoaded(c) {
        return this.parts[c] !== null;
    }

    /// Are some of group g's consumed clusters drawn (g refined, or blending out)?
    isDrawnRefined(g) {
        return this.dag.groups[g].consumed.some((c) => this.shown[c] === 1);
    }

    /// The geomorph weight cluster c is drawn with (0 when not drawn).
    clusterWeight(c) {
        const g = this.dag.consumer[c];
        return this.shown[c] && g >= 0 ? this.weight[g] : 0;
    }

    /// Selects, requests and shows this object alone (see StrataProgressivePlugin.update).
    update(camera, viewportHeightPx, tauPx = 1, budget = Infinity, options = {}) {
        return this.plugin.update(camera, viewportHeightPx, tauPx, budget, { ...options, controllers: [this] });
    }

    /// Shows the cut (refined groups, drawn clusters, weights) at time now (ms). Groups the cut
    /// coarsens without the threshold having announced it stay drawn refined for blendMs while
    /// their consumed clusters morph onto the produced ones (when their parents are drawn refined:
    /// so the drawn set stays closed upward).
    apply(cut, now, morph) {
        const dag = this.dag;
        const blend = this.plugin.options.blendMs;
        const shown = Uint8Array.from(cut.refined);
        for (let g = dag.ng - 1; g >= 0; --g) {
            if (cut.refined[g] && !this.refined[g]) {
                // refined now: blend in over blendMs unless the threshold already starts at w ~ 1
                this.refinedAt[g] = cut.weight[g] > 0.95 || !morph ? -Infinity : now;
                this.coarsenAt[g] = -Infinity;
            } else if (!cut.refined[g] && this.refined[g]) {
                // coarsened now: blend out unless the consumed clusters already reached w ~ 1
                const w = this.weight[g];
                this.coarsenAt[g] = w > 0.95 || !morph || blend <= 0 ? -Infinity : now;
                this.coarsenFrom[g] = w;
            }
            if (
                !shown[g] &&
                now - this.coarsenAt[g] < blend &&
                dag.groups[g].consumed.every((c) => this.isLoaded(c)) &&
                dag.parents[g].every((p) => shown[p])
            ) {
                shown[g] = 1;
            } else if (!shown[g]) {
                this.coarsenAt[g] = -Infinity;
            }
        }
        this.refined = cut.refined;
        this.priority = cut.priority;
        const drawn = shown.some((x, g) => x !== cut.refined[g]) ? drawnClusters(dag, shown) : cut.drawn;
        let changed = false;
        for (let g = 0; g < dag.ng; ++g) {
            let w = 0;
            if (shown[g]) {
                this.groupUsed[g] = now;
                if (morph) {
                    if (!cut.refined[g]) {
                        const t = Math.min(1, (now - this.coarsenAt[g]) / blend);
                        w = this.coarsenFrom[g] + (1 - this.coarsenFrom[g]) * t;
                    } else {
                        const t = blend > 0 ? 1 - (now - this.refinedAt[g]) / blend : 0;
                        w = Math.max(0, cut.weight[g], Math.min(1, t));
                    }
                }
            }
            this.weight[g] = w;
        }
        const key = drawn.join(',');
        if (key !== this.drawnKey) {
            // the welded normals are recomputed by the plugin within a time budget per update
            // (newly loaded clusters show their chunk's own normals until then)
            this.drawnKey = key;
            this.normalsDirtySince ??= now;
            this.shown.fill(0);
            for (const c of drawn) this.shown[c] = 1;
            this.drawStale = true;
            changed = true;
        }
        this.drawn = drawn;
        if (!this.drawStale) {
            for (const entry of this.drawChunks) {
                const g = entry.chunk.group;
                if (g >= 0 && this.weight[g] !== entry.weight) {
                    this.weightsStale = true;
                    changed = true;
                    break;
                }
            }
        }
        return changed;
    }

    /// Brings the object's draw mesh up to date: the geometry rebuilt when the drawn clusters or
    /// their normals changed (every drawn cluster's triangles, the points of their chunks), else
    /// only the geomorph weights rewritten when they changed. One draw call per object.
    syncDraw() {
        if (this.drawStale) {
            this.buildDraw();
        } else {
            if (this.normalsStale) this.writeNormals();
            if (this.weightsStale) this.writeWeights();
        }
        this.drawStale = false;
        this.normalsStale = false;
        this.weightsStale = false;
    }

    /// Copies the drawn chunks' normals into the draw geometry (their points are where buildDraw
    /// put them) and uploads them.
    writeNormals() {
        const attribute = this.drawMesh.geometry.getAttribute('normal');
        let end = 0;
        for (const { chunk, first } of this.drawChunks) {
            attribute.array.set(chunk.normals, 3 * first);
            end = first + chunk.count;
        }
        attribute.clearUpdateRanges();
        attribute.addUpdateRange(0, 3 * end);
        attribute.needsUpdate = true;
    }

    /// The draw geometry with room for `points` points and `indices` indices (kept while it is
    /// large enough: its buffers are updated in place; else a new one replaces it).
    drawGeometry(points, indices) {
        const old = this.drawMesh?.geometry;
        const keep = old && !this.newGeometry;
        if (keep && old.userData.points >= points && old.userData.indices >= indices) return old;
        this.newGeometry = false;
        const p = capacityFor(Math.max(points, keep ? old.userData.points : 0));
        const n = capacityFor(Math.max(indices, keep ? old.userData.indices : 0));
        const geometry = new BufferGeometry();
        const dynamic = (array, size) => new BufferAttribute(array, size).setUsage(DynamicDrawUsage);
        geometry.setAttribute('position', dynamic(new Float32Array(3 * p), 3));
        geometry.setAttribute(kThreeAttributes.coarsePosition, dynamic(new Float32Array(3 * p), 3));
        geometry.setAttribute('normal', dynamic(new Float32Array(3 * p), 3));
        geometry.setAttribute(kMorphWeight, dynamic(new Float32Array(p), 1));
        if (this.colorByLevel) geometry.setAttribute('color', dynamic(new Float32Array(3 * p), 3));
        geometry.setIndex(dynamic(new Uint32Array(n), 1));
        geometry.userData.points = p;
        geometry.userData.indices = n;
        if (this.drawMesh === null) {
            this.drawMesh = new Mesh(geometry, this.drawMaterial);
            this.drawMesh.name = `${this.name} (strata cut)`;
            this.drawMesh.userData.strataObject = this;
            this.object.add(this.drawMesh);
        } else {
            this.drawMesh.geometry = geometry;
            old.dispose();
        }
        return geometry;
    }

    /// Rebuilds the draw geometry from the drawn clusters (see syncDraw).
    buildDraw() {
        const byChunk = new Map(); // chunk -> drawn clusters in it
        let points = 0;
        let indices = 0;
        for (const c of this.drawn) {
            const part = this.parts[c];
            if (part === null) continue;
            let list = byChunk.get(part.chunk);
            if (list === undefined) {
                byChunk.set(part.chunk, (list = []));
                points += part.chunk.count;
            }
            list.push(c);
            indices += part.range[1] - part.range[0];
        }
        const geometry = this.drawGeometry(points, indices);
        const position = geometry.getAttribute('position');
        const coarse = geometry.getAttribute(kThreeAttributes.coarsePosition);
        const normal = geometry.getAttribute('normal');
        const color = this.colorByLevel ? geometry.getAttribute('color') : null;
        const index = geometry.index.array;
        this.drawChunks = [];
        let first = 0;
        let n = 0;
        for (const [chunk, clusters] of byChunk) {
            position.array.set(chunk.positions, 3 * first);
            coarse.array.set(chunk.coarse, 3 * first);
            normal.array.set(chunk.normals, 3 * first);
            for (const c of clusters) {
                const [a, b] = this.parts[c].range;
                for (let i = a; i < b; ++i) index[n++] = chunk.index[i] + first;
                if (color !== null) {
                    const rgb = this.levelColor(c);
                    for (let i = a; i < b; ++i) rgb.toArray(color.array, 3 * (chunk.index[i] + first));
                }
            }
            this.drawChunks.push({ chunk, first, weight: NaN });
            first += chunk.count;
        }
        this.writeWeights(false);
        for (const attribute of [position, coarse, normal, color, geometry.getAttribute(kMorphWeight)]) {
            if (attribute === null) continue;
            attribute.clearUpdateRanges();
            attribute.addUpdateRange(0, attribute.itemSize * first);
            attribute.needsUpdate = true;
        }
        geometry.index.clearUpdateRanges();
        geometry.index.addUpdateRange(0, n);
        geometry.index.needsUpdate = true;
        geometry.setDrawRange(0, n);
        // bounds of the points drawn and their morph targets (frustum culling, picking)
        const box = new Box3();
        const v = new Vector3();
        for (let i = 0; i < first; ++i) {
            box.expandByPoint(v.fromArray(position.array, 3 * i));
            box.expandByPoint(v.fromArray(coarse.array, 3 * i));
        }
        geometry.boundingBox = box;
        geometry.boundingSphere = box.isEmpty() ? new Sphere() : box.getBoundingSphere(new Sphere());
        this.drawMesh.visible = n > 0;
    }

    /// Writes the drawn chunks' geomorph weights (their consuming group's weight; 0 for the base).
    writeWeights(upload = true) {
        const attribute = this.drawMesh.geometry.getAttribute(kMorphWeight);
        let end = 0;
        for (const entry of this.drawChunks) {
            const w = entry.chunk.group >= 0 ? this.weight[entry.chunk.group] : 0;
            end = entry.first + entry.chunk.count;
            if (w === entry.weight) continue;
            attribute.array.fill(w, entry.first, end);
            entry.weight = w;
        }
        if (upload) {
            attribute.clearUpdateRanges();
            attribute.addUpdateRange(0, end);
            attribute.needsUpdate = true;
        }
    }

    /// Brings the shading normals up to date with the drawn clusters (strata-decode.js
    /// shadingNormals, in patient mm, welded by position across clusters and levels), written to
    /// every drawn cluster's points in the object's local frame. Incremental and exact: a
    /// vertex's normal depends on the triangles within 4 edges of it (3 rings of angle-weighted
    /// normals), so only the vertices within 3 edges of a cluster that appeared or disappeared
    /// are rewritten, computed over the drawn clusters within 7 edges of one (found by a
    /// breadth-first search that grows the context, cluster by cluster, where it reaches a
    /// border vertex of a drawn cluster outside it); the whole cut when the context grows beyond
    /// options.normalsFullShare of it.
    updateNormals(drawn) {
        const nc = this.parts.length;
        const now = new Uint8Array(nc);
        for (const c of drawn) if (this.parts[c] !== null) now[c] = 1;
        const previous = this.normalsCut;
        this.normalsCut = now;
        this.normalsDirtySince = null;
        const full = () => {
            this.computeNormals(drawn, null);
            ++this.plugin.stats.normalsFull;
        };
        if (previous === null) return full();
        // seeds: the vertices of the clusters that appeared, and the border vertices of those that
        // disappeared (the only ones of theirs that can still be drawn)
        const context = new Uint8Array(nc);
        let inContext = 0;
        const add = (n) => {
            if (now[n] && !context[n]) {
                context[n] = 1;
                ++inContext;
                return true;
            }
            return false;
        };
        const seeds = [];
        for (let c = 0; c < nc; ++c) {
            if (now[c] === previous[c]) continue;
            if (now[c]) {
                add(c);
                const { chunk, range } = this.parts[c];
                for (let i = range[0]; i < range[1]; ++i) seeds.push(chunk.vertexOf[chunk.index[i]]);
            } else {
                for (const v of this.border[c] ?? []) seeds.push(v);
            }
            for (const v of this.border[c] ?? []) for (const n of this.clustersAt.get(v) ?? []) add(n);
        }
        if (seeds.length === 0 && inContext === 0) return;
        const kReach = 7;
        const kWrite = 3;
        const depth = new Int8Array(this.vertexCount);
        for (;;) {
            if (inContext > this.plugin.options.normalsFullShare * drawn.length) return full();
            // the context's vertex adjacency (object vertex ids, compressed rows over a local numbering)
            const clusters = drawn.filter((c) => context[c]);
            const local = new Int32Array(this.vertexCount).fill(-1);
            const ids = [];
            const triangles = [];
            for (const c of clusters) {
                const { chunk, range } = this.parts[c];
                for (let i = range[0]; i < range[1]; ++i) {
                    const v = chunk.vertexOf[chunk.index[i]];
                    if (local[v] < 0) {
                        local[v] = ids.length;
                        ids.push(v);
                    }
                    triangles.push(local[v]);
                }
            }
            const start = new Uint32Array(ids.length + 1);
            for (const v of triangles) start[v + 1] += 2;
            for (let v = 0; v < ids.length; ++v) start[v + 1] += start[v];
            const fill = start.slice(0, ids.length);
            const adjacent = new Uint32Array(start[ids.length]);
            for (let t = 0; t < triangles.length; t += 3) {
                for (let k = 0; k < 3; ++k) {
                    const v = triangles[t + k];
                    adjacent[fill[v]++] = triangles[t + ((k + 1) % 3)];
                    adjacent[fill[v]++] = triangles[t + ((k + 2) % 3)];
                }
            }
            // breadth-first from the seeds, kReach edges deep
            depth.fill(-1);
            let frontier = [];
            for (const v of seeds) {
                if (local[v] >= 0 && depth[v] < 0) {
                    depth[v] = 0;
                    frontier.push(local[v]);
                }
            }
            let grown = false;
            for (let d = 0; frontier.length > 0; ++d) {
                const next = [];
                for (const u of frontier) {
                    for (const n of this.clustersAt.get(ids[u]) ?? []) if (add(n)) grown = true;
                    if (d === kReach) continue;
                    for (let k = start[u]; k < start[u + 1]; ++k) {
                        const w = adjacent[k];
                        if (depth[ids[w]] >= 0) continue;
                        depth[ids[w]] = d + 1;
                        next.push(w);
                    }
                }
                frontier = next;
            }
            if (grown) continue; // the search left the context: again with the clusters it reached
            const write = new Uint8Array(this.vertexCount);
            for (const v of ids) if (depth[v] >= 0 && depth[v] <= kWrite) write[v] = 1;
            this.computeNormals(clusters, null, write);
            ++this.plugin.stats.normalsIncremental;
            return;
        }
    }

    /// Shading normals over the triangles of `clusters`, welded by position, written to the points
    /// of those clusters c with write[c] (write null: all of them) whose object vertex v has
    /// writeVertex[v] (writeVertex null: all of them); rings as shadingNormals.
    computeNormals(clusters, write, writeVertex = null, rings = 3) {
        const drawn = clusters;
        let count = 0;
        for (const c of drawn) {
            const part = this.parts[c];
            if (part !== null) count += part.range[1] - part.range[0];
        }
        // the vertices used, renumbered 0 .. used - 1
        const local = new Int32Array(this.vertexCount).fill(-1);
        const positions = [];
        const triangles = new Uint32Array(count);
        let n = 0;
        for (const c of drawn) {
            const part = this.parts[c];
            if (part === null) continue;
            const { index, vertexOf } = part.chunk;
            for (let i = part.range[0]; i < part.range[1]; ++i) {
                const v = vertexOf[index[i]];
                if (local[v] < 0) {
                    local[v] = positions.length / 3;
                    positions.push(this.positionsMm[3 * v], this.positionsMm[3 * v + 1], this.positionsMm[3 * v + 2]);
                }
                triangles[n++] = local[v];
            }
        }
        const normalsMm = shadingNormals(Float64Array.from(positions), triangles, positions.length / 3, rings);
        // mm -> local: n_local ~ M^T n_mm (three.js then applies the normal matrix, inverse transpose of M)
        const e = this.toMm.elements;
        for (const c of drawn) {
            const part = this.parts[c];
            if (part === null || (write !== null && !write[c])) continue;
            const { index, vertexOf, normals: out } = part.chunk;
            if (this.shown[c]) this.normalsStale = true; // the draw geometry holds a copy
            for (let i = part.range[0]; i < part.range[1]; ++i) {
                const p = index[i];
                if (writeVertex !== null && !writeVertex[vertexOf[p]]) continue;
                const v = local[vertexOf[p]];
                const x = normalsMm[3 * v];
                const y = normalsMm[3 * v + 1];
                const z = normalsMm[3 * v + 2];
                const lx = e[0] * x + e[1] * y + e[2] * z;
                const ly = e[4] * x + e[5] * y + e[6] * z;
                const lz = e[8] * x + e[9] * y + e[10] * z;
                const l = Math.hypot(lx, ly, lz) || 1;
                out[3 * p] = lx / l;
                out[3 * p + 1] = ly / l;
                out[3 * p + 2] = lz / l;
            }
        }
    }

    /// True while some drawn cluster is morphing by time (an app rendering on demand keeps going).
    blending(now) {
        const blend = this.plugin.options.blendMs;
        for (let g = 0; g < this.dag.ng; ++g) {
            if (now - this.refinedAt[g] < blend || now - this.coarsenAt[g] < blend) return true;
        }
        return false;
    }

    setOpacity(opacity) {
        this.opacity = opacity;
        this.plugin.changed = true;
        const material = this.drawMaterial;
        material.opacity = opacity;
        material.transparent = opacity < 1;
        material.depthWrite = opacity >= 1;
        material.needsUpdate = true;
    }

    /// Debug colouring: each cluster by its level (0 = full resolution: blue ... coarse: red), as
    /// a colour per point of the draw geometry.
    setColorByLevel(on) {
        if (this.colorByLevel === on) return;
        this.colorByLevel = on;
        this.plugin.changed = true;
        const material = this.drawMaterial;
        material.vertexColors = on;
        if (material.color) material.color.copy(on ? new Color(1, 1, 1) : material.userData.strataBaseColor);
        material.needsUpdate = true;
        // a new geometry, with or without the colour attribute
        this.newGeometry = true;
        if (this.drawMesh !== null) this.buildDraw();
    }

    levelColor(c) {
        this.maxLevel ??= this.table.clusters.reduce((m, k) => Math.max(m, k.level), 1);
        const level = this.table.clusters[c].level;
        return new Color().setHSL(0.66 * (1 - level / this.maxLevel), 0.8, 0.5 + 0.1 * (((c * 7) % 3) - 1));
    }
}

// ------------------------------------------------------------------------------------------------
// the plugin

export class StrataProgressivePlugin {
    constructor(parser, options = {}) {
        this.name = kExtension;
        this.parser = parser;
        this.options = { ...kDefaults, ...options };
        // distinct bytes per file: the ranges read before GLTFLoader ran, then every fetch
        this.coverage = new ByteCoverage();
        for (const [url, start, end] of this.options.initialRanges) this.coverage.add(url, start, end);
        this.stats = {
            bytesLoaded: this.options.initialRanges.length > 0 ? this.coverage.size : this.options.initialBytes,
            bytesFetched: this.options.initialBytes,
            bytesTotal: this.options.totalBytes,
            requests: 0,
            chunksLoaded: 0,
            chunksTotal: 0,
            chunkBytesLoaded: 0,
            failures: 0,
            cancelled: 0,
            evicted: 0,
            decodeWaitMs: 0, // summed time chunks waited for the Draco workers
            attachMs: 0, // main-thread time spent resolving slots and splitting chunks by cluster
            normalsFull: 0, // normals computed over a whole drawn cut
            normalsIncremental: 0, // ... over the part of it that changed
            normalsTimeMs: 0, // main-thread time spent on normals
            drawBuildMs: 0, // main-thread time spent filling the objects' draw geometries
        };
        this.fetcher = new RangeFetcher(
            this.options.fetch ?? globalThis.fetch.bind(globalThis),
            this.stats,
            this.coverage,
        );
        this.controllers = [];
        this.controllerOf = new Map(); // node index -> controller
        this.viewBytes = new Map(); // bufferView index -> ArrayBuffer fetched ahead (ranges)
        // bytes of each buffer (key: buffer index) requested so far (the prefix, the base, chunk
        // requests), in buffer coordinates: a coalesced request never spans bytes requested before
        this.requested = new ByteCoverage();
        this.baseRanges = []; // the base's fetched ranges { buffer, start, end, bytes }, stashed after setup
        this.stashed = new Map(); // "node/group" -> ArrayBuffer of a chunk that came in a fetched range
        this.queue = []; // wanted chunks of the last update, best first: { controller, group, priority }
        this.batches = new Set(); // fetches in flight: { items, abort, fetched }
        this.requests = 0; // HTTP requests in flight
        this.decoding = 0; // chunks requested and not yet attached
        this.arrived = []; // decoded chunks waiting to be attached by an update: { controller, group, decoded }
        this.changed = false; // something to draw differently since the last update
        this.sceneRoot = null;
        this.setupState = 'waiting'; // 'running', 'done' (afterRoot, settingUp)
        this.updates = 0;
        this.ready = null; // a Promise resolved when the setup is done (controllers made)
        this.last = null; // the last update's summary
        this.errors = [];
    }

    // --- GLTFLoader hooks ------------------------------------------------------------------------

    beforeRoot() {
        const json = this.parser.json;
        if (this.stats.bytesTotal === 0) {
            this.stats.bytesTotal = (json.buffers ?? []).reduce((s, b) => s + (b.byteLength ?? 0), 0);
        }
        if (this.options.source?.kind !== 'glb-range') return null;
        // GLB streaming: fetch every bufferView of buffer 0 the first frame needs (the base
        // meshes and the DAG tables), in few coalesced ranges.
        const views = new Set();
        for (const node of json.nodes ?? []) {
            if (node.mesh !== undefined) meshBufferViews(json, node.mesh).forEach((v) => views.add(v));
        }
        const dag = json.extensions?.[kExtension]?.dag; // every object's table
        if (Number.isInteger(dag) && json.bufferViews?.[dag] !== undefined) views.add(dag);
        const ranges = coalesceRanges(
            json,
            [...views].filter((v) => json.bufferViews[v].buffer === 0),
            4096,
        );
        mark('strata:base-request');
        const { prefix, binOffset } = this.options.source;
        if (prefix) this.requested.add(0, 0, Math.max(0, prefix.byteLength - binOffset));
        for (const range of ranges) this.requested.add(0, range.start, range.end);
        return Promise.all(
            ranges.map(async (range) => {
                const bytes = await this.glbRange(range.start, range.end);
                // chunks in the gaps between the base's views are kept once the DAGs are read
                this.baseRanges.push({ buffer: 0, start: range.start, end: range.end, bytes, items: [] });
                for (const v of range.views) {
                    const def = json.bufferViews[v];
                    const start = (def.byteOffset ?? 0) - range.start;
                    this.viewBytes.set(v, bytes.slice(start, start + def.byteLength));
                }
            }),
        );
    }

    /// bytes [start, end) of the GLB's BIN data (glb-range source), using the prefix already read.
    glbRange(start, end, signal = undefined) {
        const { url, binOffset, prefix } = this.options.source;
        const a = binOffset + start;
        const b = binOffset + end;
        if (prefix && b <= prefix.byteLength) return Promise.resolve(prefix.slice(a, b));
        if (prefix && a < prefix.byteLength) {
            // the first part is in the prefix: fetch the rest only
            return this.fetcher.range(url, prefix.byteLength, b, signal).then((rest) => {
                const joined = new Uint8Array(b - a);
                joined.set(new Uint8Array(prefix, a, prefix.byteLength - a), 0);
                joined.set(new Uint8Array(rest), prefix.byteLength - a);
                return joined.buffer;
            });
        }
        return this.fetcher.range(url, a, b, signal);
    }

    loadBufferView(index) {
        const json = this.parser.json;
        const def = json.bufferViews[index];
        if (this.viewBytes.has(index)) {
            const bytes = this.viewBytes.get(index);
            this.viewBytes.delete(index);
            return Promise.resolve(bytes);
        }
        const start = def.byteOffset ?? 0;
        const end = start + def.byteLength;
        if (this.options.source?.kind === 'glb-range' && def.buffer === 0) {
            return this.glbRange(start, end);
        }
        const uri = json.buffers[def.buffer]?.uri;
        if (uri === undefined || uri.startsWith('data:')) return null; // in memory: GLTFLoader's way
        const url = LoaderUtils.resolveURL(uri, this.parser.options.path);
        return this.fetcher.range(url, start, end);
    }

    /// GLTFLoader has built the scene (the base meshes, drawable as they are: Draco-decoded with
    /// their shading normals). With options.deferSetup the plugin's own setup (DAG tables, the
    /// base split by cluster, welded normals, one draw mesh per object) waits for the second update, so that the
    /// first frame shows the base without waiting for it; strata.ready resolves after it.
    async afterRoot(result) {
        mark('strata:after-root');
        this.sceneRoot = result.scene;
        result.userData.strata = this;
        if (this.options.deferSetup) {
            this.setupState = 'waiting';
            this.setupResult = result;
            this.ready = new Promise((resolve) => (this.resolveReady = resolve));
        } else {
            await this.setup(result);
            this.setupState = 'done';
            this.ready = Promise.resolve();
        }
        return null;
    }

    /// Starts the deferred setup in a task after the first update (whose frame draws the base; in
    /// software WebGL the next update comes 0.1-0.6 s later, which the setup used to wait for), and
    /// once it is done selects and requests at once with the last update's arguments, rather than at
    /// the next frame; true while the setup is not done.
    settingUp(args) {
        if (this.setupState === 'done') return false;
        this.lastArgs = args;
        if (this.setupState === 'waiting') {
            this.setupState = 'running';
            // the DAG tables and the requests of this view's target cut at once (after this
            // update's frame is drawn, in its task), the heavy setup in tasks of its own (about
            // setupSliceMs each): the network overlaps the setup
            const early = this.readTables(this.setupResult).then((tables) => {
                try {
                    this.requestTargetCut(tables);
                } catch (error) {
                    this.errors.push(`${error.message ?? error}`);
                }
                return tables;
            });
            setTimeout(() =>
                this.setup(this.setupResult, early).finally(async () => {
                    this.setupState = 'done';
                    this.setupResult = null;
                    this.resolveReady();
                    await nextTask(); // the update below in a task of its own as well
                    if (this.lastArgs && this.controllers.length > 0) {
                        try {
                            this.update(...this.lastArgs);
                        } catch (error) {
                            this.errors.push(`${error.message ?? error}`);
                        }
                    }
                    this.changed = true; // the next update draws the objects' meshes
                    this.options.onChange?.(null, null);
                }),
            );
        }
        ++this.updates;
        return true;
    }

    /// One controller per object node with the extension (an object whose data is invalid keeps
    /// its base mesh: schema/README.md, Validation).
    async setup(result, early = null) {
        const setupStart = performance.now();
        const json = this.parser.json;
        const tables = await (early ?? this.readTables(result));
        let sliceStart = performance.now();
        for (const { nodeIndex, node, object, table } of tables) {
            if (performance.now() - sliceStart > this.options.setupSliceMs) {
                await nextTask();
                sliceStart = performance.now();
            }
            try {
                let base = null;
                object.traverse((o) => {
                    const a = this.parser.associations.get(o);
                    if (o.isMesh && a?.meshes === node.mesh && base === null) base = o;
                });
                if (base === null) throw new Error('no base mesh');
                const controller = new StrataObjectController(this, nodeIndex, object, table, base, json);
                object.userData.strata = controller;
                this.controllers.push(controller);
                this.controllerOf.set(nodeIndex, controller);
                this.stats.chunksTotal += controller.dag.ng;
            } catch (error) {
                // fall back to the base mesh (schema/README.md, Validation)
                this.errors.push(`node ${nodeIndex}: ${error.message ?? error}`);
                console.warn(`${kExtension}: node ${nodeIndex} uses its base mesh only: ${error.message ?? error}`);
            }
        }
        for (const range of this.baseRanges) this.stash(range, range.bytes);
        this.baseRanges = [];
        this.controllersMade = true; // ranges arriving from now on are stashed at once
        this.stats.setupMs = performance.now() - setupStart;
        mark('strata:setup-done');
    }

    /// Each object node's DAG table (light work): [{ nodeIndex, node, object, table }]; an object
    /// whose extension or table is invalid keeps its base mesh (schema/README.md, Validation).
    async readTables(result) {
        const json = this.parser.json;
        result.scene.updateMatrixWorld(true);
        const objects = new Map();
        result.scene.traverse((o) => {
            const node = this.parser.associations.get(o)?.nodes;
            if (node !== undefined && !objects.has(node)) objects.set(node, o);
        });
        const tables = [];
        for (const { nodeIndex, node, ext } of progressiveNodes(json, kExtension)) {
            const object = objects.get(nodeIndex);
            try {
                if (object === undefined) throw new Error('not in the scene');
                const info = readExtension(ext, json, `node ${nodeIndex} (${node.name})/extensions/${kExtension}`);
                const bytes = new Uint8Array(await this.parser.getDependency('bufferView', info.dag));
                const table = parseDagTable(bytes, info, chunksByteLength(info, json), `node ${nodeIndex} DAG table`);
                tables.push({ nodeIndex, node, object, table });
            } catch (error) {
                // fall back to the base mesh (schema/README.md, Validation)
                this.errors.push(`node ${nodeIndex}: ${error.message ?? error}`);
                console.warn(`${kExtension}: node ${nodeIndex} uses its base mesh only: ${error.message ?? error}`);
            }
        }
        return tables;
    }

    /// During a deferred setup, before the objects' controllers are made: selects the target cut
    /// of the first update's view from the DAG tables alone (the base loaded, prefetch of every
    /// level below it) and requests its chunks' bytes in coalesced ranges (at most `concurrency`),
    /// so that they travel while the setup runs. They arrive as requests in flight without items:
    /// the pump waits for the chunks inside them, then takes them from the stash.
    requestTargetCut(tables) {
        const args = this.lastArgs;
        const chunksView = this.parser.json.extensions?.[kExtension]?.chunks;
        if (!args || !this.options.prefetch || chunksView === undefined || tables.length === 0) return;
        const def = this.parser.json.bufferViews[chunksView];
        if (def === undefined || !this.isRanged(def.buffer)) return;
        const [camera, viewportHeightPx, tauPx, , options = {}] = args;
        let result;
        const shown = tables.filter(({ object }) => object.visible && isShown(object));
        try {
            const dags = shown.map(({ table }) =>
                buildDag(
                    {
                        ...table,
                        // spheres of never simplified roots come with the base split: unused here
                        clusters: table.clusters.map((c) => (c.sphere === null ? { ...c, sphere: [0, 0, 0, 0] } : c)),
                    },
                    { refineOn: this.options.refineOn },
                ),
            );
            result = selectCut(dags, this.viewOf(camera, viewportHeightPx), {
                tauPx,
                roi: options.roi ?? null,
                cull: options.cull ?? this.options.cull,
                prefetch: true,
                isLoaded: (di, c) => dags[di].consumer[c] < 0,
            });
        } catch {
            return; // the requests come with the first update after the setup
        }
        const base = def.byteOffset ?? 0;
        const ranges = [];
        const seen = new Set();
        for (const w of result.wanted) {
            const { table } = shown[w.dag];
            const g = table.clusters[w.cluster].consumer;
            const key = `${w.dag}/${g}`;
            if (g === undefined || seen.has(key)) continue;
            seen.add(key);
            const start = base + table.groups[g].chunkOffset;
            const end = start + table.groups[g].chunkLength;
            if (this.requested.overlap(def.buffer, start, end) < end - start) ranges.push([start, end]);
        }
        ranges.sort((a, b) => a[0] - b[0]);
        const merged = [];
        for (const [start, end] of ranges) {
            const last = merged[merged.length - 1];
            if (
                last !== undefined &&
                start - last[1] <= this.options.maxRangeGap &&
                Math.max(end, last[1]) - last[0] <= this.options.maxRangeBytes &&
                this.requested.overlap(def.buffer, last[1], start) === 0
            ) {
                last[1] = Math.max(last[1], end);
            } else {
                merged.push([start, end]);
            }
        }
        mark('strata:target-cut-request');
        for (const [start, end] of merged.slice(0, this.options.concurrency)) {
            const entry = { items: [], controller: null, fetched: false, ranged: true, buffer: def.buffer, start, end };
            this.batches.add(entry);
            this.requested.add(def.buffer, start, end);
            ++this.requests;
            const bytes =
                this.options.source?.kind === 'glb-range' && def.buffer === 0
                    ? this.glbRange(start, end)
                    : this.fetcher.range(
                          LoaderUtils.resolveURL(this.parser.json.buffers[def.buffer].uri, this.parser.options.path),
                          start,
                          end,
                      );
            bytes
                .then(
                    (data) => {
                        if (this.controllersMade) {
                            this.stash(entry, data);
                        } else {
                            this.baseRanges.push({ ...entry, bytes: data });
                        }
                    },
                    () => {}, // its chunks are requested again as they are wanted
                )
                .finally(() => {
                    entry.fetched = true;
                    this.batches.delete(entry);
                    --this.requests;
                    if (this.setupState === 'done') this.pump();
                });
        }
    }

    // --- selection -------------------------------------------------------------------------------

    /// The view of a three.js camera in the glTF scene frame (the spheres' frame): camera position,
    /// vertical field of view, viewport height, frustum planes. A transform on the glTF scene root
    /// is taken into account (uniform scale assumed).
    viewOf(camera, viewportHeightPx) {
        camera.updateMatrixWorld();
        const toScene = new Matrix4();
        if (this.sceneRoot) {
            this.sceneRoot.updateMatrixWorld();
            toScene.copy(this.sceneRoot.matrixWorld).invert();
        }
        const scale = toScene.getMaxScaleOnAxis();
        const position = new Vector3().setFromMatrixPosition(camera.matrixWorld).applyMatrix4(toScene);
        const frustum = new Frustum().setFromProjectionMatrix(
            new Matrix4().multiplyMatrices(camera.projectionMatrix, camera.matrixWorldInverse),
        );
        const planes = frustum.planes.map((p) => {
            const q = p.clone().applyMatrix4(toScene);
            return [q.normal.x, q.normal.y, q.normal.z, q.constant];
        });
        if (camera.isOrthographicCamera) {
            return {
                orthographic: true,
                viewHeight: ((camera.top - camera.bottom) / camera.zoom) * scale,
                heightPx: viewportHeightPx,
                position: position.toArray(),
                frustum: planes,
            };
        }
        const fovy = 2 * Math.atan(Math.tan((camera.fov * Math.PI) / 360) / camera.zoom);
        return { position: position.toArray(), fovy, heightPx: viewportHeightPx, frustum: planes };
    }

    /// Selects the cut of every visible object together (one triangle budget for all), shows it,
    /// requests missing chunks, cancels requests no longer wanted and unloads chunks beyond the
    /// memory budget. options: { roi: { center: [x, y, z] scene frame, radius, factor } | null,
    /// morph, cull, controllers (default: all) }. Returns a summary (also in this.last):
    /// { triangles, maxErrorPx, maxError (m), budgetLimited, wanted, roiTriangles, changed (the
    /// picture differs from the last update's: an app rendering on demand renders) }.
    update(camera, viewportHeightPx, tauPx = 1, budget = Infinity, options = {}) {
        if (this.settingUp([camera, viewportHeightPx, tauPx, budget, options])) {
            this.last = {
                triangles: 0,
                maxError: 0,
                maxErrorPx: 0,
                budgetLimited: false,
                wanted: 0,
                roiTriangles: 0,
                refinedGroups: 0,
                blending: false,
                changed: false,
            };
            return this.last;
        }
        this.attachArrived();
        // nothing to select again while the view, the settings, the shown objects and the loaded
        // chunks are those of the last update and nothing blends (a settled view costs ~nothing)
        const key = options.controllers
            ? null
            : [
                  camera.matrixWorld.elements.join(),
                  camera.projectionMatrix.elements.join(),
                  this.sceneRoot?.matrixWorld.elements.join(),
                  viewportHeightPx,
                  tauPx,
                  budget,
                  JSON.stringify(options.roi ?? null),
                  options.morph,
                  options.cull,
                  this.controllers.map((c) => (isShown(c.object) ? 1 : 0)).join(''),
              ].join('|');
        if (
            key !== null &&
            key === this.lastKey &&
            !this.changed &&
            this.last !== null &&
            !this.last.blending &&
            !this.controllers.some((c) => c.normalsDirtySince != null)
        ) {
            this.last = { ...this.last, changed: false };
            return this.last;
        }
        this.lastKey = key;
        const now = performance.now();
        const previousUpdate = this.lastUpdateAt;
        this.lastUpdateAt = now;
        const controllers = (options.controllers ?? this.controllers).filter(
            (c) => c.object.visible && isShown(c.object),
        );
        const view = this.viewOf(camera, viewportHeightPx);
        const result = selectCut(
            controllers.map((c) => c.dag),
            view,
            {
                tauPx,
                budget,
                roi: options.roi ?? null,
                cull: options.cull ?? this.options.cull,
                morphK: this.options.morphK,
                prefetch: this.options.prefetch,
                isLoaded: (di, c) => controllers[di].isLoaded(c),
            },
        );
        const morph = options.morph ?? this.options.morph;
        let maxError = 0;
        let maxErrorPx = 0;
        let roiTriangles = 0;
        let changed = this.changed;
        this.changed = false;
        controllers.forEach((controller, di) => {
            if (controller.apply(result.cuts[di], now, morph)) changed = true;
            const stats = cutStats(controller.dag, result.cuts[di].drawn, view);
            controller.stats = stats;
            maxError = Math.max(maxError, stats.maxError);
            maxErrorPx = Math.max(maxErrorPx, stats.maxErrorPx);
            if (options.roi) {
                for (const c of result.cuts[di].drawn) {
                    if (sphereMeetsRoi(controller.dag.clusterSphere, 4 * c, options.roi)) {
                        roiTriangles += controller.dag.triangles[c];
                    }
                }
            }
        });
        // welded normals of the objects whose drawn cut changed, oldest first, within normalsMs
        // (at least one object per update), once an object has no chunk on its way: an object
        // refines level after level as its chunks arrive, and its normals were computed again
        // after each (FreeSurfer: 502 computations over whole objects for 188 objects, 5.9 s)
        if (this.options.normals) {
            const loading = new Set(this.queue.map((w) => w.controller));
            for (const c of controllers) if (c.groupState.includes(1)) loading.add(c);
            const dirty = controllers.filter((c) => c.normalsDirtySince != null && !loading.has(c));
            dirty.sort((a, b) => a.normalsDirtySince - b.normalsDirtySince);
            const t0 = performance.now();
            const sinceLast = previousUpdate === undefined ? 0 : t0 - previousUpdate;
            const deadline = t0 + Math.min(100, Math.max(this.options.normalsMs, 0.4 * sinceLast));
            for (const [i, controller] of dirty.entries()) {
                if (i > 0 && performance.now() > deadline) break;
                controller.updateNormals(controller.drawn);
                changed = true;
            }
            this.stats.normalsTimeMs += performance.now() - t0;
        }
        // each object's cut as one mesh (rebuilt where the cut or its normals changed)
        const d0 = performance.now();
        for (const controller of controllers) controller.syncDraw();
        this.stats.drawBuildMs += performance.now() - d0;
        // wanted groups (a cluster is wanted when its consumer's chunk is missing), best first
        const seen = new Set();
        this.queue = [];
        for (const w of result.wanted) {
            const controller = controllers[w.dag];
            const group = controller.dag.consumer[w.cluster];
            const key = `${controller.nodeIndex}/${group}`;
            if (seen.has(key)) continue;
            seen.add(key);
            if (controller.groupState[group] === 0) this.queue.push({ controller, group, priority: w.priority });
        }
        this.cancelObsolete(seen);
        this.pump();
        this.evictBeyondBudget();
        this.last = {
            triangles: result.triangles,
            maxError,
            maxErrorPx,
            budgetLimited: result.budgetLimited,
            wanted: this.queue.length,
            roiTriangles,
            refinedGroups: result.refinedCount,
            blending: controllers.some((c) => c.blending(now)),
            changed,
        };
        return this.last;
    }

    /// Nothing loading, nothing wanted, no time blend running.
    get idle() {
        return (
            this.setupState === 'done' &&
            this.decoding === 0 &&
            this.queue.length === 0 &&
            !this.last?.blending &&
            !this.controllers.some((c) => c.normalsDirtySince != null)
        );
    }

    // --- loading ---------------------------------------------------------------------------------

    /// Where the chunk of group g of a controller lies: { buffer, start, end } in its buffer.
    chunkRange(controller, g) {
        const def = this.parser.json.bufferViews[controller.chunksView];
        const group = controller.dag.groups[g];
        const start = (def.byteOffset ?? 0) + group.chunkOffset;
        return { buffer: def.buffer, start, end: start + group.chunkLength };
    }

    /// Is buffer b fetched by ranges (a separate file, or a streamed GLB)?
    isRanged(b) {
        if (this.options.source?.kind === 'glb-range' && b === 0) return true;
        const uri = this.parser.json.buffers[b]?.uri;
        return uri !== undefined && !uri.startsWith('data:');
    }

    /// Starts loading the best wanted chunks: at most `concurrency` HTTP requests in flight and
    /// at most `maxDecodes` chunks fetched but not yet decoded and attached. Wanted chunks of one
    /// buffer close to the best one (within maxRangeGap) come in the same request.
    pump() {
        const deferred = []; // chunks inside a request in flight: stashed when it arrives
        while (this.queue.length > 0 && this.decoding < this.options.maxDecodes) {
            const first = this.queue[0];
            if (first.controller.groupState[first.group] !== 0) {
                this.queue.shift();
                continue;
            }
            const range = this.chunkRange(first.controller, first.group);
            const ranged =
                this.isRanged(range.buffer) && !this.stashed.has(`${first.controller.nodeIndex}/${first.group}`);
            if (ranged && this.inFlightCovers(range)) {
                deferred.push(this.queue.shift());
                continue;
            }
            if (ranged && this.requests >= this.options.concurrency) break;
            this.queue.shift();
            const items = [{ ...first, range }];
            let lo = range.start;
            let hi = range.end;
            // passes over the queue until none grows the range: the queue is in priority order,
            // the file in error order, so a chunk next to the range may come before the one that
            // makes it adjacent (one pass sent the TotalSegmentator example's 83 wanted chunks,
            // adjacent in the file, in 8 requests)
            for (let grown = ranged; grown;) {
                grown = false;
                for (let i = 0; i < this.queue.length && i < 256; ++i) {
                    if (this.decoding + items.length >= this.options.maxDecodes) break;
                    const w = this.queue[i];
                    if (
                        w.controller.groupState[w.group] !== 0 ||
                        this.stashed.has(`${w.controller.nodeIndex}/${w.group}`)
                    )
                        continue;
                    const r = this.chunkRange(w.controller, w.group);
                    if (
                        r.buffer !== range.buffer ||
                        r.start - hi > this.options.maxRangeGap ||
                        lo - r.end > this.options.maxRangeGap ||
                        Math.max(hi, r.end) - Math.min(lo, r.start) > this.options.maxRangeBytes ||
                        // the gap it adds holds no byte requested before (fetched twice otherwise)
                        (r.start > hi && this.requested.overlap(range.buffer, hi, r.start) > 0) ||
                        (r.end < lo && this.requested.overlap(range.buffer, r.end, lo) > 0) ||
                        this.inFlightCovers(r)
                    ) {
                        continue;
                    }
                    lo = Math.min(lo, r.start);
                    hi = Math.max(hi, r.end);
                    items.push({ ...w, range: r });
                    this.queue.splice(i--, 1);
                    grown = true;
                }
            }
            for (const w of items) w.controller.groupState[w.group] = 1;
            if (ranged) this.requested.add(range.buffer, lo, hi);
            this.decoding += items.length;
            this.loadBatch({ items, buffer: range.buffer, start: lo, end: hi, ranged });
        }
        if (deferred.length > 0) this.queue.unshift(...deferred);
    }

    /// Does a request in flight hold the bytes of range (a chunk in its gaps)?
    inFlightCovers(range) {
        for (const batch of this.batches) {
            if (!batch.fetched && batch.ranged && batch.buffer === range.buffer) {
                if (batch.start <= range.start && range.end <= batch.end) return true;
            }
        }
        return false;
    }

    /// Chunks being fetched or decoded.
    get inFlight() {
        return this.decoding;
    }

    /// Keeps the chunks not yet loaded that lie wholly inside a fetched range (the gaps of a
    /// coalesced request), so that they are not fetched again when they are wanted.
    stash(batch, bytes) {
        const inBatch = new Set(batch.items.map((w) => `${w.controller.nodeIndex}/${w.group}`));
        for (const controller of this.controllers) {
            if (controller.chunksView === undefined) continue; // no groups
            const def = this.parser.json.bufferViews[controller.chunksView];
            if (def.buffer !== batch.buffer) continue;
            const base = def.byteOffset ?? 0;
            if (base + def.byteLength <= batch.start || base >= batch.end) continue;
            controller.dag.groups.forEach((group, g) => {
                const a = base + group.chunkOffset;
                const b = a + group.chunkLength;
                const key = `${controller.nodeIndex}/${g}`;
                if (a < batch.start || b > batch.end || controller.groupState[g] !== 0 || inBatch.has(key)) return;
                if (!this.stashed.has(key)) this.stashed.set(key, bytes.slice(a - batch.start, b - batch.start));
            });
        }
    }

    /// Aborts fetches none of whose chunks is wanted any more (their groups can be asked again).
    cancelObsolete(wanted) {
        for (const batch of this.batches) {
            if (batch.fetched || batch.controller === null) continue;
            if (batch.items.some((w) => wanted.has(`${w.controller.nodeIndex}/${w.group}`))) continue;
            batch.controller.abort();
        }
    }

    /// Unloads loaded chunks whose groups are neither drawn refined nor wanted by the view, least
    /// recently used first, while the loaded chunk triangles exceed the memory budget.
    evictBeyondBudget() {
        let resident = this.controllers.reduce((s, c) => s + c.chunkTriangles, 0);
        const budget = this.options.memoryBudget;
        if (!(resident > budget)) return;
        const candidates = [];
        for (const controller of this.controllers) {
            for (let g = 0; g < controller.dag.ng; ++g) {
                // not wanted by the view (priority <= 1: refining it would not be asked for now)
                if (
                    controller.groupState[g] === 2 &&
                    !(controller.priority?.[g] > 1) &&
                    controller.weight[g] === 0 &&
                    !controller.isDrawnRefined(g)
                ) {
                    candidates.push({ controller, g, used: controller.groupUsed[g] });
                }
            }
        }
        candidates.sort((a, b) => a.used - b.used);
        for (const { controller, g } of candidates) {
            if (resident <= 0.9 * budget) break;
            const before = controller.chunkTriangles;
            controller.evict(g);
            resident -= before - controller.chunkTriangles;
            ++this.stats.evicted;
            --this.stats.chunksLoaded;
        }
    }

    async loadBatch(batch) {
        const json = this.parser.json;
        const abort = typeof AbortController === 'function' ? new AbortController() : null;
        const entry = {
            items: batch.items,
            controller: abort,
            fetched: false,
            ranged: batch.ranged,
            buffer: batch.buffer,
            start: batch.start,
            end: batch.end,
        };
        this.batches.add(entry);
        if (batch.ranged) ++this.requests;
        let bytes;
        const key = `${batch.items[0].controller.nodeIndex}/${batch.items[0].group}`;
        try {
            if (this.stashed.has(key)) {
                bytes = this.stashed.get(key);
                this.stashed.delete(key);
            } else if (batch.ranged) {
                try {
                    if (this.options.source?.kind === 'glb-range' && batch.buffer === 0) {
                        bytes = await this.glbRange(batch.start, batch.end, abort?.signal);
                    } else {
                        const url = LoaderUtils.resolveURL(json.buffers[batch.buffer].uri, this.parser.options.path);
                        bytes = await this.fetcher.range(url, batch.start, batch.end, abort?.signal);
                    }
                } finally {
                    --this.requests;
                }
            } else {
                const whole = await this.parser.getDependency('buffer', batch.buffer);
                bytes = whole.slice(batch.start, batch.end);
            }
        } catch (error) {
            entry.fetched = true;
            this.batches.delete(entry);
            for (const { controller, group } of batch.items) {
                if (controller.groupState[group] === 1) controller.groupState[group] = abort?.signal.aborted ? 0 : 3;
            }
            this.decoding -= batch.items.length;
            if (abort?.signal.aborted) {
                this.stats.cancelled += batch.items.length;
            } else {
                this.stats.failures += batch.items.length;
                this.errors.push(`${error.message ?? error}`);
                console.error(`${kExtension}: ${error.message ?? error}`);
            }
            this.pump();
            return;
        }
        entry.fetched = true;
        this.batches.delete(entry);
        if (batch.ranged) this.stash(batch, bytes);
        this.pump(); // the request slot is free
        await Promise.all(
            batch.items.map(async ({ controller, group, range }) => {
                let queued = false;
                try {
                    const chunk = bytes.slice(range.start - batch.start, range.end - batch.start);
                    this.stats.chunkBytesLoaded += chunk.byteLength;
                    const d0 = performance.now();
                    const decoded = await this.decodeChunk(chunk);
                    this.stats.decodeWaitMs += performance.now() - d0;
                    if (controller.groupState[group] !== 1) return; // unloaded meanwhile
                    // attached by a task of its own or the next update, within a time budget (attachArrived)
                    this.arrived.push({ controller, group, decoded });
                    this.scheduleAttach();
                    queued = true;
                    this.changed = true;
                    this.options.onChange?.(controller, group);
                } catch (error) {
                    this.groupFailed(controller, group, error);
                } finally {
                    if (!queued) {
                        --this.decoding;
                        this.pump();
                    }
                }
            }),
        );
    }

    /// A group whose chunk could not be fetched, decoded or attached: marked failed (never asked
    /// for again), counted, and its error kept and logged.
    groupFailed(controller, group, error) {
        controller.groupState[group] = 3;
        ++this.stats.failures;
        this.errors.push(`${controller.name} group ${group}: ${error.message ?? error}`);
        console.error(`${kExtension}: ${controller.name} group ${group}: ${error.message ?? error}`);
    }

    /// Attaches arrived chunks in tasks of their own (attachMs each, yielding in between), until
    /// none is left.
    scheduleAttach() {
        if (this.attachScheduled) return;
        this.attachScheduled = true;
        setTimeout(() => {
            this.attachScheduled = false;
            this.attachArrived();
            if (this.arrived.length > 0) this.scheduleAttach();
        }, 0);
    }

    /// Attaches decoded chunks (slots resolved, split by cluster, their own normals) for at
    /// most options.attachMs of main-thread time (at least one chunk), so that a frame never
    /// waits for a whole burst of arrivals.
    attachArrived() {
        const deadline = performance.now() + this.options.attachMs;
        let n = 0;
        while (this.arrived.length > 0 && (n === 0 || performance.now() < deadline)) {
            const { controller, group, decoded } = this.arrived.shift();
            ++n;
            try {
                if (controller.groupState[group] !== 1) continue;
                const t0 = performance.now();
                controller.attachChunk(group, decoded);
                this.stats.attachMs += performance.now() - t0;
                ++this.stats.chunksLoaded;
                this.changed = true;
            } catch (error) {
                this.groupFailed(controller, group, error);
            } finally {
                --this.decoding;
            }
        }
        if (n > 0) this.pump();
    }

    /// Decodes a chunk (ArrayBuffer) with GLTFLoader's DRACOLoader: { positions, cluster, slot,
    /// index } as typed arrays.
    async decodeChunk(buffer) {
        const dracoLoader = this.parser.extensions?.[kDraco]?.dracoLoader;
        if (!dracoLoader) throw new Error('no DRACOLoader (GLTFLoader.setDRACOLoader)');
        const geometry = await dracoLoader.decodeGeometry(buffer, {
            attributeIDs: {
                position: kChunkAttributeIds.position,
                _cluster: kChunkAttributeIds.cluster,
                _slot: kChunkAttributeIds.slot,
            },
            attributeTypes: { position: 'Float32Array', _cluster: 'Uint32Array', _slot: 'Uint32Array' },
            useUniqueIDs: true,
            vertexColorSpace: 'srgb-linear',
        });
        const position = geometry.getAttribute('position');
        const cluster = geometry.getAttribute('_cluster');
        const slot = geometry.getAttribute('_slot');
        if (!position || !cluster || !slot || !geometry.index)
            throw new Error('chunk without POSITION, _CLUSTER, _SLOT or triangles');
        if (position.count > geometry.index.count)
            throw new Error(`${position.count} points for ${geometry.index.count / 3} triangles`);
        return {
            positions: position.array,
            cluster: scalarValues(cluster),
            slot: scalarValues(slot),
            index: geometry.index.array,
        };
    }

    // --- helpers for apps ------------------------------------------------------------------------

    /// The scene's bounding sphere in the glTF scene frame (from the root clusters' spheres).
    sceneSphere() {
        const box = new Box3();
        for (const controller of this.controllers) {
            for (const c of controller.dag.roots) {
                const s = controller.dag.clusterSphere.subarray(4 * c, 4 * c + 4);
                box.expandByPoint(new Vector3(s[0] - s[3], s[1] - s[3], s[2] - s[3]));
                box.expandByPoint(new Vector3(s[0] + s[3], s[1] + s[3], s[2] + s[3]));
            }
        }
        return box.getBoundingSphere(new Sphere());
    }

    /// The meshes drawn now (for picking): one per shown object; userData.strataObject is its
    /// controller.
    drawnMeshes() {
        const out = [];
        for (const controller of this.controllers) {
            if (!isShown(controller.object) || !controller.drawMesh?.visible) continue;
            out.push(controller.drawMesh);
        }
        return out;
    }

    /// Error bound of cluster c of a controller, metres.
    static clusterError(controller, c) {
        return clusterError(controller.dag, c);
    }
}

function isShown(object) {
    for (let o = object; o; o = o.parent) if (!o.visible) return false;
    return true;
}

// ------------------------------------------------------------------------------------------------
// opening a model by URL with streaming

/// The default first request of a streamed .glb: 24 kB holds the torso's GLB header, JSON, DAG
/// tables and base (18.7 kB); larger models fetch the rest of their base with one more request.
/// 64 kB took a third of the torso's file before anything was wanted.
export const kPrefixBytes = 24 * 1024;

/// Opens a progressive model by URL, streaming when it can:
///   * .glb on a server that supports Range requests: reads the header and the JSON by ranges,
///     then only the base meshes' bytes; chunks are fetched later by ranges (glb-range source);
///   * .gltf: the JSON, then the base buffer; chunks by ranges of the level files;
///   * a server without ranges: the whole file (then chunks are decoded lazily from memory).
/// loader: a GLTFLoader with a DRACOLoader set (the plugin is registered here, for this load
/// only); prefixBytes: the size of the first request (GLB header and JSON; what it holds beyond
/// them is kept, so it may also hold the base and chunks; Infinity: the whole file in one
/// request without Range, as a single-rate viewer loads it); returns the glTF result;
/// result.userData.strata is the plugin.
export async function loadStrataModel(
    url,
    { createLoader, pluginOptions = {}, fetch: fetchFn = null, prefixBytes = kPrefixBytes } = {},
) {
    const doFetch = fetchFn ?? globalThis.fetch.bind(globalThis);
    const absolute = new URL(url, globalThis.location?.href ?? undefined).href;
    const basePath = LoaderUtils.extractUrlBase(absolute);
    if (!((Number.isInteger(prefixBytes) && prefixBytes >= 20) || prefixBytes === Infinity))
        throw new Error(`prefixBytes ${prefixBytes}: expected an integer >= 20 (the GLB header) or Infinity`);
    const kPrefix = prefixBytes;
    let bytesRead = 0;
    let requests = 0;
    const ranges = []; // [url, start, end) read here
    // the page may have sent this first request already (index.html: globalThis.strataFirstRequest)
    const early = globalThis.strataFirstRequest;
    const response =
        early?.url === absolute && early.prefix === kPrefix && fetchFn === null
            ? await early.response
            : await doFetch(absolute, kPrefix === Infinity ? {} : { headers: { Range: `bytes=0-${kPrefix - 1}` } });
    if (early?.url === absolute) globalThis.strataFirstRequest = null;
    mark('strata:prefix-response');
    if (!response.ok) throw new Error(`${url}: HTTP ${response.status}`);
    let prefix = await response.arrayBuffer();
    bytesRead += prefix.byteLength;
    ++requests;
    ranges.push([absolute, 0, prefix.byteLength]);
    const partial = response.status === 206;
    const total = partial ? Number(response.headers.get('Content-Range')?.split('/')[1]) : prefix.byteLength;
    // appends bytes [prefix.byteLength, end) of the file to `prefix` (one Range request)
    const extendPrefix = async (end) => {
        const more = await doFetch(absolute, { headers: { Range: `bytes=${prefix.byteLength}-${end - 1}` } });
        if (more.status !== 206) throw new Error(`${url}: HTTP ${more.status} for a range request`);
        const rest = await more.arrayBuffer();
        bytesRead += rest.byteLength;
        ++requests;
        ranges.push([absolute, prefix.byteLength, prefix.byteLength + rest.byteLength]);
        const joined = new Uint8Array(prefix.byteLength + rest.byteLength);
        joined.set(new Uint8Array(prefix), 0);
        joined.set(new Uint8Array(rest), prefix.byteLength);
        prefix = joined.buffer;
    };
    const layout = glbLayout(new Uint8Array(prefix, 0, Math.min(20, prefix.byteLength)));
    let data;
    let options = { ...pluginOptions, totalBytes: 0 };
    if (layout !== null && partial) {
        const jsonEnd = layout.jsonOffset + layout.jsonLength;
        if (prefix.byteLength < jsonEnd) await extendPrefix(jsonEnd);
        data = new TextDecoder().decode(new Uint8Array(prefix, layout.jsonOffset, layout.jsonLength));
        options.source = { kind: 'glb-range', url: absolute, binOffset: layout.binOffset, length: total, prefix };
        options.totalBytes = total;
    } else if (layout !== null) {
        data = prefix; // the whole GLB: in memory
        options.totalBytes = prefix.byteLength;
    } else {
        if (partial && prefix.byteLength < total) await extendPrefix(total);
        data = new TextDecoder().decode(prefix);
        const json = JSON.parse(data);
        options.totalBytes =
            total +
            (json.buffers ?? []).reduce((s, b) => s + (b.uri && !b.uri.startsWith('data:') ? b.byteLength : 0), 0);
    }
    options.initialBytes = bytesRead;
    options.initialRanges = ranges;
    const loader = createLoader();
    let plugin = null;
    loader.register((parser) => (plugin = new StrataProgressivePlugin(parser, options)));
    mark('strata:parse');
    const gltf = await new Promise((resolve, reject) => loader.parse(data, basePath, resolve, reject));
    mark('strata:parsed');
    plugin.stats.requests += requests;
    gltf.userData.strata ??= plugin;
    return gltf;
}

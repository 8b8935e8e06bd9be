// A three.js GLTFLoader plugin for STRATA_progressive_mesh (schema/README.md): any three.js app
// can register it, independently of this folder's page.
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
// GLTFLoader builds the base (the node's mesh, the root clusters) as usual; the plugin then
//   * makes one controller per object node (strata.controllers; controller.update(camera,
//     viewportHeightPx, tauPx, budget) selects, loads and swaps that object alone);
//   * per update selects the cut (selection.js: screen-space error with the 3D Tiles formula,
//     region of interest, frustum, triangle budget, chunks not loaded yet), shows and hides the
//     cluster meshes, and sets each chunk's geomorph weight;
//   * requests the missing chunks by priority, a few at a time, through
//     parser.getDependency('mesh', i) (GLTFLoader's own KHR_draco_mesh_compression path);
//   * fetches the bytes of a chunk by an HTTP Range request of its bufferView when the buffer is a
//     separate file (.gltf with per-level .bin files) or when the model was opened with
//     loadStrataModel() on a server that supports ranges (.glb streaming); a GLB given whole to
//     GLTFLoader is already in memory and only decoded lazily.
// Geomorphs: every cluster mesh gets a clone of its object's material whose vertex shader draws
// position + (_COARSE_POSITION - position) * w, with one uniform w per cluster (the weight of the
// group that consumes it: 1 at the refinement threshold, 0 from k * tau on, and a short time blend
// after a refinement the threshold did not announce, e.g. a chunk arriving late). Root clusters use
// the same program with w = 0 (no _COARSE_POSITION: it reads as 0, and p + (0 - p) * 0 == p
// exactly), so shared vertices are transformed by identical code in every cluster.
import { Frustum, LoaderUtils, Matrix4, Mesh, MeshBasicMaterial, Vector3, Sphere, Box3 } from 'three';
import {
    buildDag,
    clusterError,
    clusterTriangleCounts,
    cutStats,
    selectCut,
    sphereMeetsRoi,
    validateExtension,
} from './selection.js';
import { ByteCoverage, coalesceRanges, glbLayout, meshBufferViews, progressiveNodes } from './gltf-file.js';
import { kDraco, kExtension, kThreeAttributes } from './strata-format.js';

const kDefaults = {
    concurrency: 4, // HTTP requests in flight
    maxDecodes: 16, // chunks fetched or decoding at once (DRACOLoader's workers queue them)
    morph: true, // geomorphs
    morphK: 2, // w = clamp((k - sse / tau) / (k - 1), 0, 1)
    blendMs: 300, // time blend after a refinement the threshold did not announce
    cull: true, // refine only groups whose sphere meets the view frustum
    maxRangeGap: 16384, // merge chunk ranges of one buffer closer than this into one request
    maxRangeBytes: 1 << 20, // ... up to this length
    source: null, // set by loadStrataModel: { kind: 'glb-range', url, binOffset, length, prefix }
    initialBytes: 0, // bytes fetched before GLTFLoader ran (loadStrataModel: the JSON)
    initialRanges: [], // ... as [url, start, end) triples (distinct bytes are counted once)
    totalBytes: 0, // total size of the model's files, when known
    fetch: null, // fetch function (default globalThis.fetch)
    onChange: null, // called when a chunk arrives (an app that renders on demand re-renders)
};

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
            if (body.byteLength !== end - start)
                throw new Error(`${url}: range ${start}-${end} gave ${body.byteLength} bytes`);
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

/// A clone of an object's material that morphs POSITION towards _COARSE_POSITION by the uniform
/// strataMorph (per clone, i.e. per cluster). All clones share one program.
function morphMaterial(base) {
    const material = base.clone();
    const uniform = { value: 0 };
    material.userData.strataMorph = uniform;
    material.userData.strataBaseColor = base.color?.clone();
    material.onBeforeCompile = (shader) => {
        shader.uniforms.strataMorph = uniform;
        shader.vertexShader =
            'invariant gl_Position;\nattribute vec3 _coarse_position;\nuniform float strataMorph;\n' +
            shader.vertexShader.replace(
                '#include <begin_vertex>',
                'vec3 transformed = position + ( _coarse_position - position ) * strataMorph;',
            );
    };
    material.customProgramCacheKey = () => 'strata-morph-1';
    return material;
}

// ------------------------------------------------------------------------------------------------
// one object

/// The controller of one object node: its DAG, its cluster meshes and their state.
export class StrataObjectController {
    constructor(plugin, nodeIndex, object, ext, json) {
        this.plugin = plugin;
        this.nodeIndex = nodeIndex;
        this.object = object;
        this.name = json.nodes[nodeIndex].name ?? `node ${nodeIndex}`;
        this.extras = json.nodes[nodeIndex].extras ?? {};
        this.ext = ext;
        this.dag = buildDag(ext, { clusterTriangles: clusterTriangleCounts(ext, json) });
        const nc = this.dag.nc;
        this.meshes = new Array(nc).fill(null); // cluster -> Mesh (null until loaded)
        this.state = new Uint8Array(nc); // 0 not requested, 1 requested, 2 loaded, 3 failed
        this.refined = new Uint8Array(this.dag.ng);
        this.refinedAt = new Float64Array(this.dag.ng).fill(-Infinity);
        this.drawn = [];
        this.stats = { triangles: this.dag.baseTriangles, maxError: 0, maxErrorPx: 0 };
        this.opacity = 1;
        this.colorByLevel = false;
        // the base: the GLTFLoader meshes of the node's mesh, one per primitive = root cluster
        const nodeMesh = json.nodes[nodeIndex].mesh;
        const byPrimitive = new Map();
        object.traverse((o) => {
            const a = plugin.parser.associations.get(o);
            if (o.isMesh && a?.meshes === nodeMesh && a.primitives !== undefined) byPrimitive.set(a.primitives, o);
        });
        this.material = null;
        // If the node object is itself the (single-primitive) mesh, hiding it would hide the chunk
        // meshes added below it: let a child draw its geometry instead.
        if (object.isMesh) {
            const proxy = new Mesh(object.geometry, object.material);
            proxy.name = `${object.name} base`;
            object.add(proxy);
            object.material = new MeshBasicMaterial({ visible: false });
            for (const [p, m] of byPrimitive) if (m === object) byPrimitive.set(p, proxy);
        }
        ext.clusters.forEach((cluster, c) => {
            if (this.dag.consumer[c] >= 0) return;
            const mesh = byPrimitive.get(cluster.primitive ?? 0);
            if (mesh === undefined) throw new Error(`${this.name}: no mesh for root cluster ${c}`);
            this.material ??= mesh.material;
            this.adopt(c, mesh);
            this.state[c] = 2;
        });
    }

    /// Makes mesh the drawable of cluster c: its own morph material, userData for picking.
    adopt(c, mesh) {
        mesh.material = morphMaterial(this.material ?? mesh.material);
        mesh.userData.strataCluster = c;
        mesh.userData.strataObject = this;
        if (this.opacity < 1) this.applyOpacity(mesh.material);
        if (this.colorByLevel) this.applyLevelColor(c, mesh.material);
        this.meshes[c] = mesh;
    }

    /// Cluster c (not a root) arrived: its Mesh from GLTFLoader (geometry with position, normal,
    /// _coarse_position).
    attach(c, loaded) {
        const geometry = loaded.geometry;
        // bounds that contain the morph too (frustum culling of the mesh)
        const box = new Box3().setFromBufferAttribute(geometry.getAttribute('position'));
        const coarse = geometry.getAttribute(kThreeAttributes.coarsePosition);
        if (coarse !== undefined) box.union(new Box3().setFromBufferAttribute(coarse));
        geometry.boundingBox = box;
        geometry.boundingSphere = box.getBoundingSphere(new Sphere());
        const mesh = new Mesh(geometry, this.material ?? loaded.material);
        mesh.name = `${this.name} cluster ${c}`;
        mesh.visible = false;
        this.adopt(c, mesh);
        this.object.add(mesh);
        this.state[c] = 2;
    }

    isLoaded(c) {
        return this.state[c] === 2;
    }

    /// Selects, requests and shows this object alone (see StrataProgressivePlugin.update).
    update(camera, viewportHeightPx, tauPx = 1, budget = Infinity, options = {}) {
        return this.plugin.update(camera, viewportHeightPx, tauPx, budget, { ...options, controllers: [this] });
    }

    /// Shows the cut (refined groups, drawn clusters, weights) at time now (ms).
    apply(cut, now, morph) {
        const dag = this.dag;
        for (let g = 0; g < dag.ng; ++g) {
            if (cut.refined[g] && !this.refined[g]) {
                // refined now: blend in over blendMs unless the threshold already starts at w ~ 1
                this.refinedAt[g] = cut.weight[g] > 0.95 ? -Infinity : now;
            }
        }
        this.refined = cut.refined;
        const drawnSet = new Uint8Array(dag.nc);
        for (const c of cut.drawn) drawnSet[c] = 1;
        const blend = this.plugin.options.blendMs;
        let changed = false;
        for (let c = 0; c < dag.nc; ++c) {
            const mesh = this.meshes[c];
            if (mesh === null) continue;
            const visible = drawnSet[c] === 1;
            let w = 0;
            const g = dag.consumer[c];
            if (morph && visible && g >= 0) {
                const t = blend > 0 ? 1 - (now - this.refinedAt[g]) / blend : 0;
                w = Math.max(0, cut.weight[g], Math.min(1, t));
            }
            const uniform = mesh.material.userData.strataMorph;
            if (mesh.visible !== visible || (visible && uniform.value !== w)) changed = true;
            mesh.visible = visible;
            uniform.value = w;
        }
        this.drawn = cut.drawn;
        return changed;
    }

    /// True while some drawn cluster is morphing by time (an app rendering on demand keeps going).
    blending(now) {
        const blend = this.plugin.options.blendMs;
        return this.refinedAt.some((t) => now - t < blend);
    }

    setOpacity(opacity) {
        this.opacity = opacity;
        this.plugin.changed = true;
        for (const mesh of this.meshes) if (mesh) this.applyOpacity(mesh.material);
    }

    applyOpacity(material) {
        material.opacity = this.opacity;
        material.transparent = this.opacity < 1;
        material.depthWrite = this.opacity >= 1;
        material.needsUpdate = true;
    }

    /// Debug colouring: each cluster by its level (0 = full resolution: blue ... coarse: red).
    setColorByLevel(on) {
        this.colorByLevel = on;
        this.plugin.changed = true;
        this.meshes.forEach((mesh, c) => mesh && this.applyLevelColor(c, mesh.material));
    }

    applyLevelColor(c, material) {
        if (!material.color) return;
        if (!this.colorByLevel) {
            material.color.copy(material.userData.strataBaseColor);
            return;
        }
        this.maxLevel ??= this.ext.clusters.reduce((m, k) => Math.max(m, k.level), 1);
        const levels = this.maxLevel;
        const level = this.ext.clusters[c].level;
        material.color.setHSL(0.66 * (1 - level / levels), 0.8, 0.5 + 0.1 * (((c * 7) % 3) - 1));
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
        };
        this.fetcher = new RangeFetcher(
            this.options.fetch ?? globalThis.fetch.bind(globalThis),
            this.stats,
            this.coverage,
        );
        this.controllers = [];
        this.chunkViews = new Map(); // bufferView index -> { nodeIndex, cluster } of every chunk
        this.controllerOf = new Map(); // node index -> controller
        this.viewBytes = new Map(); // bufferView index -> ArrayBuffer fetched ahead (ranges)
        this.queue = []; // wanted chunks of the last update, best first
        this.requests = 0; // HTTP requests in flight
        this.decoding = 0; // chunks requested and not yet attached
        this.changed = false; // something to draw differently since the last update
        this.sceneRoot = null;
        this.last = null; // the last update's summary
        this.errors = [];
    }

    // --- GLTFLoader hooks ------------------------------------------------------------------------

    beforeRoot() {
        const json = this.parser.json;
        const source = this.options.source;
        for (const { nodeIndex, ext } of progressiveNodes(json, kExtension)) {
            for (const [c, cluster] of (ext.clusters ?? []).entries()) {
                const view =
                    json.meshes?.[cluster.mesh]?.primitives?.[cluster.primitive ?? 0]?.extensions?.[kDraco]?.bufferView;
                if (cluster.consumer !== undefined && view !== undefined)
                    this.chunkViews.set(view, { nodeIndex, cluster: c });
            }
        }
        if (this.stats.bytesTotal === 0) {
            this.stats.bytesTotal = (json.buffers ?? []).reduce((s, b) => s + (b.byteLength ?? 0), 0);
        }
        if (source?.kind !== 'glb-range') return null;
        // GLB streaming: fetch every bufferView of buffer 0 the scene needs now (all but the
        // chunks), in few coalesced ranges.
        const views = new Set();
        for (const node of json.nodes ?? []) {
            if (node.mesh !== undefined) meshBufferViews(json, node.mesh).forEach((v) => views.add(v));
        }
        const ranges = coalesceRanges(
            json,
            [...views].filter((v) => json.bufferViews[v].buffer === 0),
            4096,
        );
        return Promise.all(
            ranges.map(async (range) => {
                const bytes = await this.glbRange(range.start, range.end);
                this.stash(0, range.start, bytes);
                for (const v of range.views) {
                    const def = json.bufferViews[v];
                    const start = (def.byteOffset ?? 0) - range.start;
                    this.viewBytes.set(v, bytes.slice(start, start + def.byteLength));
                }
            }),
        );
    }

    /// Keeps the bytes of every chunk bufferView that lies inside a fetched range of a buffer (the
    /// gaps of coalesced ranges), so that it is not fetched again. bytes: ArrayBuffer of
    /// [start, start + bytes.byteLength) of buffer.
    stash(buffer, start, bytes) {
        const end = start + bytes.byteLength;
        for (const [view, { nodeIndex, cluster }] of this.chunkViews) {
            const def = this.parser.json.bufferViews[view];
            const a = def.byteOffset ?? 0;
            if (def.buffer !== buffer || a < start || a + def.byteLength > end || this.viewBytes.has(view)) continue;
            const controller = this.controllerOf.get(nodeIndex);
            if (controller !== undefined && controller.state[cluster] !== 0) continue;
            this.viewBytes.set(view, bytes.slice(a - start, a - start + def.byteLength));
        }
    }

    /// bytes [start, end) of the GLB's BIN data (glb-range source), using the prefix already read.
    glbRange(start, end) {
        const { url, binOffset, prefix } = this.options.source;
        const a = binOffset + start;
        const b = binOffset + end;
        if (prefix && b <= prefix.byteLength) return Promise.resolve(prefix.slice(a, b));
        return this.fetcher.range(url, a, b);
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
        if (this.chunkViews.has(index)) return this.fetcher.range(url, start, end);
        return this.fetcher.all(url).then((buffer) => buffer.slice(start, end));
    }

    afterRoot(result) {
        const json = this.parser.json;
        this.sceneRoot = result.scene;
        const objects = new Map();
        result.scene.traverse((o) => {
            const node = this.parser.associations.get(o)?.nodes;
            if (node !== undefined && !objects.has(node)) objects.set(node, o);
        });
        for (const { nodeIndex, ext } of progressiveNodes(json, kExtension)) {
            const object = objects.get(nodeIndex);
            const problems = validateExtension(ext);
            if (object === undefined || problems.length > 0) {
                // fall back to the base mesh (schema/README.md, Validation)
                console.warn(
                    `${kExtension}: node ${nodeIndex} uses its base mesh only: ${problems[0] ?? 'not in the scene'}`,
                );
                continue;
            }
            const controller = new StrataObjectController(this, nodeIndex, object, ext, json);
            object.userData.strata = controller;
            this.controllers.push(controller);
            this.controllerOf.set(nodeIndex, controller);
            this.stats.chunksTotal += ext.clusters.filter((c) => c.consumer !== undefined).length;
        }
        result.userData.strata = this;
        return null;
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
    /// and requests missing chunks. options: { roi: { center: [x, y, z] scene frame, radius,
    /// factor } | null, morph, cull, controllers (default: all) }. Returns a summary (also in
    /// this.last): { triangles, maxErrorPx, maxError (m), budgetLimited, wanted, roiTriangles,
    /// changed (the picture differs from the last update's: an app rendering on demand renders) }.
    update(camera, viewportHeightPx, tauPx = 1, budget = Infinity, options = {}) {
        const now = performance.now();
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
                    if (sphereMeetsRoi(controller.dag.clusterSphere, 4 * c, options.roi))
                        roiTriangles += controller.dag.triangles[c];
                }
            }
        });
        this.queue = result.wanted
            .map((w) => ({ controller: controllers[w.dag], cluster: w.cluster, priority: w.priority }))
            .filter((w) => w.controller.state[w.cluster] === 0);
        this.pump();
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
        return this.decoding === 0 && this.queue.length === 0 && !this.last?.blending;
    }

    // --- loading ---------------------------------------------------------------------------------

    /// Starts loading the best wanted chunks: at most `concurrency` HTTP requests in flight and
    /// at most `maxDecodes` chunks fetched but not yet decoded and attached (a request's slot is
    /// free again as soon as its bytes arrived). Chunks in separate buffer files (or a streamed
    /// GLB) are fetched in coalesced Range requests (neighbouring bufferViews of one buffer, best
    /// chunk first).
    pump() {
        const json = this.parser.json;
        const viewOf = (w) =>
            json.meshes[w.controller.ext.clusters[w.cluster].mesh].primitives[0].extensions[kDraco].bufferView;
        while (this.queue.length > 0 && this.decoding < this.options.maxDecodes) {
            const first = this.queue[0];
            if (first.controller.state[first.cluster] !== 0) {
                this.queue.shift();
                continue;
            }
            const ranged = !this.viewBytes.has(viewOf(first)) && this.isRanged(viewOf(first));
            if (ranged && this.requests >= this.options.concurrency) break;
            this.queue.shift();
            const batch = [first];
            if (ranged) {
                // add wanted chunks of the same buffer close to the first one
                const buffer = json.bufferViews[viewOf(first)].buffer;
                let lo = json.bufferViews[viewOf(first)].byteOffset ?? 0;
                let hi = lo + json.bufferViews[viewOf(first)].byteLength;
                for (
                    let i = 0;
                    i < this.queue.length && i < 256 && this.decoding + batch.length < this.options.maxDecodes;
                    ++i
                ) {
                    const w = this.queue[i];
                    if (w.controller.state[w.cluster] !== 0 || this.viewBytes.has(viewOf(w))) continue;
                    const def = json.bufferViews[viewOf(w)];
                    const a = def.byteOffset ?? 0;
                    const b = a + def.byteLength;
                    if (
                        def.buffer !== buffer ||
                        a - hi > this.options.maxRangeGap ||
                        lo - b > this.options.maxRangeGap ||
                        Math.max(hi, b) - Math.min(lo, a) > this.options.maxRangeBytes
                    )
                        continue;
                    lo = Math.min(lo, a);
                    hi = Math.max(hi, b);
                    batch.push(w);
                    this.queue.splice(i--, 1);
                }
            }
            for (const w of batch) w.controller.state[w.cluster] = 1;
            this.decoding += batch.length;
            if (ranged) ++this.requests;
            this.loadBatch(batch, ranged ? viewOf : null);
        }
    }

    /// Chunks being fetched or decoded.
    get inFlight() {
        return this.decoding;
    }

    isRanged(view) {
        const def = this.parser.json.bufferViews[view];
        if (this.options.source?.kind === 'glb-range' && def.buffer === 0) return true;
        const uri = this.parser.json.buffers[def.buffer]?.uri;
        return uri !== undefined && !uri.startsWith('data:');
    }

    async loadBatch(batch, viewOf) {
        const json = this.parser.json;
        let pending = batch.length;
        const done = () => {
            --this.decoding;
            --pending;
            this.pump();
        };
        try {
            if (viewOf !== null) {
                const views = batch.map(viewOf);
                const [range] = coalesceRanges(json, views, Infinity);
                let bytes;
                if (this.options.source?.kind === 'glb-range' && range.buffer === 0) {
                    bytes = await this.glbRange(range.start, range.end).finally(() => --this.requests);
                } else {
                    const url = LoaderUtils.resolveURL(json.buffers[range.buffer].uri, this.parser.options.path);
                    bytes = await this.fetcher.range(url, range.start, range.end).finally(() => --this.requests);
                }
                for (const v of views) {
                    const def = json.bufferViews[v];
                    const start = (def.byteOffset ?? 0) - range.start;
                    this.viewBytes.set(v, bytes.slice(start, start + def.byteLength));
                    this.stats.chunkBytesLoaded += def.byteLength;
                }
                this.stash(range.buffer, range.start, bytes);
                this.pump(); // the request slot is free
            }
            await Promise.all(
                batch.map(async ({ controller, cluster }) => {
                    try {
                        const mesh = await this.parser.getDependency('mesh', controller.ext.clusters[cluster].mesh);
                        if (!mesh?.isMesh) throw new Error('not one mesh');
                        controller.attach(cluster, mesh);
                        ++this.stats.chunksLoaded;
                        this.options.onChange?.(controller, cluster);
                    } catch (error) {
                        controller.state[cluster] = 3;
                        ++this.stats.failures;
                        this.errors.push(`${controller.name} cluster ${cluster}: ${error.message ?? error}`);
                        console.error(
                            `${kExtension}: ${controller.name} cluster ${cluster}: ${error.message ?? error}`,
                        );
                    } finally {
                        done();
                    }
                }),
            );
        } catch (error) {
            // the fetch failed: nothing of the batch was decoded
            for (const { controller, cluster } of batch)
                if (controller.state[cluster] === 1) controller.state[cluster] = 3;
            this.stats.failures += batch.length;
            this.errors.push(`${error.message ?? error}`);
            console.error(`${kExtension}: ${error.message ?? error}`);
            while (pending > 0) done();
        }
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

    /// The meshes drawn now (for picking).
    drawnMeshes() {
        const out = [];
        for (const controller of this.controllers) {
            if (!controller.object.visible) continue;
            for (const c of controller.drawn) if (controller.meshes[c]) out.push(controller.meshes[c]);
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

/// Opens a progressive model by URL, streaming when it can:
///   * .glb on a server that supports Range requests: reads the header and the JSON by ranges,
///     then only the base meshes' bytes; chunks are fetched later by ranges (glb-range source);
///   * .gltf: the JSON, then the base buffer; chunks by ranges of the level files;
///   * a server without ranges: the whole file (then chunks are decoded lazily from memory).
/// loader: a GLTFLoader with a DRACOLoader set (the plugin is registered here, for this load
/// only); prefixBytes: the size of the first request (GLB header and JSON; what it holds beyond
/// them is kept, so it may also hold the base and chunks); returns the glTF result;
/// result.userData.strata is the plugin.
export async function loadStrataModel(
    url,
    { createLoader, pluginOptions = {}, fetch: fetchFn = null, prefixBytes = 64 * 1024 } = {},
) {
    const doFetch = fetchFn ?? globalThis.fetch.bind(globalThis);
    const absolute = new URL(url, globalThis.location?.href ?? undefined).href;
    const basePath = LoaderUtils.extractUrlBase(absolute);
    if (!(Number.isInteger(prefixBytes) && prefixBytes >= 20))
        throw new Error(`prefixBytes ${prefixBytes}: expected an integer >= 20 (the GLB header)`);
    const kPrefix = prefixBytes;
    let bytesRead = 0;
    let requests = 0;
    const ranges = []; // [url, start, end) read here
    const response = await doFetch(absolute, { headers: { Range: `bytes=0-${kPrefix - 1}` } });
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
    const gltf = await new Promise((resolve, reject) => loader.parse(data, basePath, resolve, reject));
    plugin.stats.requests += requests;
    gltf.userData.strata ??= plugin;
    return gltf;
}

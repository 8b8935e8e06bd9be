// Pure selection logic for STRATA_progressive_mesh (schema/README.md): which clusters to draw.
// No DOM, no three.js: plain arrays and numbers, importable in Node and in the browser.
//
// Terms (schema/README.md): a group g is *refined* when its consumed clusters are drawn instead of
// its produced ones. A cluster c is drawn iff (c has no producer or producer(c) is not refined) and
// (c has no consumer or consumer(c) is refined). The set of refined groups must be *closed upward*:
// if g is refined, every group that consumes a cluster g produced (a parent of g) is refined too.
// Groups are listed children first, so a parent always has a larger index than its children.
//
// Main entry points:
//   buildDag(ext, { clusterTriangles, refineOn })   indexes one extension object
//   closeUpward / restrictToLoaded        the two passes of schema/README.md for any predicate
//   drawnClusters(dag, refined)           the stateless draw rule
//   screenSpaceError(error, sphere, view) the 3D Tiles formula (infinite inside the sphere)
//   selectCut(dags, view, options)        the viewer's cut: tau in pixels, region of interest,
//                                         frustum, triangle budget, chunks not yet loaded

import { kExtension } from './strata-format.js';

export { kExtension };

// ------------------------------------------------------------------------------------------------
// the DAG

/// Checks the extension object's links (schema/README.md "Validation", points 2 to 6; the caller
/// checks mesh indices). Returns a list of problems, empty when the DAG can be used.
export function validateExtension(ext) {
    const problems = [];
    const clusters = Array.isArray(ext?.clusters) ? ext.clusters : null;
    const groups = Array.isArray(ext?.groups) ? ext.groups : null;
    if (clusters === null || clusters.length === 0 || groups === null) {
        return ['clusters or groups missing'];
    }
    const isIndex = (v, n) => Number.isInteger(v) && v >= 0 && v < n;
    const consumedBy = new Array(clusters.length).fill(undefined);
    const producedBy = new Array(clusters.length).fill(undefined);
    groups.forEach((g, gi) => {
        for (const [list, by, what] of [
            [g.consumed, consumedBy, 'consumed'],
            [g.produced, producedBy, 'produced'],
        ]) {
            if (!Array.isArray(list) || list.length === 0) {
                problems.push(`group ${gi}: no ${what} clusters`);
                continue;
            }
            for (const c of list) {
                if (!isIndex(c, clusters.length)) {
                    problems.push(`group ${gi}: ${what} cluster ${c} is not a cluster index`);
                } else if (by[c] !== undefined) {
                    problems.push(`cluster ${c} is ${what} by groups ${by[c]} and ${gi}`);
                } else {
                    by[c] = gi;
                }
            }
        }
        if (!Array.isArray(g.sphere) || g.sphere.length !== 4 || !(g.error >= 0)) {
            problems.push(`group ${gi}: bad sphere or error`);
        }
    });
    clusters.forEach((c, ci) => {
        if (c.consumer !== consumedBy[ci] || c.producer !== producedBy[ci]) {
            problems.push(`cluster ${ci}: producer/consumer links disagree with the groups`);
        }
        if ((c.producer === undefined) !== (c.level === 0)) {
            problems.push(`cluster ${ci}: level ${c.level} and producer ${c.producer}`);
        }
        if (!Array.isArray(c.sphere) || c.sphere.length !== 4) {
            problems.push(`cluster ${ci}: bad sphere`);
        }
    });
    if (problems.length > 0) {
        return problems;
    }
    groups.forEach((g, gi) => {
        for (const c of g.consumed) {
            const p = clusters[c].producer;
            if (p !== undefined && p >= gi) {
                problems.push(`group ${gi} consumes cluster ${c} of the later group ${p} (not children first)`);
            }
            if (p !== undefined && groups[p].error > g.error) {
                problems.push(`group ${gi}: error ${g.error} below its child ${p}'s ${groups[p].error}`);
            }
            if (clusters[c].level >= g.level) {
                problems.push(`group ${gi}: consumed cluster ${c} has level ${clusters[c].level} >= ${g.level}`);
            }
        }
        for (const c of g.produced) {
            if (clusters[c].level !== g.level) {
                problems.push(`group ${gi}: produced cluster ${c} has level ${clusters[c].level}`);
            }
        }
        if (g.error < (ext.fullResolutionError ?? 0)) {
            problems.push(`group ${gi}: error below fullResolutionError`);
        }
    });
    return problems;
}

/// Triangle count of every cluster, from the glTF JSON (the indices accessor's count / 3).
export function clusterTriangleCounts(ext, json) {
    return ext.clusters.map((c) => {
        const primitive = json.meshes?.[c.mesh]?.primitives?.[c.primitive ?? 0];
        const accessor = primitive === undefined ? undefined : json.accessors?.[primitive.indices];
        if (accessor !== undefined) {
            return Math.floor(accessor.count / 3);
        }
        const position = primitive === undefined ? undefined : json.accessors?.[primitive.attributes?.POSITION];
        return position === undefined ? 0 : Math.floor(position.count / 3);
    });
}

/// Indexes an extension object for selection. clusterTriangles: per cluster triangle count
/// (clusterTriangleCounts), default 0 each (then budgets count nothing). refineOn: what selection
/// projects against tau (dag.fine), 'finest' (default): each group's bound against the finest
/// level, what the rest of the refinement can still change on screen; 'data': how much its slice
/// bound exceeds the full-resolution surface's own (error - fullResolutionError), what the rest
/// of the refinement can still gain in the bound against the original contours.
export function buildDag(ext, { clusterTriangles, refineOn = 'finest' } = {}) {
    if (refineOn !== 'finest' && refineOn !== 'data') {
        throw new Error(`refineOn ${refineOn}, expected 'finest' or 'data'`);
    }
    const problems = validateExtension(ext);
    if (problems.length > 0) {
        throw new Error(`invalid ${kExtension}: ${problems.slice(0, 3).join('; ')}`);
    }
    const clusters = ext.clusters;
    const groups = ext.groups;
    const nc = clusters.length;
    const ng = groups.length;
    const producer = new Int32Array(nc).fill(-1);
    const consumer = new Int32Array(nc).fill(-1);
    clusters.forEach((c, i) => {
        if (c.producer !== undefined) producer[i] = c.producer;
        if (c.consumer !== undefined) consumer[i] = c.consumer;
    });
    const triangles = Float64Array.from(clusterTriangles ?? new Array(nc).fill(0));
    const error = Float64Array.from(groups, (g) => g.error);
    // what selection projects: the bound against the finest level (what the rest of the
    // refinement can still change), the slice bound where a DAG has none; or the slice bound's
    // excess over full resolution's (monotone along the DAG as the slice bound is)
    const full = ext.fullResolutionError ?? 0;
    const fine = Float64Array.from(groups, (g) => (refineOn === 'data' ? g.error - full : (g.fineError ?? g.error)));
    const sphere = new Float64Array(4 * ng);
    groups.forEach((g, i) => sphere.set(g.sphere, 4 * i));
    const clusterSphere = new Float64Array(4 * nc);
    clusters.forEach((c, i) => clusterSphere.set(c.sphere, 4 * i));
    // children: producers of the consumed clusters; parents: consumers of the produced clusters
    const children = groups.map((g) => [...new Set(g.consumed.map((c) => producer[c]).filter((p) => p >= 0))]);
    const parents = groups.map((g) => [...new Set(g.produced.map((c) => consumer[c]).filter((p) => p >= 0))]);
    // triangles added by refining g: consumed minus produced
    const delta = Float64Array.from(
        groups,
        (g) => g.consumed.reduce((s, c) => s + triangles[c], 0) - g.produced.reduce((s, c) => s + triangles[c], 0),
    );
    const roots = [];
    for (let c = 0; c < nc; ++c) {
        if (consumer[c] < 0) roots.push(c);
    }
    const baseTriangles = roots.reduce((s, c) => s + triangles[c], 0);
    const totalTriangles = triangles.reduce((s, t) => s + t, 0);
    return {
        ext,
        clusters,
        groups,
        nc,
        ng,
        producer,
        consumer,
        triangles,
        error,
        fine,
        sphere,
        clusterSphere,
        children,
        parents,
        delta,
        roots,
        baseTriangles,
        totalTriangles,
        fullResolutionError: ext.fullResolutionError ?? 0,
    };
}

/// The error bound of cluster c in metres: its producer's error, or fullResolutionError at level 0.
export function clusterError(dag, c) {
    return dag.producer[c] >= 0 ? dag.error[dag.producer[c]] : dag.fullResolutionError;
}

// ------------------------------------------------------------------------------------------------
// the passes of schema/README.md "Selecting a cut" and "Streaming"

/// Pass 1: makes an arbitrary set of refined groups (Uint8Array, 1 = refined) closed upward, in
/// one pass children first (schema/README.md: refined[g] = P(g) or some child of g refined);
/// written here as "a refined group marks its parents", which visits the same groups in the same
/// order and gives the same set.
export function closeUpward(dag, refined) {
    for (let g = 0; g < dag.ng; ++g) {
        if (refined[g]) {
            for (const p of dag.parents[g]) refined[p] = 1;
        }
    }
    return refined;
}

/// Pass 2 (streaming): parents first, a group whose consumed clusters are not all loaded is not
/// refined, and then neither are its children. isLoaded(c) -> bool.
export function restrictToLoaded(dag, refined, isLoaded) {
    for (let g = dag.ng - 1; g >= 0; --g) {
        if (refined[g] && !dag.groups[g].consumed.every((c) => isLoaded(c))) {
            refined[g] = 0;
        }
        if (!refined[g]) {
            for (const child of dag.children[g]) refined[child] = 0;
        }
    }
    return refined;
}

/// True when the set is closed upward (every parent of a refined group is refined).
export function isClosedUpward(dag, refined) {
    for (let g = 0; g < dag.ng; ++g) {
        if (refined[g] && dag.parents[g].some((p) => !refined[p])) return false;
    }
    return true;
}

/// The stateless rule: the clusters to draw for a set of refined groups.
export function drawnClusters(dag, refined) {
    const out = [];
    for (let c = 0; c < dag.nc; ++c) {
        const p = dag.producer[c];
        const q = dag.consumer[c];
        if ((p < 0 || !refined[p]) && (q < 0 || refined[q])) out.push(c);
    }
    return out;
}

/// The refined set of a per-group predicate P(g) (closed upward, optionally restricted to loaded
/// clusters), and the clusters it draws.
export function cutForPredicate(dag, predicate, isLoaded = null) {
    const refined = new Uint8Array(dag.ng);
    for (let g = 0; g < dag.ng; ++g) refined[g] = predicate(g) ? 1 : 0;
    closeUpward(dag, refined);
    if (isLoaded !== null) restrictToLoaded(dag, refined, isLoaded);
    return { refined, drawn: drawnClusters(dag, refined) };
}

// ------------------------------------------------------------------------------------------------
// screen-space error

/// view: { position: [x, y, z] (scene frame, metres), heightPx, fovy (radians) } for a
/// perspective camera, or { orthographic: true, viewHeight (metres), heightPx }.
/// Optional view.frustum: six planes [nx, ny, nz, d], normals pointing inside (a point p is
/// inside a plane when n.p + d >= 0).
/// Returns error (metres) projected to pixels at the distance of sphere [x, y, z, r] (3D Tiles):
/// error * heightPx / (d * 2 tan(fovy / 2)), d = max(0, |camera - centre| - r); Infinity at d = 0.
export function screenSpaceError(error, sphere, view, offset = 0) {
    if (view.orthographic) {
        return (error * view.heightPx) / view.viewHeight;
    }
    const dx = view.position[0] - sphere[offset];
    const dy = view.position[1] - sphere[offset + 1];
    const dz = view.position[2] - sphere[offset + 2];
    const d = Math.sqrt(dx * dx + dy * dy + dz * dz) - sphere[offset + 3];
    if (!(d > 0)) {
        return error > 0 ? Infinity : 0;
    }
    return (error * view.heightPx) / (d * 2 * Math.tan(view.fovy / 2));
}

/// Screen-space error of group g: its bound against the finest level at its sphere (how far the
/// rest of the refinement below g can still move the surface on screen).
export function groupScreenSpaceError(dag, g, view) {
    return screenSpaceError(dag.fine[g], dag.sphere, view, 4 * g);
}

/// Does sphere (at offset in array s) meet the view frustum?
export function sphereInFrustum(s, offset, frustum) {
    if (!frustum) return true;
    for (const [nx, ny, nz, d] of frustum) {
        if (nx * s[offset] + ny * s[offset + 1] + nz * s[offset + 2] + d < -s[offset + 3]) return false;
    }
    return true;
}

/// Do sphere (array s at offset) and roi { center: [x, y, z], radius } meet?
export function sphereMeetsRoi(s, offset, roi) {
    const dx = s[offset] - roi.center[0];
    const dy = s[offset + 1] - roi.center[1];
    const dz = s[offset + 2] - roi.center[2];
    const r = s[offset + 3] + roi.radius;
    return dx * dx + dy * dy + dz * dz <= r * r;
}

/// The threshold factor of group g: 1, or roi.factor (> 1) when its sphere meets the region of
/// interest. sse(g) / (tauPx / factor) > 1 is the refinement predicate. Since a parent's sphere
/// contains its children's, a parent meets the region whenever a child does, so the threshold
/// does not increase from a group to its parents and the predicate stays closed upward.
function roiFactor(dag, g, roi) {
    return roi && roi.factor > 1 && sphereMeetsRoi(dag.sphere, 4 * g, roi) ? roi.factor : 1;
}

// ------------------------------------------------------------------------------------------------
// the viewer's cut

/// A binary max-heap on (key, tie) pairs with payloads.
class MaxHeap {
    constructor() {
        this.items = [];
    }

    get size() {
        return this.items.length;
    }

    static before(a, b) {
        return a.key > b.key || (a.key === b.key && a.tie < b.tie);
    }

    push(item) {
        const items = this.items;
        items.push(item);
        let i = items.length - 1;
        while (i > 0) {
            const parent = (i - 1) >> 1;
            if (!MaxHeap.before(items[i], items[parent])) break;
            [items[i], items[parent]] = [items[parent], items[i]];
            i = parent;
        }
    }

    pop() {
        const items = this.items;
        const top = items[0];
        const last = items.pop();
        if (items.length > 0) {
            items[0] = last;
            let i = 0;
            for (;;) {
                const l = 2 * i + 1;
                const r = l + 1;
                let best = i;
                if (l < items.length && MaxHeap.before(items[l], items[best])) best = l;
                if (r < items.length && MaxHeap.before(items[r], items[best])) best = r;
                if (best === i) break;
                [items[i], items[best]] = [items[best], items[i]];
                i = best;
            }
        }
        return top;
    }
}

/// Selects the cut of one or several objects (DAGs in the same scene frame) together:
///
///   ratio(g) = sse(g) * factor(g) / tauPx     (factor: roi.factor inside the region of interest)
///   priority(g) = max(ratio(g), priority of every child of g)   (0 outside the frustum)
///
/// The priority is the upward closure of the predicate ratio > 1 (a group is wanted when it or
/// any group below it is), so it never increases from a group to its parents. Starting from the
/// base (no group refined), groups are refined in order of decreasing priority, a group becoming
/// a candidate once all its parents are refined (so the refined set stays closed upward at every
/// step), while priority > 1 and the triangle budget allows:
///   * a candidate whose consumed clusters are not all loaded is not refined (its produced
///     clusters stay drawn, its children are never reached) and its missing clusters are
///     reported in `wanted`, with the priority;
///   * the first candidate that does not fit the budget ends the refinement (the cut is then the
///     longest prefix of the order that fits, so it grows monotonically with the budget and
///     shrinks monotonically with tau).
///
/// dags: array of DAGs (buildDag); view: see screenSpaceError; options:
///   tauPx (default 1), budget (triangles over all DAGs, base included; default Infinity),
///   roi: { center, radius, factor } or null, cull (default true: use view.frustum when given),
///   isLoaded(dagIndex, cluster) -> bool (default: everything loaded),
///   morphK (default 2): geomorph weights w(g) = clamp((k - ratio) / (k - 1), 0, 1) (schema/README.md),
///   prefetch (default false): also report, after the missing clusters of a candidate that cannot
///     be refined, those of the groups below it that the predicate would refine once it is
///     (priority > 1, in priority order), so that a viewer can fetch the levels of a view in one
///     round instead of one level per round trip; they do not change the cut.
/// Returns { cuts: per DAG { refined, drawn, ratio, weight }, wanted: [{ dag, cluster, priority }]
/// (best first), triangles, budgetLimited, refinedCount }.
export function selectCut(dags, view, options = {}) {
    const tau = options.tauPx ?? 1;
    const budget = options.budget ?? Infinity;
    const roi = options.roi ?? null;
    const frustum = options.cull === false ? null : (view.frustum ?? null);
    const isLoaded = options.isLoaded ?? null;
    const k = options.morphK ?? 2;
    const heap = new MaxHeap();
    let triangles = 0;
    const cuts = dags.map((dag, di) => {
        const ratio = new Float64Array(dag.ng);
        const priority = new Float64Array(dag.ng);
        for (let g = 0; g < dag.ng; ++g) {
            let r = 0;
            if (sphereInFrustum(dag.sphere, 4 * g, frustum)) {
                r = (groupScreenSpaceError(dag, g, view) * roiFactor(dag, g, roi)) / tau;
            }
            ratio[g] = r;
            let p = r;
            for (const child of dag.children[g]) p = Math.max(p, priority[child]);
            priority[g] = p;
        }
        triangles += dag.baseTriangles;
        // candidates: groups without parents (their produced clusters are root clusters)
        const waiting = Int32Array.from(dag.parents, (list) => list.length);
        for (let g = 0; g < dag.ng; ++g) {
            if (waiting[g] === 0) heap.push({ key: priority[g], tie: di * 1e9 + (dag.ng - g), dag: di, g });
        }
        return {
            refined: new Uint8Array(dag.ng),
            ratio,
            priority,
            waiting,
            weight: new Float64Array(dag.ng),
            speculative: null,
        };
    });
    const prefetch = options.prefetch === true && isLoaded !== null;
    // a group reached by prefetching only (a parent not refined): its children are reached too
    const speculate = (di, g) => {
        const dag = dags[di];
        const cut = cuts[di];
        cut.speculative ??= new Uint8Array(dag.ng);
        cut.speculative[g] = 1;
        for (const child of dag.children[g]) {
            if (--cut.waiting[child] === 0) {
                heap.push({ key: cut.priority[child], tie: di * 1e9 + (dag.ng - child), dag: di, g: child });
            }
        }
    };
    const wanted = [];
    let budgetLimited = false;
    let refinedCount = 0;
    while (heap.size > 0) {
        const { key, dag: di, g } = heap.pop();
        if (!(key > 1)) break;
        const dag = dags[di];
        const cut = cuts[di];
        const consumed = dag.groups[g].consumed;
        const speculative = prefetch && dag.parents[g].some((p) => cut.speculative?.[p]);
        if (isLoaded !== null) {
            const missing = consumed.filter((c) => !isLoaded(di, c));
            if (missing.length > 0 || speculative) {
                for (const c of missing) wanted.push({ dag: di, cluster: c, priority: key });
                if (prefetch && !budgetLimited) speculate(di, g);
                continue;
            }
        }
        if (triangles + dag.delta[g] > budget) {
            budgetLimited = true;
            break;
        }
        triangles += dag.delta[g];
        cut.refined[g] = 1;
        ++refinedCount;
        for (const child of dag.children[g]) {
            if (--cut.waiting[child] === 0) {
                heap.push({ key: cut.priority[child], tie: di * 1e9 + (dag.ng - child), dag: di, g: child });
            }
        }
    }
    for (const [di, dag] of dags.entries()) {
        const cut = cuts[di];
        for (let g = 0; g < dag.ng; ++g) {
            // weight of the clusters consumed by g while g is refined: 1 at the threshold
            // (ratio = 1), 0 from ratio = k on; parents' priorities are >= their children's.
            const r = cut.priority[g];
            cut.weight[g] = cut.refined[g] ? Math.min(1, Math.max(0, (k - r) / (k - 1))) : 0;
        }
        cut.drawn = drawnClusters(dag, cut.refined);
        delete cut.waiting;
        delete cut.speculative;
    }
    return { cuts, wanted, triangles, budgetLimited, refinedCount };
}

/// Statistics of a cut of one DAG: triangles, the largest error bound of the drawn clusters
/// (metres, against the slices), the largest bound against the finest level (metres) and that
/// bound projected (pixels; each cluster's producer's bound at its sphere, 0 for level 0: what
/// the viewer's tau limits; only clusters in the frustum).
export function cutStats(dag, drawn, view) {
    let triangles = 0;
    let maxError = 0;
    let maxFineError = 0;
    let maxErrorPx = 0;
    const frustum = view?.frustum ?? null;
    for (const c of drawn) {
        triangles += dag.triangles[c];
        maxError = Math.max(maxError, clusterError(dag, c));
        const p = dag.producer[c];
        if (p < 0) continue;
        maxFineError = Math.max(maxFineError, dag.fine[p]);
        if (view && sphereInFrustum(dag.clusterSphere, 4 * c, frustum)) {
            maxErrorPx = Math.max(maxErrorPx, screenSpaceError(dag.fine[p], dag.sphere, view, 4 * p));
        }
    }
    return { triangles, maxError, maxFineError, maxErrorPx };
}

/// Sets the triangle count of cluster c (known once its chunk or the base is decoded) and keeps
/// the per-group deltas and the totals in step.
export function setClusterTriangles(dag, c, triangles) {
    const old = dag.triangles[c];
    if (old === triangles) return;
    dag.triangles[c] = triangles;
    dag.totalTriangles += triangles - old;
    if (dag.consumer[c] >= 0) dag.delta[dag.consumer[c]] += triangles - old;
    if (dag.producer[c] >= 0) dag.delta[dag.producer[c]] -= triangles - old;
    if (dag.consumer[c] < 0) dag.baseTriangles += triangles - old;
}

// Small, dependency-free helpers for glTF files (no DOM, no three.js): the GLB container layout
// and the parts of the JSON the progressive viewer needs. Used by strata-progressive.js in the
// browser and by the Node tests.

import { kDraco, kExtension, kGlb } from './strata-format.js';

/// Reads the GLB header and the JSON chunk header from the first bytes of a file
/// (at least 20). Returns null when the bytes are not a GLB, else
/// { length, jsonOffset, jsonLength, binOffset } where binOffset is the offset of the BIN chunk's
/// data (valid when the file has one: jsonOffset + jsonLength + 8).
export function glbLayout(bytes) {
    if (bytes.byteLength < 20) return null;
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    if (view.getUint32(0, true) !== kGlb.magic) return null;
    if (view.getUint32(4, true) !== kGlb.version) throw new Error(`GLB version ${view.getUint32(4, true)}, not 2`);
    const length = view.getUint32(8, true);
    const jsonLength = view.getUint32(12, true);
    if (view.getUint32(16, true) !== kGlb.chunkJson) throw new Error('GLB: the first chunk is not JSON');
    const jsonOffset = 20;
    return { length, jsonOffset, jsonLength, binOffset: jsonOffset + jsonLength + 8 };
}

/// Splits a whole GLB file: { json, bin: Uint8Array | null }.
export function parseGlb(bytes) {
    const layout = glbLayout(bytes);
    if (layout === null) throw new Error('not a GLB file');
    const json = JSON.parse(
        new TextDecoder().decode(bytes.subarray(layout.jsonOffset, layout.jsonOffset + layout.jsonLength)),
    );
    let bin = null;
    const binHeader = layout.jsonOffset + layout.jsonLength;
    if (binHeader + 8 <= bytes.byteLength) {
        const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
        const binLength = view.getUint32(binHeader, true);
        if (view.getUint32(binHeader + 4, true) === kGlb.chunkBin) {
            bin = bytes.subarray(binHeader + 8, binHeader + 8 + binLength);
        }
    }
    return { json, bin };
}

/// The nodes that carry the extension: [{ nodeIndex, node, ext }].
export function progressiveNodes(json, extensionName = kExtension) {
    return (json.nodes ?? [])
        .map((node, nodeIndex) => ({ nodeIndex, node, ext: node.extensions?.[extensionName] }))
        .filter((o) => o.ext !== undefined && o.node.mesh !== undefined);
}

/// Every bufferView a mesh needs (accessors' bufferViews and Draco bufferViews).
export function meshBufferViews(json, meshIndex) {
    const views = new Set();
    for (const primitive of json.meshes?.[meshIndex]?.primitives ?? []) {
        const draco = primitive.extensions?.[kDraco];
        if (draco !== undefined) {
            views.add(draco.bufferView);
            continue;
        }
        for (const accessor of [...Object.values(primitive.attributes ?? {}), primitive.indices]) {
            const view = json.accessors?.[accessor]?.bufferView;
            if (view !== undefined) views.add(view);
        }
    }
    return [...views];
}

/// Byte ranges [start, end) that cover the given bufferViews of one buffer, merging views whose
/// gap is at most maxGap bytes; each range lists its views. views: bufferView indices.
export function coalesceRanges(json, views, maxGap = 0, maxLength = Infinity) {
    const items = views
        .map((v) => {
            const def = json.bufferViews[v];
            const start = def.byteOffset ?? 0;
            return { view: v, buffer: def.buffer, start, end: start + def.byteLength };
        })
        .sort((a, b) => a.buffer - b.buffer || a.start - b.start);
    const ranges = [];
    for (const item of items) {
        const last = ranges[ranges.length - 1];
        if (
            last !== undefined &&
            last.buffer === item.buffer &&
            item.start - last.end <= maxGap &&
            Math.max(last.end, item.end) - last.start <= maxLength
        ) {
            last.end = Math.max(last.end, item.end);
            last.views.push(item.view);
        } else {
            ranges.push({ buffer: item.buffer, start: item.start, end: item.end, views: [item.view] });
        }
    }
    return ranges;
}

/// The distinct bytes fetched of each file: a set of disjoint [start, end) intervals per key (URL),
/// so that bytes fetched twice (a range overlapping an earlier one) are counted once.
export class ByteCoverage {
    constructor() {
        this.files = new Map(); // key -> sorted disjoint [start, end) pairs
        this.size = 0;
    }

    /// Adds [start, end) of key; returns the number of bytes not covered before.
    add(key, start, end) {
        if (!(end > start)) return 0;
        const list = this.files.get(key) ?? [];
        let added = end - start;
        const out = [];
        let lo = start;
        let hi = end;
        for (const [a, b] of list) {
            if (b < lo || a > hi) {
                out.push([a, b]);
                continue;
            }
            added -= Math.max(0, Math.min(b, end) - Math.max(a, start)); // overlap with [start, end)
            lo = Math.min(lo, a);
            hi = Math.max(hi, b);
        }
        out.push([lo, hi]);
        out.sort((x, y) => x[0] - y[0]);
        this.files.set(key, out);
        this.size += added;
        return added;
    }

    /// The bytes of [start, end) of key already covered.
    overlap(key, start, end) {
        let covered = 0;
        for (const [a, b] of this.files.get(key) ?? []) covered += Math.max(0, Math.min(b, end) - Math.max(a, start));
        return covered;
    }
}

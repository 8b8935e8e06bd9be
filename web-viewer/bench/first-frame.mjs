#!/usr/bin/env node
// Benchmark (not a test): bytes and time to the first frame, and frame times while refining, of
// strata's progressive model against the same surfaces as one single-rate Draco .glb, in the same
// page (index.html) in headless Chromium (Debian's chromium, software WebGL).
//
//   node web-viewer/bench/first-frame.mjs OUT [--gltf OUT_GLTF] [--throttle MBIT,RTT_MS] [--runs N]
//        [--viewport WxH] [--json FILE] [--no-zoom] [--cache cold|warm|both] [--tau PX] [--no-compress]
//        [--refine finest|data]
//
// OUT: a folder written by `strata build` (OUT/model.glb, the progressive model, and OUT/scene.glb,
// the full-resolution plain glTF). --gltf: a folder written with `--model-format gltf` from the
// same input (its model.gltf is measured too, streaming by Range requests of the level files).
// The single-rate Draco .glb is made here from OUT/scene.glb with glTF-Transform's draco()
// (Edgebreaker, its default quantization: 14-bit positions, 10-bit normals).
// The single-rate file is loaded as a single-rate viewer loads it: one request for the whole file,
// sent from the page's first script as the progressive model's first range is (index.html ?whole).
// Each variant runs in a fresh browser profile, on the same viewport and camera (the viewer's
// fitted anterior view), the viewer's default tau (--tau PX) bounding the plugin's default measure (--refine:
// its refineOn, selection.js buildDag), the default triangle budget, in two cache states
// (--cache, default both):
//   cold          nothing cached: the page, three.js (as npm ships it, unminified, sent
//                 brotli-compressed by serve.mjs as a web server does; --no-compress: as they
//                 are), the Draco decoder and the model all come over the emulated link;
//   warm          a returning visitor: the page, its modules and the Draco decoder are in the
//                 browser's cache (one visit of the page without a model before; the viewer's
//                 files are served with max-age), the model is not;
// and for each the times of the steps before the first frame (User Timing marks of viewer.js and
// strata-progressive.js, Resource Timing of three.js, the decoder and the model):
//   first frame   ms from navigation to the first frame that shows the model; model bytes then
//   refined       ms until nothing is loading or queued (progressive) ; model bytes then
//   redraw        intervals between drawn frames from the first frame to the refined state
//                 (the page draws on demand: when the cut changed), median, 95th percentile, max
//   zoom in       the camera dollied to 40 % of the distance: ms until refined, bytes, triangles,
//                 redraw intervals meanwhile
//   longest frame gap: the longest interval between animation frames (main thread busy)
// --throttle 20,40 emulates a 20 Mbit/s link with 40 ms round trips (Chrome DevTools protocol),
// since on the loopback bytes cost almost nothing.
import { existsSync, mkdtempSync, readdirSync, rmSync, statSync, symlinkSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { startServer } from '../serve.mjs';
import { chromiumMissing, launchChromium } from '../chromium.mjs';
import { parseThrottle, throttlePage, visitUntilDecoder } from './link.mjs';

function usage(message) {
    if (message) console.error(`first-frame: ${message}`);
    console.error(
        'usage: node web-viewer/bench/first-frame.mjs OUT [--gltf OUT_GLTF] [--throttle MBIT,RTT_MS] [--runs N] [--viewport WxH] [--json FILE] [--no-zoom] [--cache cold|warm|both] [--tau PX] [--no-compress] [--refine finest|data]',
    );
    process.exit(2);
}

function parseArgs(args) {
    const options = {
        out: null,
        gltf: null,
        throttle: null,
        runs: 1,
        viewport: { width: 960, height: 640 },
        json: null,
        zoom: true,
        caches: ['cold', 'warm'],
        tau: null, // the viewer's default
        compress: true, // serve.mjs compresses the viewer's files (never the models)
        refine: null, // the plugin's default refineOn
    };
    for (let i = 0; i < args.length; ++i) {
        const arg = args[i];
        if (arg === '--gltf') options.gltf = args[++i];
        else if (arg === '--throttle') {
            options.throttle = parseThrottle(args[++i]);
            if (!options.throttle) usage('--throttle MBIT,RTT_MS');
        } else if (arg === '--runs') options.runs = Number(args[++i]);
        else if (arg === '--viewport') {
            const [width, height] = (args[++i] ?? '').split('x').map(Number);
            options.viewport = { width, height };
        } else if (arg === '--json') options.json = args[++i];
        else if (arg === '--no-zoom') options.zoom = false;
        else if (arg === '--cache') {
            const c = args[++i];
            if (!['cold', 'warm', 'both'].includes(c)) usage('--cache cold|warm|both');
            options.caches = c === 'both' ? ['cold', 'warm'] : [c];
        } else if (arg === '--tau') {
            options.tau = Number(args[++i]);
            if (!(options.tau > 0)) usage('--tau PX (> 0)');
        } else if (arg === '--no-compress') options.compress = false;
        else if (arg === '--refine') {
            options.refine = args[++i];
            if (!['finest', 'data'].includes(options.refine)) usage('--refine finest|data');
        } else if (arg.startsWith('-')) usage(`unknown option ${arg}`);
        else if (options.out === null) options.out = arg;
        else usage('one OUT folder');
    }
    if (options.out === null) usage('no OUT folder');
    for (const f of ['model.glb', 'scene.glb']) {
        if (!existsSync(join(options.out, f))) usage(`${join(options.out, f)} not found`);
    }
    if (options.gltf && !existsSync(join(options.gltf, 'model.gltf')))
        usage(`${join(options.gltf, 'model.gltf')} not found`);
    return options;
}

/// OUT/scene.glb -> single-rate Draco .glb (glTF-Transform draco(), Edgebreaker).
async function makeDracoGlb(sceneGlb, target) {
    const { NodeIO } = await import('@gltf-transform/core');
    const { KHRONOS_EXTENSIONS } = await import('@gltf-transform/extensions');
    const { draco } = await import('@gltf-transform/functions');
    const draco3d = (await import('draco3d')).default;
    const io = new NodeIO().registerExtensions(KHRONOS_EXTENSIONS).registerDependencies({
        'draco3d.decoder': await draco3d.createDecoderModule(),
        'draco3d.encoder': await draco3d.createEncoderModule(),
    });
    const document = await io.read(sceneGlb);
    await document.transform(draco({ method: 'edgebreaker' }));
    await io.write(target, document);
    let triangles = 0;
    for (const mesh of document.getRoot().listMeshes()) {
        for (const p of mesh.listPrimitives())
            triangles += (p.getIndices()?.getCount() ?? p.getAttribute('POSITION').getCount()) / 3;
    }
    return triangles;
}

function quantiles(values) {
    if (values.length === 0) return { n: 0, median: null, p95: null, max: null };
    const sorted = [...values].sort((a, b) => a - b);
    const at = (q) => sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
    return { n: values.length, median: at(0.5), p95: at(0.95), max: sorted[sorted.length - 1] };
}

/// The steps before the first frame, ms from the navigation: the viewer's module running (page,
/// three.js and our modules loaded), the Draco decoder's bytes, the model's first response, the
/// glTF parsed up to the plugin's afterRoot (base bytes fetched and Draco-decoded), the plugin's
/// setup done, the model shown (scene built), the first frame drawn.
function breakdownInPage() {
    const mark = (name) => performance.getEntriesByName(name, 'mark')[0]?.startTime ?? null;
    const resources = performance.getEntriesByType('resource');
    const end = (re) => {
        const e = resources.filter((r) => re.test(new URL(r.name).pathname));
        return e.length ? Math.max(...e.map((r) => r.responseEnd)) : null;
    };
    const model = resources
        .filter((r) => new URL(r.name).pathname.startsWith('/model/'))
        .sort((a, b) => a.startTime - b.startTime);
    return {
        three: end(/three\.(core|module)\.js$/),
        decoder: end(/draco_decoder\.wasm$/),
        modules: mark('strata:viewer-module'),
        modelRequest: model[0]?.startTime ?? null,
        modelResponse: model[0]?.responseEnd ?? null,
        decoded: mark('strata:after-root'),
        setup: mark('strata:setup-done'),
        shown: mark('strata:shown'),
        firstFrame: mark('strata:first-frame'),
        // bytes of the viewer's own files over the link (0 from the cache), and uncompressed
        pageBytes: resources
            .filter((r) => !new URL(r.name).pathname.startsWith('/model/'))
            .reduce((s, r) => s + r.transferSize, 0),
        pageBodyBytes: resources
            .filter((r) => !new URL(r.name).pathname.startsWith('/model/'))
            .reduce((s, r) => s + r.decodedBodySize, 0),
    };
}

async function measure(url, options, label, { cache, base }) {
    const browser = await launchChromium({ viewport: options.viewport });
    const errors = [];
    try {
        const page = await browser.context.newPage();
        page.on('pageerror', (e) => errors.push(e.message));
        page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
        if (options.throttle) await throttlePage(browser.context, page, options.throttle);
        if (cache === 'warm') {
            // the returning visitor: the page without a model, until its decoder has arrived
            await visitUntilDecoder(page, base);
            await page.waitForTimeout(500);
        }
        await page.goto(url);
        const ok = await page.evaluate(() => window.strataViewer.ready);
        if (!ok) throw new Error(`${label}: the page did not load the model: ${errors.join('; ')}`);
        await page.evaluate(() => window.strataViewer.idle(600000, 3));
        const first = await page.evaluate(() => {
            const v = window.strataViewer;
            const t = v.timing;
            return {
                state: v.state(),
                firstFrameMs: t.firstFrame,
                loadStartMs: t.loadStart,
                refinedMs: t.refined,
                firstBytes: v.modelBytes(t.firstFrame),
                refinedBytes: v.modelBytes(t.refined),
                stamps: v.renderStamps.filter((x) => x >= t.firstFrame && x <= t.refined),
                ticks: v.tickTimes.slice(),
            };
        });
        first.steps = await page.evaluate(breakdownInPage);
        // draw calls and main-thread ms of one frame of the settled view (redrawn: the next frame
        // draws the same picture again)
        first.drawCalls = await page.evaluate(async () => {
            const v = window.strataViewer;
            v.redraw();
            await v.nextFrame();
            return v.renderer.info.render.calls;
        });
        // zoom in
        const zoom = !options.zoom
            ? { ms: null, bytes: 0, requests: 0, stamps: [], ticks: [], state: { triangles: null } }
            : await page.evaluate(async () => {
                  const v = window.strataViewer;
                  const before = v.modelBytes();
                  const start = performance.now();
                  v.tickTimes.length = 0;
                  v.dolly(0.4);
                  await v.idle(600000, 3);
                  const end = performance.now();
                  const after = v.modelBytes();
                  return {
                      ms: end - start,
                      bytes: after.bytes - before.bytes,
                      requests: after.requests - before.requests,
                      stamps: v.renderStamps.filter((x) => x >= start && x <= end),
                      ticks: v.tickTimes.slice(),
                      state: v.state(),
                  };
              });
        const intervals = (stamps) => stamps.slice(1).map((x, i) => x - stamps[i]);
        return {
            label,
            cache,
            steps: first.steps,
            triangles: first.state.triangles,
            firstFrameMs: first.firstFrameMs,
            loadStartMs: first.loadStartMs,
            firstFrameBytes: first.firstBytes.bytes,
            firstFrameRequests: first.firstBytes.requests,
            refinedMs: first.refinedMs,
            refinedBytes: first.refinedBytes.bytes,
            refinedRequests: first.refinedBytes.requests,
            refiningFrames: quantiles(intervals(first.stamps)),
            loadTicks: quantiles(first.ticks),
            maxErrorPx: first.state.maxErrorPx,
            drawCalls: first.drawCalls,
            maxErrorMm: first.state.maxErrorMm,
            zoom: {
                ms: zoom.ms,
                bytes: zoom.bytes,
                requests: zoom.requests,
                triangles: zoom.state.triangles,
                frames: quantiles(intervals(zoom.stamps)),
                ticks: quantiles(zoom.ticks),
            },
            totalBytes: first.state.bytesTotal,
            errors,
        };
    } finally {
        await browser.close();
    }
}

function fmtMs(x) {
    return x === null || x === undefined ? '-' : `${Math.round(x)}`;
}

function fmtMB(x) {
    return `${(x / 1e6).toFixed(2)}`;
}

async function main() {
    const options = parseArgs(process.argv.slice(2));
    const missing = chromiumMissing();
    if (missing) usage(missing);
    const dir = mkdtempSync(join(tmpdir(), 'strata-bench-'));
    try {
        // one folder with every variant (the server serves the model's folder)
        const link = (source, name) => symlinkSync(resolve(source), join(dir, name));
        link(join(options.out, 'model.glb'), 'model.glb');
        const variants = [
            {
                label: 'progressive .glb (ranges)',
                file: 'model.glb',
                query: options.refine === null ? '' : `&refine=${options.refine}`,
            },
            {
                label: 'progressive, all refined',
                file: 'model.glb',
                query: '&tau=0.000001&budget=1000000000',
                full: true,
            },
        ];
        if (options.gltf) {
            for (const f of readdirSync(options.gltf)) {
                if (/^model\.(gltf|.*bin)$/.test(f)) link(join(options.gltf, f), f);
            }
            variants.push({ label: 'progressive .gltf (ranges)', file: 'model.gltf' });
        }
        console.error('first-frame: making the single-rate Draco .glb with glTF-Transform ...');
        const t0 = performance.now();
        const dracoTriangles = await makeDracoGlb(join(options.out, 'scene.glb'), join(dir, 'single-draco.glb'));
        console.error(
            `first-frame: single-draco.glb ${statSync(join(dir, 'single-draco.glb')).size} bytes, ` +
                `${dracoTriangles} triangles (${Math.round(performance.now() - t0)} ms)`,
        );
        variants.push({ label: 'single-rate Draco .glb', file: 'single-draco.glb', query: '&whole' });
        const server = await startServer({
            model: join(dir, 'model.glb'),
            port: 0,
            viewerMaxAge: 3600,
            compress: options.compress,
        });
        const base = server.url.replace(/\?.*$/, '');
        {
            // one visit of the page, unthrottled and not measured, so that the server has compressed
            // the viewer's files before the first measured visit (as a static host stores them)
            const browser = await launchChromium({ viewport: options.viewport });
            try {
                const page = await browser.context.newPage();
                await visitUntilDecoder(page, base);
            } finally {
                await browser.close();
            }
        }
        const results = [];
        try {
            for (let run = 0; run < options.runs; ++run) {
                for (const cache of options.caches) {
                    for (const variant of variants) {
                        const url =
                            `${base}?model=model/${encodeURIComponent(variant.file)}&aa=0` +
                            (variant.full || options.tau === null ? '' : `&tau=${options.tau}`) +
                            (variant.query ?? '');
                        console.error(`first-frame: ${variant.label}, ${cache}, run ${run + 1} ...`);
                        const r = await measure(
                            url,
                            variant.full ? { ...options, zoom: false } : options,
                            variant.label,
                            {
                                cache,
                                base,
                            },
                        );
                        r.full = variant.full ?? false;
                        r.run = run;
                        r.fileBytes = statSync(join(dir, variant.file)).size;
                        results.push(r);
                    }
                }
            }
        } finally {
            await server.close();
        }
        const net = options.throttle
            ? `${options.throttle.mbit} Mbit/s, ${options.throttle.rtt} ms RTT (emulated)`
            : 'loopback, unthrottled';
        console.log(
            `model: ${resolve(options.out)}; network: ${net}; viewport ${options.viewport.width}x${options.viewport.height}; ` +
                `tau ${options.tau ?? "the viewer's default"} px${options.refine ? ` on '${options.refine}'` : ''}; viewer files ${options.compress ? 'compressed (br)' : 'uncompressed'}; ` +
                'Chromium software WebGL (SwiftShader)',
        );
        console.log(
            'variant                    | cache | file MB | 1st frame ms | MB at 1st | tris at rest | draw calls | refined ms | MB refined | redraw ms med/p95/max (n) | zoom in: ms, MB, tris | redraw ms med/p95/max (n) | longest frame gap ms',
        );
        for (const r of results) {
            const f = r.refiningFrames;
            const z = r.zoom;
            console.log(
                `${r.label.padEnd(26)} | ${r.cache.padEnd(5)} | ${fmtMB(r.fileBytes).padStart(7)} | ${fmtMs(r.firstFrameMs).padStart(12)} | ` +
                    `${fmtMB(r.firstFrameBytes).padStart(9)} | ${String(r.triangles).padStart(12)} | ${String(r.drawCalls).padStart(10)} | ${fmtMs(r.refinedMs).padStart(10)} | ` +
                    `${fmtMB(r.refinedBytes).padStart(10)} | ${fmtMs(f.median)}/${fmtMs(f.p95)}/${fmtMs(f.max)} (${f.n}) | ` +
                    `${fmtMs(z.ms)}, ${fmtMB(z.bytes)}, ${z.triangles} | ${fmtMs(z.frames.median)}/${fmtMs(z.frames.p95)}/${fmtMs(z.frames.max)} (${z.frames.n}) | ` +
                    `${fmtMs(Math.max(r.loadTicks.max ?? 0, z.ticks.max ?? 0))}` +
                    (r.errors.length ? `  ERRORS: ${r.errors.slice(0, 2).join('; ')}` : ''),
            );
        }
        console.log(
            'steps before the first frame, ms from the navigation (three.js and decoder: bytes arrived; modules: viewer.js running; ' +
                "model: first request sent, first response complete; decoded: the base fetched and Draco-decoded, the plugin's afterRoot; " +
                'setup: the plugin ready; shown: the scene built; first frame drawn)',
        );
        console.log(
            'variant                    | cache | page MB (unpacked) | three.js | decoder | modules | model req | model resp | decoded | setup | shown | 1st frame',
        );
        for (const r of results.filter((x) => !x.full)) {
            const t = r.steps;
            console.log(
                `${r.label.padEnd(26)} | ${r.cache.padEnd(5)} | ${`${fmtMB(t.pageBytes)} (${fmtMB(t.pageBodyBytes)})`.padStart(18)} | ${fmtMs(t.three).padStart(8)} | ${fmtMs(t.decoder).padStart(7)} | ` +
                    `${fmtMs(t.modules).padStart(7)} | ${fmtMs(t.modelRequest).padStart(9)} | ${fmtMs(t.modelResponse).padStart(10)} | ` +
                    `${fmtMs(t.decoded).padStart(7)} | ${fmtMs(t.setup).padStart(5)} | ${fmtMs(t.shown).padStart(5)} | ${fmtMs(t.firstFrame).padStart(9)}`,
            );
        }
        // the issue's targets, against the time to show the single-rate Draco file (its first
        // frame); times from the navigation (page and decoder included) and from the model's
        // first request (the viewer's own code, the same for every variant, excluded)
        for (let run = 0; run < options.runs; ++run) {
            for (const cache of options.caches) {
                const of = (label) => results.find((r) => r.label === label && r.run === run && r.cache === cache);
                const single = of('single-rate Draco .glb');
                const progressive = of('progressive .glb (ranges)');
                const full = of('progressive, all refined');
                for (const [name, zero] of [
                    ['from navigation', () => 0],
                    ['from the model request', (r) => r.loadStartMs],
                ]) {
                    const t = single.firstFrameMs - zero(single);
                    const ratio = (r, ms) => ((ms - zero(r)) / t).toFixed(2);
                    console.log(
                        `run ${run + 1}, ${cache}, ${name}: single-rate Draco shown at ${fmtMs(t)} ms (${fmtMB(single.fileBytes)} MB); ` +
                            `progressive first frame ${ratio(progressive, progressive.firstFrameMs)}x (target <= 0.25), ` +
                            `settled at tau ${options.tau ?? 'default'} ${ratio(progressive, progressive.refinedMs)}x (<= 1.0) with ` +
                            `${((100 * progressive.refinedBytes) / single.fileBytes).toFixed(0)} % of its bytes (< 60 %), ` +
                            `all refined ${ratio(full, full.refinedMs)}x (<= 1.6) with ${((100 * full.refinedBytes) / single.fileBytes).toFixed(0)} %, ` +
                            `${full.triangles} triangles (single-rate ${dracoTriangles})`,
                    );
                }
            }
        }
        if (options.json) writeFileSync(options.json, JSON.stringify({ options, results }, null, 2));
    } finally {
        rmSync(dir, { recursive: true, force: true });
    }
}

await main();

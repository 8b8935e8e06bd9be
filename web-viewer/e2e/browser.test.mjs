// node --test web-viewer/e2e/
// The viewer in headless Chromium (Debian's chromium, driven by playwright-core, offline): the
// page is served by serve.mjs on 127.0.0.1 with the model of STRATA_VIEWER_MODEL (a .glb or
// .gltf written by `strata build`; when unset, the test builds one: test/test-model.mjs).
//   * the first view frames the model: its pixels span most of the canvas the side panel leaves
//     free in width or in height; the HUD never says more than 100 % loaded;
//   * the model loads, streaming: the first view needs only part of the bytes;
//   * the canvas shows the objects: a substantial fraction of non-background pixels, and each
//     object drawn alone (its row's isolate button) shows its own colour (the swatch's hue), so
//     that an object enclosing the others (a structure set's BODY) passes too;
//   * zooming in (the test hook dollies the camera) loads chunks and raises the triangle count;
//     zooming out lowers it; a refinement geomorphs (some drawn clusters have 0 < w < 1);
//   * a region-of-interest click refines locally: the triangles in the region increase, every
//     group the region's factor refines has a sphere meeting the region (whatever the objects
//     around it), the HUD reports the region;
//   * no console errors, no failed requests.
// Screenshots go to STRATA_VIEWER_ARTIFACTS (default /tmp/strata-viewer-artifacts).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { mkdirSync } from 'node:fs';
import { join } from 'node:path';
import { startServer } from '../serve.mjs';
import { chromiumMissing, launchChromium } from '../chromium.mjs';
import { testModel } from '../test/test-model.mjs';

const kModel = testModel();
const kArtifacts = process.env.STRATA_VIEWER_ARTIFACTS ?? '/tmp/strata-viewer-artifacts';
// The first view at a coarse tau, so that zooming in has something to refine.
const kTau = 8;

test('the viewer streams, refines and coarsens the model in headless Chromium', { timeout: 120000 }, async (t) => {
    const missing = chromiumMissing();
    assert.equal(missing, null, missing ?? '');
    mkdirSync(kArtifacts, { recursive: true });
    const server = await startServer({ model: kModel, port: 0 });
    const browser = await launchChromium({ viewport: { width: 900, height: 640 } });
    const problems = [];
    try {
        const page = await browser.context.newPage();
        page.on('console', (message) => {
            if (message.type() === 'error') problems.push(`console error: ${message.text()}`);
        });
        page.on('pageerror', (error) => problems.push(`page error: ${error.message}`));
        page.on('requestfailed', (request) =>
            problems.push(`request failed: ${request.url()} ${request.failure()?.errorText}`),
        );
        page.on('response', (response) => {
            if (response.status() >= 400) problems.push(`HTTP ${response.status()} ${response.url()}`);
        });
        const hook = (fn, arg) => page.evaluate(fn, arg);
        // every state read also checks the loaded bytes: never more than the model has
        const state = async () => {
            const s = await hook(() => window.strataViewer.state());
            assert.ok(s.bytesLoaded <= s.bytesTotal, `loaded ${s.bytesLoaded} of ${s.bytesTotal} bytes`);
            const percent = /loaded .*\((\d+)%\)/.exec(s.hud);
            assert.ok(percent !== null && Number(percent[1]) <= 100, `the HUD says: ${s.hud}`);
            return s;
        };
        // the plugin's incremental normals, as drawn (each object's one draw geometry: what the GPU
        // got), against a recomputation over the whole drawn cut; and the draw geometry holds the
        // drawn clusters' triangles, no others (computeNormals overwrites the normals: the next
        // check compares with this state again)
        let normalsChecked = 0;
        let normalsIncremental = 0;
        const checkNormals = async (when) => {
            const r = await hook(() => {
                let worst = 0;
                let compared = 0;
                const problems = [];
                for (const c of window.strataViewer.strata.controllers) {
                    const geometry = c.drawMesh.geometry;
                    const drawnIndex = geometry.index.array.subarray(0, geometry.drawRange.count);
                    const drawnPosition = geometry.getAttribute('position').array;
                    const drawnNormal = geometry.getAttribute('normal').array;
                    c.computeNormals(c.drawn, null);
                    // the drawn clusters' triangles (as position triples, any order) and the fresh
                    // normal at each position (welded: one per position)
                    const key = (a, p) => `${a[p]},${a[p + 1]},${a[p + 2]}`;
                    const fresh = new Map();
                    const expected = [];
                    for (const k of c.drawn) {
                        const { chunk, range } = c.parts[k];
                        for (let i = range[0]; i < range[1]; i += 3) {
                            const t = [0, 1, 2].map((j) => 3 * chunk.index[i + j]);
                            for (const p of t) fresh.set(key(chunk.positions, p), chunk.normals.subarray(p, p + 3));
                            expected.push(t.map((p) => key(chunk.positions, p)).join('|'));
                        }
                    }
                    const drawnTriangles = [];
                    for (let i = 0; i < drawnIndex.length; i += 3) {
                        const t = [0, 1, 2].map((j) => 3 * drawnIndex[i + j]);
                        drawnTriangles.push(t.map((q) => key(drawnPosition, q)).join('|'));
                        for (const q of t) {
                            const b = fresh.get(key(drawnPosition, q));
                            if (b === undefined) continue; // a triangle not in the cut: reported below
                            worst = Math.max(
                                worst,
                                Math.hypot(b[0] - drawnNormal[q], b[1] - drawnNormal[q + 1], b[2] - drawnNormal[q + 2]),
                            );
                            ++compared;
                        }
                    }
                    expected.sort();
                    drawnTriangles.sort();
                    if (expected.length !== drawnTriangles.length || expected.some((t, i) => t !== drawnTriangles[i])) {
                        problems.push(
                            `${c.name}: the draw geometry's ${drawnTriangles.length} triangles are not the cut's ${expected.length}`,
                        );
                    }
                }
                return { worst, compared, problems, incremental: window.strataViewer.strata.stats.normalsIncremental };
            });
            assert.deepEqual(r.problems.slice(0, 5), [], `${when}: the draw geometries are not the cut`);
            normalsChecked += r.compared;
            normalsIncremental = r.incremental;
            assert.ok(r.worst < 1e-5, `${when}: the normals differ by ${r.worst} from a recomputation over the cut`);
        };
        const idle = async (when = null) => {
            assert.ok(await hook(() => window.strataViewer.idle(30000)), 'the viewer did not settle in 30 s');
            if (when !== null) await checkNormals(when);
        };
        const shot = async (name) => {
            const path = join(kArtifacts, `${name}.png`);
            await page.screenshot({ path });
            t.diagnostic(`screenshot ${path}`);
        };

        // a first request of 16 KiB: the default phantom's file is small enough that a larger
        // one would hold much of it, and zooming in would stream little
        // normals-full=1: the normals are always updated incrementally (over the part of the cut
        // that changed), which the checks at each settled view compare with a full recomputation
        await page.goto(`${server.url}&tau=${kTau}&prefix=16384&preserve&normals-full=1`);
        assert.ok(await hook(() => window.strataViewer.ready), 'the model did not load');
        await idle('first view');
        const first = await state();
        t.diagnostic(
            `first view: ${first.triangles} triangles, ${first.chunksLoaded}/${first.chunksTotal} chunks, ` +
                `${first.bytesLoaded}/${first.bytesTotal} bytes in ${first.requests} requests; ` +
                `first frame ${(first.timing.firstFrame - first.timing.loadStart).toFixed(0)} ms after the load started`,
        );
        assert.ok(first.objects.length > 0, 'no objects with STRATA_progressive_mesh');
        assert.ok(
            first.triangles > 0 && first.triangles === first.rendererTriangles,
            `triangles: selection ${first.triangles}, renderer ${first.rendererTriangles}`,
        );
        assert.ok(first.chunksLoaded < first.chunksTotal, 'the first coarse view loaded every chunk');
        assert.ok(
            first.bytesLoaded < first.bytesTotal,
            `the first view fetched ${first.bytesLoaded} of ${first.bytesTotal} bytes: no streaming`,
        );
        assert.ok(first.maxErrorPx <= kTau, `max error ${first.maxErrorPx} px above tau ${kTau}`);

        const pixels = await hook(() => window.strataViewer.pixelStats());
        t.diagnostic(
            `pixels: ${(100 * pixels.foreground).toFixed(1)}% foreground, box ${pixels.box}, hues ${JSON.stringify(pixels.hues)}`,
        );
        assert.ok(
            pixels.foreground > 0.03 && pixels.foreground < 0.9,
            `foreground ${pixels.foreground}: empty or filled canvas`,
        );
        const [x0, y0, x1, y1] = pixels.box;
        const panelRight = await hook(() => document.getElementById('side').getBoundingClientRect().right);
        const freeWidth = pixels.width - panelRight;
        t.diagnostic(`framing: ${x1 - x0 + 1} of ${freeWidth} free px wide, ${y1 - y0 + 1} of ${pixels.height} high`);
        assert.ok(
            (x1 - x0 + 1) / freeWidth > 0.6 || (y1 - y0 + 1) / pixels.height > 0.6,
            `the model is not framed: it spans ${x1 - x0 + 1} of ${freeWidth} px in width, ${y1 - y0 + 1} of ${pixels.height} in height`,
        );
        assert.ok(x0 >= panelRight - 1, `the model is drawn under the side panel (from x = ${x0})`);
        await shot('1-overview');

        // colours per object: each object alone shows the hue of its swatch (objects with a
        // saturated colour; hue buckets of 30 degrees as pixelStats, one bucket of slack for the
        // lighting)
        const hueBucket = (rgb) => {
            const [r, g, b] = rgb.map((x) => x / 255);
            const max = Math.max(r, g, b);
            const min = Math.min(r, g, b);
            const l = (max + min) / 2;
            const d = max - min;
            if (d === 0) return null;
            const sat = l > 0.5 ? d / (2 - max - min) : d / (max + min);
            if (sat <= 0.25 || l <= 0.1 || l >= 0.9) return null;
            let h = max === r ? (g - b) / d + (g < b ? 6 : 0) : max === g ? (b - r) / d + 2 : (r - g) / d + 4;
            h /= 6;
            return Math.round(h * 12) % 12;
        };
        const rows = await page.$$('#objects .object');
        assert.ok(
            rows.length >= first.objects.length,
            `${rows.length} object rows for ${first.objects.length} objects`,
        );
        let coloured = 0;
        for (const row of rows) {
            const name = await row.$eval('.name', (el) => el.textContent);
            const swatch = await row.$eval('.swatch', (el) =>
                getComputedStyle(el)
                    .backgroundColor.match(/[\d.]+/g)
                    .slice(0, 3)
                    .map(Number),
            );
            const expected = hueBucket(swatch);
            await (await row.$('button')).click(); // isolate
            await idle();
            const alone = await hook(() => window.strataViewer.pixelStats());
            await (await row.$('button')).click(); // every object again
            if (expected === null) continue;
            const [bucket, count] = Object.entries(alone.hues)
                .map(([b, n]) => [Number(b), n])
                .reduce((best, x) => (x[1] > best[1] ? x : best), [null, 0]);
            t.diagnostic(`${name} alone: swatch rgb(${swatch}) hue ${expected}, canvas hue ${bucket} (${count} px)`);
            assert.ok(alone.foreground > 0, `${name} alone draws nothing`);
            const off =
                bucket === null ? Infinity : Math.min((bucket - expected + 12) % 12, (expected - bucket + 12) % 12);
            assert.ok(off <= 1, `${name} alone shows hue ${bucket}, its swatch has hue ${expected}`);
            ++coloured;
        }
        assert.ok(coloured > 0 || rows.length === 0, 'no object has a saturated colour to check');
        await idle();

        // zoom in: chunks load, triangles rise; geomorphs run
        await hook(() => window.strataViewer.dolly(0.35));
        let morphing = 0;
        for (let i = 0; i < 20; ++i) {
            await hook(() => window.strataViewer.nextFrame());
            morphing = Math.max(morphing, (await hook(() => window.strataViewer.morphWeights())).morphing);
        }
        await idle('zoomed in');
        const zoomedIn = await state();
        t.diagnostic(
            `zoomed in: ${zoomedIn.triangles} triangles, ${zoomedIn.chunksLoaded} chunks, ${zoomedIn.bytesLoaded} bytes, ` +
                `max error ${zoomedIn.maxErrorPx.toFixed(2)} px / ${zoomedIn.maxErrorMm.toFixed(2)} mm; ${morphing} clusters seen morphing`,
        );
        assert.ok(
            zoomedIn.triangles > first.triangles,
            `zooming in: ${first.triangles} -> ${zoomedIn.triangles} triangles`,
        );
        assert.ok(zoomedIn.chunksLoaded > first.chunksLoaded, 'zooming in loaded no chunk');
        assert.ok(zoomedIn.bytesLoaded > first.bytesLoaded, 'zooming in fetched no bytes');
        assert.ok(morphing > 0, 'no cluster geomorphed while refining');
        assert.equal(zoomedIn.failures, 0);
        await shot('2-zoomed-in');

        // zoom out: coarser
        await hook(() => window.strataViewer.dolly((1 / 0.35) * 2.5));
        for (let i = 0; i < 3; ++i) await hook(() => window.strataViewer.nextFrame());
        await idle('zoomed out');
        const zoomedOut = await state();
        t.diagnostic(`zoomed out: ${zoomedOut.triangles} triangles`);
        assert.ok(
            zoomedOut.triangles < zoomedIn.triangles,
            `zooming out: ${zoomedIn.triangles} -> ${zoomedOut.triangles} triangles`,
        );
        assert.ok(zoomedOut.triangles <= first.triangles, 'farther than the first view but more triangles');
        await shot('3-zoomed-out');

        // region of interest: back to the first view, click on the surface
        await hook(() => window.strataViewer.fit());
        await hook(() => window.strataViewer.setColorByLevel(true));
        await idle();
        // candidate pixels: the projected centres of the root clusters' spheres
        const candidates = await hook(() => {
            const v = window.strataViewer;
            const out = [];
            for (const c of v.strata.controllers) {
                for (const k of c.dag.roots) out.push(v.project([...c.dag.clusterSphere.subarray(4 * k, 4 * k + 3)]));
            }
            return out;
        });
        let picked = null;
        // ROI factor 1 first (no change of tau): the triangles in the region before
        await page.evaluate(() => {
            const el = document.getElementById('roi-factor');
            el.value = '1';
            el.dispatchEvent(new Event('input'));
        });
        for (const { x, y } of candidates) {
            if (x < 300 || x > 880 || y < 20 || y > 620) continue; // not under the panels
            await page.mouse.click(x, y);
            picked = (await state()).roi;
            if (picked !== null) break;
        }
        assert.ok(picked !== null, 'no click hit the surface');
        await idle();
        const before = await state();
        const refinedGroups = () =>
            hook(() => window.strataViewer.strata.controllers.map((c) => Array.from(c.refined ?? [], Boolean)));
        const refinedBefore = await refinedGroups();
        await page.evaluate(() => {
            const el = document.getElementById('roi-factor');
            el.value = '8';
            el.dispatchEvent(new Event('input'));
        });
        for (let i = 0; i < 3; ++i) await hook(() => window.strataViewer.nextFrame());
        await idle('region of interest');
        const after = await state();
        // the groups the factor refined, and whether their spheres meet the region (the dags'
        // spheres and the region are in the scene frame)
        const newlyRefined = await hook(
            ({ beforeRefined, roi }) =>
                window.strataViewer.strata.controllers.flatMap((c, i) =>
                    Array.from(c.refined ?? [], Boolean).flatMap((now, g) => {
                        if (!now || beforeRefined[i]?.[g]) return [];
                        const s = c.dag.sphere.subarray(4 * g, 4 * g + 4);
                        const d = Math.hypot(s[0] - roi.center[0], s[1] - roi.center[1], s[2] - roi.center[2]);
                        return [{ object: c.name, group: g, gap: d - s[3] - roi.radius }];
                    }),
                ),
            { beforeRefined: refinedBefore, roi: after.roi },
        );
        t.diagnostic(`normals: ${normalsChecked} points checked, ${normalsIncremental} incremental updates`);
        assert.ok(normalsIncremental > 0, 'the normals were never updated incrementally');
        t.diagnostic(
            `region of interest at ${picked.center.map((x) => (1000 * x).toFixed(1))} mm, radius ${(1000 * picked.radius).toFixed(1)} mm: ` +
                `${before.roiTriangles} -> ${after.roiTriangles} triangles in the region, ${before.triangles} -> ${after.triangles} in all`,
        );
        assert.ok(after.roiTriangles > before.roiTriangles, 'the region of interest did not refine');
        assert.ok(newlyRefined.length > 0, 'no group was refined for the region');
        const away = newlyRefined.filter((x) => x.gap > 1e-9 * (1 + Math.abs(x.gap)));
        assert.deepEqual(away, [], 'groups refined for the region of interest whose spheres do not meet it');
        assert.match(after.hud, /region\s+\S+ triangles, tau \/ 8/, `the HUD does not report the region: ${after.hud}`);
        await shot('4-region-of-interest');

        assert.deepEqual(problems, [], 'console errors or failed requests');
    } finally {
        await browser.close();
        await server.close();
    }
});

test(
    'chunks leaving the cut are unloaded under a memory budget, obsolete requests cancelled, coarsening blended',
    { timeout: 120000 },
    async (t) => {
        const missing = chromiumMissing();
        assert.equal(missing, null, missing ?? '');
        const server = await startServer({ model: kModel, port: 0 });
        const browser = await launchChromium({ viewport: { width: 900, height: 640 } });
        const problems = [];
        try {
            const page = await browser.context.newPage();
            page.on('console', (message) => {
                if (message.type() === 'error') problems.push(`console error: ${message.text()}`);
            });
            page.on('pageerror', (error) => problems.push(`page error: ${error.message}`));
            page.on('requestfailed', (request) => {
                // cancelled chunk requests are expected here; anything else is not
                if (request.failure()?.errorText !== 'net::ERR_ABORTED')
                    problems.push(`request failed: ${request.url()}`);
            });
            const hook = (fn, arg) => page.evaluate(fn, arg);
            const state = () => hook(() => window.strataViewer.state());
            const idle = async () =>
                assert.ok(await hook(() => window.strataViewer.idle(30000)), 'the viewer did not settle');
            const settle = async (frames = 3) => {
                for (let i = 0; i < frames; ++i) await hook(() => window.strataViewer.nextFrame());
                await idle();
            };
            await page.goto(`${server.url}&tau=8&prefix=16384&preserve`);
            assert.ok(await hook(() => window.strataViewer.ready), 'the model did not load');
            await idle();
            const first = await state();
            // zoom in: everything near gets loaded; learn how many chunk triangles that is
            await hook(() => window.strataViewer.dolly(0.2));
            await settle();
            const near = await state();
            assert.ok(near.residentTriangles > 0, 'zooming in loaded nothing');
            // the same with a memory budget of half of that: zooming out unloads chunks down to it
            const memory = Math.floor(near.residentTriangles / 2);
            await page.goto(`${server.url}&tau=8&prefix=16384&preserve&memory=${memory}`);
            assert.ok(await hook(() => window.strataViewer.ready), 'the model did not load');
            await idle();
            await hook(() => window.strataViewer.dolly(0.2));
            await settle();
            const loaded = await state();
            await hook(() => window.strataViewer.dolly(1 / 0.2));
            await settle();
            const out = await state();
            t.diagnostic(
                `memory budget ${memory} triangles: zoomed in ${loaded.residentTriangles} resident, zoomed out ${out.residentTriangles}, ${out.evicted} chunks unloaded`,
            );
            assert.ok(out.evicted > 0, 'no chunk was unloaded');
            assert.ok(
                out.residentTriangles <= memory,
                `${out.residentTriangles} chunk triangles resident, budget ${memory}`,
            );
            assert.equal(out.triangles, first.triangles, 'after unloading, the first view draws what it drew at first');
            // blending out: zoomed in with everything loaded, a smaller triangle budget coarsens
            // without the threshold announcing it: the consumed clusters stay drawn while they morph
            await hook(() => window.strataViewer.dolly(0.2));
            await settle();
            const before = await state();
            // a blend of 3 s instead of 0.3 s, so that the frames sampled below see it even where
            // one frame of a large model takes longer than 0.3 s (software WebGL, loaded machine)
            const blendMs = await hook(() => window.strataViewer.strata.options.blendMs);
            await hook(() => (window.strataViewer.strata.options.blendMs = 3000));
            await hook((budget) => (window.strataViewer.settings.budget = budget), first.triangles + 1);
            let morphing = 0;
            let extra = 0;
            for (let i = 0; i < 10; ++i) {
                await hook(() => window.strataViewer.nextFrame());
                morphing = Math.max(morphing, (await hook(() => window.strataViewer.morphWeights())).morphing);
                const s = await state();
                extra = Math.max(extra, s.rendererTriangles - s.triangles);
            }
            await idle();
            const coarse = await state();
            t.diagnostic(
                `budget cut: ${before.triangles} -> ${coarse.triangles} triangles; ${morphing} clusters morphing out, up to ${extra} triangles drawn beyond the cut meanwhile`,
            );
            assert.ok(coarse.triangles < before.triangles, 'the smaller budget did not coarsen');
            assert.ok(morphing > 0 && extra > 0, 'the coarsening did not blend');
            await hook((ms) => (window.strataViewer.strata.options.blendMs = ms), blendMs);
            // the draw geometries hold the cut's clusters alone (three.js may cull objects outside the
            // view: the renderer draws at most that many)
            const shownTriangles = await hook(() =>
                window.strataViewer.strata.controllers.reduce(
                    (sum, c) => sum + (c.drawMesh.visible ? c.drawMesh.geometry.drawRange.count / 3 : 0),
                    0,
                ),
            );
            assert.equal(shownTriangles, coarse.triangles, 'after the blend the cut alone is drawn');
            assert.ok(coarse.rendererTriangles <= coarse.triangles, 'the renderer draws more than the cut');
            // cancelling: a slow link; zoom in (chunks requested), then back out at once
            await hook((budget) => (window.strataViewer.settings.budget = budget), 2e6);
            await hook(() => window.strataViewer.dolly(1 / 0.2));
            await settle();
            const cdp = await browser.context.newCDPSession(page);
            await cdp.send('Network.enable');
            await cdp.send('Network.emulateNetworkConditions', {
                offline: false,
                latency: 1500,
                downloadThroughput: 1e6,
                uploadThroughput: 1e6,
            });
            const cancelledBefore = (await state()).cancelled;
            await hook(() => window.strataViewer.dolly(0.2));
            await hook(() => window.strataViewer.nextFrame());
            const requested = await state();
            await hook(() => window.strataViewer.dolly(1 / 0.2));
            await settle();
            const after = await state();
            t.diagnostic(
                `slow link: ${requested.inFlight} chunks in flight after zooming in; zoomed out at once: ${after.cancelled - cancelledBefore} cancelled`,
            );
            assert.ok(requested.inFlight > 0, 'zooming in requested no chunk');
            assert.ok(after.cancelled > cancelledBefore, 'no obsolete request was cancelled');
            assert.equal(after.failures, 0);
            assert.deepEqual(problems, []);
        } finally {
            await browser.close();
            await server.close();
        }
    },
);

// node --test web-viewer/e2e/
// The viewer in headless Chromium (Debian's chromium, driven by playwright-core, offline): the
// page is served by serve.mjs on 127.0.0.1 with the model of STRATA_VIEWER_MODEL (a .glb or
// .gltf written by `strata build`; when unset, the test builds one: test/test-model.mjs).
//   * the first view frames the model: its pixels span most of the canvas the side panel leaves
//     free in width or in height; the HUD never says more than 100 % loaded;
//   * the model loads, streaming: the first view needs only part of the bytes;
//   * the canvas shows the objects: a substantial fraction of non-background pixels, several
//     colours, and the picture is not empty;
//   * zooming in (the test hook dollies the camera) loads chunks and raises the triangle count;
//     zooming out lowers it; a refinement geomorphs (some drawn clusters have 0 < w < 1);
//   * a region-of-interest click refines locally: the triangles in the region increase, the
//     HUD reports the region;
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
        const idle = async () =>
            assert.ok(await hook(() => window.strataViewer.idle(30000)), 'the viewer did not settle in 30 s');
        const shot = async (name) => {
            const path = join(kArtifacts, `${name}.png`);
            await page.screenshot({ path });
            t.diagnostic(`screenshot ${path}`);
        };

        // a first request of 16 KiB: the default phantom's file is small enough that the
        // default 64 KiB would hold nearly all of it, and zooming in would stream nothing
        await page.goto(`${server.url}&tau=${kTau}&prefix=16384&preserve`);
        assert.ok(await hook(() => window.strataViewer.ready), 'the model did not load');
        await idle();
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
        const hues = Object.values(pixels.hues).filter((n) => n > 200).length;
        assert.ok(hues >= Math.min(3, first.objects.length), `only ${hues} colours on the canvas`);
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

        // zoom in: chunks load, triangles rise; geomorphs run
        await hook(() => window.strataViewer.dolly(0.35));
        let morphing = 0;
        for (let i = 0; i < 20; ++i) {
            await hook(() => window.strataViewer.nextFrame());
            morphing = Math.max(morphing, (await hook(() => window.strataViewer.morphWeights())).morphing);
        }
        await idle();
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
        await idle();
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
        await page.evaluate(() => {
            const el = document.getElementById('roi-factor');
            el.value = '8';
            el.dispatchEvent(new Event('input'));
        });
        for (let i = 0; i < 3; ++i) await hook(() => window.strataViewer.nextFrame());
        await idle();
        const after = await state();
        t.diagnostic(
            `region of interest at ${picked.center.map((x) => (1000 * x).toFixed(1))} mm, radius ${(1000 * picked.radius).toFixed(1)} mm: ` +
                `${before.roiTriangles} -> ${after.roiTriangles} triangles in the region, ${before.triangles} -> ${after.triangles} in all`,
        );
        assert.ok(after.roiTriangles > before.roiTriangles, 'the region of interest did not refine');
        assert.ok(
            after.triangles - after.roiTriangles <=
                before.triangles - before.roiTriangles + 0.5 * (after.roiTriangles - before.roiTriangles),
            'the region of interest refined mostly outside the region',
        );
        assert.match(after.hud, /region\s+\S+ triangles, tau \/ 8/, `the HUD does not report the region: ${after.hud}`);
        await shot('4-region-of-interest');

        assert.deepEqual(problems, [], 'console errors or failed requests');
    } finally {
        await browser.close();
        await server.close();
    }
});

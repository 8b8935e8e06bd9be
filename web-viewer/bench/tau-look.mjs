#!/usr/bin/env node
// Benchmark (not a test): what the viewer's tau costs and what it shows. For each tau, the model
// is opened in a fresh headless Chromium (software WebGL) on an emulated link, left to settle at
// the fitted first view, and compared with the same view fully refined (tau 0.000001):
//
//   node web-viewer/bench/tau-look.mjs MODEL.glb [--taus 1,1.5,2] [--throttle MBIT,RTT_MS]
//        [--viewport WxH] [--out DIR] [--refine finest|data]
//
// Prints per tau: triangles drawn, bytes loaded (distinct, of the file), the time to settle from
// the model's first request, the largest projected error of the cut (px), the silhouette error
// (pixels whose coverage differs from the full-resolution picture, divided by the full-resolution
// outline's length: the mean distance between the outlines, px) and the share of covered pixels
// whose colour differs by more than 24/255 summed over RGB (shading). Screenshots of the page go to
// DIR/tau-X.png (default /tmp/strata-tau-look). --refine: what tau bounds (the plugin's refineOn,
// selection.js buildDag); the full-resolution reference is always drawn on 'finest'.
import { mkdirSync } from 'node:fs';
import { basename, join } from 'node:path';
import { startServer } from '../serve.mjs';
import { chromiumMissing, launchChromium } from '../chromium.mjs';
import { parseThrottle, throttlePage } from './link.mjs';

function usage(message) {
    if (message) console.error(`tau-look: ${message}`);
    console.error(
        'usage: node web-viewer/bench/tau-look.mjs MODEL.glb [--taus 1,1.5,2] [--throttle MBIT,RTT_MS] [--viewport WxH] [--out DIR] [--refine finest|data]',
    );
    process.exit(2);
}

const args = process.argv.slice(2);
const options = {
    model: null,
    taus: [1, 1.5, 2],
    throttle: { mbit: 20, rtt: 40 },
    width: 960,
    height: 640,
    refine: null,
};
options.out = '/tmp/strata-tau-look';
for (let i = 0; i < args.length; ++i) {
    const arg = args[i];
    if (arg === '--taus') options.taus = (args[++i] ?? '').split(',').map(Number);
    else if (arg === '--throttle') {
        options.throttle = parseThrottle(args[++i]);
        if (!options.throttle) usage('--throttle MBIT,RTT_MS');
    } else if (arg === '--viewport') [options.width, options.height] = (args[++i] ?? '').split('x').map(Number);
    else if (arg === '--out') options.out = args[++i];
    else if (arg === '--refine') {
        options.refine = args[++i];
        if (!['finest', 'data'].includes(options.refine)) usage('--refine finest|data');
    } else if (arg.startsWith('-')) usage(`unknown option ${arg}`);
    else if (options.model === null) options.model = arg;
    else usage('one model');
}
if (options.model === null) usage('no model');
if (options.taus.some((t) => !(t > 0))) usage('--taus: positive numbers');
const missing = chromiumMissing();
if (missing) usage(missing);
mkdirSync(options.out, { recursive: true });

/// Opens the model at tau, waits until it settled; returns its state, the canvas' RGBA pixels
/// (base64) and the time to settle from the model's first request.
async function look(server, tau, refine = null) {
    const browser = await launchChromium({ viewport: { width: options.width, height: options.height } });
    try {
        const page = await browser.context.newPage();
        await throttlePage(browser.context, page, options.throttle);
        await page.goto(`${server.url}&tau=${tau}&preserve&aa=0${refine ? `&refine=${refine}` : ''}`);
        if (!(await page.evaluate(() => window.strataViewer.ready))) throw new Error(`tau ${tau}: no model`);
        await page.evaluate(() => window.strataViewer.idle(600000, 3));
        const state = await page.evaluate(() => {
            const v = window.strataViewer;
            return { ...v.state(), settledMs: v.timing.refined - v.timing.loadStart };
        });
        const pixels = await page.evaluate(() => {
            const source = window.strataViewer.renderer.domElement;
            const canvas = document.createElement('canvas');
            canvas.width = source.width;
            canvas.height = source.height;
            const ctx = canvas.getContext('2d');
            ctx.drawImage(source, 0, 0);
            const data = ctx.getImageData(0, 0, canvas.width, canvas.height).data;
            let s = '';
            for (let i = 0; i < data.length; i += 0x8000) s += String.fromCharCode(...data.subarray(i, i + 0x8000));
            return { width: canvas.width, height: canvas.height, rgba: btoa(s) };
        });
        await page.screenshot({ path: join(options.out, `tau-${tau}.png`) });
        return { state, pixels: { ...pixels, rgba: Buffer.from(pixels.rgba, 'base64') } };
    } finally {
        await browser.close();
    }
}

const kBackground = [0x1d, 0x21, 0x29];
function covered(rgba, i) {
    return (
        Math.abs(rgba[4 * i] - kBackground[0]) +
            Math.abs(rgba[4 * i + 1] - kBackground[1]) +
            Math.abs(rgba[4 * i + 2] - kBackground[2]) >
        24
    );
}

const server = await startServer({ model: options.model, port: 0 });
try {
    const reference = await look(server, 0.000001);
    const { width, height, rgba: ref } = reference.pixels;
    const n = width * height;
    let outline = 0;
    let area = 0;
    for (let y = 0; y < height; ++y) {
        for (let x = 0; x < width; ++x) {
            const i = y * width + x;
            if (!covered(ref, i)) continue;
            ++area;
            if (x === 0 || y === 0 || x === width - 1 || y === height - 1) ++outline;
            else if (
                !covered(ref, i - 1) ||
                !covered(ref, i + 1) ||
                !covered(ref, i - width) ||
                !covered(ref, i + width)
            )
                ++outline;
        }
    }
    const total = reference.state.bytesTotal;
    console.log(
        `${basename(options.model)}: ${total} bytes; ${options.throttle.mbit} Mbit/s, ${options.throttle.rtt} ms (emulated); ` +
            `${width}x${height}; full resolution ${reference.state.triangles} triangles, settled in ${Math.round(reference.state.settledMs)} ms`,
    );
    console.log('tau px | triangles | bytes loaded | settled ms | max error px | silhouette px | shading differs');
    for (const tau of options.taus) {
        const { state, pixels } = await look(server, tau, options.refine);
        let xor = 0;
        let shaded = 0;
        for (let i = 0; i < n; ++i) {
            const a = covered(ref, i);
            const b = covered(pixels.rgba, i);
            if (a !== b) ++xor;
            else if (a) {
                const d =
                    Math.abs(ref[4 * i] - pixels.rgba[4 * i]) +
                    Math.abs(ref[4 * i + 1] - pixels.rgba[4 * i + 1]) +
                    Math.abs(ref[4 * i + 2] - pixels.rgba[4 * i + 2]);
                if (d > 24) ++shaded;
            }
        }
        console.log(
            `${String(tau).padStart(6)} | ${String(state.triangles).padStart(9)} | ` +
                `${`${state.bytesLoaded} (${((100 * state.bytesLoaded) / total).toFixed(0)} %)`.padStart(18)} | ` +
                `${String(Math.round(state.settledMs)).padStart(10)} | ${state.maxErrorPx.toFixed(2).padStart(12)} | ` +
                `${(xor / outline).toFixed(2).padStart(13)} | ${((100 * shaded) / area).toFixed(1).padStart(13)} %`,
        );
    }
    console.log(`screenshots: ${options.out}/tau-*.png`);
} finally {
    await server.close();
}

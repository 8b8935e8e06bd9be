#!/usr/bin/env node
// Diagnostic (not a test): where one progressive load's time goes, in headless Chromium (software
// WebGL) on an emulated link, warm cache (the page and its decoder cached, the model not):
//
//   node web-viewer/bench/load-trace.mjs OUT [--throttle MBIT,RTT_MS] [--query '&tau=1']
//
// OUT: a folder written by `strata build` (OUT/model.glb). Prints
//   * the main thread's CPU profile, self time per function (ms; '(program)' is native work,
//     WebGL calls included), the 25 largest;
//   * the User Timing marks (ms from the navigation) and the viewer's timing;
//   * every model request: start-end ms and bytes (Resource Timing), i.e. the request waterfall;
//   * the frames drawn (ms), the main thread's long tasks (over 50 ms), the plugin's stats (decode wait, attach, normals, draw build, setup);
//   * a timeline, polled every few ms, of the plugin's state whenever it changes: requests done,
//     requests in flight, chunks fetched or decoding, decoded chunks waiting for their attach,
//     wanted chunks not yet requested, chunks attached, then the cumulated attach, normals and
//     draw-build ms and the setup state.
import { startServer } from '../serve.mjs';
import { chromiumMissing, launchChromium } from '../chromium.mjs';
import { parseThrottle, throttlePage, visitUntilDecoder } from './link.mjs';

function usage(message) {
    if (message) console.error(`load-trace: ${message}`);
    console.error("usage: node web-viewer/bench/load-trace.mjs OUT [--throttle MBIT,RTT_MS] [--query '&tau=1']");
    process.exit(2);
}

const options = { out: null, throttle: { mbit: 20, rtt: 40 }, query: '' };
const args = process.argv.slice(2);
for (let i = 0; i < args.length; ++i) {
    if (args[i] === '--throttle') {
        options.throttle = parseThrottle(args[++i]);
        if (!options.throttle) usage('--throttle MBIT,RTT_MS');
    } else if (args[i] === '--query') options.query = args[++i] ?? '';
    else if (args[i].startsWith('-')) usage(`unknown option ${args[i]}`);
    else if (options.out === null) options.out = args[i];
    else usage('one OUT folder');
}
if (options.out === null) usage('no OUT folder');
const missing = chromiumMissing();
if (missing) usage(missing);

const server = await startServer({ model: `${options.out}/model.glb`, port: 0, viewerMaxAge: 3600, compress: true });
const base = server.url.replace(/\?.*$/, '');
const browser = await launchChromium({});
try {
    const page = await browser.context.newPage();
    await throttlePage(browser.context, page, options.throttle);
    // warm: the page without a model first, until its Draco decoder has arrived
    await visitUntilDecoder(page, base);
    await page.waitForTimeout(500);
    await page.addInitScript(() => {
        window.strataTrace = [];
        window.strataLongTasks = [];
        new PerformanceObserver((list) => {
            for (const e of list.getEntries()) window.strataLongTasks.push([e.startTime, e.duration].map(Math.round));
        }).observe({ type: 'longtask', buffered: true });
        let last = '';
        const poll = () => {
            const s = window.strataViewer?.strata;
            if (s) {
                const st = s.stats;
                const row = [
                    st.requests,
                    s.requests,
                    s.decoding,
                    s.arrived.length,
                    s.queue.length,
                    st.chunksLoaded,
                    Math.round(st.attachMs),
                    Math.round(st.normalsTimeMs),
                    Math.round(st.drawBuildMs),
                    s.setupState,
                ].join(' ');
                if (row !== last) {
                    window.strataTrace.push(`${Math.round(performance.now())} ${row}`);
                    last = row;
                }
            }
            setTimeout(poll, 2);
        };
        poll();
    });
    const cdp = await browser.context.newCDPSession(page);
    await cdp.send('Profiler.enable');
    await cdp.send('Profiler.setSamplingInterval', { interval: 200 });
    await cdp.send('Profiler.start');
    await page.goto(`${base}?model=model/model.glb&aa=0${options.query}`);
    if (!(await page.evaluate(() => window.strataViewer.ready))) throw new Error('the page did not load the model');
    await page.evaluate(() => window.strataViewer.idle(600000, 3));
    const { profile } = await cdp.send('Profiler.stop');
    const out = await page.evaluate(() => {
        const v = window.strataViewer;
        return {
            requests: performance
                .getEntriesByType('resource')
                .filter((r) => new URL(r.name).pathname.startsWith('/model/'))
                .map((r) => `${Math.round(r.startTime)}-${Math.round(r.responseEnd)} ${r.encodedBodySize}`),
            marks: performance.getEntriesByType('mark').map((m) => `${m.name} ${Math.round(m.startTime)}`),
            timing: v.timing,
            renders: v.renderStamps.map(Math.round),
            stats: v.strata.stats,
            trace: window.strataTrace,
            longTasks: window.strataLongTasks,
        };
    });
    const self = new Map();
    const nodes = new Map(profile.nodes.map((n) => [n.id, n]));
    profile.samples.forEach((id, i) => {
        const f = nodes.get(id).callFrame;
        const key = `${f.functionName || '(anonymous)'} ${f.url.split('/').pop()}:${f.lineNumber + 1}`;
        self.set(key, (self.get(key) ?? 0) + (profile.timeDeltas[i] ?? 0) / 1000);
    });
    console.log('main thread CPU profile, self ms:');
    for (const [key, ms] of [...self].sort((a, b) => b[1] - a[1]).slice(0, 25)) {
        console.log(`${ms.toFixed(0).padStart(7)} ${key}`);
    }
    console.log(`marks: ${out.marks.join(', ')}`);
    console.log(`viewer timing: ${JSON.stringify(out.timing)}`);
    console.log(`model requests (${out.requests.length}), start-end ms and bytes: ${out.requests.join(' | ')}`);
    console.log(`frames drawn at ms: ${out.renders.join(' ')}`);
    console.log(
        `long tasks (> 50 ms; drawn frames are tasks too), start+duration ms: ${out.longTasks.map(([t, d]) => `${t}+${d}`).join(' ')}`,
    );
    console.log(`plugin stats: ${JSON.stringify(out.stats)}`);
    console.log(
        'timeline: ms, requests done, in flight, chunks fetched or decoding, waiting for attach, wanted not requested, attached, attach ms, normals ms, draw build ms, setup',
    );
    console.log(out.trace.join('\n'));
} finally {
    await browser.close();
    await server.close();
}

// The emulated network link of the benchmarks (--throttle MBIT,RTT_MS): on the loopback bytes
// cost almost nothing, so the benchmarks slow the page's network down through the Chrome DevTools
// protocol. Also their warm-up visit (the viewer's files cached before a measured one).

/// Parses `MBIT,RTT_MS` into { mbit, rtt }; null unless the rate is positive and the round trip
/// not negative.
export function parseThrottle(text) {
    const [mbit, rtt] = (text ?? '').split(',').map(Number);
    return mbit > 0 && rtt >= 0 ? { mbit, rtt } : null;
}

/// Emulates the link { mbit, rtt } for `page` of the browser context `context`.
export async function throttlePage(context, page, { mbit, rtt }) {
    const cdp = await context.newCDPSession(page);
    await cdp.send('Network.enable');
    await cdp.send('Network.emulateNetworkConditions', {
        offline: false,
        latency: rtt,
        downloadThroughput: (mbit * 1e6) / 8,
        uploadThroughput: (mbit * 1e6) / 8,
    });
}

/// Opens the viewer page `base` without a model and waits until its Draco decoder has arrived:
/// the returning visitor's cache (and the server's compressed copies) before a measured visit.
export async function visitUntilDecoder(page, base) {
    await page.goto(base);
    await page.waitForFunction(
        () => performance.getEntriesByType('resource').some((r) => /draco_decoder\.wasm$/.test(r.name)),
        null,
        { timeout: 120000 },
    );
}

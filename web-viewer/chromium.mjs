// Launching Debian's Chromium headless with playwright-core, offline (for e2e/ and bench/).
// The browser is the Debian package (`apt-get install -y chromium`: /usr/bin/chromium); playwright
// never downloads one. STRATA_CHROMIUM overrides the path.
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

export const kChromium = process.env.STRATA_CHROMIUM ?? '/usr/bin/chromium';

/// Flags: headless without sandbox (root), software WebGL (SwiftShader; no GPU here), and no
/// background networking (the machine has no network but the loopback).
export const kChromiumArgs = [
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist',
];

/// Why Chromium cannot run, or null.
export function chromiumMissing() {
    if (!existsSync(kChromium)) {
        return `${kChromium} not found: install Debian's chromium (apt-get install -y chromium) or set STRATA_CHROMIUM`;
    }
    return null;
}

/// Launches Chromium with a fresh, empty profile. Returns { browser, context, close() }.
export async function launchChromium({ viewport = { width: 960, height: 640 } } = {}) {
    const { chromium } = await import('playwright-core');
    const profile = mkdtempSync(join(tmpdir(), 'strata-viewer-chromium-'));
    const context = await chromium.launchPersistentContext(profile, {
        executablePath: kChromium,
        headless: true,
        args: kChromiumArgs,
        viewport,
        deviceScaleFactor: 1,
        offline: false,
    });
    return {
        context,
        close: async () => {
            await context.close().catch(() => {});
            rmSync(profile, { recursive: true, force: true });
        },
    };
}

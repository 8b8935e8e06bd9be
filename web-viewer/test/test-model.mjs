// The model the viewer's model tests run on (test/selection.test.mjs, e2e/browser.test.mjs):
// STRATA_VIEWER_MODEL when set (CTest sets it to the build_scene fixture's model.glb); otherwise
// these tests build one themselves with `strata build` (the built-in phantom scene) from the
// binary STRATA_BIN or <repository>/build/strata, into a temporary folder removed at exit. When
// neither is there, they fail (never skip): a suite that passes without a model tests nothing.
import { execFileSync } from 'node:child_process';
import { existsSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const kRepository = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');

let built = null;

/// The path of the model to test (building it when STRATA_VIEWER_MODEL is unset); throws with
/// what to do when there is no way to get one.
export function testModel() {
    const given = process.env.STRATA_VIEWER_MODEL;
    if (given) {
        if (!existsSync(given)) throw new Error(`STRATA_VIEWER_MODEL=${given}: no such file`);
        return given;
    }
    if (built !== null) return built;
    const strata = process.env.STRATA_BIN ?? join(kRepository, 'build', 'strata');
    if (!existsSync(strata)) {
        throw new Error(
            `STRATA_VIEWER_MODEL is not set and there is no strata binary at ${strata} to build a model: ` +
                'build strata (cmake --build build) or set STRATA_BIN, or set STRATA_VIEWER_MODEL to a .glb written by `strata build`',
        );
    }
    const dir = mkdtempSync(join(tmpdir(), 'strata-viewer-model-'));
    process.on('exit', () => rmSync(dir, { recursive: true, force: true }));
    execFileSync(strata, ['build', '-o', join(dir, 'out'), '--quiet'], { stdio: ['ignore', 'ignore', 'inherit'] });
    built = join(dir, 'out', 'model.glb');
    if (!existsSync(built)) throw new Error(`${strata} build wrote no ${built}`);
    return built;
}

// Loads strata's LOD glTF (lods.glb: MSFT_lod, _LOD<i> node names, MSFT_screencoverage) with
// Babylon.js (@babylonjs/core + @babylonjs/loaders from npm) in Node on its NullEngine, as an
// engine pipeline would:
//   node tests/babylon/check_lods_babylon.mjs FILE.glb...
// Checks, per file:
//   [progressive] Babylon's own MSFT_lod loader shows every object's coarsest level first, then
//                 each finer one in turn (onNodeLODsLoadedObservable), and the finest at the end;
//                 each shown mesh has the triangles its node's extras state.
//   [distance]    every level loaded by Babylon (maxLODsToLoad 1..n) and chained with
//                 Mesh.addLODLevel from the file's MSFT_screencoverage (screen-coverage mode, as
//                 Babylon documents for MSFT_lod): rendering from a camera moving away, the drawn
//                 mesh goes from the finest level at close range to the coarsest far away, never
//                 finer again; each drawn level's error bound (extras error_mm) projects to at most
//                 the file's screen_error_px on Babylon's viewport; every level is drawn at some
//                 distance; and where Babylon's bounding sphere is the file's (isotropic frames),
//                 at the geometric middle between two switch distances computed here from the error
//                 bounds alone (distance = error * height / (2 tan(fov / 2) * screen_error_px)) the
//                 drawn level is exactly the expected one.
// Draco decodes in-process with the npm draco3d module (Babylon's jsModule option), as Node has
// no Web Workers. Exits 0 when every check passes, 1 otherwise, 2 for usage errors or a missing
// node_modules (run `npm ci` in tests/babylon; scripts/test.sh does).
import { spawnSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { dirname } from 'node:path';
import { fileURLToPath } from 'node:url';

const kHere = dirname(fileURLToPath(import.meta.url));

async function loadBabylon() {
    try {
        const core = await import('@babylonjs/core');
        const { DracoDecoder } = await import('@babylonjs/core/Meshes/Compression/dracoDecoder.js');
        await import('@babylonjs/loaders/glTF/index.js');
        const draco3d = (await import('draco3d')).default;
        // note: DracoDecoder counts a configuration as available only with a URL (its TODO:
        // "Account for jsModule"); with jsModule and no workers the URL is never read.
        DracoDecoder.DefaultConfiguration = {
            jsModule: draco3d.createDecoderModule,
            numWorkers: 0,
            fallbackUrl: 'unused: jsModule',
        };
        return core;
    } catch (error) {
        console.error(`check_lods_babylon: cannot load the npm packages (${error.message})`);
        console.error(`check_lods_babylon: run \`npm ci\` in ${kHere}`);
        process.exit(2);
    }
}

/// The JSON chunk of a .glb.
function glbJson(bytes) {
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    if (bytes.byteLength < 20 || view.getUint32(0, true) !== 0x46546c67) {
        throw new Error('not a .glb file');
    }
    const length = view.getUint32(12, true);
    return JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + length)));
}

/// Per object: { name, levels: [{ node, error_mm, triangles }], coverage, screenErrorPx }, from
/// the LOD0 nodes (those with MSFT_lod, or any `_LOD0` node without coarser levels).
function lodObjects(json) {
    const objects = [];
    for (const node of json.nodes ?? []) {
        if (!node.name?.endsWith('_LOD0')) {
            continue;
        }
        const ids = node.extensions?.MSFT_lod?.ids ?? [];
        const levels = [node, ...ids.map((id) => json.nodes[id])].map((n) => ({
            node: n,
            name: n.name,
            error_mm: n.extras.error_mm,
            triangles: n.extras.triangles,
        }));
        objects.push({
            name: node.name.slice(0, -'_LOD0'.length),
            levels,
            coverage: node.extras.MSFT_screencoverage,
            screenErrorPx: node.extras.screen_error_px,
            radiusMm: node.extras.bounding_radius_mm,
        });
    }
    return objects;
}

class Checker {
    constructor() {
        this.failures = 0;
        this.checks = 0;
    }

    expect(ok, message) {
        ++this.checks;
        if (!ok) {
            ++this.failures;
            console.error(`  FAIL ${message}`);
        }
        return ok;
    }
}

/// Loads `bytes` into `scene` with Babylon's glTF loader; resolves when every MSFT_lod level it
/// loads is in, with the loader's MSFT_lod events: [{ index, shown: Map(name -> triangles) }].
async function load(B, scene, bytes, maxLODsToLoad) {
    const events = [];
    let complete;
    const done = new Promise((resolve) => (complete = resolve));
    const shown = () =>
        new Map(
            scene.meshes
                .filter((m) => m.isEnabled() && m.getTotalIndices() > 0 && !m.isDisposed())
                .map((m) => [m.name, m.getTotalIndices() / 3]),
        );
    const observer = B.SceneLoader.OnPluginActivatedObservable.add((loader) => {
        loader.onExtensionLoadedObservable.add((extension) => {
            if (extension.name === 'MSFT_lod') {
                extension.onNodeLODsLoadedObservable.add((index) => events.push({ index, shown: shown() }));
            }
        });
        loader.onCompleteObservable.add(() => complete());
    });
    let result;
    try {
        result = await B.ImportMeshAsync(bytes, scene, {
            pluginExtension: '.glb',
            pluginOptions: { gltf: { extensionOptions: { MSFT_lod: { maxLODsToLoad } } } },
        });
    } finally {
        B.SceneLoader.OnPluginActivatedObservable.remove(observer);
    }
    await done;
    return { result, events };
}

async function checkProgressive(B, file, bytes, objects, c) {
    const engine = new B.NullEngine({ renderWidth: 1920, renderHeight: 1080, textureSize: 256 });
    const scene = new B.Scene(engine);
    new B.FreeCamera('camera', new B.Vector3(0, 0, -1), scene);
    // What Babylon shows, in order: a mesh with triangles becoming enabled, or being disposed
    // (MSFT_lod enables each level when it is loaded and disposes the coarser one it replaces).
    const log = [];
    scene.onNewMeshAddedObservable.add((mesh) => {
        mesh.onEnabledStateChangedObservable.add((enabled) => {
            if (enabled && mesh.getTotalIndices() > 0) {
                log.push({ shown: mesh.name, triangles: mesh.getTotalIndices() / 3 });
            }
        });
        mesh.onDisposeObservable.add(() => log.push({ disposed: mesh.name }));
    });
    const { events } = await load(B, scene, bytes, 10);
    const most = Math.max(...objects.map((o) => o.levels.length));
    c.expect(
        events.map((e) => e.index).join() === [...Array(most).keys()].join(),
        `${file}: MSFT_lod events ${events.map((e) => e.index).join()}, expected 0..${most - 1}`,
    );
    for (const o of objects) {
        const mine = log.filter((e) => (e.shown ?? e.disposed).startsWith(`${o.name}_LOD`));
        const shown = mine.filter((e) => e.shown);
        const expected = o.levels.map((l) => l.name).reverse();
        c.expect(
            shown.map((e) => e.shown).join() === expected.join(),
            `${file}: ${o.name}: Babylon showed ${shown.map((e) => e.shown).join(', ')}, expected ` +
                `${expected.join(', ')} (coarsest first)`,
        );
        for (const e of shown) {
            const level = o.levels.find((l) => l.name === e.shown);
            c.expect(
                level !== undefined && e.triangles === level.triangles,
                `${file}: ${e.shown}: ${e.triangles} triangles in Babylon, the file states ${level?.triangles}`,
            );
        }
        // Each coarser level is disposed once the next finer one is shown; the finest stays.
        for (let k = 0; k + 1 < shown.length; ++k) {
            const at = mine.indexOf(shown[k + 1]);
            c.expect(
                mine.findIndex((e) => e.disposed === shown[k].shown) > mine.indexOf(shown[k]) &&
                    mine.findIndex((e) => e.disposed === shown[k].shown) <= at + 1,
                `${file}: ${shown[k].shown} is not replaced when ${shown[k + 1].shown} is shown`,
            );
        }
        const alive = scene.meshes.filter((m) => m.name.startsWith(`${o.name}_LOD`) && m.isEnabled());
        c.expect(
            alive.length === 1 && alive[0].name === o.levels[0].name,
            `${file}: ${o.name}: at the end Babylon shows ${alive.map((m) => m.name).join(', ')}, expected ` +
                `${o.levels[0].name} alone`,
        );
    }
    console.log(
        `${file}: [progressive] Babylon showed ` +
            log
                .filter((e) => e.shown)
                .map((e) => e.shown)
                .join(' -> '),
    );
    engine.dispose();
}

async function checkDistance(B, file, bytes, objects, c) {
    const engine = new B.NullEngine({ renderWidth: 1920, renderHeight: 1080, textureSize: 256 });
    const scene = new B.Scene(engine);
    const camera = new B.FreeCamera('camera', new B.Vector3(0, 0, -1), scene);
    camera.minZ = 0.0001;
    camera.maxZ = 10000;
    const most = Math.max(...objects.map((o) => o.levels.length));
    // Babylon loads the coarsest m levels for maxLODsToLoad = m: the finest of those stays.
    const meshOf = new Map(); // node name -> Babylon mesh
    for (let m = 1; m <= most; ++m) {
        const { result } = await load(B, scene, bytes, m);
        for (const mesh of result.meshes) {
            if (mesh.getTotalIndices() > 0 && !mesh.isDisposed() && !meshOf.has(mesh.name)) {
                meshOf.set(mesh.name, mesh);
            }
        }
    }
    for (const o of objects) {
        const missing = o.levels.filter((l) => !meshOf.has(l.name)).map((l) => l.name);
        if (!c.expect(missing.length === 0, `${file}: Babylon did not load ${missing.join(', ')}`)) {
            continue;
        }
    }
    const height = engine.getRenderHeight();
    const tanHalf = Math.tan(camera.fov / 2);
    for (const o of objects) {
        if (o.levels.some((l) => !meshOf.has(l.name))) {
            continue;
        }
        // Only this object's meshes are enabled; its LOD chain from the file's screen coverage.
        for (const mesh of scene.meshes) {
            if (mesh.getTotalIndices() > 0) {
                mesh.setEnabled(false);
            }
        }
        const master = meshOf.get(o.levels[0].name);
        master.setEnabled(true);
        master.useLODScreenCoverage = true;
        for (let j = 1; j < o.levels.length; ++j) {
            const mesh = meshOf.get(o.levels[j].name);
            mesh.setEnabled(true);
            master.addLODLevel(o.coverage[j - 1], mesh);
        }
        if (o.coverage[o.coverage.length - 1] > 0) {
            master.addLODLevel(o.coverage[o.coverage.length - 1], null);
        }
        master.computeWorldMatrix(true);
        const sphere = master.getBoundingInfo().boundingSphere;
        const center = sphere.centerWorld.clone();
        // The level Babylon's render loop selects (Mesh.onLODLevelSelection, called by the scene's
        // active-mesh evaluation with the mesh it then draws).
        let selected;
        master.onLODLevelSelection = (_coverage, _master, mesh) => {
            selected = mesh ?? null;
        };
        const drawnAt = (distance) => {
            camera.position = center.add(new B.Vector3(0, 0, -distance));
            camera.setTarget(center);
            selected = undefined;
            scene.render();
            const j = o.levels.findIndex((l) => meshOf.get(l.name) === selected);
            return selected === undefined ? -1 : j;
        };
        // Distance (m) from which level j's bound projects to at most screenErrorPx.
        const switchAt = o.levels.map((l) => ((l.error_mm / 1000) * height) / (2 * tanHalf * o.screenErrorPx));
        const near = switchAt[1] ?? switchAt[0];
        const far = switchAt[o.levels.length - 1];
        const distances = [];
        for (let d = Math.max(sphere.radiusWorld * 1.5, near / 8); d < far * 8; d *= 1.15) {
            distances.push(d);
        }
        const path = [];
        let previous = 0;
        for (const d of distances) {
            const j = drawnAt(d);
            if (!c.expect(j >= 0, `${file}: ${o.name} at ${d.toFixed(3)} m: Babylon selected no level of it`)) {
                continue;
            }
            // The finest level is drawn however close the camera is (nothing finer exists).
            const projected = ((o.levels[j].error_mm / 1000) * height) / (2 * tanHalf * d);
            c.expect(
                j === 0 || projected <= o.screenErrorPx * (1 + 1e-6),
                `${file}: ${o.name} at ${d.toFixed(3)} m draws ${o.levels[j].name}, whose ${o.levels[j].error_mm} mm ` +
                    `project to ${projected.toFixed(3)} px > ${o.screenErrorPx}`,
            );
            c.expect(j >= previous, `${file}: ${o.name} at ${d.toFixed(3)} m draws a finer level than closer up`);
            previous = Math.max(previous, j);
            if (path.length === 0 || path[path.length - 1].level !== j) {
                path.push({ level: j, from: d });
            }
        }
        c.expect(path[0]?.level === 0, `${file}: ${o.name}: the finest level is not drawn at close range`);
        c.expect(
            path[path.length - 1]?.level === o.levels.length - 1,
            `${file}: ${o.name}: the coarsest level is not drawn far away`,
        );
        c.expect(
            new Set(path.map((p) => p.level)).size === o.levels.length,
            `${file}: ${o.name}: levels drawn ${path.map((p) => p.level).join()}, expected every one`,
        );
        const isotropic = Math.abs(sphere.radiusWorld / (o.radiusMm / 1000) - 1) < 1e-3;
        if (isotropic) {
            for (let j = 0; j + 1 < o.levels.length; ++j) {
                const lo = j === 0 ? switchAt[1] / 4 : switchAt[j];
                const d = Math.sqrt(lo * switchAt[j + 1]);
                c.expect(
                    drawnAt(d) === j,
                    `${file}: ${o.name} at ${d.toFixed(3)} m draws level ${drawnAt(d)}, expected ${j} ` +
                        `(switch distances ${switchAt.map((s) => s.toFixed(3)).join(', ')} m)`,
                );
            }
            const d = switchAt[o.levels.length - 1] * 2;
            c.expect(drawnAt(d) === o.levels.length - 1, `${file}: ${o.name} at ${d.toFixed(3)} m: not the coarsest`);
        }
        console.log(
            `${file}: [distance] ${o.name}: ` +
                path.map((p) => `${o.levels[p.level].name} from ${p.from.toFixed(3)} m`).join(', ') +
                (isotropic ? ' (exact switch distances checked)' : ' (anisotropic frame: bounds checked)'),
        );
        for (let j = 1; j < o.levels.length; ++j) {
            master.removeLODLevel(meshOf.get(o.levels[j].name));
        }
        master.removeLODLevel(null);
        master.onLODLevelSelection = undefined;
    }
    engine.dispose();
}

async function main() {
    const files = process.argv.slice(2);
    if (files.length === 0) {
        console.error('usage: node check_lods_babylon.mjs FILE.glb...');
        process.exit(2);
    }
    if (files.length > 1) {
        // note: one process per file: in a second file loaded by the same process, Babylon 9.35
        // no longer reports the MSFT_lod meshes' enabled-state changes.
        let status = 0;
        for (const file of files) {
            const run = spawnSync(process.execPath, [fileURLToPath(import.meta.url), file], { stdio: 'inherit' });
            status = Math.max(status, run.status ?? 1);
        }
        process.exit(status);
    }
    const B = await loadBabylon();
    B.Logger.LogLevels = B.Logger.WarningLogLevel | B.Logger.ErrorLogLevel;
    const c = new Checker();
    const file = files[0];
    let bytes;
    let objects;
    try {
        bytes = new Uint8Array(readFileSync(file));
        objects = lodObjects(glbJson(bytes));
    } catch (error) {
        console.error(`check_lods_babylon: ${file}: cannot read it: ${error.message}`);
        process.exit(1);
    }
    if (c.expect(objects.length > 0, `${file}: no _LOD0 nodes`)) {
        await checkProgressive(B, file, bytes, objects, c);
        await checkDistance(B, file, bytes, objects, c);
    }
    console.log(`check_lods_babylon: ${file}: ${c.checks - c.failures} of ${c.checks} checks pass`);
    process.exit(c.failures === 0 ? 0 : 1);
}

await main();

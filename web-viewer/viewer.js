// The page: opens a model (?model=URL or a dropped .glb), draws it with the STRATA_progressive_mesh
// plugin (strata-progressive.js), and gives the controls (tau, budget, geomorphs, region of
// interest, objects), the HUD and the orientation axes. window.strataViewer is a small hook for
// tests and benchmarks (test/browser.test.mjs, bench/first-frame.mjs).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { loadStrataModel, StrataProgressivePlugin } from './strata-progressive.js';
import { kExtension } from './strata-format.js';

performance.mark('strata:viewer-module');
const kBackground = 0x1d2129;
performance.setResourceTimingBufferSize?.(100000); // every chunk request, for the benchmark
const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);

// ------------------------------------------------------------------------------------------------
// three.js setup

const renderer = new THREE.WebGLRenderer({
    antialias: params.get('aa') !== '0',
    preserveDrawingBuffer: params.has('preserve'),
});
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
renderer.setSize(window.innerWidth, window.innerHeight);
$('view').appendChild(renderer.domElement);

const scene = new THREE.Scene();
scene.background = new THREE.Color(kBackground);
const camera = new THREE.PerspectiveCamera(35, window.innerWidth / window.innerHeight, 0.001, 100);
scene.add(camera);
scene.add(new THREE.HemisphereLight(0xffffff, 0x3a3f4a, 1.4));
const headlight = new THREE.DirectionalLight(0xffffff, 1.8);
headlight.position.set(0.4, 0.6, 1);
camera.add(headlight);
camera.add(headlight.target);
headlight.target.position.set(0, 0, -1);

const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
controls.screenSpacePanning = true;

const dracoLoader = new DRACOLoader();
dracoLoader.setDecoderPath('./node_modules/three/examples/jsm/libs/draco/gltf/');

dracoLoader.setWorkerLimit(4);
dracoLoader.preload();
// Start Draco workers (each compiles the decoder's WebAssembly) while the page waits for the
// model's first bytes, by decoding a one-triangle mesh on each: the base's decode then finds them
// ready (on the torso this took about 100 ms off the first frame, from the worker start-up).
{
    const kOneTriangle = 'RFJBQ08CAgEAAAABAwEAAQIBAQAJAwAAAAAAAAAAAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAA==';
    const bytes = Uint8Array.from(atob(kOneTriangle), (c) => c.charCodeAt(0));
    for (let i = 0; i < Math.min(4, navigator.hardwareConcurrency || 2); ++i) {
        dracoLoader.decodeDracoFile(bytes.slice().buffer, () => {});
    }
}

function createLoader() {
    const loader = new GLTFLoader();
    loader.setDRACOLoader(dracoLoader);
    return loader;
}

window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    if (camera.view?.enabled)
        camera.setViewOffset(
            window.innerWidth,
            window.innerHeight,
            camera.view.offsetX,
            camera.view.offsetY,
            window.innerWidth,
            window.innerHeight,
        );
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
});

// ------------------------------------------------------------------------------------------------
// settings

// tau 2 px by measurement (docs/format.md, "Default tau"; web-viewer/bench/tau-look.mjs): on the
// framed torso the settled silhouettes differ from the full-resolution ones by 0.65 px on average,
// with 30 % of the file's bytes (81 % at 1 px, 0.37 px); FreeSurfer and the TotalSegmentator
// example fetch 94-100 % of their files at any tau up to 2 px (their full resolutions' bounds
// project to 3.5 and 5.4 px)
const settings = {
    tau: 2,
    budget: 2e6,
    morph: true,
    cull: true,
    roiFactor: 8,
    roiRadiusMm: 15,
};
let roi = null; // { center: [x, y, z] scene frame, radius (m), factor }
const roiMarker = new THREE.Mesh(
    new THREE.SphereGeometry(1, 24, 12),
    new THREE.MeshBasicMaterial({
        color: 0xffd060,
        wireframe: true,
        transparent: true,
        opacity: 0.25,
        depthWrite: false,
    }),
);
roiMarker.visible = false;
scene.add(roiMarker);

function formatCount(n) {
    return n >= 1e6 ? `${(n / 1e6).toFixed(2)}M` : n >= 1e4 ? `${Math.round(n / 1e3)}k` : `${Math.round(n)}`;
}

function formatBytes(n) {
    return n >= 1e6 ? `${(n / 1e6).toFixed(2)} MB` : n >= 1e3 ? `${(n / 1e3).toFixed(1)} kB` : `${n} B`;
}

function bindSettings() {
    const tau = $('tau');
    const budget = $('budget');
    const show = () => {
        settings.tau = 2 ** Number(tau.value);
        settings.budget = Math.round(10 ** Number(budget.value));
        $('tau-value').textContent = `${settings.tau < 1 ? settings.tau.toFixed(2) : settings.tau.toFixed(1)} px`;
        $('budget-value').textContent = formatCount(settings.budget);
        settings.roiFactor = Number($('roi-factor').value);
        $('roi-factor-value').textContent = `${settings.roiFactor}x`;
        settings.roiRadiusMm = Number($('roi-radius').value);
        $('roi-radius-value').textContent = `${settings.roiRadiusMm} mm`;
        if (roi) {
            roi.factor = settings.roiFactor;
            roi.radius = settings.roiRadiusMm / 1000;
            placeRoiMarker();
        }
    };
    for (const id of ['tau', 'budget', 'roi-factor', 'roi-radius']) $(id).addEventListener('input', show);
    $('morph').addEventListener('change', () => (settings.morph = $('morph').checked));
    $('cull').addEventListener('change', () => (settings.cull = $('cull').checked));
    $('levels').addEventListener('change', () => {
        for (const c of strata?.controllers ?? []) c.setColorByLevel($('levels').checked);
    });
    $('roi-clear').addEventListener('click', () => setRoi(null));
    show();
}
bindSettings();

function setTau(px) {
    $('tau').value = String(Math.log2(px));
    $('tau').dispatchEvent(new Event('input'));
}

function setBudget(triangles) {
    $('budget').value = String(Math.log10(triangles));
    $('budget').dispatchEvent(new Event('input'));
}

// ------------------------------------------------------------------------------------------------
// the model

let gltf = null;
let strata = null; // the plugin of the current model (null for a file without the extension)
const timing = { start: performance.timeOrigin, loadStart: 0, loaded: 0, firstFrame: 0, refined: 0 };
const frameTimes = []; // intervals between consecutive animation frames that both rendered (ms)
const renderStamps = []; // performance.now() of every rendered frame
const tickTimes = []; // intervals between animation frames, rendered or not (main-thread jank)
let lastFrame = 0;
const cpu = { update: 0, render: 0 }; // main-thread ms spent selecting (with normals) and drawing

async function openUrl(url) {
    // the model's first request may have started in index.html, before the modules loaded
    timing.loadStart = window.strataFirstRequest?.at ?? performance.now();
    $('message').textContent = `loading ${url} ...`;
    const prefixBytes = params.has('whole')
        ? Infinity
        : params.has('prefix')
          ? Number(params.get('prefix'))
          : undefined;
    // plugin options from the URL (for tests and benchmarks): ?memory=TRIANGLES, ?gap=BYTES
    // (maxRangeGap), ?normals-full=SHARE (normalsFullShare), ?prefetch=0 (no prefetching),
    // ?refine=data (refineOn: tau bounds the gain in the bound against the slices)
    const pluginOptions = {};
    if (params.has('memory')) pluginOptions.memoryBudget = Number(params.get('memory'));
    if (params.has('gap')) pluginOptions.maxRangeGap = Number(params.get('gap'));
    if (params.has('normals-full')) pluginOptions.normalsFullShare = Number(params.get('normals-full'));
    if (params.has('prefetch')) pluginOptions.prefetch = params.get('prefetch') !== '0';
    if (params.has('refine')) pluginOptions.refineOn = params.get('refine');
    const result = await loadStrataModel(url, { createLoader, pluginOptions, prefixBytes });
    show(result, url.split('/').pop());
    await result.userData.strata?.ready;
}

async function openFile(file) {
    timing.loadStart = performance.now();
    $('message').textContent = `reading ${file.name} ...`;
    const buffer = await file.arrayBuffer();
    const loader = createLoader();
    loader.register(
        (parser) =>
            new StrataProgressivePlugin(parser, { initialBytes: buffer.byteLength, totalBytes: buffer.byteLength }),
    );
    const result = await new Promise((resolve, reject) => loader.parse(buffer, '', resolve, reject));
    show(result, file.name);
    await result.userData.strata?.ready;
}

function disposeModel() {
    if (gltf === null) return;
    scene.remove(gltf.scene);
    gltf.scene.traverse((o) => {
        o.geometry?.dispose();
        if (o.material) for (const m of [o.material].flat()) m.dispose();
    });
    gltf = null;
    strata = null;
}

function show(result, name) {
    performance.mark('strata:shown');
    disposeModel();
    gltf = result;
    strata = result.userData.strata ?? null;
    // the plugin sets itself up after the first frame (which shows the base as GLTFLoader built it)
    strata?.ready.then(() => {
        if (gltf !== result) return;
        if (strata.controllers.length === 0) strata = null;
        buildObjectList();
        dirty = true;
    });
    scene.add(gltf.scene);
    timing.loaded = performance.now();
    timing.firstFrame = 0;
    timing.refined = 0;
    dirty = true;
    $('message').style.display = 'none';
    $('title').textContent = name;
    document.title = `${name} - strata viewer`;
    fitCamera();
    buildObjectList();
    setRoi(null);
}

/// The points of the base meshes as GLTFLoader built them (not the plugin's draw meshes), in the
/// world frame: x, y, z triples.
function basePoints() {
    const out = [];
    const v = new THREE.Vector3();
    gltf.scene.traverse((o) => {
        if (!o.isMesh || o.userData.strataObject) return;
        const position = o.geometry.getAttribute('position');
        if (!position) return;
        for (let i = 0; i < position.count; ++i) {
            v.fromBufferAttribute(position, i).applyMatrix4(o.matrixWorld);
            out.push(v.x, v.y, v.z);
        }
    });
    return out;
}

/// Anterior view of the whole scene (glTF X = patient left, Y = superior, Z = anterior): the camera
/// in front of the patient, looking posterior, superior up, as close as it can be while every
/// point of the base meshes is inside the part of the canvas that the side panel (left) and the
/// HUD and axes (bottom strip) leave free, with a 5 % margin, the points' projection centred in
/// it (the orbit target). The corners of the bounding box, used before, framed rounded shapes
/// loosely: FreeSurfer's brain filled 52 % of the free width and 67 % of its height.
function fitCamera() {
    gltf.scene.updateMatrixWorld(true);
    const box = new THREE.Box3().setFromObject(gltf.scene);
    if (box.isEmpty()) box.setFromCenterAndSize(new THREE.Vector3(), new THREE.Vector3(1, 1, 1));
    const center = box.getCenter(new THREE.Vector3());
    const radius = Math.max(box.getSize(new THREE.Vector3()).length() / 2, 1e-3);
    const width = window.innerWidth;
    const height = window.innerHeight;
    // the free part of the canvas: right of the side panel (when the canvas is wide enough)
    const panel = $('side').getBoundingClientRect();
    const left = panel.right + 10 < width * 0.6 ? panel.right + 10 : 0;
    const freeWidth = width - left;
    // the bottom strip of the HUD and the axes (at least 5 HUD lines tall), when the canvas is
    // tall enough
    const strip = Math.max($('axes').getBoundingClientRect().height, 80, $('hud').getBoundingClientRect().height) + 20;
    const bottom = strip < height * 0.3 ? strip : 0;
    const freeHeight = height - bottom;
    camera.aspect = width / height;
    if (left > 0 || bottom > 0) camera.setViewOffset(width, height, -left / 2, bottom / 2, width, height);
    else camera.clearViewOffset();
    const tanFull = Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2);
    const tanY = tanFull * 0.95 * (freeHeight / height);
    const tanX = tanFull * 0.95 * (freeWidth / height);
    // camera on +Z looking at -Z: a point at (x, y, z) relative to the centre is inside when
    // |x| <= tanX (d - z) and |y| <= tanY (d - z); the box's corners when there are no points
    let points = basePoints();
    if (points.length === 0) {
        points = [];
        for (let i = 0; i < 8; ++i) {
            points.push(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z);
        }
    }
    const distanceFor = () => {
        let d = 0;
        for (let i = 0; i < points.length; i += 3) {
            const z = points[i + 2] - center.z;
            d = Math.max(d, z + Math.abs(points[i] - center.x) / tanX, z + Math.abs(points[i + 1] - center.y) / tanY);
        }
        return Math.max(d, radius * 0.01);
    };
    let distance = distanceFor();
    // centre the projection: move the target by the middle of the projected extent (at the
    // target's depth), then fit again
    for (let pass = 0; pass < 2; ++pass) {
        let [minU, maxU, minV, maxV] = [Infinity, -Infinity, Infinity, -Infinity];
        for (let i = 0; i < points.length; i += 3) {
            const depth = distance - (points[i + 2] - center.z);
            const u = (points[i] - center.x) / depth;
            const v = (points[i + 1] - center.y) / depth;
            [minU, maxU, minV, maxV] = [Math.min(minU, u), Math.max(maxU, u), Math.min(minV, v), Math.max(maxV, v)];
        }
        center.x += ((minU + maxU) / 2) * distance;
        center.y += ((minV + maxV) / 2) * distance;
        distance = distanceFor();
    }
    camera.position.copy(center).add(new THREE.Vector3(0, 0, distance));
    camera.up.set(0, 1, 0);
    camera.near = radius / 200;
    camera.far = distance + radius * 50;
    camera.updateProjectionMatrix();
    controls.target.copy(center);
    controls.minDistance = radius / 500;
    controls.update();
    $('roi-radius').max = String(Math.max(10, Math.round(radius * 1000)));
    $('roi-radius').value = String(Math.max(1, Math.round(radius * 1000 * 0.15)));
    $('roi-radius').dispatchEvent(new Event('input'));
}

function objectColor(controller) {
    const color = controller.material?.color;
    return color ? `#${color.getHexString(THREE.SRGBColorSpace)}` : '#888';
}

function buildObjectList() {
    const list = $('objects');
    list.textContent = '';
    const items = strata?.controllers.length
        ? strata.controllers.map((c) => ({ name: c.name, object: c.object, controller: c }))
        : gltf.scene.children
              .flatMap((o) => (o.children.length ? o.children : [o]))
              .map((o) => ({ name: o.name, object: o, controller: null }));
    for (const item of items) {
        const row = document.createElement('div');
        row.className = 'object';
        const swatch = document.createElement('span');
        swatch.className = 'swatch';
        swatch.style.background = item.controller ? objectColor(item.controller) : '#888';
        const name = document.createElement('span');
        name.className = 'name';
        name.textContent = item.name;
        name.title = item.controller?.extras?.volume_ml
            ? `${item.name}: ${item.controller.extras.volume_ml.toFixed(1)} ml, label ${item.controller.extras.label}`
            : item.name;
        const visible = document.createElement('input');
        visible.type = 'checkbox';
        visible.checked = item.object.visible;
        visible.title = 'show';
        visible.addEventListener('change', () => (item.object.visible = visible.checked));
        const controlsRow = document.createElement('div');
        controlsRow.className = 'controls';
        const isolate = document.createElement('button');
        isolate.type = 'button';
        isolate.textContent = 'isolate';
        isolate.addEventListener('click', () => {
            const alone = items.every((other) => other === item || !other.object.visible) && item.object.visible;
            for (const other of items) {
                other.object.visible = alone || other === item;
                other.checkbox.checked = other.object.visible;
            }
        });
        const opacity = document.createElement('input');
        opacity.type = 'range';
        opacity.min = '0.05';
        opacity.max = '1';
        opacity.step = '0.05';
        opacity.value = '1';
        opacity.title = 'opacity';
        opacity.addEventListener('input', () => item.controller?.setOpacity(Number(opacity.value)));
        controlsRow.append(isolate, opacity);
        row.append(swatch, name, visible, controlsRow);
        list.append(row);
        item.checkbox = visible;
    }
}

// ------------------------------------------------------------------------------------------------
// region of interest

function placeRoiMarker() {
    roiMarker.visible = roi !== null;
    if (roi === null) return;
    const center = new THREE.Vector3(...roi.center).applyMatrix4(gltf.scene.matrixWorld);
    roiMarker.position.copy(center);
    roiMarker.scale.setScalar(roi.radius);
}

function setRoi(center) {
    roi = center === null ? null : { center, radius: settings.roiRadiusMm / 1000, factor: settings.roiFactor };
    placeRoiMarker();
}

const raycaster = new THREE.Raycaster();

/// Picks the surface under client pixel (x, y) and makes it the region of interest.
function roiAt(x, y) {
    if (gltf === null) return null;
    const rect = renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2(((x - rect.left) / rect.width) * 2 - 1, -((y - rect.top) / rect.height) * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const meshes = strata ? strata.drawnMeshes() : [];
    if (!strata) gltf.scene.traverse((o) => o.isMesh && meshes.push(o));
    const hit = raycaster.intersectObjects(meshes, false)[0];
    if (hit === undefined) return null;
    const toScene = gltf.scene.matrixWorld.clone().invert();
    const center = hit.point.clone().applyMatrix4(toScene).toArray();
    setRoi(center);
    const controller = hit.object.userData.strataObject;
    return { center, object: controller?.name ?? hit.object.name, point: hit.point.toArray() };
}

let pointerDown = null;
renderer.domElement.addEventListener('pointerdown', (e) => (pointerDown = { x: e.clientX, y: e.clientY }));
renderer.domElement.addEventListener('pointerup', (e) => {
    if (pointerDown && Math.hypot(e.clientX - pointerDown.x, e.clientY - pointerDown.y) < 4 && e.button === 0) {
        roiAt(e.clientX, e.clientY);
    }
    pointerDown = null;
});

// ------------------------------------------------------------------------------------------------
// drag and drop

window.addEventListener('dragover', (e) => {
    e.preventDefault();
    document.body.classList.add('dragging');
});
window.addEventListener('dragleave', () => document.body.classList.remove('dragging'));
window.addEventListener('drop', (e) => {
    e.preventDefault();
    document.body.classList.remove('dragging');
    const file = [...(e.dataTransfer?.files ?? [])].find((f) => /\.glb$/i.test(f.name));
    if (file) openFile(file).catch(reportError);
});

// ------------------------------------------------------------------------------------------------
// HUD and orientation axes

let last = null;
let hudAt = 0;

function updateHud(now) {
    if (now - hudAt < 150) return;
    hudAt = now;
    const lines = [];
    const drawn = renderer.info.render.triangles;
    if (strata) {
        const s = strata.stats;
        lines.push(
            `triangles  ${formatCount(last?.triangles ?? 0)} of budget ${formatCount(settings.budget)}${last?.budgetLimited ? ' (full)' : ''}`,
        );
        lines.push(
            `loaded     ${formatBytes(s.bytesLoaded)} of ${formatBytes(s.bytesTotal)} (${Math.round((100 * s.bytesLoaded) / Math.max(1, s.bytesTotal))}%)`,
        );
        lines.push(
            `chunks     ${s.chunksLoaded} of ${s.chunksTotal}, ${strata.inFlight} loading, ${strata.queue.length} queued` +
                (s.evicted || s.cancelled ? `, ${s.evicted} unloaded, ${s.cancelled} cancelled` : ''),
        );
        const px = last?.maxErrorPx ?? 0;
        lines.push(
            `max error  ${Number.isFinite(px) ? px.toFixed(2) : 'inf'} px ${strata.options.refineOn === 'data' ? 'above full resolution to the slices' : 'to full resolution'}, ${((last?.maxError ?? 0) * 1000).toFixed(2)} mm to the slices`,
        );
        if (roi) lines.push(`region     ${formatCount(last?.roiTriangles ?? 0)} triangles, tau / ${roi.factor}`);
    } else if (gltf) {
        lines.push(`triangles  ${formatCount(drawn)} (no ${kExtension}: drawn as is)`);
    }
    const recent = frameTimes.slice(-30);
    if (recent.length > 1) {
        const ms = recent.reduce((a, b) => a + b, 0) / recent.length;
        lines.push(`frame      ${ms.toFixed(1)} ms`);
    }
    $('hud').textContent = lines.join('\n');
}

const axesCanvas = $('axes');
const axesContext = axesCanvas.getContext('2d');
const kAxes = [
    { v: [1, 0, 0], label: 'L', color: '#e8655a' },
    { v: [-1, 0, 0], label: 'R', color: '#e8655a' },
    { v: [0, 1, 0], label: 'S', color: '#6cc46a' },
    { v: [0, -1, 0], label: 'I', color: '#6cc46a' },
    { v: [0, 0, 1], label: 'A', color: '#5d9bec' },
    { v: [0, 0, -1], label: 'P', color: '#5d9bec' },
];

/// The patient axes as seen by the camera (glTF X = left, Y = superior, Z = anterior).
function drawAxes() {
    const ctx = axesContext;
    const size = axesCanvas.width;
    const c = size / 2;
    ctx.clearRect(0, 0, size, size);
    ctx.fillStyle = 'rgba(20, 24, 31, 0.6)';
    ctx.beginPath();
    ctx.arc(c, c, c - 2, 0, 2 * Math.PI);
    ctx.fill();
    const inverse = camera.quaternion.clone().invert();
    const sceneRotation = gltf
        ? new THREE.Quaternion().setFromRotationMatrix(gltf.scene.matrixWorld)
        : new THREE.Quaternion();
    const items = kAxes
        .map((a) => ({ ...a, p: new THREE.Vector3(...a.v).applyQuaternion(sceneRotation).applyQuaternion(inverse) }))
        .sort((a, b) => a.p.z - b.p.z);
    ctx.font = 'bold 26px system-ui, sans-serif';
    ctx.textAlign = 'center';
    ctx.textBaseline = 'middle';
    for (const a of items) {
        const x = c + a.p.x * c * 0.62;
        const y = c - a.p.y * c * 0.62;
        ctx.globalAlpha = a.p.z < -0.2 ? 0.45 : 1;
        ctx.strokeStyle = a.color;
        ctx.lineWidth = 4;
        ctx.beginPath();
        ctx.moveTo(c, c);
        ctx.lineTo(x, y);
        ctx.stroke();
        ctx.fillStyle = a.color;
        ctx.fillText(a.label, c + a.p.x * c * 0.8, c - a.p.y * c * 0.8);
    }
    ctx.globalAlpha = 1;
}

// ------------------------------------------------------------------------------------------------
// the frame loop

// Rendering on demand: a frame is drawn when the camera moved, the page changed (any input, a
// resize, a model), or the cut changed (chunks arrived, refinement, geomorph weights); otherwise
// the loop only selects (about a millisecond), which leaves the main thread to loading.
let dirty = true;
const lastView = new THREE.Matrix4();
const lastProjection = new THREE.Matrix4();
for (const type of ['input', 'change', 'click', 'resize']) window.addEventListener(type, () => (dirty = true), true);
controls.addEventListener('change', () => (dirty = true));
let rendered = false; // whether the previous tick rendered (frame times are between rendered frames)
let cutChanged = false; // the cut changed since the last drawn frame
let lastRender = 0;
let renderInterval = 16; // recent time between consecutive drawn frames (ms)

function frame(now) {
    controls.update();
    camera.updateMatrixWorld();
    if (!lastView.equals(camera.matrixWorld) || !lastProjection.equals(camera.projectionMatrix)) {
        dirty = true;
        lastView.copy(camera.matrixWorld);
        lastProjection.copy(camera.projectionMatrix);
    }
    if (strata) {
        const height = renderer.getDrawingBufferSize(new THREE.Vector2()).y;
        const t0 = performance.now();
        last = strata.update(camera, height, settings.tau, settings.budget, {
            roi,
            morph: settings.morph,
            cull: settings.cull,
        });
        if (last.changed || last.blending) cutChanged = true;
        cpu.update += performance.now() - t0;
    }
    // the cost of a drawn frame: the time from it to the next tick (the main thread waits for the
    // GPU there: in software WebGL Chromium reads every frame back, 0.1-0.6 s on FreeSurfer)
    if (rendered && lastFrame > 0) renderInterval = 0.5 * renderInterval + 0.5 * (now - lastFrame);
    // A change of the cut alone (chunks arriving) is drawn at most every 4 frame costs while
    // chunks are loading, at once when loading is over: where drawing is slow (software WebGL,
    // huge cuts) loading then keeps most of the main thread. (The cost used to be measured only
    // between consecutive drawn frames, which this throttle makes rare: it stayed at 16 ms, and
    // FreeSurfer drew a frame per arriving chunk, 18 s of its 28 s settling in readbacks.)
    // (At most every 10 s: a cap of 2 s drew FreeSurfer's 2 s frames back to back while loading.)
    if (cutChanged && (strata?.idle || now - lastRender >= Math.min(10000, 4 * renderInterval))) dirty = true;
    if (lastFrame > 0) tickTimes.push(now - lastFrame);
    if (tickTimes.length > 20000) tickTimes.splice(0, tickTimes.length - 20000);
    if (dirty) {
        renderStamps.push(now);
        if (renderStamps.length > 20000) renderStamps.splice(0, renderStamps.length - 20000);
        lastRender = now;
        cutChanged = false;
        if (rendered && lastFrame > 0) frameTimes.push(now - lastFrame);
        if (frameTimes.length > 5000) frameTimes.splice(0, frameTimes.length - 5000);
        const t1 = performance.now();
        renderer.render(scene, camera);
        cpu.render += performance.now() - t1;
        ++window.strataViewer.renderedFrames;
        drawAxes();
        dirty = false;
        rendered = true;
    } else {
        rendered = false;
    }
    lastFrame = now;
    if (gltf && timing.firstFrame === 0) {
        timing.firstFrame = performance.now();
        performance.mark('strata:first-frame');
    }
    if (gltf && timing.refined === 0 && (!strata || strata.idle) && !cutChanged) timing.refined = performance.now();
    updateHud(now);
}
renderer.setAnimationLoop(frame);

// ------------------------------------------------------------------------------------------------
// the test hook

const errors = [];
function reportError(error) {
    errors.push(String(error?.stack ?? error));
    console.error(error);
    $('message').style.display = '';
    $('message').textContent = `error: ${error?.message ?? error}`;
}

function nextFrame() {
    return new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve)));
}

window.strataViewer = {
    THREE,
    renderer,
    scene,
    camera,
    controls,
    settings,
    timing,
    frameTimes,
    renderStamps,
    tickTimes,
    errors,
    renderedFrames: 0,
    /// Draws the next frame even if nothing changed.
    redraw() {
        dirty = true;
    },
    get gltf() {
        return gltf;
    },
    get strata() {
        return strata;
    },
    ready: null,
    /// Counts of the last frame and of the loading.
    state() {
        const s = strata?.stats ?? {};
        return {
            loaded: gltf !== null,
            triangles: strata ? (last?.triangles ?? 0) : renderer.info.render.triangles,
            rendererTriangles: renderer.info.render.triangles,
            drawCalls: renderer.info.render.calls,
            bytesLoaded: s.bytesLoaded ?? 0,
            bytesTotal: s.bytesTotal ?? 0,
            requests: s.requests ?? 0,
            chunksLoaded: s.chunksLoaded ?? 0,
            evicted: s.evicted ?? 0,
            cancelled: s.cancelled ?? 0,
            residentTriangles: strata?.controllers.reduce((sum, c) => sum + c.chunkTriangles, 0) ?? 0,
            chunksTotal: s.chunksTotal ?? 0,
            failures: s.failures ?? 0,
            inFlight: strata?.inFlight ?? 0,
            queued: strata?.queue.length ?? 0,
            idle: strata ? strata.idle : true,
            maxErrorPx: last?.maxErrorPx ?? null,
            maxErrorMm: (last?.maxError ?? 0) * 1000,
            budgetLimited: last?.budgetLimited ?? false,
            roi,
            roiTriangles: last?.roiTriangles ?? 0,
            hud: $('hud').textContent,
            objects: strata?.controllers.map((c) => c.name) ?? [],
            cameraDistance: camera.position.distanceTo(controls.target),
            timing: { ...timing },
            cpu: { ...cpu, attach: s.attachMs ?? 0, decodeWait: s.decodeWaitMs ?? 0, setup: s.setupMs ?? 0 },
        };
    },
    /// Moves the camera towards the orbit target (factor < 1) or away from it (factor > 1).
    dolly(factor) {
        camera.position.sub(controls.target).multiplyScalar(factor).add(controls.target);
        controls.update();
    },
    /// Orbits the camera about the target (degrees).
    orbit(azimuthDeg, elevationDeg = 0) {
        const offset = camera.position.clone().sub(controls.target);
        const spherical = new THREE.Spherical().setFromVector3(offset);
        spherical.theta += THREE.MathUtils.degToRad(azimuthDeg);
        spherical.phi = THREE.MathUtils.clamp(
            spherical.phi - THREE.MathUtils.degToRad(elevationDeg),
            0.01,
            Math.PI - 0.01,
        );
        camera.position.copy(controls.target).add(new THREE.Vector3().setFromSpherical(spherical));
        camera.lookAt(controls.target);
        controls.update();
    },
    /// Points the camera at a scene-frame point (keeps the distance).
    lookAt(point) {
        const offset = camera.position.clone().sub(controls.target);
        controls.target.set(...point);
        camera.position.copy(controls.target).add(offset);
        controls.update();
    },
    fit: () => fitCamera(),
    setTau,
    setBudget,
    setMorph(on) {
        $('morph').checked = on;
        settings.morph = on;
    },
    setColorByLevel(on) {
        $('levels').checked = on;
        $('levels').dispatchEvent(new Event('change'));
    },
    roiAt,
    clearRoi: () => setRoi(null),
    /// Projects a scene-frame point to client pixels.
    project(point) {
        const p = new THREE.Vector3(...point).applyMatrix4(gltf.scene.matrixWorld).project(camera);
        const rect = renderer.domElement.getBoundingClientRect();
        return { x: rect.left + ((p.x + 1) / 2) * rect.width, y: rect.top + ((1 - p.y) / 2) * rect.height };
    },
    /// Resolves when nothing is loading or queued, no blend runs and the last change is drawn,
    /// for `frames` frames in a row.
    async idle(timeoutMs = 30000, frames = 3) {
        const end = performance.now() + timeoutMs;
        let calm = 0;
        while (performance.now() < end) {
            await nextFrame();
            calm = (strata === null || strata.idle) && !cutChanged && !dirty ? calm + 1 : 0;
            if (calm >= frames) return true;
        }
        return false;
    },
    nextFrame,
    openUrl,
    /// Bytes of the model's responses (Resource Timing: encoded body sizes of the requests under
    /// /model/) finished by time t (performance.now() ms; default now), and their count.
    modelBytes(t = Infinity) {
        let bytes = 0;
        let requests = 0;
        for (const entry of performance.getEntriesByType('resource')) {
            if (!new URL(entry.name).pathname.startsWith('/model/') || entry.responseEnd > t) continue;
            bytes += entry.encodedBodySize;
            ++requests;
        }
        return { bytes, requests };
    },
    /// Geomorph weights of the drawn chunk clusters: { count, morphing (0 < w < 1), max }.
    morphWeights() {
        let count = 0;
        let morphing = 0;
        let max = 0;
        for (const controller of strata?.controllers ?? []) {
            for (const c of controller.drawn) {
                const w = controller.clusterWeight(c);
                ++count;
                if (w > 0 && w < 1) ++morphing;
                max = Math.max(max, w);
            }
        }
        return { count, morphing, max };
    },
    /// Pixels of the WebGL canvas (needs ?preserve in the URL): fraction that differs from the
    /// background, the bounding box of those pixels, and coarse hue buckets present.
    pixelStats() {
        const source = renderer.domElement;
        const canvas = document.createElement('canvas');
        canvas.width = source.width;
        canvas.height = source.height;
        const ctx = canvas.getContext('2d');
        ctx.drawImage(source, 0, 0);
        const { data, width, height } = ctx.getImageData(0, 0, canvas.width, canvas.height);
        const ref = [(kBackground >> 16) & 255, (kBackground >> 8) & 255, kBackground & 255]; // sRGB, as drawn
        let foreground = 0;
        let minX = width,
            minY = height,
            maxX = -1,
            maxY = -1;
        const hues = new Map();
        const color = new THREE.Color();
        const hsl = {};
        for (let y = 0; y < height; ++y) {
            for (let x = 0; x < width; ++x) {
                const i = 4 * (y * width + x);
                const d = Math.abs(data[i] - ref[0]) + Math.abs(data[i + 1] - ref[1]) + Math.abs(data[i + 2] - ref[2]);
                if (d <= 24) continue;
                ++foreground;
                minX = Math.min(minX, x);
                maxX = Math.max(maxX, x);
                minY = Math.min(minY, y);
                maxY = Math.max(maxY, y);
                color.setRGB(data[i] / 255, data[i + 1] / 255, data[i + 2] / 255);
                color.getHSL(hsl);
                if (hsl.s > 0.25 && hsl.l > 0.1) {
                    const bucket = Math.round(hsl.h * 12) % 12;
                    hues.set(bucket, (hues.get(bucket) ?? 0) + 1);
                }
            }
        }
        return {
            width,
            height,
            foreground: foreground / (width * height),
            box: [minX, minY, maxX, maxY],
            hues: Object.fromEntries(hues),
            background: ref,
        };
    },
};

const model = params.get('model');
window.strataViewer.ready = model
    ? openUrl(model)
          .then(nextFrame)
          .then(() => true)
          .catch((e) => {
              reportError(e);
              return false;
          })
    : Promise.resolve(false);
// URL values are taken as given (the sliders show them clamped to their ranges)
if (params.has('tau')) {
    setTau(Number(params.get('tau')));
    settings.tau = Number(params.get('tau'));
}
if (params.has('budget')) {
    setBudget(Number(params.get('budget')));
    settings.budget = Number(params.get('budget'));
}

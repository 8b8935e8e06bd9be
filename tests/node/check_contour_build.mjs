// Planar contour input, checked from outside strata:
//   node check_contour_build.mjs CONTOURS.json SUMMARY.json MODEL.glb
//     every structure of CONTOURS.json with a closed contour is an object of the progressive
//     model (node name = structure name, material colour = its colour), and summary.json names
//     every structure, the empty ones with a warning;
//   node check_contour_build.mjs --schema SCHEMA.json FILE.json...
//     each contour JSON file is valid against the schema (ajv, draft-04 as the other schemas).
// Exit 0 when everything holds, 1 otherwise (messages on stderr).
import { readFile } from 'node:fs/promises';
import AjvDraft04 from 'ajv-draft-04';

let failures = 0;
const fail = (message) => {
    console.error(`check_contour_build: ${message}`);
    failures += 1;
};

const args = process.argv.slice(2);
if (args[0] === '--schema') {
    const schema = JSON.parse(await readFile(args[1], 'utf8'));
    const ajv = new AjvDraft04({ allErrors: true, strict: false });
    const validate = ajv.compile(schema);
    for (const file of args.slice(2)) {
        const data = JSON.parse(await readFile(file, 'utf8'));
        if (!validate(data)) {
            fail(`${file}: ${ajv.errorsText(validate.errors)}`);
        }
    }
    // and a file that must fail: a point with one coordinate
    if (validate({ format: 'planar contours v1', rois: [{ slices: [{ z: 0, contours: [{ points: [[1]] }] }] }] })) {
        fail('the schema accepts a point with one coordinate');
    }
} else {
    const [contoursFile, summaryFile, modelFile] = args;
    const contours = JSON.parse(await readFile(contoursFile, 'utf8'));
    const summary = JSON.parse(await readFile(summaryFile, 'utf8'));
    const glb = await readFile(modelFile);
    if (glb.readUInt32LE(0) !== 0x46546c67) {
        fail(`${modelFile}: not a GLB file`);
        process.exit(1);
    }
    const jsonLength = glb.readUInt32LE(12);
    const gltf = JSON.parse(glb.subarray(20, 20 + jsonLength).toString('utf8'));
    const nodes = new Map((gltf.nodes ?? []).map((n) => [n.name, n]));
    const srgbToLinear = (c) => {
        const s = c / 255;
        return s <= 0.04045 ? s / 12.92 : ((s + 0.055) / 1.055) ** 2.4;
    };
    let withContours = 0;
    for (const roi of contours.rois) {
        const closed = (roi.slices ?? []).some((s) =>
            s.contours.some((c) => (c.geometric_type ?? 'CLOSED_PLANAR') === 'CLOSED_PLANAR' && c.points.length >= 3),
        );
        const inSummary = summary.objects.find((o) => o.name === roi.name);
        if (!inSummary) {
            fail(`structure ${roi.number} (${roi.name}) is not in summary.json`);
        }
        if (!closed) {
            const warned = summary.warnings.some(
                (w) => w.where.includes(`(${roi.name})`) && w.message.includes('no contours'),
            );
            if (!warned) {
                fail(`structure ${roi.number} (${roi.name}) has no contours and no warning says so`);
            }
            continue;
        }
        withContours += 1;
        const node = nodes.get(roi.name);
        if (!node) {
            fail(`structure ${roi.number} (${roi.name}) is not a node of the model`);
            continue;
        }
        const mesh = gltf.meshes[node.mesh];
        const material = gltf.materials[mesh.primitives[0].material];
        const color = material.pbrMetallicRoughness.baseColorFactor;
        for (let i = 0; i < 3; i += 1) {
            if (roi.color_rgb && Math.abs(color[i] - srgbToLinear(roi.color_rgb[i])) > 1e-3) {
                fail(`structure ${roi.name}: colour ${color} is not its ROI Display Color ${roi.color_rgb}`);
                break;
            }
        }
        if (!inSummary?.surface?.verified) {
            fail(`structure ${roi.name}: its surface is not verified in summary.json`);
        }
    }
    console.log(`check_contour_build: ${withContours} structures with contours, all in the model`);
}
process.exit(failures === 0 ? 0 : 1);

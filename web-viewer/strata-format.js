// The names and constants of the STRATA_progressive_mesh format (schema/README.md), defined once
// for JavaScript: the plugin (strata-progressive.js), the selection logic, the page, the viewer's
// tests and the glTF client checks in tests/node import them from here. The C++ writer and
// reader have their own single definition (src/exporters/).

/// The node extension.
export const kExtension = 'STRATA_progressive_mesh';
/// The primitive extension every refinement chunk uses.
export const kDraco = 'KHR_draco_mesh_compression';
/// The scene's root node, LPS mm -> glTF (X = left, Y = superior, Z = anterior, metres).
export const kPatientNode = 'patient';
/// The JSON schema of the node extension (in schema/).
export const kSchemaFile = 'node.STRATA_progressive_mesh.schema.json';

/// Attribute names of a chunk primitive (glTF) and of the three.js geometry GLTFLoader builds.
export const kAttributes = {
    position: 'POSITION',
    normal: 'NORMAL',
    coarsePosition: '_COARSE_POSITION', // geomorph target of every vertex (version 1)
};
/// three.js lower-cases custom attribute names (GLTFLoader: '_COARSE_POSITION' -> '_coarse_position').
export const kThreeAttributes = {
    position: 'position',
    normal: 'normal',
    coarsePosition: '_coarse_position',
};

/// glTF accessor component types.
export const kComponentType = {
    int8: 5120,
    uint8: 5121,
    int16: 5122,
    uint16: 5123,
    uint32: 5125,
    float32: 5126,
};
/// Bytes per component and the DataView getter of each component type.
export const kComponentReaders = {
    [kComponentType.int8]: [1, (v, o) => v.getInt8(o)],
    [kComponentType.uint8]: [1, (v, o) => v.getUint8(o)],
    [kComponentType.int16]: [2, (v, o) => v.getInt16(o, true)],
    [kComponentType.uint16]: [2, (v, o) => v.getUint16(o, true)],
    [kComponentType.uint32]: [4, (v, o) => v.getUint32(o, true)],
    [kComponentType.float32]: [4, (v, o) => v.getFloat32(o, true)],
};
/// Components per accessor type.
export const kTypeComponents = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };

/// The GLB container (glTF 2.0 binary).
export const kGlb = {
    magic: 0x46546c67, // 'glTF'
    version: 2,
    headerBytes: 12,
    chunkJson: 0x4e4f534a, // 'JSON'
    chunkBin: 0x004e4942, // 'BIN\0'
};

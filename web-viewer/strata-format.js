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
/// Its one child: the storage frame every object shares (-> patient mm); the objects below it.
export const kStorageNode = 'storage';
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

// ------------------------------------------------------------------------------------------------
// version 3 (schema/README.md)

/// The extension object's version this code reads (files of versions 1 and 2 are not read).
export const kVersion = 3;

/// The DAG table in the `dag` buffer view: a 16-byte header, 32-byte group records, then the
/// cluster-id lists (consumed then produced, per group), zero-padded to a multiple of 4.
export const kDagTable = {
    magic: 'SDAG',
    headerBytes: 16,
    recordBytes: 32,
    // header fields
    clusterCountOffset: 4,
    groupCountOffset: 8,
    idBytesOffset: 12,
    idBytesAllowed: [2, 4],
    // group record fields
    centerOffset: 0, // float32[3]
    radiusOffset: 12, // float32
    chunkOffsetOffset: 16, // uint32
    chunkLengthOffset: 20, // uint32
    consumedCountOffset: 24, // uint16
    producedCountOffset: 26, // uint16
    levelOffset: 28, // uint16
    fineOffset: 30, // uint16: bound against the finest level = error * fine / fineDenominator
    fineDenominator: 65535,
};

/// A group's bound against the finest level (metres) from its error and its record's `fine`,
/// evaluated in this order in binary64, as the C++ reader does.
export function fineError(error, fine) {
    return (error * fine) / kDagTable.fineDenominator;
}

/// Draco unique ids of a chunk's attributes (and the base primitive's glTF attribute names).
export const kChunkAttributeIds = { position: 0, cluster: 1, slot: 2 };
export const kClusterAttribute = '_CLUSTER';
export const kSlotAttribute = '_SLOT';
/// ... as GLTFLoader names them on a three.js geometry.
export const kThreeClusterAttribute = '_cluster';

#pragma once

// One triangle mesh as EXT_meshopt_compression streams (Khronos extension, 2021; meshoptimizer's
// vertex codec version 0 and index codec version 1, the versions the extension requires): what
// the LOD file (lod_gltf) and the meshopt option of the single-rate scene write. The library is
// Debian's libmeshoptimizer-dev (0.18): the writers are C++, and its encoders produce exactly the
// bitstreams the extension fixes, which every decoder release reads.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace strata::detail {

/// A mesh ready for meshopt: positions as unsigned 16-bit grid coordinates (KHR_mesh_quantization;
/// the caller's node matrix maps them back) or, when `float_positions` is not empty, float32;
/// unit normals; triangles.
struct MeshoptInput {
    std::vector<std::array<std::uint16_t, 3>> grid_positions;  ///< used when float_positions empty
    std::vector<std::array<float, 3>> float_positions;
    std::vector<std::array<float, 3>> normals;  ///< unit, one per position
    std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// One compressed stream: the bytes and what its buffer view says about them.
struct MeshoptStream {
    std::string bytes;              ///< compressed (meshopt_encodeVertexBuffer / IndexBuffer)
    std::uint32_t count = 0;        ///< elements (vertices, or indices)
    std::uint32_t byte_stride = 0;  ///< decoded bytes per element
};

/// The three streams of a mesh, vertices reordered for the vertex cache and fetch
/// (meshopt_optimizeVertexCache, meshopt_optimizeVertexFetchRemap), as gltfpack does: the order
/// is what makes the codecs small. Positions: 8-byte elements (three uint16 and a zero pad) or
/// 12-byte floats; normals: 4-byte elements (three snorm8 and a zero pad); indices: 2 bytes when
/// there are at most 65535 vertices, else 4. Every stream is decoded again and compared with the
/// reordered input before it is returned.
struct MeshoptMesh {
    MeshoptStream positions;
    MeshoptStream normals;
    MeshoptStream indices;
    bool float_positions = false;
    std::array<double, 3> min{}, max{};  ///< of the stored positions (accessor bounds)
};

/// \throw Error{InvalidInput} when the input is empty, a triangle index is out of range or the
///        attribute lengths differ; Error{Internal} when a stream does not decode to its input.
MeshoptMesh encode_meshopt_mesh(const MeshoptInput& in);

/// Decodes one vertex stream (for tests and the benchmark). \throw Error{InvalidInput} when the
/// bytes are not a valid stream of `count` elements of `byte_stride` bytes.
std::vector<unsigned char> decode_meshopt_vertices(const std::string& bytes,
                                                   std::uint32_t count,
                                                   std::uint32_t byte_stride);

/// Decodes one index stream (triangles) into 32-bit indices. \throw Error{InvalidInput} when the
/// bytes are not a valid index stream of `count` indices.
std::vector<std::uint32_t> decode_meshopt_indices(const std::string& bytes, std::uint32_t count);

}  // namespace strata::detail

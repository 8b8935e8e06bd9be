#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "simplify/multires_dag.h"

namespace strata {

/// One object of a progressive glTF file (schema/README.md), decoded.
struct ProgressiveFileObject {
    std::string name;
    std::int64_t label = -1;                       ///< `extras.label`, -1 when absent
    std::array<double, 4> base_color{1, 1, 1, 1};  ///< linear RGBA of the material
    /// The multiresolution model in the file's units: positions in the node's storage frame
    /// (grid coordinates), `error_px` and `full_resolution_error_px` in metres of the scene frame,
    /// cluster and group `bounds` in the scene frame (metres). Vertices shared by clusters are
    /// merged by their (bit-identical) positions, so cuts are closed meshes.
    MultiresMesh model;
    std::array<double, 16> to_patient{};   ///< storage frame -> LPS mm (the node's matrix)
    std::array<double, 16> to_scene{};     ///< storage frame -> scene metres (patient * node)
    std::size_t base_bytes = 0;            ///< bytes of the base primitives' data
    std::vector<std::size_t> level_bytes;  ///< Draco bytes of the chunks of each level
};

/// A decoded progressive glTF file.
struct ProgressiveFile {
    std::string generator;
    std::size_t total_bytes = 0;  ///< the file and every buffer file it uses
    std::vector<ProgressiveFileObject> objects;
};

/// Reads a `.glb` or `.gltf` written by write_progressive_gltf (or anything following
/// schema/README.md) and validates all of it before returning: the GLB container, the JSON,
/// buffers and buffer views (sizes, ranges), accessors (types, counts, ranges, index values),
/// the extension (every index in range, producer/consumer links consistent with the groups'
/// lists, groups listed children first, so the DAG is acyclic, errors finite and monotone, spheres
/// finite with radius >= 0, levels consistent), every Draco chunk (decoded; counts as the
/// accessors say; positions on the grid; each coarse position a vertex of the object) and the
/// primitives of root clusters. `.gltf` buffers must be relative file names beside the file
/// (no `..`, no absolute paths, no data URIs).
/// \throw Error{InvalidInput} with what is wrong and where (a JSON pointer or byte offset) for
///        malformed, inconsistent or hostile content; Error{Unsupported} for files that are valid
///        glTF but not progressive; Error{Io} when a file cannot be read.
ProgressiveFile read_progressive_gltf(const std::filesystem::path& path);

/// The same from memory: `bytes` is a GLB, or glTF JSON whose buffers `load_buffer(uri)` returns
/// (it may throw). `name` is used in messages.
ProgressiveFile read_progressive_gltf(
    std::string_view bytes,
    const std::string& name,
    const std::function<std::string(const std::string& uri)>& load_buffer);

/// The triangles of a cut of a file object in patient LPS millimetres (through `to_patient`),
/// outward facing.
TriMesh file_cut_to_patient(const ProgressiveFileObject& object, const MultiresCut& cut);

}  // namespace strata

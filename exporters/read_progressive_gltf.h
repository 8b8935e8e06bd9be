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
    std::array<double, 16> to_patient{};  ///< storage frame -> LPS mm (the node's matrix)
    std::array<double, 16> to_scene{};    ///< storage frame -> scene metres (patient * node)
    std::size_t base_bytes = 0;           ///< Draco bytes of the base mesh
    std::size_t dag_bytes = 0;            ///< bytes of the DAG table
    /// Draco bytes of the chunks per level L: the chunks of the groups of level L + 1, which hold
    /// clusters of level L (or lower, for a cluster that was kept a level longer)
    std::vector<std::size_t> level_bytes;
};

/// A decoded progressive glTF file.
struct ProgressiveFile {
    std::string generator;
    std::size_t total_bytes = 0;  ///< the file and every buffer file it uses
    std::vector<ProgressiveFileObject> objects;
};

/// Reads a `.glb` or `.gltf` of STRATA_progressive_mesh version 3 (schema/README.md) in three
/// steps, each complete before the next: parse (GLB container, every JSON field read with its
/// type checked, buffers and views, the base primitive's accessors, the DAG tables), check the
/// graph (every rule of the spec's "Validation" that needs no geometry: links, levels, order,
/// monotone errors, nested spheres, chunk ranges inside their view and not shared), then decode
/// (the base and each chunk once, with decoded sizes capped by the bytes that hold them; positions
/// on the grid; slots resolved, each coarse vertex a vertex of the group's produced clusters;
/// spheres containing their clusters' vertices). `.gltf` buffers must be relative file names
/// beside the file (no `..`, no absolute paths, no data URIs).
/// \throw Error{InvalidInput} with what is wrong and where (a JSON pointer or byte offset) for
///        malformed, inconsistent or hostile content (never another exception type);
///        Error{Unsupported} for files that are valid glTF but not progressive version 3;
///        Error{Io} when a file cannot be read.
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

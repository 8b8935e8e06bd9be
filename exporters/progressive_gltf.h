#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/slice_frame.h"
#include "exporters/scene_gltf.h"
#include "simplify/multires_dag.h"

namespace strata {

/// One structure of a progressive scene: its multiresolution model and how to show it.
struct ProgressiveObject {
    std::string name;              ///< structure name (node, mesh and material name)
    std::uint16_t label = 0;       ///< label value in the source
    std::array<double, 3> srgb{};  ///< display colour, sRGB, each channel in [0, 1]
    double volume_ml = 0.0;        ///< enclosed volume, for `extras`
    /// Slice space (x, y px, slice k at z = k d), positions on the grid of `grid_step` (the
    /// pipeline's quantize stage); not owned.
    const MultiresMesh* model = nullptr;
};

/// Options of `write_progressive_gltf`.
struct ProgressiveOptions {
    int normal_bits = 10;       ///< Draco quantization of the base mesh's normals (octahedral)
    int compression_level = 7;  ///< Draco, 0 (fastest) .. 10 (smallest)
    unsigned threads = 0;       ///< encoding threads, 0 = all cores; output identical for any count
};

/// What was written, for summaries and benchmarks.
struct ProgressiveStats {
    std::size_t total_bytes = 0;  ///< every file written
    /// What a first frame needs: GLB header, JSON, DAG tables and base meshes (for `.gltf`: the
    /// JSON and the prefix of the .bin with tables and bases).
    std::size_t base_bytes = 0;
    std::size_t json_bytes = 0;   ///< the JSON text (unpadded)
    std::size_t dag_bytes = 0;    ///< the DAG tables
    std::size_t chunk_bytes = 0;  ///< Draco refinement chunks (one per group)
    std::size_t chunks = 0;
    std::size_t groups = 0;
    std::size_t objects = 0;                   ///< objects written (those with a triangle)
    std::vector<std::filesystem::path> files;  ///< in the order written (JSON / .glb last)
};

/// Writes `objects` as progressive glTF 2.0, STRATA_progressive_mesh version 2
/// (schema/README.md; names and constants in exporters/progressive_format.h): `.glb`, or `.gltf`
/// with one `<stem>.bin`, by the extension of `path`; compact JSON. A root node "patient" maps
/// LPS mm to glTF metres; its one child "storage" maps the storage frame shared by every object
/// (x, y px, z in slices; x negated when the frame mirrors, so the matrix is a rotation times
/// positive scales) to LPS mm; under it one node per object, without a matrix. The node's mesh is
/// the base: one Draco primitive holding every root cluster (POSITION, NORMAL, `_CLUSTER` when
/// there are several). Each group's consumed clusters are one Draco chunk (welded, `_CLUSTER` per
/// point, `_SLOT` geomorph ranks), in the file's one `chunks` buffer view; every object's DAG
/// (group spheres, chunk ranges, cluster lists) is a binary table in the file's one `dag` view
/// (the top-level extension object names both views and the version; a node names its table's
/// byte offset); the node's extension holds one error per group. Positions are quantized on the
/// model's own grid, so they are lossless and shared vertices bit-identical. Every encoded chunk
/// and base is decoded again and compared with its clusters (triangles, orientation, coarse
/// vertices from the slots) before anything is written. The buffer starts with every object's
/// base and the tables (a first frame's bytes), then the chunks of all objects, coarse first (by
/// decreasing error).
///
/// Atomic per file (temporary file, then rename); for `.gltf` the buffer goes first, the JSON
/// last. \throw Error{InvalidInput} for models that are not on a grid, empty scenes, bad colours,
/// sheared frames; Error{Unsupported} for another extension or a `.glb` over 4 GiB; Error{Io} if
/// a file cannot be written; Error{Internal} if Draco fails or its output differs from the input.
ProgressiveStats write_progressive_gltf(const std::filesystem::path& path,
                                        const std::vector<ProgressiveObject>& objects,
                                        const SliceFrame& frame,
                                        const SceneInfo& info,
                                        const ProgressiveOptions& options = {});

}  // namespace strata

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
    int normal_bits = 10;       ///< Draco quantization of normals (octahedral)
    int compression_level = 7;  ///< Draco, 0 (fastest) .. 10 (smallest)
    unsigned threads = 0;       ///< encoding threads, 0 = all cores; output identical for any count
};

/// What was written, for summaries and benchmarks.
struct ProgressiveStats {
    std::size_t total_bytes = 0;  ///< every file written
    std::size_t base_bytes = 0;   ///< JSON plus the base meshes' data (what a first frame needs)
    std::size_t chunk_bytes = 0;  ///< Draco refinement chunks
    std::size_t chunks = 0;
    std::vector<std::filesystem::path> files;  ///< in the order written (JSON / .glb last)
};

/// Writes `objects` as progressive glTF 2.0 (../shared/DESIGN.md section 4, schema/README.md):
/// `.glb` (one file: the base meshes' data first, then the chunks from the coarsest level down) or
/// `.gltf` with `<stem>.bin` (base meshes) and `<stem>.level<L>.bin` (the Draco chunks of level L,
/// one buffer view each, for HTTP range requests), by the extension of `path`; compact JSON. A root
/// node "patient" maps LPS mm to glTF metres; under it one node per object whose matrix maps the
/// storage frame (x, y px, z in slices; x negated when the frame mirrors, so the matrix is a
/// rotation times positive scales) to LPS mm. The node's mesh is the base: one plain primitive per
/// root cluster. Every other cluster is a mesh of its own with one KHR_draco_mesh_compression
/// primitive (Edgebreaker) carrying POSITION, NORMAL and
/// `_COARSE_POSITION` (where each vertex goes in the coarser clusters, for geomorphs); the
/// positions are quantized on the model's own grid, so they are lossless and shared vertices
/// bit-identical. Normals are those of the cluster's level (progressive_cluster_normals). Each
/// node's `extensions.STRATA_progressive_mesh` lists clusters and groups with errors (metres) and
/// spheres in the scene frame. Every encoded chunk is decoded again and compared with its
/// cluster (triangles, orientation, coarse positions) before anything is written.
///
/// Atomic per file (temporary file, then rename); for `.gltf` the buffers go first, the JSON
/// last. \throw Error{InvalidInput} for models that are not on a grid, empty scenes, bad colours,
/// sheared frames; Error{Unsupported} for another extension or a `.glb` over 4 GiB; Error{Io} if
/// a file cannot be written; Error{Internal} if Draco fails or its output differs from the input.
ProgressiveStats write_progressive_gltf(const std::filesystem::path& path,
                                        const std::vector<ProgressiveObject>& objects,
                                        const SliceFrame& frame,
                                        const SceneInfo& info,
                                        const ProgressiveOptions& options = {});

/// The NORMAL the writer stores for every cluster of `model` (one per entry of the cluster's
/// `vertices`, unit): the area-weighted vertex normals of the cut of the cluster's level
/// (select_cut_at_level(model, level) holds every cluster of that level), over `points` (the
/// model's vertices in the storage frame; triangles reversed when `reverse`, for mirroring
/// frames). Clusters of one level agree on every vertex they share; a coarse cluster is shaded as
/// the smooth surface it is (the full-resolution normals at its few vertices would look faceted
/// and cost bytes: Draco predicts normals from the decoded positions).
std::vector<std::vector<std::array<float, 3>>> progressive_cluster_normals(
    const MultiresMesh& model, const std::vector<std::array<float, 3>>& points, bool reverse);

}  // namespace strata

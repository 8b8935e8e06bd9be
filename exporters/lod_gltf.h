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

/// One structure of a LOD file: its multiresolution model and how to show it.
struct LodObject {
    std::string name;              ///< structure name (node names get `_LOD<i>`)
    std::uint16_t label = 0;       ///< label value in the source
    std::array<double, 3> srgb{};  ///< display colour, sRGB, each channel in [0, 1]
    /// Slice space, positions on the grid of `grid_step` (the quantize stage); not owned.
    const MultiresMesh* model = nullptr;
};

/// How the levels' meshes are compressed.
enum class LodCompression {
    Draco,    ///< KHR_draco_mesh_compression, lossless on the model's grid (detail/draco_chunk)
    Meshopt,  ///< EXT_meshopt_compression with KHR_mesh_quantization (detail/meshopt_streams)
};

/// Options of `write_lod_gltf`.
struct LodOptions {
    /// Requested error bounds (mm), increasing: level i is the coarsest cut of the model whose
    /// bound is at most error_mm[i] (select_cut_by_error). Empty: `level_count` levels spread
    /// evenly over the model's own levels (select_cut_at_level).
    std::vector<double> error_mm;
    unsigned level_count = 3;
    LodCompression compression = LodCompression::Draco;
    int compression_level = 7;  ///< Draco, 0 (fastest) .. 10 (smallest)
    int normal_bits = 10;       ///< Draco quantization of normals (octahedral)
    /// MSFT_screencoverage: a level is shown while its error bound projects to at most this many
    /// pixels on a viewport of `viewport_height_px` x `viewport_height_px * aspect`.
    double screen_error_px = 1.0;
    double viewport_height_px = 1080.0;
    double aspect = 16.0 / 9.0;
};

/// One written level of one object.
struct LodLevelStats {
    double error_mm = 0.0;  ///< the cut's declared bound (>= the request when at full resolution)
    std::size_t triangles = 0;
    std::size_t vertices = 0;
    std::size_t bytes = 0;          ///< compressed geometry in the buffer
    std::uint32_t model_level = 0;  ///< the coarsest model level among the cut's clusters
};

/// What was written, for summaries and benchmarks.
struct LodStats {
    std::size_t total_bytes = 0;
    std::vector<std::vector<LodLevelStats>> objects;  ///< per object, finest (LOD0) first
};

/// The cuts of `model` for the LOD levels, finest first: one per requested bound (or spread over
/// the model's levels for a count), cuts equal to a finer one left out. `mm_per_px` converts the
/// model's px errors to mm. Every cut is a closed, crack-free surface (MultiresMesh's cut
/// guarantee) within its error_px.
std::vector<MultiresCut> lod_cuts(const MultiresMesh& model,
                                  double mm_per_px,
                                  const LodOptions& options);

/// Writes `objects` as a discrete-LOD glTF 2.0 binary (`.glb`) for pipelines that read standard
/// glTF. Root node "patient" (LPS mm -> glTF metres); under it, per object, the finest level's
/// node `<name>_LOD0` with `extensions.MSFT_lod.ids` naming the coarser nodes `<name>_LOD1`, ...
/// (finest to coarsest, not in the scene's hierarchy, as MSFT_lod specifies) and
/// `extras.MSFT_screencoverage`: per level the least screen coverage (projected area of the
/// object's bounding sphere over the viewport area, as Babylon.js measures it) at which the next
/// coarser level would project its error above `screen_error_px`, and 0 for the coarsest (never
/// culled). The sphere is the finest level's patient-frame box's half diagonal (extras
/// "bounding_radius_mm"): an engine with a larger sphere switches later, i.e. finer, never too
/// early (Babylon.js takes the node's local box times its largest axis scale, larger on
/// anisotropic voxel grids: 1.8x on the phantom's 1 x 1 x 2 mm). Every level node's matrix maps its
/// stored positions to LPS mm, and its extras give "error_mm" (the level's bound), "triangles" and
/// "lod". Meshes carry POSITION and NORMAL (area weighted, of that level) and one material per
/// object. The buffer holds the levels coarse-first (every object's coarsest, then the next finer,
/// ...), so a loader reading the file from its start (Babylon.js's MSFT_lod with range requests)
/// gets the coarse levels early. Draco primitives store positions on the model's grid losslessly
/// and are decoded again and compared with their cut before anything is written.
///
/// Atomic (temporary file, then rename). \throw Error{Unsupported} for an extension other than
/// .glb, or over 4 GiB; Error{InvalidInput} for empty scenes, models without a grid, bad colours,
/// bad options or sheared frames; Error{Io} if the file cannot be written; Error{Internal} when
/// an encoder fails or its output differs from the input.
LodStats write_lod_gltf(const std::filesystem::path& path,
                        const std::vector<LodObject>& objects,
                        const SliceFrame& frame,
                        const SceneInfo& info,
                        const LodOptions& options = {});

}  // namespace strata

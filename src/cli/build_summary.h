#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "contours/contour_stats.h"
#include "core/report.h"
#include "exporters/lod_gltf.h"
#include "exporters/progressive_gltf.h"
#include "input/slice_stack.h"
#include "mesh/mesh_checks.h"
#include "pipeline/reconstruct.h"

// The report layer of the `strata` command: what a command made, as typed values filled once,
// rendered twice (JSON for summary.json and --json, text for the terminal). Nothing here parses
// JSON back; both renderings read the same structs.

namespace strata::cli {

using Json = nlohmann::ordered_json;

/// A label of the input stack with its voxel statistics.
struct InputLabelSummary {
    LabelInfo label;
    std::uint64_t voxels = 0;
    std::uint32_t first_slice = 0;  ///< 0 when the label has no voxel
    std::uint32_t last_slice = 0;
    std::uint32_t slices = 0;  ///< slices holding at least one voxel
    double volume_ml = 0.0;    ///< voxels times the voxel volume
};

/// The input stack as read: source, grid, affine and labels.
struct InputSummary {
    std::string source;
    std::string source_frame;
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::uint32_t depth = 0;
    Vec3 spacing_mm;
    Affine3 index_to_world;  ///< voxel index -> patient LPS mm
    std::vector<InputLabelSummary> labels;
};

/// Summarises `stack` (one pass over its voxels).
InputSummary summarize_input(const SliceStack& stack);

/// The medial axes of one label, over every slice pair.
struct MedialSummary {
    std::uint64_t curves = 0;
    std::uint64_t points = 0;
    std::uint64_t unmatched_runs = 0;  ///< contour runs without a correspondence
    std::uint64_t unmatched_points = 0;
};

/// One level of a multiresolution model: the cut at that level.
struct LevelSummary {
    std::uint32_t level = 0;
    std::size_t triangles = 0;
    std::size_t clusters = 0;
    double error_px = 0.0;
    double error_mm = 0.0;
};

/// One object's full-resolution surface (checked in patient LPS mm) and its model's levels.
struct SurfaceSummary {
    std::uint16_t label = 0;
    std::filesystem::path file;  ///< its mesh file under the output folder
    std::size_t vertices = 0;
    std::size_t triangles = 0;
    std::size_t components = 0;
    std::vector<int> genus;  ///< per component
    bool closed_manifold = false;
    double volume_ml = 0.0;
    std::uint32_t slabs = 0;
    std::uint32_t caps = 0;
    std::uint32_t steiner_points = 0;
    std::size_t fallback_corner_slices = 0;
    std::size_t fallback_partly_unsimplified_slices = 0;
    std::uint32_t fallback_unsimplified_slices = 0;
    std::uint32_t fallback_split_slabs = 0;
    bool verified = false;
    std::uint32_t topology_mismatches = 0;
    std::uint32_t failed_slabs = 0;
    /// The multiresolution model, when one was built: its levels, finest first, and groups.
    std::optional<std::vector<LevelSummary>> levels;
    std::size_t groups = 0;
    std::vector<std::string> problems;  ///< check_mesh's problems when not a closed manifold
};

/// One label of the input: its contours, medial axes and surface.
struct ObjectSummary {
    std::uint16_t label = 0;
    std::string name;
    LabelContourStats contours;  ///< zeros when the label has no contour
    MedialSummary medial;
};

/// One object of OUTPUT/lods.glb.
struct LodObjectSummary {
    std::string name;
    std::uint16_t label = 0;
    std::vector<LodLevelStats> levels;  ///< finest first
};

/// OUTPUT/lods.glb.
struct LodSummary {
    std::filesystem::path file;
    std::string compression;  ///< "draco" or "meshopt"
    std::size_t total_bytes = 0;
    std::vector<LodObjectSummary> objects;
};

/// OUTPUT/model.<format>: the progressive scene.
struct ModelSummary {
    std::filesystem::path file;
    std::size_t objects = 0;  ///< objects with a surface
    ProgressiveStats stats;
};

/// Wall time and process CPU time of one step of the build, in the order run.
struct TimingSummary {
    std::string step;
    double seconds = 0.0;      ///< wall time
    double cpu_seconds = 0.0;  ///< process CPU time (every thread, user + system)
};

/// Everything `strata build` reports, filled once by run_build.
struct BuildSummary {
    InputSummary input;
    double tolerance_px = 0.0;                     ///< contour simplification tolerance
    std::vector<LabelContourStats> contour_stats;  ///< labels with contours, by value
    std::vector<ObjectSummary> objects;            ///< every label of the input, table order
    double slice_spacing_px = 0.0;                 ///< d of the slice-space surfaces
    std::vector<SurfaceSummary> surfaces;          ///< one per surface built, in build order
    std::optional<std::filesystem::path> scene;    ///< OUTPUT/scene.glb when written
    std::optional<ModelSummary> model;             ///< when written
    std::optional<LodSummary> lods;                ///< OUTPUT/lods.glb when written
    std::filesystem::path output_dir;
    std::filesystem::path summary_file;  ///< OUTPUT/summary.json
    std::vector<TimingSummary> timings;  ///< input, the stages, export
    std::vector<Warning> warnings;
};

/// Per label of the stack's table: its contour statistics (from `contour_stats`, sorted by
/// label) and its medial axes' counts (Reconstruction::medial_counts).
std::vector<ObjectSummary> summarize_objects(const SliceStack& stack,
                                             const Reconstruction& result,
                                             const std::vector<LabelContourStats>& contour_stats);

/// A surface's counts, the repair steps taken on it (`repairs`), with `check` of its mesh in
/// patient LPS mm written to `file` (levels and groups left to the caller).
SurfaceSummary summarize_surface(const ObjectSurface& surface,
                                 const RepairRecord& repairs,
                                 const MeshReport& check,
                                 const std::filesystem::path& file);

/// The cut at every level of `model`, finest first; `mm_per_px` converts its errors.
std::vector<LevelSummary> summarize_levels(const MultiresMesh& model, double mm_per_px);

/// The JSON of an input stack (`strata info`, `strata phantom --json`, summary.json's "input").
Json input_json(const InputSummary& input);

/// The warnings as a JSON array of {stage, where, message}.
Json warnings_json(const std::vector<Warning>& warnings);

/// summary.json: the build summary as indented JSON text, ending in a newline.
std::string build_summary_json(const BuildSummary& summary);

/// The input stack as text: source, grid, affine and one line per label.
void print_input(std::ostream& out, const InputSummary& input);

/// The terminal report of `strata build` (warnings not included: they go to stderr).
void print_build_report(std::ostream& out, const BuildSummary& summary);

/// Every warning as "strata: warning: <stage>: <where>: <message>", one per line.
void print_warnings(std::ostream& out, const std::vector<Warning>& warnings);

/// "X x Y x Z" with %g.
std::string format_vec(Vec3 v);

}  // namespace strata::cli

#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/report.h"
#include "pipeline/reconstruct.h"

namespace strata {

/// The repair policy: what the pipeline does where a stage cannot give its guarantee on some
/// input, in the order it is tried (docs/architecture.md section 3). Every step taken is
/// recorded in the label's RepairRecord (pipeline/repair_record.h) and in summary.json, and
/// reported as a warning; a surface is never silently broken.
enum class RepairStep : std::uint8_t {
    /// A slab's contours overlap unlike the pixels (LabelTriangulation::mismatched_slabs): the
    /// label's contours on both its slices are simplified again with vertices at pixel corners
    /// only (resimplify_label), and the label triangulated again.
    kCornerVertices,
    /// Still mismatched: the simplified edges of those slices near a neighbouring slice's
    /// contours go back to their original points (unsimplify_near_neighbours), unless that makes
    /// the contours cross.
    kOriginalNearNeighbours,
    /// Still mismatched: the whole slice unsimplified (exactly the pixel boundary).
    kOriginalContours,
    /// Even the original contours mismatch (saddle corners): the slab is split at the pixels'
    /// AND layer (triangulate_label_split).
    kSplitAtAndLayer,
    /// The surface does not snap to the quantization grid, or its snapped form fails
    /// verification: the step is halved, up to QuantizeOptions::max_halvings times.
    kFinerGrid,
    /// Still unsnapped with edge-midpoint contours: the label's contours are simplified again
    /// at pixel corners on every slice, the medial axes recomputed, the label triangulated
    /// (with the steps above), quantized and verified again. An object that still is not on a
    /// grid fails `strata build` (its surface cannot be in the progressive model).
    kLabelAtCorners,
    /// The surface fails verification: it is kept at full resolution only (no coarser levels).
    kFullResolutionOnly,
};

/// One step of the policy, by name.
struct RepairStepName {
    RepairStep step;
    std::string_view name;
};

/// The steps in the order they are tried.
inline constexpr std::array<RepairStepName, 7> kRepairPolicy{{
    {RepairStep::kCornerVertices, "contour vertices at pixel corners"},
    {RepairStep::kOriginalNearNeighbours, "original points near the neighbouring contours"},
    {RepairStep::kOriginalContours, "original contours"},
    {RepairStep::kSplitAtAndLayer, "slab split at the pixels' AND layer"},
    {RepairStep::kFinerGrid, "finer quantization grid"},
    {RepairStep::kLabelAtCorners, "label rebuilt from corner-only contours"},
    {RepairStep::kFullResolutionOnly, "full resolution only"},
}};

/// The radius (px) of kOriginalNearNeighbours around a neighbouring slice's contours within
/// which simplified edges go back to their original points: the two contours' simplification
/// tolerances plus half a pixel (the contour sites lie every half pixel).
double unsimplify_radius_px(double tolerance_px);

/// kOriginalNearNeighbours for slice `slice` of `label`: every simplified edge of the label's
/// contours in `set` that replaces an original point within `radius_px` of an original contour
/// of the label on slice - 1 or slice + 1 (by those slices' distance fields in `fields`) is
/// replaced by its original points; the rest stays as it is. Only where the contours of
/// neighbouring slices come that close can simplification change how they overlap. Returns
/// whether any edge changed. The result may cross itself: the caller checks.
bool unsimplify_near_neighbours(SliceContourSet& set,
                                std::uint16_t label,
                                const std::vector<SliceDistanceFields>& fields,
                                std::uint32_t slice,
                                double radius_px);

/// The triangulation stage with the repairs of its mismatched slabs (kCornerVertices ..
/// kSplitAtAndLayer): one closed surface per label of `labels` (increasing), in that order,
/// labels in parallel on `threads` workers (0: all cores; output identical for any number),
/// `progress` called per label (may be empty). `stack` gives the pixels for kSplitAtAndLayer.
struct RepairedSurfaces {
    std::vector<ObjectSurface> surfaces;
    std::vector<RepairRecord> repairs;  ///< per surface: the steps taken on it
};
RepairedSurfaces triangulate_with_repairs(const SliceStack& stack,
                                          const SliceContours& contours,
                                          const std::vector<SliceDistanceFields>& fields,
                                          const std::vector<MedialAxis>& medial_axes,
                                          const TriangulateOptions& options,
                                          const std::vector<std::uint16_t>& labels,
                                          unsigned threads,
                                          const ProgressFn& progress);

/// The quantize stage for one surface, with verification and kFinerGrid: snaps it to the grid
/// of `options.step` and verifies the snapped surface, and checks it exactly for
/// self-intersections and degenerate triangles in the grid frame files store too
/// (grid_frame_positions; with or without `verify`). When the surface does not snap, or its
/// snapped form fails these checks while the original passes, the step is halved (up to
/// `options.max_halvings` times); failing that, the original is kept unsnapped. Returns why the
/// surface stayed unsnapped (empty when it was snapped or quantization is off).
std::string quantize_with_repairs(const SliceStack& stack,
                                  double slice_spacing_px,
                                  const QuantizeOptions& options,
                                  bool verify,
                                  ObjectSurface& surface);

/// What kLabelAtCorners needs of the stages' options, as reconstruct() ran them.
struct RebuildOptions {
    double tolerance_px = 0.5;  ///< the contours' simplification tolerance
    MedialOptions medial;
    TriangulateOptions triangulate;
    QuantizeOptions quantize;
    bool verify = true;
    unsigned threads = 0;  ///< worker threads, 0 = all cores
};

/// kLabelAtCorners for the surfaces `redo` (indices into `result.surfaces`, whose
/// `unsnapped[i]` says why they stayed unsnapped): re-simplifies their contours in
/// `result.contours` at pixel corners, recomputes `result.medial_axes`, triangulates them
/// (triangulate_with_repairs, replacing their `result.repairs`) and quantizes them again
/// (quantize_with_repairs, updating `unsnapped`). Warns in `report` how each rebuild ended.
void rebuild_at_corners(const SliceStack& stack,
                        const RebuildOptions& options,
                        const std::vector<std::size_t>& redo,
                        Reconstruction& result,
                        std::vector<std::string>& unsnapped,
                        Report& report);

}  // namespace strata

#pragma once

#include <cstdint>
#include <vector>

#include "core/report.h"
#include "input/planar_contours.h"
#include "input/slice_stack.h"
#include "pipeline/reconstruct.h"

namespace strata {

/// Largest distance (px) of a scan-converted boundary from the polygons it was traced from: half
/// a pixel diagonal. Added to every error bound of a model built from planar contours.
inline constexpr double kScanConversionPx = 0.70710678118654757;

/// How planar contours become slice stacks for the pipeline.
struct ContourGridOptions {
    /// In-plane pixel pitch (mm) of the slice grid the contours are scan-converted on; 0: a
    /// quarter of the reference grid's pixel, else the largest structure's extent / 1024, in both
    /// cases coarsened until one structure's grid has at most `max_voxels` voxels.
    double pitch_mm = 0.0;
    std::uint64_t max_voxels = std::uint64_t(1) << 26;
    /// Pixels of background around each structure's extent.
    std::uint32_t margin_px = 4;
};

/// One structure as the pipeline sees it: a one-label stack on the structure's own planes (slice
/// k = the k-th plane carrying a contour of it), cropped to its extent on the common pixel grid.
struct ContourStack {
    SliceStack stack;             ///< label value = the object's label, one slice per plane
    std::vector<double> plane_w;  ///< per slice: the plane's position along the normal, mm
    std::int64_t offset_x = 0;    ///< the crop's first column in the common grid, px
    std::int64_t offset_y = 0;    ///< the crop's first row in the common grid, px
};

/// The common frame of every structure: slice space x, y in px of `pitch_mm` on the plane axes,
/// z = (w - first plane) / pitch_mm px, so slice k of the reference spacing lies at z = k d.
struct ContourFrame {
    SliceStack stack;  ///< no voxels (depth 0): its affine and label table (one per object)
    double pitch_mm = 0.0;
    double slice_spacing_px = 1.0;  ///< d: reference plane spacing / pitch
    double first_w = 0.0;           ///< w of z = 0
    double u0 = 0.0;                ///< u of x = 0 (a pixel corner)
    double v0 = 0.0;                ///< v of y = 0
};

/// The frame of `contours` (see ContourFrame) and the pitch chosen (reported in `report`).
ContourFrame contour_frame(const PlanarContours& contours,
                           const ContourGridOptions& options,
                           Report& report);

/// Scan-converts one object's polygons on `frame`'s grid: a pixel is inside when its centre is
/// inside the plane's contours by the even-odd rule (exact crossings of each pixel row), so the
/// traced pixel boundary lies within one pixel diagonal of the polygons. Objects without planes
/// give an empty stack (depth 0).
ContourStack contour_stack(const ContourObject& object,
                           std::uint16_t label,
                           const ContourFrame& frame,
                           const ContourGridOptions& options);

/// Maps a surface of `roi`'s slice space (its own planes, spacing roi.stack's) into `frame`'s
/// slice space: x, y shifted by the crop, z piecewise linear through the planes (exact: every
/// full-resolution triangle lies between two consecutive planes).
Vec3 contour_to_frame(const ContourStack& roi, const ContourFrame& frame, Vec3 p);

/// Runs the pipeline on every object of `contours` with planes (one reconstruction each, on its
/// own stack) and gathers the surfaces and models in `frame`'s slice space, in object order.
/// The models' error bounds include kScanConversionPx (so they hold against the input polygons
/// in the mesh-to-contour direction; a feature thinner than a pixel can vanish). With unevenly
/// spaced planes the groups' bounds are measured again in the frame after the plane map (see
/// remap_bounds in the .cpp), so every cut's bound holds there, not only in slice space.
/// Objects without closed contours get no surface (clean_planar_contours reported them).
/// Returns the reconstruction; `result.contours`, `fields` and `medial_axes` are left empty.
Reconstruction reconstruct_contours(const PlanarContours& contours,
                                    const ContourFrame& frame,
                                    const ContourGridOptions& grid,
                                    const ReconstructOptions& options,
                                    Report& report);

}  // namespace strata

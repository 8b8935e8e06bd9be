#pragma once

#include <cstdint>
#include <vector>

#include "contours/slice_contours.h"
#include "core/progress.h"
#include "input/slice_stack.h"

namespace strata {

/// Options of the contour stage.
struct ContourOptions {
    double tolerance_px = 0.5;   ///< Douglas-Peucker tolerance (px); 0.5 keeps every pixel exact
    bool edge_midpoints = true;  ///< SimplifyOptions::edge_midpoints
    unsigned threads = 0;        ///< worker threads, 0 = all cores; output is identical for any
    ProgressFn progress;         ///< called per traced slice (may be empty)
};

/// Traces every contour of every label on slice `k` of `stack` (paper 2.I.1): closed simple
/// polygons on the pixel-corner grid, foreground 8-connected, background 4-connected, outer
/// contours counter-clockwise and holes clockwise, nesting and regions recorded (see Contour).
/// Objects touching the image border are closed along the border (pixels outside the image are
/// background). `simplified` is left empty. Only labels listed in `labels` are traced (sorted,
/// non-zero).
SliceContourSet trace_slice_contours(const SliceStack& stack,
                                     std::uint32_t k,
                                     const std::vector<std::uint16_t>& labels);

/// Links between the regions of slices k and k+1 by pixel overlap (see RegionLink), for every
/// label in `labels`; `lower` and `upper` are the traced contour sets of those slices.
std::vector<RegionLink> link_slices(const SliceStack& stack,
                                    std::uint32_t k,
                                    const SliceContourSet& lower,
                                    const SliceContourSet& upper,
                                    const std::vector<std::uint16_t>& labels);

/// The contour stage: traces all slices (in parallel), links consecutive slices and simplifies
/// every contour with Douglas-Peucker to `options.tolerance_px` without self-intersections or
/// crossings between contours of a label. Only labels of `stack.label_table` are traced.
SliceContours extract_contours(const SliceStack& stack, const ContourOptions& options);

}  // namespace strata

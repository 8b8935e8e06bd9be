#pragma once

#include <cstdint>
#include <vector>

#include "contours/slice_contours.h"

namespace strata {

/// What the contour stage produced for one label.
struct LabelContourStats {
    std::uint16_t label = 0;
    std::uint32_t contours = 0;           ///< all contours, every slice
    std::uint32_t holes = 0;              ///< of which holes
    std::uint32_t slices = 0;             ///< slices holding the label
    std::uint32_t max_depth = 0;          ///< deepest nesting (0: no holes)
    std::uint64_t points_original = 0;    ///< original contour points
    std::uint64_t points_simplified = 0;  ///< simplified contour vertices
    double max_deviation_px = 0.0;        ///< largest simplification deviation
    std::uint32_t links = 0;              ///< foreground links to the next slice
    std::uint32_t hole_links = 0;         ///< background links touching holes
};

/// Per-label statistics, sorted by label value.
std::vector<LabelContourStats> contour_stats(const SliceContours& contours);

}  // namespace strata

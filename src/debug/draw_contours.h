#pragma once

#include <cstdint>

#include "contours/slice_contours.h"
#include "debug/rgb_image.h"
#include "input/slice_stack.h"

namespace strata {

/// Debug picture of slice k: the label mask (dimmed label colours), the original contours
/// (grey) and the simplified contours (outer yellow, holes cyan, vertices as dots), magnified
/// `scale` times (pixel (i, j) covers canvas [i*scale, (i+1)*scale)).
RgbImage draw_slice_contours(const SliceStack& stack,
                             const SliceContours& contours,
                             std::uint32_t k,
                             int scale);

/// A magnification that makes a slice of this size about 1000 canvas pixels wide (1 to 16).
int debug_scale(std::uint32_t width, std::uint32_t height);

}  // namespace strata

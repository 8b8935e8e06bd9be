#pragma once

#include <cstdint>

#include "contours/slice_contours.h"
#include "core/rgb_image.h"
#include "input/slice_stack.h"

namespace strata {

/// The part of the slices a debug picture shows, and its magnification.
struct DebugView {
    std::uint32_t x0 = 0;  ///< first pixel column shown
    std::uint32_t y0 = 0;  ///< first pixel row shown
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    int scale = 1;  ///< canvas pixels per slice pixel

    Vec2 to_canvas(Vec2 p_px) const { return {(p_px.x - x0) * scale, (p_px.y - y0) * scale}; }
};

/// A view of every non-zero pixel of the stack plus a 4 px border, magnified so that it is
/// about 1000 canvas pixels across (1 to 32 times).
DebugView debug_view(const SliceStack& stack);

/// Debug picture of slice k: the label mask (dimmed label colours), the original contours
/// (grey) and the simplified contours (outer yellow, holes cyan, vertices red).
RgbImage draw_slice_contours(const SliceStack& stack,
                             const SliceContours& contours,
                             std::uint32_t k,
                             const DebugView& view);

}  // namespace strata

#include "debug/draw_contours.h"

#include <algorithm>

namespace strata {

DebugView debug_view(const SliceStack& stack) {
    std::uint32_t x0 = stack.width;
    std::uint32_t y0 = stack.height;
    std::uint32_t x1 = 0;
    std::uint32_t y1 = 0;
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        const auto slice = stack.slice(k);
        for (std::uint32_t j = 0; j < stack.height; ++j) {
            for (std::uint32_t i = 0; i < stack.width; ++i) {
                if (slice[std::size_t(j) * stack.width + i] != 0) {
                    x0 = std::min(x0, i);
                    y0 = std::min(y0, j);
                    x1 = std::max(x1, i + 1);
                    y1 = std::max(y1, j + 1);
                }
            }
        }
    }
    DebugView view;
    if (x1 <= x0) {  // nothing to show: the whole slice
        x0 = 0;
        y0 = 0;
        x1 = stack.width;
        y1 = stack.height;
    }
    constexpr std::uint32_t kBorder = 4;
    view.x0 = x0 > kBorder ? x0 - kBorder : 0;
    view.y0 = y0 > kBorder ? y0 - kBorder : 0;
    view.width = std::min(stack.width, x1 + kBorder) - view.x0;
    view.height = std::min(stack.height, y1 + kBorder) - view.y0;
    const std::uint32_t size = std::max({view.width, view.height, 1u});
    view.scale = static_cast<int>(std::clamp<std::uint32_t>(1000 / size, 1, 32));
    return view;
}

RgbImage draw_slice_contours(const SliceStack& stack,
                             const SliceContours& contours,
                             std::uint32_t k,
                             const DebugView& view) {
    const int scale = view.scale;
    RgbImage image(view.width * scale, view.height * scale);
    std::vector<ColorSrgb8> colors(65536, ColorSrgb8{255, 255, 255});
    for (const LabelInfo& l : stack.label_table) {
        colors[l.value] = l.color;
    }
    for (std::uint32_t j = 0; j < view.height; ++j) {
        for (std::uint32_t i = 0; i < view.width; ++i) {
            const std::uint16_t v = stack.at(view.x0 + i, view.y0 + j, k);
            if (v == 0) {
                continue;
            }
            const ColorSrgb8 c = colors[v];
            const ColorSrgb8 dim = {static_cast<std::uint8_t>(c[0] * 2 / 5),
                                    static_cast<std::uint8_t>(c[1] * 2 / 5),
                                    static_cast<std::uint8_t>(c[2] * 2 / 5)};
            for (int y = 0; y < scale; ++y) {
                for (int x = 0; x < scale; ++x) {
                    image.set(std::int64_t(i) * scale + x, std::int64_t(j) * scale + y, dim);
                }
            }
        }
    }
    const SliceContourSet& set = contours.slices.at(k);
    for (const Contour& c : set.contours) {
        for (std::size_t i = 0; i < c.points.size(); ++i) {
            image.line(view.to_canvas(c.points[i]),
                       view.to_canvas(c.points[(i + 1) % c.points.size()]), {150, 150, 150});
        }
    }
    for (const Contour& c : set.contours) {
        const ColorSrgb8 color = c.is_hole ? ColorSrgb8{0, 230, 255} : ColorSrgb8{255, 230, 0};
        const std::size_t n = c.simplified.size();
        for (std::size_t e = 0; e < n; ++e) {
            image.line(view.to_canvas(c.points[c.simplified[e]]),
                       view.to_canvas(c.points[c.simplified[(e + 1) % n]]), color);
        }
        const int r = scale >= 4 ? 1 : 0;
        for (std::uint32_t v : c.simplified) {
            image.dot(view.to_canvas(c.points[v]), r, {255, 60, 60});
        }
    }
    return image;
}

}  // namespace strata

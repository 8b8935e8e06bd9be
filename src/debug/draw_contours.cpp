#include "debug/draw_contours.h"

#include <algorithm>

namespace strata {

int debug_scale(std::uint32_t width, std::uint32_t height) {
    const std::uint32_t size = std::max(width, height);
    return static_cast<int>(
        std::clamp<std::uint32_t>(1000 / std::max<std::uint32_t>(size, 1), 1, 16));
}

RgbImage draw_slice_contours(const SliceStack& stack,
                             const SliceContours& contours,
                             std::uint32_t k,
                             int scale) {
    RgbImage image(stack.width * scale, stack.height * scale);
    std::vector<ColorSrgb8> colors(65536, ColorSrgb8{255, 255, 255});
    for (const LabelInfo& l : stack.label_table) {
        colors[l.value] = l.color;
    }
    for (std::uint32_t j = 0; j < stack.height; ++j) {
        for (std::uint32_t i = 0; i < stack.width; ++i) {
            const std::uint16_t v = stack.at(i, j, k);
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
    auto canvas = [scale](Vec2 p) { return Vec2{p.x * scale, p.y * scale}; };
    const SliceContourSet& set = contours.slices.at(k);
    for (const Contour& c : set.contours) {
        for (std::size_t i = 0; i < c.points.size(); ++i) {
            image.line(canvas(c.points[i]), canvas(c.points[(i + 1) % c.points.size()]),
                       {150, 150, 150});
        }
    }
    for (const Contour& c : set.contours) {
        const ColorSrgb8 color = c.is_hole ? ColorSrgb8{0, 230, 255} : ColorSrgb8{255, 230, 0};
        const std::size_t n = c.simplified.size();
        for (std::size_t e = 0; e < n; ++e) {
            image.line(canvas(c.points[c.simplified[e]]),
                       canvas(c.points[c.simplified[(e + 1) % n]]), color);
        }
        const int r = scale >= 4 ? 1 : 0;
        for (std::uint32_t v : c.simplified) {
            image.dot(canvas(c.points[v]), r, {255, 60, 60});
        }
    }
    return image;
}

}  // namespace strata

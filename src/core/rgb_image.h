#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/types.h"

namespace strata {

/// An 8-bit RGB picture for debug output (row-major, 3 bytes per pixel).
struct RgbImage {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<std::uint8_t> rgb;

    RgbImage() = default;
    RgbImage(std::uint32_t w, std::uint32_t h) : width(w), height(h), rgb(std::size_t(w) * h * 3) {}

    void set(std::int64_t x, std::int64_t y, ColorSrgb8 c) {
        if (x < 0 || y < 0 || x >= width || y >= height) {
            return;
        }
        std::uint8_t* p = &rgb[(std::size_t(y) * width + std::size_t(x)) * 3];
        p[0] = c[0];
        p[1] = c[1];
        p[2] = c[2];
    }
    /// Straight line between two canvas points (DDA, both ends drawn).
    void line(Vec2 a, Vec2 b, ColorSrgb8 c) {
        const double steps = std::max({std::abs(b.x - a.x), std::abs(b.y - a.y), 1.0});
        for (int i = 0; i <= static_cast<int>(std::ceil(steps)); ++i) {
            const double t = std::min(1.0, i / steps);
            set(std::llround(a.x + t * (b.x - a.x)), std::llround(a.y + t * (b.y - a.y)), c);
        }
    }
    /// Filled square dot of half-width r around a canvas point.
    void dot(Vec2 p, int r, ColorSrgb8 c) {
        for (int dy = -r; dy <= r; ++dy) {
            for (int dx = -r; dx <= r; ++dx) {
                set(std::llround(p.x) + dx, std::llround(p.y) + dy, c);
            }
        }
    }
};

}  // namespace strata

#pragma once

// Random label stacks for property tests: unions of ellipsoids minus random balls (through
// holes, cavities, branching, objects appearing and vanishing). Header-only.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "input/slice_stack.h"

namespace strata::test {

/// Uniform double in [lo, hi) drawn from `rng`.
inline double uniform(std::mt19937& rng, double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
}

/// An axis-aligned ellipsoid (px, slice space).
struct Blob {
    double cx, cy, cz, rx, ry, rz;
    bool inside(double x, double y, double z) const {
        const double u = (x - cx) / rx;
        const double v = (y - cy) / ry;
        const double w = (z - cz) / rz;
        return u * u + v * v + w * w <= 1.0;
    }
};

/// A 40 x 40 stack of 3..12 slices, slice spacing d = 1..10 px (integer, in index_to_world's
/// third column: the slice spacing in pixels is its length), label 1 = 1..4 random ellipsoids
/// minus 0..2 random ellipsoidal holes near them, rasterised at pixel centres
/// (i + 0.5, j + 0.5, k d). May be empty. The same `rng` state gives the same stack.
inline SliceStack random_blob_stack(std::mt19937& rng) {
    SliceStack stack;
    stack.width = 40;
    stack.height = 40;
    stack.depth = std::uniform_int_distribution<std::uint32_t>(3, 12)(rng);
    const double d = std::uniform_int_distribution<int>(1, 10)(rng);
    const double z_extent = (stack.depth - 1) * d;
    std::vector<Blob> solids;
    std::vector<Blob> holes;
    const int n = std::uniform_int_distribution<int>(1, 4)(rng);
    for (int i = 0; i < n; ++i) {
        solids.push_back({uniform(rng, 8, 32), uniform(rng, 8, 32), uniform(rng, 0, z_extent),
                          uniform(rng, 2, 12), uniform(rng, 2, 12),
                          uniform(rng, 0.6, 1.0) * std::max(2.0, z_extent / 2)});
    }
    const int m = std::uniform_int_distribution<int>(0, 2)(rng);
    for (int i = 0; i < m; ++i) {
        const Blob& s = solids[std::size_t(i) % solids.size()];
        holes.push_back({s.cx + uniform(rng, -3, 3), s.cy + uniform(rng, -3, 3),
                         s.cz + uniform(rng, -d, d), uniform(rng, 1.5, 6), uniform(rng, 1.5, 6),
                         uniform(rng, 0.3, 1.5) * std::max(d, z_extent / 3)});
    }
    stack.labels.assign(std::size_t(stack.width) * stack.height * stack.depth, 0);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        for (std::uint32_t j = 0; j < stack.height; ++j) {
            for (std::uint32_t i = 0; i < stack.width; ++i) {
                const double x = i + 0.5;
                const double y = j + 0.5;
                const double z = k * d;
                const bool in = std::any_of(solids.begin(), solids.end(),
                                            [&](const Blob& b) { return b.inside(x, y, z); }) &&
                                std::none_of(holes.begin(), holes.end(),
                                             [&](const Blob& b) { return b.inside(x, y, z); });
                stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = in ? 1 : 0;
            }
        }
    }
    stack.index_to_world.linear = {{{1, 0, 0}, {0, 1, 0}, {0, 0, d}}};
    stack.label_table.push_back({1, "blob", {200, 80, 80}});
    stack.source = "random";
    return stack;
}

}  // namespace strata::test

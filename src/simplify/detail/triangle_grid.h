#pragma once

// Candidate neighbours for exact triangle intersection tests during simplification.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/types.h"

namespace strata::detail {

/// True when the bounding boxes of two triangles overlap (touching counts).
inline bool boxes_overlap(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b) {
    // note: one lambda per axis; Vec3::operator[] branches on every call in this hot test.
    auto separated = [&](auto coord) {
        const double alo = std::min({coord(a[0]), coord(a[1]), coord(a[2])});
        const double ahi = std::max({coord(a[0]), coord(a[1]), coord(a[2])});
        const double blo = std::min({coord(b[0]), coord(b[1]), coord(b[2])});
        const double bhi = std::max({coord(b[0]), coord(b[1]), coord(b[2])});
        return ahi < blo || bhi < alo;
    };
    return !separated([](const Vec3& p) { return p.x; }) &&
           !separated([](const Vec3& p) { return p.y; }) &&
           !separated([](const Vec3& p) { return p.z; });
}

/// A uniform grid over triangle boxes: candidate neighbours for the intersection tests. Entries
/// go stale when a triangle changes (it is added again where it now lies); queries return a
/// superset, which the exact test sorts out.
class TriangleGrid {
public:
    explicit TriangleGrid(double cell) : inverse_(1.0 / cell) {}

    void insert(std::uint32_t id, const std::array<Vec3, 3>& t) {
        for_cells(t, [&](std::uint64_t key) { cells_[key].push_back(id); });
    }
    template <class Visit>
    void query(const std::array<Vec3, 3>& t, Visit&& visit) const {
        for_cells(t, [&](std::uint64_t key) {
            const auto it = cells_.find(key);
            if (it != cells_.end()) {
                for (const std::uint32_t id : it->second) {
                    visit(id);
                }
            }
        });
    }

private:
    template <class Fn>
    void for_cells(const std::array<Vec3, 3>& t, Fn&& fn) const {
        std::array<std::int64_t, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
            const double mn = std::min({t[0][a], t[1][a], t[2][a]});
            const double mx = std::max({t[0][a], t[1][a], t[2][a]});
            lo[a] = static_cast<std::int64_t>(std::floor(mn * inverse_));
            hi[a] = static_cast<std::int64_t>(std::floor(mx * inverse_));
        }
        for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
            for (std::int64_t y = lo[1]; y <= hi[1]; ++y) {
                for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
                    fn((std::uint64_t(x & 0x1fffff) << 42) | (std::uint64_t(y & 0x1fffff) << 21) |
                       std::uint64_t(z & 0x1fffff));
                }
            }
        }
    }

    double inverse_;
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> cells_;
};

}  // namespace strata::detail

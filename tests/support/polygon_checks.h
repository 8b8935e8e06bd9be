#pragma once

// Brute-force polygon predicates for tests: independent of the library's own geometry code.
// Exact for coordinates on the half-pixel grid of moderate size (products fit a double exactly).

#include <cstddef>
#include <vector>

#include "core/types.h"

namespace strata::test {

inline double orient(Vec2 a, Vec2 b, Vec2 c) {
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

inline bool on_segment(Vec2 a, Vec2 b, Vec2 p) {
    return orient(a, b, p) == 0 && std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) &&
           std::min(a.y, b.y) <= p.y && p.y <= std::max(a.y, b.y);
}

/// True when closed segments ab and cd share at least one point.
inline bool segments_touch(Vec2 a, Vec2 b, Vec2 c, Vec2 d) {
    const double d1 = orient(a, b, c);
    const double d2 = orient(a, b, d);
    const double d3 = orient(c, d, a);
    const double d4 = orient(c, d, b);
    if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) {
        return true;
    }
    return on_segment(a, b, c) || on_segment(a, b, d) || on_segment(c, d, a) || on_segment(c, d, b);
}

/// Closed polygon (last vertex connects to first) is simple: no two non-adjacent edges share a
/// point, adjacent edges share only their common vertex, no repeated vertex. O(n^2).
inline bool is_simple_polygon(const std::vector<Vec2>& p) {
    const std::size_t n = p.size();
    if (n < 3) {
        return false;
    }
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2 a = p[i];
        const Vec2 b = p[(i + 1) % n];
        if (a == b) {
            return false;
        }
        for (std::size_t j = i + 1; j < n; ++j) {
            const Vec2 c = p[j];
            const Vec2 d = p[(j + 1) % n];
            const bool adjacent = j == i + 1 || (i == 0 && j == n - 1);
            if (!adjacent) {
                if (segments_touch(a, b, c, d)) {
                    return false;
                }
            } else {
                // adjacent edges: the far endpoint of one must not lie on the other
                const Vec2 shared = (j == i + 1) ? b : a;
                const Vec2 other_i = (j == i + 1) ? a : b;
                const Vec2 other_j = (j == i + 1) ? d : c;
                (void)shared;
                if (on_segment(c, d, other_i) || on_segment(a, b, other_j)) {
                    return false;
                }
            }
        }
    }
    return true;
}

/// True when two closed polygons share no point (boundaries disjoint).
inline bool polygons_disjoint(const std::vector<Vec2>& p, const std::vector<Vec2>& q) {
    for (std::size_t i = 0; i < p.size(); ++i) {
        for (std::size_t j = 0; j < q.size(); ++j) {
            if (segments_touch(p[i], p[(i + 1) % p.size()], q[j], q[(j + 1) % q.size()])) {
                return false;
            }
        }
    }
    return true;
}

/// Shoelace signed area (positive: counter-clockwise in the (x, y) frame).
inline double signed_area(const std::vector<Vec2>& p) {
    double a = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        const Vec2 u = p[i];
        const Vec2 v = p[(i + 1) % p.size()];
        a += u.x * v.y - v.x * u.y;
    }
    return a / 2;
}

/// Even-odd crossing count of point q against one closed polygon (q must not lie on it).
inline bool inside_even_odd(const std::vector<Vec2>& p, Vec2 q) {
    bool inside = false;
    for (std::size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) {
        const Vec2 a = p[i];
        const Vec2 b = p[j];
        if ((a.y > q.y) != (b.y > q.y)) {
            const double x = a.x + (q.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if (q.x < x) {
                inside = !inside;
            }
        }
    }
    return inside;
}

}  // namespace strata::test

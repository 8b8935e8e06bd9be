// Property tests of contour simplification: random polylines (tolerance bound and exact
// deviations), random x-monotone polylines (the path hull reproduces textbook Douglas-Peucker),
// random masks (simplified contours stay simple and disjoint). Each iteration runs on its own
// std::mt19937 seeded from a std::mt19937(42) stream (the seed is in the failure message); more
// iterations with STRATA_PROPERTY_ITERATIONS.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "contours/simplify_contours.h"
#include "support/property.h"

namespace strata {
namespace {

using test::property_iterations;

double uniform(std::mt19937& rng, double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// ---- Independent brute force ----------------------------------------------------------------

double distance_to_segment(Vec2 p, Vec2 a, Vec2 b) {
    const double dx = b.x - a.x;
    const double dy = b.y - a.y;
    const double length_sq = dx * dx + dy * dy;
    double t = length_sq > 0 ? ((p.x - a.x) * dx + (p.y - a.y) * dy) / length_sq : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return std::hypot(p.x - (a.x + t * dx), p.y - (a.y + t * dy));
}

/// Checks the kept indices, the per-edge bound and recorded deviations, and (if asked; it is
/// O(n m)) the one-sided Hausdorff distance from the original points to the simplified
/// polyline.
void check_simplification(const std::vector<Vec2>& points,
                          const std::vector<std::uint32_t>& kept,
                          const std::vector<double>& deviation,
                          bool closed,
                          double tolerance,
                          bool with_hausdorff = true) {
    const std::size_t n = points.size();
    ASSERT_FALSE(kept.empty());
    for (std::size_t i = 1; i < kept.size(); ++i) {
        ASSERT_LT(kept[i - 1], kept[i]);
    }
    ASSERT_LT(kept.back(), n);
    if (closed) {
        ASSERT_GE(kept.size(), std::min<std::size_t>(3, n));
        ASSERT_EQ(kept.front(), 0u);
    } else {
        ASSERT_EQ(kept.front(), 0u);
        ASSERT_EQ(kept.back(), n - 1);
    }
    const std::size_t edges = closed ? kept.size() : kept.size() - 1;
    ASSERT_EQ(deviation.size(), edges);
    for (std::size_t e = 0; e < edges; ++e) {
        const std::size_t s = kept[e];
        const std::size_t t = kept[(e + 1) % kept.size()];
        double worst = 0.0;
        for (std::size_t k = (s + 1) % n; k != t; k = (k + 1) % n) {
            worst = std::max(worst, distance_to_segment(points[k], points[s], points[t]));
        }
        ASSERT_LE(worst, tolerance + 1e-12) << "edge " << e;
        ASSERT_NEAR(deviation[e], worst, 1e-12) << "edge " << e;
    }
    if (!with_hausdorff) {
        return;
    }
    double hausdorff = 0.0;
    for (const Vec2& p : points) {
        double nearest = std::numeric_limits<double>::infinity();
        for (std::size_t e = 0; e < std::max<std::size_t>(edges, 1); ++e) {
            nearest = std::min(nearest, distance_to_segment(p, points[kept[e]],
                                                            points[kept[(e + 1) % kept.size()]]));
        }
        hausdorff = std::max(hausdorff, nearest);
    }
    EXPECT_LE(hausdorff, tolerance + 1e-12);
}

// ---- (a) Random polylines ------------------------------------------------------------------

std::vector<Vec2> random_polyline(std::mt19937& rng) {
    const int n = 1 + static_cast<int>(rng() % 200);
    std::vector<Vec2> points;
    switch (rng() % 3) {
        case 0: {  // random walk on the half-pixel grid (repeats, folds, coincident ends)
            Vec2 p{0.5 * static_cast<int>(rng() % 20), 0.5 * static_cast<int>(rng() % 20)};
            for (int i = 0; i < n; ++i) {
                points.push_back(p);
                p = p + Vec2{0.5 * (static_cast<int>(rng() % 5) - 2),
                             0.5 * (static_cast<int>(rng() % 5) - 2)};
            }
            break;
        }
        case 1:  // random real points in a box
            for (int i = 0; i < n; ++i) {
                points.push_back({uniform(rng, 0, 20), uniform(rng, 0, 20)});
            }
            break;
        default: {  // random real walk
            Vec2 p{uniform(rng, -5, 5), uniform(rng, -5, 5)};
            for (int i = 0; i < n; ++i) {
                points.push_back(p);
                p = p + Vec2{uniform(rng, -2, 2), uniform(rng, -2, 2)};
            }
            break;
        }
    }
    return points;
}

TEST(SimplifyProperty, RandomPolylinesStayWithinToleranceWithExactDeviations) {
    const int iterations = property_iterations(3000);
    std::mt19937 seeds(42);
    for (int i = 0; i < iterations; ++i) {
        const std::uint32_t seed = seeds();
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937 rng(seed);
        const std::vector<Vec2> points = random_polyline(rng);
        const double tolerance = rng() % 8 == 0 ? 0.0 : uniform(rng, 0.05, 3.0);
        std::vector<double> deviation;
        const std::vector<std::uint32_t> open = simplify_polyline(points, tolerance, &deviation);
        const bool with_hausdorff = i % 4 == 0;
        check_simplification(points, open, deviation, false, tolerance, with_hausdorff);
        const std::vector<std::uint32_t> closed =
            simplify_closed_polyline(points, tolerance, &deviation);
        check_simplification(points, closed, deviation, true, tolerance, with_hausdorff);
        if (HasFatalFailure()) {
            return;
        }
    }
}

// ---- Path hull versus textbook Douglas-Peucker --------------------------------------------

/// Recursive O(n^2) Douglas-Peucker with line distance, first farthest point on ties.
void classic_dp(const std::vector<Vec2>& p,
                std::size_t i,
                std::size_t j,
                double tolerance,
                std::vector<std::uint32_t>& kept) {
    double worst = -1.0;
    std::size_t at = i;
    const Vec2 d = p[j] - p[i];
    for (std::size_t k = i + 1; k < j; ++k) {
        const double distance = std::abs(cross(d, p[k] - p[i])) / norm(d);
        if (distance > worst) {
            worst = distance;
            at = k;
        }
    }
    if (j > i + 1 && worst > tolerance) {
        classic_dp(p, i, at, tolerance, kept);
        classic_dp(p, at, j, tolerance, kept);
    } else {
        kept.push_back(static_cast<std::uint32_t>(j));
    }
}

TEST(SimplifyProperty, PathHullMatchesClassicDouglasPeucker) {
    const int iterations = property_iterations(1000);
    int compared = 0;
    std::mt19937 seeds(42);
    for (int i = 0; i < iterations; ++i) {
        const std::uint32_t seed = seeds();
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937 rng(seed);
        const int n = 2 + static_cast<int>(rng() % 400);
        std::vector<Vec2> points;
        double x = 0.0;
        double y = 0.0;
        const double roughness = uniform(rng, 0.1, 3.0);
        for (int k = 0; k < n; ++k) {
            points.push_back({x, y});
            x += uniform(rng, 0.2, 2.0);
            y += uniform(rng, -roughness, roughness);
        }
        const double tolerance = uniform(rng, 0.05, 4.0);
        std::vector<std::uint32_t> expected{0};
        classic_dp(points, 0, points.size() - 1, tolerance, expected);
        // Only inputs where line and segment distance agree on the accepted segments.
        bool segment_ok = true;
        for (std::size_t e = 0; e + 1 < expected.size(); ++e) {
            for (std::uint32_t k = expected[e] + 1; k < expected[e + 1]; ++k) {
                segment_ok =
                    segment_ok && distance_to_segment(points[k], points[expected[e]],
                                                      points[expected[e + 1]]) <= tolerance;
            }
        }
        if (!segment_ok) {
            continue;
        }
        ++compared;
        EXPECT_EQ(simplify_polyline(points, tolerance), expected);
    }
    EXPECT_GE(compared, iterations * 9 / 10);
}

// ---- (b) Random masks ---------------------------------------------------------------------

/// Test-only boundary tracer: pixel (i, j) covers [i, i+1] x [j, j+1]; crack edges between
/// foreground and background (outside the image is background) are directed with the
/// foreground on the left; at a saddle corner the contour turns right and cuts the corner
/// through the midpoints of its two edges.
std::vector<std::vector<Vec2>> trace_boundaries(const std::vector<std::uint8_t>& mask,
                                                int width,
                                                int height) {
    const auto fg = [&](int i, int j) {
        return i >= 0 && j >= 0 && i < width && j < height && mask[j * width + i] != 0;
    };
    struct Edge {
        int sx, sy, dx, dy;
    };
    std::vector<Edge> edges;
    for (int j = 0; j < height; ++j) {
        for (int i = 0; i < width; ++i) {
            if (!fg(i, j)) {
                continue;
            }
            if (!fg(i, j - 1))
                edges.push_back({i, j, 1, 0});
            if (!fg(i + 1, j))
                edges.push_back({i + 1, j, 0, 1});
            if (!fg(i, j + 1))
                edges.push_back({i + 1, j + 1, -1, 0});
            if (!fg(i - 1, j))
                edges.push_back({i, j + 1, 0, -1});
        }
    }
    const int corners_x = width + 1;
    std::vector<std::array<int, 2>> outgoing((width + 1) * (height + 1), {-1, -1});
    for (int e = 0; e < static_cast<int>(edges.size()); ++e) {
        auto& slot = outgoing[edges[e].sy * corners_x + edges[e].sx];
        slot[slot[0] < 0 ? 0 : 1] = e;
    }
    const auto is_saddle = [&](int x, int y) { return outgoing[y * corners_x + x][1] >= 0; };
    std::vector<bool> used(edges.size(), false);
    std::vector<std::vector<Vec2>> contours;
    for (int start = 0; start < static_cast<int>(edges.size()); ++start) {
        if (used[start]) {
            continue;
        }
        std::vector<Vec2> points;
        const auto emit = [&](Vec2 p) {
            if (points.empty() || !(points.back() == p)) {
                points.push_back(p);
            }
        };
        int e = start;
        while (!used[e]) {
            used[e] = true;
            const Edge& edge = edges[e];
            const int tx = edge.sx + edge.dx;
            const int ty = edge.sy + edge.dy;
            const Vec2 mid{edge.sx + 0.5 * edge.dx, edge.sy + 0.5 * edge.dy};
            emit(is_saddle(edge.sx, edge.sy) ? mid : Vec2{double(edge.sx), double(edge.sy)});
            if (is_saddle(tx, ty)) {
                emit(mid);
            }
            const auto& next = outgoing[ty * corners_x + tx];
            e = next[0];
            if (next[1] >= 0) {  // saddle: turn right
                const Edge& a = edges[next[0]];
                if (!(a.dx == edge.dy && a.dy == -edge.dx)) {
                    e = next[1];
                }
            }
        }
        if (points.size() > 1 && points.front() == points.back()) {
            points.pop_back();
        }
        contours.push_back(std::move(points));
    }
    return contours;
}

// Exact predicates on the half-pixel grid: coordinates doubled to integers.
struct IPoint {
    std::int64_t x, y;
};
IPoint to_int(Vec2 p) {
    return {std::llround(2 * p.x), std::llround(2 * p.y)};
}
int orient(IPoint a, IPoint b, IPoint c) {
    const std::int64_t det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    return det > 0 ? 1 : (det < 0 ? -1 : 0);
}
bool within(IPoint a, IPoint b, IPoint p) {
    return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
           p.y <= std::max(a.y, b.y);
}
bool touch(IPoint a, IPoint b, IPoint c, IPoint d) {
    const int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a),
              o4 = orient(c, d, b);
    if (o1 * o2 < 0 && o3 * o4 < 0) {
        return true;
    }
    return (o1 == 0 && within(a, b, c)) || (o2 == 0 && within(a, b, d)) ||
           (o3 == 0 && within(c, d, a)) || (o4 == 0 && within(c, d, b));
}

std::vector<IPoint> polygon(const std::vector<Vec2>& points,
                            const std::vector<std::uint32_t>& kept) {
    std::vector<IPoint> result;
    for (const std::uint32_t k : kept) {
        result.push_back(to_int(points[k]));
    }
    return result;
}

/// Brute force O(m^2): non-adjacent edges share no point; adjacent ones only their vertex.
bool is_simple(const std::vector<IPoint>& p) {
    const std::size_t m = p.size();
    if (m < 3) {
        return false;
    }
    for (std::size_t i = 0; i < m; ++i) {
        const IPoint a = p[i], b = p[(i + 1) % m], c = p[(i + 2) % m];
        if (orient(a, b, c) == 0 && (a.x - b.x) * (c.x - b.x) + (a.y - b.y) * (c.y - b.y) > 0) {
            return false;
        }
        for (std::size_t j = i + 2; j < m; ++j) {
            if ((j + 1) % m != i && touch(a, b, p[j], p[(j + 1) % m])) {
                return false;
            }
        }
    }
    return true;
}

bool polygons_touch(const std::vector<IPoint>& p, const std::vector<IPoint>& q) {
    for (std::size_t i = 0; i < p.size(); ++i) {
        for (std::size_t j = 0; j < q.size(); ++j) {
            if (touch(p[i], p[(i + 1) % p.size()], q[j], q[(j + 1) % q.size()])) {
                return true;
            }
        }
    }
    return false;
}

/// A random label image: blobs (discs and boxes) of labels 1 and 2, thin lines, and noise.
std::vector<std::uint8_t> random_labels(std::mt19937& rng, int width, int height) {
    std::vector<std::uint8_t> image(width * height, 0);
    const int blobs = 1 + static_cast<int>(rng() % 6);
    for (int b = 0; b < blobs; ++b) {
        const auto label = static_cast<std::uint8_t>(1 + rng() % 2);
        const double cx = uniform(rng, 0, width), cy = uniform(rng, 0, height);
        const double r = uniform(rng, 1.0, 8.0);
        const bool disc = rng() % 2 == 0;
        for (int j = 0; j < height; ++j) {
            for (int i = 0; i < width; ++i) {
                const double dx = i + 0.5 - cx, dy = j + 0.5 - cy;
                if (disc ? dx * dx + dy * dy <= r * r
                         : std::abs(dx) <= r && std::abs(dy) <= 0.6 * r) {
                    image[j * width + i] = label;
                }
            }
        }
    }
    const int lines = static_cast<int>(rng() % 4);
    for (int l = 0; l < lines; ++l) {  // 1-pixel-wide lines, also diagonal (saddles)
        const auto label = static_cast<std::uint8_t>(rng() % 3);
        int x = static_cast<int>(rng() % width), y = static_cast<int>(rng() % height);
        const int dx = static_cast<int>(rng() % 3) - 1, dy = static_cast<int>(rng() % 3) - 1;
        for (int s = 0; s < 20 && x >= 0 && y >= 0 && x < width && y < height; ++s) {
            image[y * width + x] = label;
            x += dx;
            y += dy;
        }
    }
    const double noise = uniform(rng, 0.0, 0.25);
    for (auto& v : image) {
        if (uniform(rng, 0, 1) < noise) {
            v = static_cast<std::uint8_t>(rng() % 3);
        }
    }
    return image;
}

TEST(SimplifyProperty, MaskContoursStaySimpleAndDisjointWithinTolerance) {
    const int iterations = property_iterations(400);
    std::size_t reinserted_total = 0;
    std::mt19937 seeds(42);
    for (int i = 0; i < iterations; ++i) {
        const std::uint32_t seed = seeds();
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937 rng(seed);
        const int width = 24, height = 24;
        const std::vector<std::uint8_t> image = random_labels(rng, width, height);
        std::vector<Contour> contours;
        for (std::uint8_t label = 1; label <= 2; ++label) {
            std::vector<std::uint8_t> mask(image.size());
            for (std::size_t k = 0; k < image.size(); ++k) {
                mask[k] = image[k] == label;
            }
            for (std::vector<Vec2>& points : trace_boundaries(mask, width, height)) {
                Contour c;
                c.label = label;
                c.points = std::move(points);
                contours.push_back(std::move(c));
            }
        }
        if (i < 50) {  // the tracer itself: simple, disjoint contours
            for (std::size_t a = 0; a < contours.size(); ++a) {
                std::vector<std::uint32_t> all(contours[a].points.size());
                for (std::uint32_t k = 0; k < all.size(); ++k) {
                    all[k] = k;
                }
                ASSERT_TRUE(is_simple(polygon(contours[a].points, all))) << "traced contour " << a;
            }
        }
        const double tolerance = uniform(rng, 0.3, 4.0);
        reinserted_total += simplify_contours(contours, SimplifyOptions{tolerance});
        std::vector<std::vector<IPoint>> simplified;
        for (std::size_t a = 0; a < contours.size(); ++a) {
            SCOPED_TRACE("contour " + std::to_string(a));
            const Contour& c = contours[a];
            check_simplification(c.points, c.simplified, c.edge_deviation_px, true, tolerance);
            simplified.push_back(polygon(c.points, c.simplified));
            EXPECT_TRUE(is_simple(simplified.back()));
        }
        for (std::size_t a = 0; a < contours.size(); ++a) {
            for (std::size_t b = a + 1; b < contours.size(); ++b) {
                if (contours[a].label == contours[b].label) {
                    EXPECT_FALSE(polygons_touch(simplified[a], simplified[b]))
                        << "contours " << a << " and " << b;
                }
            }
        }
        if (HasFailure()) {
            return;
        }
    }
    // The repair must have been exercised.
    if (iterations >= 100) {
        EXPECT_GT(reinserted_total, 0u);
    }
}

}  // namespace
}  // namespace strata

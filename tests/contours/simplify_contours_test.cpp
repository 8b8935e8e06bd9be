#include "contours/simplify_contours.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "contours/detail/path_hull.h"
#include "core/error.h"

namespace strata {
namespace {

// ---- Independent brute-force helpers ---------------------------------------------------------

double distance_to_segment(Vec2 p, Vec2 a, Vec2 b) {
    const double dx = b.x - a.x;
    const double dy = b.y - a.y;
    const double length_sq = dx * dx + dy * dy;
    double t = length_sq > 0 ? ((p.x - a.x) * dx + (p.y - a.y) * dy) / length_sq : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return std::hypot(p.x - (a.x + t * dx), p.y - (a.y + t * dy));
}

/// Per kept edge, the largest distance of the original points it replaces.
std::vector<double> brute_force_deviations(const std::vector<Vec2>& points,
                                           const std::vector<std::uint32_t>& kept,
                                           bool closed) {
    std::vector<double> result;
    const std::size_t n = points.size();
    const std::size_t edges = closed ? kept.size() : kept.size() - 1;
    for (std::size_t e = 0; e < edges; ++e) {
        const std::size_t s = kept[e];
        const std::size_t t = kept[(e + 1) % kept.size()];
        double worst = 0.0;
        for (std::size_t k = (s + 1) % n; k != t; k = (k + 1) % n) {
            worst = std::max(worst, distance_to_segment(points[k], points[s], points[t]));
        }
        result.push_back(worst);
    }
    return result;
}

void expect_deviations(const std::vector<Vec2>& points,
                       const std::vector<std::uint32_t>& kept,
                       const std::vector<double>& deviation,
                       bool closed,
                       double tolerance) {
    const std::vector<double> expected = brute_force_deviations(points, kept, closed);
    ASSERT_EQ(deviation.size(), expected.size());
    for (std::size_t e = 0; e < expected.size(); ++e) {
        EXPECT_NEAR(deviation[e], expected[e], 1e-12) << "edge " << e;
        EXPECT_LE(expected[e], tolerance + 1e-12) << "edge " << e;
    }
}

double signed_area(const std::vector<Vec2>& points, const std::vector<std::uint32_t>& kept) {
    double area = 0.0;
    for (std::size_t i = 0; i < kept.size(); ++i) {
        const Vec2 a = points[kept[i]];
        const Vec2 b = points[kept[(i + 1) % kept.size()]];
        area += a.x * b.y - a.y * b.x;
    }
    return area / 2.0;
}

/// Points along the closed polygon through `corners`, one per unit step (corners integer).
std::vector<Vec2> walk(const std::vector<Vec2>& corners) {
    std::vector<Vec2> points;
    for (std::size_t i = 0; i < corners.size(); ++i) {
        const Vec2 a = corners[i];
        const Vec2 b = corners[(i + 1) % corners.size()];
        const int steps = static_cast<int>(std::max(std::abs(b.x - a.x), std::abs(b.y - a.y)));
        for (int s = 0; s < steps; ++s) {
            points.push_back(a + (static_cast<double>(s) / steps) * (b - a));
        }
    }
    return points;
}

// Exact segment predicates on the half-pixel grid (coordinates doubled to integers).
using I64 = std::int64_t;
struct IPoint {
    I64 x, y;
};
IPoint to_int(Vec2 p) {
    return {std::llround(2 * p.x), std::llround(2 * p.y)};
}
int orient(IPoint a, IPoint b, IPoint c) {
    const I64 det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    return det > 0 ? 1 : (det < 0 ? -1 : 0);
}
bool within(IPoint a, IPoint b, IPoint p) {
    return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
           p.y <= std::max(a.y, b.y);
}
bool touch(Vec2 pa, Vec2 pb, Vec2 pc, Vec2 pd) {
    const IPoint a = to_int(pa), b = to_int(pb), c = to_int(pc), d = to_int(pd);
    const int o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a),
              o4 = orient(c, d, b);
    if (o1 * o2 < 0 && o3 * o4 < 0) {
        return true;
    }
    return (o1 == 0 && within(a, b, c)) || (o2 == 0 && within(a, b, d)) ||
           (o3 == 0 && within(c, d, a)) || (o4 == 0 && within(c, d, b));
}

/// The polygon through points[kept] is simple: non-adjacent edges share no point, adjacent
/// edges share only their common vertex.
bool is_simple(const std::vector<Vec2>& points, const std::vector<std::uint32_t>& kept) {
    const std::size_t m = kept.size();
    if (m < 3) {
        return false;
    }
    for (std::size_t i = 0; i < m; ++i) {
        const Vec2 a = points[kept[i]], b = points[kept[(i + 1) % m]];
        const Vec2 c = points[kept[(i + 2) % m]];
        // adjacent pair (i, i+1): only the shared vertex b
        const IPoint ia = to_int(a), ib = to_int(b), ic = to_int(c);
        if (orient(ia, ib, ic) == 0 &&
            ((ia.x - ib.x) * (ic.x - ib.x) + (ia.y - ib.y) * (ic.y - ib.y)) > 0) {
            return false;
        }
        for (std::size_t j = i + 2; j < m; ++j) {
            if ((j + 1) % m == i) {
                continue;  // adjacent through vertex i
            }
            if (touch(a, b, points[kept[j]], points[kept[(j + 1) % m]])) {
                return false;
            }
        }
    }
    return true;
}

bool polygons_touch(const std::vector<Vec2>& p,
                    const std::vector<std::uint32_t>& pk,
                    const std::vector<Vec2>& q,
                    const std::vector<std::uint32_t>& qk) {
    for (std::size_t i = 0; i < pk.size(); ++i) {
        for (std::size_t j = 0; j < qk.size(); ++j) {
            if (touch(p[pk[i]], p[pk[(i + 1) % pk.size()]], q[qk[j]], q[qk[(j + 1) % qk.size()]])) {
                return true;
            }
        }
    }
    return false;
}

Contour make_contour(std::uint16_t label, std::vector<Vec2> points) {
    Contour c;
    c.label = label;
    c.points = std::move(points);
    return c;
}

void expect_clean(const std::vector<Contour>& contours, double tolerance) {
    for (std::size_t i = 0; i < contours.size(); ++i) {
        SCOPED_TRACE("contour " + std::to_string(i));
        const Contour& c = contours[i];
        ASSERT_GE(c.simplified.size(), 3u);
        EXPECT_TRUE(std::is_sorted(c.simplified.begin(), c.simplified.end()));
        EXPECT_TRUE(is_simple(c.points, c.simplified));
        expect_deviations(c.points, c.simplified, c.edge_deviation_px, true, tolerance);
        for (std::size_t j = i + 1; j < contours.size(); ++j) {
            if (contours[j].label == c.label) {
                EXPECT_FALSE(polygons_touch(c.points, c.simplified, contours[j].points,
                                            contours[j].simplified))
                    << "contours " << i << " and " << j;
            }
        }
    }
}

// ---- Open and closed polylines -------------------------------------------------------------

TEST(SimplifyPolyline, StraightLineKeepsItsEnds) {
    std::vector<Vec2> points;
    for (int i = 0; i <= 30; ++i) {
        points.push_back({0.5 * i, 0.25 * i});
    }
    std::vector<double> deviation;
    EXPECT_EQ(simplify_polyline(points, 0.5, &deviation), (std::vector<std::uint32_t>{0, 30}));
    EXPECT_EQ(deviation, std::vector<double>{0.0});
    EXPECT_EQ(simplify_polyline(points, 0.0), (std::vector<std::uint32_t>{0, 30}));
}

TEST(SimplifyPolyline, TinyInputs) {
    EXPECT_TRUE(simplify_polyline({}, 0.5).empty());
    const std::vector<Vec2> one{{1, 2}};
    EXPECT_EQ(simplify_polyline(one, 0.5), std::vector<std::uint32_t>{0});
    const std::vector<Vec2> two{{1, 2}, {3, 4}};
    std::vector<double> deviation{7.0};
    EXPECT_EQ(simplify_polyline(two, 0.5, &deviation), (std::vector<std::uint32_t>{0, 1}));
    EXPECT_EQ(deviation, std::vector<double>{0.0});
}

TEST(SimplifyPolyline, ZigzagKeepsTurnsAboveToleranceOnly) {
    std::vector<Vec2> high, low;
    for (int i = 0; i <= 20; ++i) {
        high.push_back({static_cast<double>(i), (i % 2) * 1.0});
        low.push_back({static_cast<double>(i), (i % 2) * 0.4});
    }
    std::vector<double> deviation;
    EXPECT_EQ(simplify_polyline(high, 0.5, &deviation).size(), 21u);
    EXPECT_EQ(simplify_polyline(low, 0.5, &deviation), (std::vector<std::uint32_t>{0, 20}));
    ASSERT_EQ(deviation.size(), 1u);
    EXPECT_DOUBLE_EQ(deviation[0], 0.4);
}

TEST(SimplifyPolyline, ChainDoublingBackIsSplitByItsSegmentDistance) {
    // Both interior points lie within 0.5 of the LINE through the ends, not of the segment.
    const std::vector<Vec2> spike{{0, 0}, {10, 0}, {5, 0.1}};
    std::vector<double> deviation;
    EXPECT_EQ(simplify_polyline(spike, 0.5, &deviation), (std::vector<std::uint32_t>{0, 1, 2}));
    const std::vector<Vec2> fold{{0, 0}, {1, 0}, {2, 0}, {3, 0}, {2, 0.5}, {1, 0.5}};
    const std::vector<std::uint32_t> kept = simplify_polyline(fold, 0.5, &deviation);
    EXPECT_EQ(kept, (std::vector<std::uint32_t>{0, 3, 5}));
    expect_deviations(fold, kept, deviation, false, 0.5);
}

TEST(SimplifyPolyline, EndsThatCoincide) {
    const std::vector<Vec2> loop{{0, 0}, {3, 0}, {3, 3}, {0, 3}, {0, 0}};
    std::vector<double> deviation;
    const std::vector<std::uint32_t> kept = simplify_polyline(loop, 0.5, &deviation);
    EXPECT_EQ(kept, (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
    expect_deviations(loop, kept, deviation, false, 0.5);
    const std::vector<Vec2> blob{{0, 0}, {0.2, 0.1}, {0.1, 0.3}, {0, 0}};
    EXPECT_EQ(simplify_polyline(blob, 0.5, &deviation), (std::vector<std::uint32_t>{0, 3}));
    EXPECT_NEAR(deviation[0], std::hypot(0.1, 0.3), 1e-15);
}

TEST(SimplifyPolyline, SpiralStaysWithinTolerance) {
    std::vector<Vec2> points;
    for (int i = 0; i < 2000; ++i) {
        const double angle = 0.05 * i;
        const double radius = 2.0 + 0.8 * angle;
        points.push_back({radius * std::cos(angle), radius * std::sin(angle)});
    }
    for (const double tolerance : {0.0, 0.1, 0.5, 2.0}) {
        SCOPED_TRACE(tolerance);
        std::vector<double> deviation;
        const std::vector<std::uint32_t> kept = simplify_polyline(points, tolerance, &deviation);
        EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));
        EXPECT_EQ(kept.front(), 0u);
        EXPECT_EQ(kept.back(), points.size() - 1);
        expect_deviations(points, kept, deviation, false, tolerance);
        if (tolerance >= 0.5) {
            EXPECT_LT(kept.size(), points.size() / 4);
        }
    }
}

TEST(SimplifyPolyline, DeviationsEqualBruteForceMaxima) {
    std::mt19937 rng(42);
    std::uniform_real_distribution<double> step(-1.0, 1.0);
    std::vector<Vec2> points{{0, 0}};
    for (int i = 0; i < 500; ++i) {
        points.push_back(points.back() + Vec2{step(rng), step(rng)});
    }
    std::vector<double> deviation;
    const std::vector<std::uint32_t> kept = simplify_polyline(points, 1.0, &deviation);
    EXPECT_LT(kept.size(), points.size());
    expect_deviations(points, kept, deviation, false, 1.0);
    EXPECT_GT(*std::max_element(deviation.begin(), deviation.end()), 0.5);
}

TEST(SimplifyClosedPolyline, SquareWithCollinearPointsKeepsCorners) {
    const std::vector<Vec2> square = walk({{0, 0}, {4, 0}, {4, 4}, {0, 4}});
    ASSERT_EQ(square.size(), 16u);
    std::vector<double> deviation;
    EXPECT_EQ(simplify_closed_polyline(square, 0.5, &deviation),
              (std::vector<std::uint32_t>{0, 4, 8, 12}));
    EXPECT_EQ(deviation, std::vector<double>(4, 0.0));
    // Starting mid-side: the side through point 0 keeps point 0 as an extra vertex.
    std::vector<Vec2> rotated(square.begin() + 2, square.end());
    rotated.insert(rotated.end(), square.begin(), square.begin() + 2);
    EXPECT_EQ(simplify_closed_polyline(rotated, 0.5),
              (std::vector<std::uint32_t>{0, 2, 6, 10, 14}));
}

TEST(SimplifyClosedPolyline, KeepsThreePointsOfDegenerateInput) {
    const std::vector<Vec2> same(5, Vec2{1, 1});
    std::vector<double> deviation;
    EXPECT_EQ(simplify_closed_polyline(same, 0.5, &deviation).size(), 3u);
    EXPECT_EQ(deviation, std::vector<double>(3, 0.0));
    const std::vector<Vec2> two{{0, 0}, {1, 0}};
    EXPECT_EQ(simplify_closed_polyline(two, 0.5, &deviation), (std::vector<std::uint32_t>{0, 1}));
    EXPECT_EQ(deviation, std::vector<double>(2, 0.0));
}

// ---- Contours ------------------------------------------------------------------------------

TEST(SimplifyContours, OnePixelWideLineKeepsFourCornersAndArea) {
    // The contour of a 1x20 line of pixels, counter-clockwise from (0, 0).
    const std::vector<Vec2> line = walk({{0, 0}, {1, 0}, {1, 20}, {0, 20}});
    ASSERT_EQ(line.size(), 42u);
    std::vector<Contour> contours{make_contour(1, line)};
    EXPECT_EQ(simplify_contours(contours, SimplifyOptions{}), 0u);
    EXPECT_EQ(contours[0].simplified, (std::vector<std::uint32_t>{0, 1, 21, 22}));
    EXPECT_DOUBLE_EQ(signed_area(line, contours[0].simplified), 20.0);
    expect_clean(contours, 0.5);
    // Any start point, and a tolerance wider than the line: still a polygon with area.
    for (const std::size_t start : {5u, 10u, 21u, 30u}) {
        for (const double tolerance : {0.5, 0.9, 2.0, 10.0}) {
            SCOPED_TRACE("start " + std::to_string(start) + " tolerance " +
                         std::to_string(tolerance));
            std::vector<Vec2> rotated(line.begin() + static_cast<std::ptrdiff_t>(start),
                                      line.end());
            rotated.insert(rotated.end(), line.begin(),
                           line.begin() + static_cast<std::ptrdiff_t>(start));
            std::vector<Contour> one{make_contour(1, rotated)};
            simplify_contours(one, SimplifyOptions{tolerance});
            EXPECT_GT(signed_area(rotated, one[0].simplified), 0.0);
            expect_clean(one, tolerance);
            if (tolerance < 0.99) {
                EXPECT_GE(one[0].simplified.size(), 4u);
                EXPECT_DOUBLE_EQ(signed_area(rotated, one[0].simplified), 20.0);
            }
        }
    }
}

TEST(SimplifyContours, SinglePixelKeepsItsFourCorners) {
    std::vector<Contour> contours{make_contour(3, {{5, 5}, {6, 5}, {6, 6}, {5, 6}})};
    simplify_contours(contours, SimplifyOptions{});
    EXPECT_EQ(contours[0].simplified, (std::vector<std::uint32_t>{0, 1, 2, 3}));
    EXPECT_EQ(contours[0].edge_deviation_px, std::vector<double>(4, 0.0));
}

/// A region under a digital line of slope 1/3: a staircase of 3-pixel runs and 1-pixel steps
/// from (0, 0) to (30, 10), closed by the sides (30, 10) - (0, 10) - (0, 0).
std::vector<Vec2> staircase_region() {
    std::vector<Vec2> corners;
    for (int k = 0; k < 10; ++k) {
        corners.push_back({3.0 * k, double(k)});
        corners.push_back({3.0 * k + 3.0, double(k)});
    }
    corners.push_back({30, 10});
    corners.push_back({0, 10});
    return walk(corners);
}

/// Largest angle (degrees) between a simplified edge running along the staircase (both ends
/// below the line y = 10) and the digital line's direction (3, 1).
double staircase_direction_error(const Contour& c) {
    double worst = 0.0;
    const std::size_t m = c.simplified.size();
    for (std::size_t e = 0; e < m; ++e) {
        const Vec2 a = c.points[c.simplified[e]];
        const Vec2 b = c.points[c.simplified[(e + 1) % m]];
        if (a.y >= 10.0 || b.y >= 10.0 || a.x >= 30.0 || b.x >= 30.0 ||
            (a.x == 0.0 && b.x == 0.0)) {
            continue;
        }
        const double angle = std::atan2(b.y - a.y, b.x - a.x) - std::atan2(1.0, 3.0);
        worst = std::max(worst, std::abs(angle) * 180.0 / std::acos(-1.0));
    }
    return worst;
}

TEST(SimplifyContours, StaircaseVerticesSitAtEdgeMidpoints) {
    const std::vector<Vec2> original = staircase_region();
    std::vector<Contour> midpoints{make_contour(1, original)};
    std::vector<Contour> corners{make_contour(1, original)};
    simplify_contours(midpoints, SimplifyOptions{0.5});
    simplify_contours(corners, SimplifyOptions{0.5, false});
    expect_clean(midpoints, 0.5);
    expect_clean(corners, 0.5);
    EXPECT_EQ(corners[0].points, original);

    // The points are the original ones plus the pixel-edge midpoints that became vertices.
    const Contour& c = midpoints[0];
    std::vector<Vec2> without;
    std::size_t inserted = 0;
    for (std::size_t i = 0; i < c.points.size(); ++i) {
        const Vec2 p = c.points[i];
        if (std::find(original.begin(), original.end(), p) != original.end()) {
            without.push_back(p);
            continue;
        }
        ++inserted;
        const Vec2 a = c.points[(i + c.points.size() - 1) % c.points.size()];
        const Vec2 b = c.points[(i + 1) % c.points.size()];
        EXPECT_EQ(p, (Vec2{0.5 * (a.x + b.x), 0.5 * (a.y + b.y)})) << "point " << i;
        EXPECT_DOUBLE_EQ(norm(b - a), 1.0) << "point " << i;
        EXPECT_TRUE(std::binary_search(c.simplified.begin(), c.simplified.end(), i))
            << "point " << i << " was inserted but is no vertex";
    }
    EXPECT_EQ(without, original);
    EXPECT_GT(inserted, 0u);

    // Corner vertices zig-zag across the staircase's band (0.95 px wide, wider than the
    // tolerance): 22 vertices, edges up to 72 degrees off. Midpoint vertices run inside it:
    // 6 vertices, edges within 9 degrees.
    EXPECT_LE(2 * c.simplified.size(), corners[0].simplified.size());
    EXPECT_LT(staircase_direction_error(c), 12.0);
    EXPECT_GT(staircase_direction_error(corners[0]), 45.0);
    // the region's true corners stay
    for (const Vec2 corner : {Vec2{30, 10}, Vec2{0, 10}}) {
        EXPECT_TRUE(std::any_of(c.simplified.begin(), c.simplified.end(),
                                [&](std::uint32_t v) { return c.points[v] == corner; }));
    }
}

/// The pixel boundary (counter-clockwise, y up, one point per pixel corner) of the digital disc
/// of the pixels whose centres lie within `radius` of (cx, cy).
std::vector<Vec2> digital_disc(double cx, double cy, double radius) {
    const int size = static_cast<int>(std::ceil(cx + cy + 2.0 * radius)) + 2;
    auto inside = [&](int i, int j) { return std::hypot(i + 0.5 - cx, j + 0.5 - cy) <= radius; };
    std::map<std::pair<int, int>, std::pair<int, int>> next;  // boundary edges, inside on the left
    for (int j = -1; j <= size; ++j) {
        for (int i = -1; i <= size; ++i) {
            if (!inside(i, j)) {
                continue;
            }
            if (!inside(i, j - 1)) {
                next[{i, j}] = {i + 1, j};
            }
            if (!inside(i + 1, j)) {
                next[{i + 1, j}] = {i + 1, j + 1};
            }
            if (!inside(i, j + 1)) {
                next[{i + 1, j + 1}] = {i, j + 1};
            }
            if (!inside(i - 1, j)) {
                next[{i, j + 1}] = {i, j};
            }
        }
    }
    std::vector<Vec2> points;
    const std::pair<int, int> start = next.begin()->first;
    std::pair<int, int> p = start;
    do {
        points.push_back({double(p.first), double(p.second)});
        p = next.at(p);
    } while (p != start);
    return points;
}

TEST(SimplifyContours, BalancedVerticesTakeTheInwardBiasOffDiscs) {
    // Douglas-Peucker keeps every pixel corner of a convex run on the outside of its chords, so
    // the simplified disc is smaller than the true one; balancing the vertices along the contour
    // puts the corners on both sides. Measured against the analytic discs' area.
    double plain_bias = 0.0, balanced_bias = 0.0;
    for (int k = 0; k < 8; ++k) {
        const double radius = 6.0 + 4.3 * k;
        const double cx = radius + 3.3, cy = radius + 3.7;
        const double truth = std::acos(-1.0) * radius * radius;
        std::vector<Contour> plain{make_contour(1, digital_disc(cx, cy, radius))};
        std::vector<Contour> balanced = plain;
        SimplifyOptions options;
        options.balance_reach = 0;
        simplify_contours(plain, options);
        options.balance_reach = 8;
        simplify_contours(balanced, options);
        expect_clean(plain, 0.5);
        expect_clean(balanced, 0.5);
        // bias as a mean radial offset: area difference over the perimeter
        const double perimeter = 2.0 * std::acos(-1.0) * radius;
        plain_bias += (signed_area(plain[0].points, plain[0].simplified) - truth) / perimeter / 8;
        balanced_bias +=
            (signed_area(balanced[0].points, balanced[0].simplified) - truth) / perimeter / 8;
    }
    std::cout << "mean radial bias: plain " << plain_bias << " px, balanced " << balanced_bias
              << " px\n";
    EXPECT_LT(plain_bias, -0.05);
    EXPECT_LT(std::abs(balanced_bias), 0.5 * std::abs(plain_bias));
}

TEST(SimplifyContours, SaddleCutContourStaysSimple) {
    // Two pixels touching at a corner (8-connected): one contour, the saddle cut through the
    // midpoints (1, 0.5) and (1.5, 1) on one side and (1, 1.5) and (0.5, 1) on the other.
    std::vector<Contour> contours{make_contour(
        1,
        {{0, 0}, {1, 0}, {1, 0.5}, {1.5, 1}, {2, 1}, {2, 2}, {1, 2}, {1, 1.5}, {0.5, 1}, {0, 1}})};
    for (const double tolerance : {0.1, 0.5, 1.0, 3.0}) {
        simplify_contours(contours, SimplifyOptions{tolerance});
        expect_clean(contours, tolerance);
        EXPECT_GT(signed_area(contours[0].points, contours[0].simplified), 0.0);
    }
}

/// A U-shaped region and a separate island of the same label inside its notch.
std::vector<Contour> u_and_island() {
    return {make_contour(
                1, walk({{0, 0}, {12, 0}, {12, 12}, {8, 12}, {8, 2}, {4, 2}, {4, 12}, {0, 12}})),
            make_contour(1, walk({{5, 3}, {7, 3}, {7, 11}, {5, 11}}))};
}

TEST(SimplifyContours, ReinsertsVerticesSoContoursOfALabelStayApart) {
    const double tolerance = 5.0;
    std::vector<Contour> contours = u_and_island();
    // Plain Douglas-Peucker lets the U's contour cut through the island.
    const std::vector<std::uint32_t> plain_u =
        simplify_closed_polyline(contours[0].points, tolerance);
    const std::vector<std::uint32_t> plain_island =
        simplify_closed_polyline(contours[1].points, tolerance);
    ASSERT_TRUE(polygons_touch(contours[0].points, plain_u, contours[1].points, plain_island) ||
                !is_simple(contours[0].points, plain_u));
    const std::size_t reinserted = simplify_contours(contours, SimplifyOptions{tolerance});
    EXPECT_GT(reinserted, 0u);
    EXPECT_EQ(contours[0].simplified.size() + contours[1].simplified.size(),
              plain_u.size() + plain_island.size() + reinserted);
    expect_clean(contours, tolerance);
}

TEST(SimplifyContours, DifferentLabelsAreIndependent) {
    const double tolerance = 5.0;
    std::vector<Contour> contours = u_and_island();
    contours[1].label = 2;
    // each contour simplified on its own
    std::vector<Contour> alone[2] = {{contours[0]}, {contours[1]}};
    EXPECT_EQ(simplify_contours(contours, SimplifyOptions{tolerance}), 0u);
    for (std::size_t c = 0; c < 2; ++c) {
        simplify_contours(alone[c], SimplifyOptions{tolerance});
        EXPECT_EQ(contours[c].points, alone[c][0].points);
        EXPECT_EQ(contours[c].simplified, alone[c][0].simplified);
    }
}

TEST(SimplifyContours, RepairsASelfIntersection) {
    // The outer contour of this mask (rows from y = 5 down to y = 0), saddles cut; plain
    // Douglas-Peucker gives (3,0) (5,2) (1,6) (3,4) (0,3), whose edge (5,2)-(1,6) runs through
    // the vertex (3,4).
    //   .##..
    //   ...#.
    //   ####.
    //   .##..
    //   ...##
    //   ##.#.
    const std::vector<Vec2> points{{3, 0},   {4, 0},   {4, 1},   {5, 1}, {5, 2}, {4, 2},   {3.5, 2},
                                   {3, 2.5}, {3, 3},   {4, 3},   {4, 4}, {4, 5}, {3.5, 5}, {3, 5.5},
                                   {3, 6},   {2, 6},   {1, 6},   {1, 5}, {2, 5}, {2.5, 5}, {3, 4.5},
                                   {3, 4},   {2, 4},   {1, 4},   {0, 4}, {0, 3}, {1, 3},   {1, 2},
                                   {2, 2},   {2.5, 2}, {3, 1.5}, {3, 1}};
    const double tolerance = 1.5;
    ASSERT_FALSE(is_simple(points, simplify_closed_polyline(points, tolerance)));
    std::vector<Contour> contours{make_contour(1, points)};
    EXPECT_GT(simplify_contours(contours, SimplifyOptions{tolerance}), 0u);
    expect_clean(contours, tolerance);
}

TEST(SimplifyContours, OffGridCoordinatesGiveTheSameResult) {
    // Shifted by a quarter pixel: the exact floating-point predicates replace the integer
    // ones, the geometry (and every computed difference) is the same.
    std::vector<Contour> on_grid = u_and_island();
    std::vector<Contour> off_grid = u_and_island();
    for (Contour& c : off_grid) {
        for (Vec2& p : c.points) {
            p = p + Vec2{0.25, -0.25};
        }
    }
    const std::size_t reinserted = simplify_contours(on_grid, SimplifyOptions{5.0});
    EXPECT_GT(reinserted, 0u);
    EXPECT_EQ(simplify_contours(off_grid, SimplifyOptions{5.0}), reinserted);
    for (std::size_t i = 0; i < on_grid.size(); ++i) {
        EXPECT_EQ(off_grid[i].simplified, on_grid[i].simplified);
        EXPECT_EQ(off_grid[i].edge_deviation_px, on_grid[i].edge_deviation_px);
    }
}

TEST(SimplifyContours, Deterministic) {
    std::vector<Contour> a = u_and_island();
    std::vector<Contour> b = u_and_island();
    EXPECT_EQ(simplify_contours(a, SimplifyOptions{4.0}),
              simplify_contours(b, SimplifyOptions{4.0}));
    for (std::size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].simplified, b[i].simplified);
        EXPECT_EQ(a[i].edge_deviation_px, b[i].edge_deviation_px);
    }
}

// ---- Errors --------------------------------------------------------------------------------

template <class F>
void expect_invalid(F&& f, const std::string& fragment) {
    try {
        f();
        ADD_FAILURE() << "no exception, expected one containing: " << fragment;
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
}

TEST(SimplifyContours, RejectsBadToleranceAndPoints) {
    const std::vector<Vec2> points{{0, 0}, {1, 0}, {1, 1}};
    expect_invalid([&] { simplify_polyline(points, -1.0); },
                   "simplify_polyline: tolerance_px = -1, expected a finite value >= 0");
    expect_invalid([&] { simplify_closed_polyline(points, std::nan("")); }, "tolerance_px = nan");
    const std::vector<Vec2> bad{{0, 0}, {std::numeric_limits<double>::infinity(), 0}, {1, 1}};
    expect_invalid([&] { simplify_polyline(bad, 0.5); }, "point 1 is (inf, 0), expected finite");
    std::vector<Contour> contours{make_contour(1, points), make_contour(4, {{0, 0}, {1, 0}})};
    expect_invalid([&] { simplify_contours(contours, SimplifyOptions{}); },
                   "contour 1 (label 4) has 2 points, expected at least 3");
    contours[1] = make_contour(4, bad);
    expect_invalid([&] { simplify_contours(contours, SimplifyOptions{}); },
                   "contour 1 (label 4): point 1 is (inf, 0)");
    expect_invalid([&] { simplify_contours(contours, SimplifyOptions{-0.5}); }, "tolerance_px");
}

TEST(SimplifyContours, RejectsIntersectingOriginalContours) {
    std::vector<Contour> contours{make_contour(2, {{0, 0}, {2, 0}, {2, 2}, {0, 2}}),
                                  make_contour(2, {{1, 1}, {3, 1}, {3, 3}, {1, 3}})};
    expect_invalid([&] { simplify_contours(contours, SimplifyOptions{}); },
                   "intersect in the original contours");
    contours[1].label = 3;  // other labels may overlap
    EXPECT_EQ(simplify_contours(contours, SimplifyOptions{}), 0u);
}

// ---- Path hull -----------------------------------------------------------------------------

/// Brute-force max and min of cross(b - a, p - a) over points[first..last].
std::pair<double, double> brute_extremes(
    const std::vector<Vec2>& points, std::uint32_t first, std::uint32_t last, Vec2 a, Vec2 b) {
    double hi = -std::numeric_limits<double>::infinity(), lo = -hi;
    for (std::uint32_t k = first; k <= last; ++k) {
        const double f = cross(b - a, points[k] - a);
        hi = std::max(hi, f);
        lo = std::min(lo, f);
    }
    return {hi, lo};
}

void expect_hull_answers(const detail::HalfHull& hull,
                         const std::vector<Vec2>& points,
                         std::uint32_t first,
                         std::uint32_t last,
                         std::mt19937& rng) {
    std::uniform_real_distribution<double> coord(-40, 40);
    for (int q = 0; q < 20; ++q) {
        Vec2 a{std::round(coord(rng)), std::round(coord(rng))};
        Vec2 b{std::round(coord(rng)), std::round(coord(rng))};
        if (q % 4 == 0) {
            b = Vec2{a.x + 1, a.y};  // axis-parallel: hull edges parallel to the line
        }
        if (a == b) {
            continue;
        }
        detail::HullExtreme max, min;
        hull.extremes(a, b, max, min);
        const auto [hi, lo] = brute_extremes(points, first, last, a, b);
        EXPECT_EQ(max.offset, hi);
        EXPECT_EQ(min.offset, lo);
    }
}

TEST(PathHull, ExtremesMatchBruteForceAfterBuildAndSplit) {
    std::mt19937 rng(42);
    for (int iteration = 0; iteration < 200; ++iteration) {
        SCOPED_TRACE(iteration);
        // Simple chains: x-monotone walks on the integer grid (many collinear points) and
        // spirals.
        std::vector<Vec2> points;
        const int n = 3 + static_cast<int>(rng() % 300);
        if (iteration % 2 == 0) {
            double y = 0;
            for (int i = 0; i < n; ++i) {
                y += static_cast<double>(static_cast<int>(rng() % 5) - 2);
                points.push_back({static_cast<double>(i), y});
            }
        } else {
            for (int i = 0; i < n; ++i) {
                const double t = 0.3 * i;
                points.push_back(
                    {std::round(4 * (1 + t) * std::cos(t)), std::round(4 * (1 + t) * std::sin(t))});
            }
            points.erase(std::unique(points.begin(), points.end()), points.end());
            if (points.size() < 3) {
                continue;
            }
        }
        const auto last = static_cast<std::uint32_t>(points.size() - 1);
        detail::HalfHull hull;
        hull.reserve(points.size());
        hull.start(points, 0, 1);
        for (std::uint32_t k = 2; k <= last; ++k) {
            hull.add(k);
        }
        expect_hull_answers(hull, points, 0, last, rng);
        for (std::uint32_t k = last; k >= 2; k = k * 2 / 3) {
            hull.undo_after(k);
            expect_hull_answers(hull, points, 0, k, rng);
        }
        // The other direction: from the end towards the start.
        detail::HalfHull back;
        back.reserve(points.size());
        back.start(points, last, last - 1);
        for (std::uint32_t k = last - 1; k-- > 0;) {
            back.add(k);
        }
        expect_hull_answers(back, points, 0, last, rng);
        const std::uint32_t k = last / 2;
        back.undo_after(k);
        expect_hull_answers(back, points, k, last, rng);
    }
}

}  // namespace
}  // namespace strata

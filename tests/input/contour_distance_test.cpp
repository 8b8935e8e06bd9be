// Distances to float polygons (src/pipeline/contour_distance.h) against independent truth: the
// brute-force minimum over every edge, the analytic inside of a disc with a square hole, and the
// analytic distance to the circle the polygon's vertices lie on (within the polygon's sagitta).

#include "pipeline/contour_distance.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "core/error.h"

namespace strata {
namespace {

constexpr Vec2 kCentre{40.25, 31.5};
constexpr double kRadius = 25.0;
constexpr double kHole = 8.0;  // half side of the square hole, centred at kCentre
constexpr int kSides = 90;

/// A disc as a 90-gon with vertices on the circle (counter-clockwise), a square hole given as a
/// separate polygon with the same orientation (the even-odd rule makes it a hole).
std::vector<std::vector<Vec2>> disc_with_hole() {
    std::vector<Vec2> disc;
    for (int i = 0; i < kSides; ++i) {
        const double a = 2.0 * std::numbers::pi * i / kSides;
        disc.push_back({kCentre.x + kRadius * std::cos(a), kCentre.y + kRadius * std::sin(a)});
    }
    const std::vector<Vec2> hole = {{kCentre.x - kHole, kCentre.y - kHole},
                                    {kCentre.x + kHole, kCentre.y - kHole},
                                    {kCentre.x + kHole, kCentre.y + kHole},
                                    {kCentre.x - kHole, kCentre.y + kHole}};
    return {disc, hole};
}

double brute_force_distance(const std::vector<std::vector<Vec2>>& polygons, Vec2 p) {
    double best = std::numeric_limits<double>::infinity();
    for (const std::vector<Vec2>& polygon : polygons) {
        for (std::size_t i = 0; i < polygon.size(); ++i) {
            const Vec2 a = polygon[i];
            const Vec2 b = polygon[(i + 1) % polygon.size()];
            // the closest point by 200 000-step sampling would be slow; use the projection,
            // clamped, written out here independently of the library
            const double ux = b.x - a.x;
            const double uy = b.y - a.y;
            double t = ((p.x - a.x) * ux + (p.y - a.y) * uy) / (ux * ux + uy * uy);
            t = t < 0 ? 0 : (t > 1 ? 1 : t);
            best = std::min(best, std::hypot(p.x - (a.x + t * ux), p.y - (a.y + t * uy)));
        }
    }
    return best;
}

TEST(PolygonEdges, ClosestIsTheNearestEdgePointEverywhere) {
    const auto polygons = disc_with_hole();
    const PolygonEdges edges(polygons);
    std::mt19937 random(21);
    std::uniform_real_distribution<double> coordinate(-60.0, 140.0);  // far outside too
    for (int n = 0; n < 5000; ++n) {
        const Vec2 p{coordinate(random), coordinate(random)};
        const PolygonClosest c = edges.closest(p);
        ASSERT_NEAR(c.distance, brute_force_distance(polygons, p), 1e-12)
            << "at (" << p.x << ", " << p.y << ")";
        // the site is on its edge and at that distance
        const std::vector<Vec2>& polygon = polygons[c.site.polygon];
        const Vec2 a = polygon[c.site.edge];
        const Vec2 b = polygon[(c.site.edge + 1) % polygon.size()];
        ASSERT_GE(c.site.t, 0.0);
        ASSERT_LE(c.site.t, 1.0);
        const Vec2 q = a + c.site.t * (b - a);
        ASSERT_NEAR(q.x, c.point.x, 1e-9);
        ASSERT_NEAR(q.y, c.point.y, 1e-9);
        ASSERT_NEAR(norm(p - q), c.distance, 1e-9);
    }
}

TEST(PolygonDistanceField, SignedDistanceOfADiscWithAHole) {
    const PolygonEdges edges(disc_with_hole());
    const PolygonDistanceField field = polygon_distance_field(edges, 10.0, 0.0, 72.0, 64.5);
    ASSERT_EQ(field.nx, 125u);
    ASSERT_EQ(field.ny, 130u);
    // the polygon lies within its sagitta of the circle
    const double sagitta = kRadius * (1.0 - std::cos(std::numbers::pi / kSides));
    std::size_t inside = 0;
    for (std::uint32_t j = 0; j < field.ny; ++j) {
        for (std::uint32_t i = 0; i < field.nx; ++i) {
            const Vec2 p = field.node_position(i, j);
            const double d = field.distance[std::size_t(j) * field.nx + i];
            const double to_circle = norm(p - kCentre) - kRadius;
            const double to_square =
                std::max(std::abs(p.x - kCentre.x), std::abs(p.y - kCentre.y)) - kHole;
            // analytic inside: in the disc (beyond the sagitta) and out of the square
            if (to_circle < -sagitta - 1e-9 && to_square > 1e-9) {
                EXPECT_LT(d, 0.0) << "at (" << p.x << ", " << p.y << ")";
                ++inside;
            } else if (to_circle > 1e-9 || to_square < -1e-9) {
                EXPECT_GT(d, 0.0) << "at (" << p.x << ", " << p.y << ")";
            }
            // far from the hole, the distance is the circle's within the sagitta
            if (to_square > std::abs(to_circle) + sagitta) {
                EXPECT_NEAR(std::abs(d), std::abs(to_circle), sagitta + 1e-6)
                    << "at (" << p.x << ", " << p.y << ")";
            }
        }
    }
    EXPECT_GT(inside, 1000u);
    EXPECT_EQ(field.distance.size(), field.closest.size());
}

TEST(PolygonDistanceField, RefusesAnEmptyOrHugeWindow) {
    const PolygonEdges edges(disc_with_hole());
    EXPECT_THROW(polygon_distance_field(edges, 5.0, 0.0, 4.0, 1.0), Error);
    EXPECT_THROW(polygon_distance_field(edges, 0.0, 0.0, 1e9, 1.0), Error);
    EXPECT_THROW(polygon_distance_field(edges, 0.0, std::nan(""), 1.0, 1.0), Error);
}

TEST(PolygonEdges, NoPolygonsMeansInfinitelyFar) {
    const PolygonEdges edges({});
    EXPECT_TRUE(edges.empty());
    EXPECT_TRUE(std::isinf(edges.distance({0, 0})));
    EXPECT_FALSE(edges.inside({0, 0}));
}

}  // namespace
}  // namespace strata

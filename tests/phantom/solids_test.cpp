#include "phantom/solids.h"

#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"

namespace strata {
namespace {

constexpr double kPi = std::numbers::pi;

Vec3 random_in_box(std::mt19937& rng, Vec3 lo, Vec3 hi) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    return {lo.x + (hi.x - lo.x) * u(rng), lo.y + (hi.y - lo.y) * u(rng),
            lo.z + (hi.z - lo.z) * u(rng)};
}

Vec3 random_unit(std::mt19937& rng) {
    std::normal_distribution<double> n(0.0, 1.0);
    Vec3 v{n(rng), n(rng), n(rng)};
    return (1.0 / norm(v)) * v;
}

// Random query points around the solid's bounds (finite bounds assumed, padded by `pad`).
std::vector<Vec3> query_points(const Solid& s, int count, std::uint32_t seed, double pad = 6.0) {
    const Bounds3 b = bounding_box(s);
    std::mt19937 rng(seed);
    std::vector<Vec3> out;
    for (int i = 0; i < count; ++i) {
        out.push_back(random_in_box(rng, b.min - Vec3{pad, pad, pad}, b.max + Vec3{pad, pad, pad}));
    }
    return out;
}

// |signed_distance(p)| never exceeds the true distance: every point closer than that has p's
// membership (checked on random points of the ball, many of them near its surface).
void expect_safe_bound(const Solid& s, Vec3 p, std::mt19937& rng) {
    const double f = signed_distance(s, p);
    const bool inside = contains(s, p);
    if (f != 0.0) {
        EXPECT_EQ(f < 0.0, inside) << "sign at " << p.x << "," << p.y << "," << p.z;
    }
    const double r = std::abs(f) * (1.0 - 1e-9);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int k = 0; k < 40; ++k) {
        const double t = k < 20 ? 1.0 - 1e-6 * k : std::cbrt(u(rng));
        const Vec3 q = p + (r * t) * random_unit(rng);
        ASSERT_EQ(contains(s, q), inside)
            << "bound " << f << " at (" << p.x << ", " << p.y << ", " << p.z << ") but (" << q.x
            << ", " << q.y << ", " << q.z << ") differs";
    }
}

// The exact distance is attained: along the (numerical) gradient the membership changes
// between |f| - eps and |f| + eps.
void expect_attained(const Solid& s, Vec3 p) {
    const double f = signed_distance(s, p);
    if (std::abs(f) < 1e-3) {
        return;
    }
    const double h = 1e-6;
    Vec3 g;
    for (int a = 0; a < 3; ++a) {
        Vec3 e{};
        e[a] = h;
        g[a] = (signed_distance(s, p + e) - signed_distance(s, p - e)) / (2 * h);
    }
    if (norm(g) < 0.5) {
        return;  // on the medial axis: no unique closest point
    }
    const Vec3 dir = (f > 0 ? -1.0 : 1.0) / norm(g) * g;
    const double eps = 1e-4 * (1.0 + std::abs(f));
    const bool inside = contains(s, p);
    EXPECT_EQ(contains(s, p + (std::abs(f) - eps) * dir), inside)
        << "at (" << p.x << ", " << p.y << ", " << p.z << ") f = " << f;
    EXPECT_NE(contains(s, p + (std::abs(f) + eps) * dir), inside)
        << "at (" << p.x << ", " << p.y << ", " << p.z << ") f = " << f;
}

// Exact primitives around `o` (px).
std::vector<std::pair<std::string, Solid>> exact_solids(Vec3 o = {}) {
    const double c = std::cos(0.5), s = std::sin(0.5);
    const Vec2 o2{o.x, o.y};
    std::vector<std::pair<std::string, Solid>> v;
    v.emplace_back("ball", make_solid(Ball{o + Vec3{3, -2, 5}, 7}));
    v.emplace_back("ellipsoid", make_solid(Ellipsoid{o, {9, 4, 2}}));
    v.emplace_back(
        "ellipsoid rotated",
        make_solid(Ellipsoid{o + Vec3{1, 2, 3}, {3, 8, 5}, {{{c, -s, 0}, {s, c, 0}, {0, 0, 1}}}}));
    v.emplace_back("spheroid", make_solid(Ellipsoid{o, {6, 6, 3}}));
    v.emplace_back("box", make_solid(Box{o + Vec3{-3, -2, -1}, o + Vec3{5, 4, 2}}));
    v.emplace_back("cylinder", make_solid(Cylinder{o2 + Vec2{2, 3}, 5, o.z - 4, o.z + 6, {}}));
    v.emplace_back("capsule", make_solid(Capsule{o, o + Vec3{8, 3, -2}, 2.5}));
    v.emplace_back("torus", make_solid(Torus{o, {0.3, 1, 0.2}, 8, 3}));
    return v;
}

TEST(Solids, ExactPrimitivesAreExact) {
    std::mt19937 rng(42);
    for (const auto& [name, solid] : exact_solids()) {
        SCOPED_TRACE(name);
        EXPECT_TRUE(has_exact_distance(solid));
        for (const Vec3& p : query_points(solid, 300, 7)) {
            expect_safe_bound(solid, p, rng);
            expect_attained(solid, p);
        }
    }
}

TEST(Solids, EllipsoidDistanceMatchesDenseSurfaceSampling) {
    const double c = std::cos(0.7), s = std::sin(0.7);
    const std::vector<Ellipsoid> ellipsoids = {
        {{0, 0, 0}, {20, 8, 3}},
        {{0, 0, 0}, {5, 5, 5}},
        {{0, 0, 0}, {3, 12, 12}},
        {{10, -4, 2}, {15, 6, 9}, {{{1, 0, 0}, {0, c, -s}, {0, s, c}}}},
    };
    std::mt19937 rng(42);
    for (const Ellipsoid& e : ellipsoids) {
        const Solid solid = make_solid(e);
        // Surface samples on a dense (u, v) grid, mapped to slice space.
        std::vector<Vec3> surface;
        const int nu = 450, nv = 900;
        for (int i = 0; i <= nu; ++i) {
            const double u = kPi * i / nu;
            for (int j = 0; j < nv; ++j) {
                const double v = 2 * kPi * j / nv;
                const Vec3 local{e.semi_axes.x * std::sin(u) * std::cos(v),
                                 e.semi_axes.y * std::sin(u) * std::sin(v),
                                 e.semi_axes.z * std::cos(u)};
                Vec3 p = e.centre;
                for (int r = 0; r < 3; ++r) {
                    for (int k = 0; k < 3; ++k) {
                        p[r] += e.rotation[r][k] * local[k];
                    }
                }
                surface.push_back(p);
            }
        }
        const double a_max = std::max({e.semi_axes.x, e.semi_axes.y, e.semi_axes.z});
        const double spacing = 2 * kPi * a_max / nv + kPi * a_max / nu;
        std::vector<Vec3> queries = query_points(solid, 40, 3, 5.0);
        // The special branches of Eberly's method: points on the principal planes and axes.
        for (Vec3 local :
             {Vec3{0, 0, 0}, Vec3{1, 0, 0}, Vec3{0, 1.5, 0}, Vec3{0, 0, 0.5}, Vec3{2, 1, 0},
              Vec3{0, 1, 1}, Vec3{30, 0, 0}, Vec3{0, 0, 20}, Vec3{4, 0, 1}, Vec3{4, 1e-13, 1},
              Vec3{4, 1, 1e-15}, Vec3{1e-14, 2, 1}, Vec3{3, 1e-9, 1e-9}}) {
            Vec3 p = e.centre;
            for (int r = 0; r < 3; ++r) {
                for (int k = 0; k < 3; ++k) {
                    p[r] += e.rotation[r][k] * local[k];
                }
            }
            queries.push_back(p);
        }
        for (const Vec3& p : queries) {
            double best = 1e300;
            for (const Vec3& q : surface) {
                best = std::min(best, norm(p - q));
            }
            const double f = signed_distance(solid, p);
            SCOPED_TRACE(::testing::Message() << "p = (" << p.x << ", " << p.y << ", " << p.z
                                              << "), f = " << f << ", sampled " << best);
            // The samples lie on the surface: the exact distance cannot exceed the nearest one.
            EXPECT_LE(std::abs(f), best + 1e-9);
            EXPECT_GE(std::abs(f), best - spacing);
            expect_safe_bound(solid, p, rng);
        }
    }
}

TEST(Solids, ZeroOnTheSurface) {
    // Parametric surface points of each exact primitive.
    const Ellipsoid e{{1, 2, 3}, {9, 4, 6}};
    const Solid ellipsoid = make_solid(e);
    const Solid torus = make_solid(Torus{{0, 0, 0}, {0, 1, 0}, 8, 3});
    const Solid capsule = make_solid(Capsule{{0, 0, 0}, {0, 0, 10}, 2});
    const Solid cylinder = make_solid(Cylinder{{0, 0}, 4, 0, 10, {}});
    const Solid box = make_solid(Box{{0, 0, 0}, {4, 5, 6}});
    for (int i = 0; i <= 20; ++i) {
        for (int j = 0; j < 40; ++j) {
            const double u = kPi * i / 20, v = 2 * kPi * j / 40;
            const Vec3 pe = e.centre + Vec3{e.semi_axes.x * std::sin(u) * std::cos(v),
                                            e.semi_axes.y * std::sin(u) * std::sin(v),
                                            e.semi_axes.z * std::cos(u)};
            EXPECT_NEAR(signed_distance(ellipsoid, pe), 0.0, 1e-9);
            const Vec3 pt{(8 + 3 * std::cos(u * 2)) * std::cos(v), 3 * std::sin(u * 2),
                          (8 + 3 * std::cos(u * 2)) * std::sin(v)};
            EXPECT_NEAR(signed_distance(torus, pt), 0.0, 1e-9);
            const Vec3 pc{2 * std::cos(v), 2 * std::sin(v), 10.0 * i / 20};
            EXPECT_NEAR(signed_distance(capsule, pc), 0.0, 1e-9);
            EXPECT_NEAR(signed_distance(cylinder, 2.0 * Vec3{pc.x, pc.y, pc.z / 2}), 0.0, 1e-9);
        }
    }
    EXPECT_NEAR(signed_distance(cylinder, {1, 1, 10}), 0.0, 1e-12);
    EXPECT_NEAR(signed_distance(box, {2, 5, 3}), 0.0, 1e-12);
    EXPECT_NEAR(signed_distance(box, {4, 5, 6}), 0.0, 1e-12);
    EXPECT_DOUBLE_EQ(signed_distance(box, {2, 2.5, 3}), -2.0);
    EXPECT_DOUBLE_EQ(signed_distance(box, {7, 9, 6}), 5.0);
    EXPECT_DOUBLE_EQ(signed_distance(make_solid(Ball{{0, 0, 0}, 2}), {0, 3, 4}), 3.0);
}

// Solids whose distance is a bound, around `o` (px).
std::vector<std::pair<std::string, Solid>> bound_solids(Vec3 o = {}) {
    const Vec2 o2{o.x, o.y};
    std::vector<std::pair<std::string, Solid>> v;
    v.emplace_back("union",
                   unite({make_solid(Ball{o, 5}), make_solid(Ball{o + Vec3{6, 0, 0}, 4})}));
    v.emplace_back("difference", subtract(make_solid(Cylinder{o2, 10, o.z, o.z + 8, {}}),
                                          make_solid(Cylinder{o2, 5, o.z, o.z + 8, {}})));
    v.emplace_back("intersection",
                   intersect({make_solid(Box{o - Vec3{5, 5, 5}, o + Vec3{5, 5, 5}}),
                              make_solid(HalfSpace{{1, 1, 1}, dot(o, {1, 1, 1}) + 2})}));
    v.emplace_back("slanted cylinder", make_solid(Cylinder{o2, 6, o.z, o.z + 16, {2.5, 1}}));
    v.emplace_back("twisted sector",
                   make_solid(TwistedSector{o2, 10, 18, 0.6, 0.3, 0.05, o.z, o.z + 20}));
    v.emplace_back("spiral band", make_solid(SpiralBand{o2, 8, 12 / (2 * kPi), 6 * kPi, 3, 0.2,
                                                        0.01, o.z, o.z + 9}));
    v.emplace_back("star morph", make_solid(StarMorph{o2, 5, 25, 10, 16, o.z, o.z + 12}));
    v.emplace_back("radial wave", make_solid(RadialWave{
                                      o2, 40, {{4, 6, 0.1, 0}, {2, 17, 0, 0.3}}, o.z, o.z + 10}));
    v.emplace_back("gaussian level set",
                   make_solid(GaussianLevelSet{{{o, 5, 1.0}, {o + Vec3{8, 2, 1}, 4, 0.8}}, 0.5}));
    return v;
}

TEST(Solids, BoundsAreSafeAndSignsExact) {
    std::mt19937 rng(42);
    for (const auto& [name, solid] : bound_solids()) {
        SCOPED_TRACE(name);
        EXPECT_FALSE(has_exact_distance(solid));
        for (const Vec3& p : query_points(solid, 400, 11, 4.0)) {
            expect_safe_bound(solid, p, rng);
        }
    }
}

TEST(Solids, CsgOfExactDistancesIsOneLipschitz) {
    std::vector<std::pair<std::string, Solid>> all = exact_solids();
    for (auto& s : bound_solids()) {
        if (s.first == "union" || s.first == "difference" || s.first == "intersection") {
            all.push_back(std::move(s));
        }
    }
    std::mt19937 rng(5);
    for (const auto& [name, solid] : all) {
        SCOPED_TRACE(name);
        const std::vector<Vec3> pts = query_points(solid, 400, 13);
        for (std::size_t i = 0; i + 1 < pts.size(); ++i) {
            const Vec3 q = pts[i] + 0.7 * random_unit(rng);
            for (Vec3 b : {pts[i + 1], q}) {
                EXPECT_LE(std::abs(signed_distance(solid, pts[i]) - signed_distance(solid, b)),
                          norm(pts[i] - b) + 1e-9);
            }
        }
    }
}

TEST(Solids, MembershipFollowsTheCatalogueBounds) {
    // [34, 94) x [44, 84) x [0, 40]: upper x / y excluded, z closed.
    const Solid box = make_solid(Box{{34, 44, 0}, {94, 84, 40}, {true, true, false}});
    EXPECT_TRUE(contains(box, {34, 44, 0}));
    EXPECT_FALSE(contains(box, {94, 60, 20}));
    EXPECT_FALSE(contains(box, {60, 84, 20}));
    EXPECT_TRUE(contains(box, {93.999, 83.999, 40}));
    // Annulus 25 < r <= 50: the subtracted closed disc leaves an open inner bound.
    const Solid annulus = subtract(make_solid(Cylinder{{0, 0}, 50, 0, 10, {}}),
                                   make_solid(Cylinder{{0, 0}, 25, 0, 10, {}}));
    EXPECT_FALSE(contains(annulus, {25, 0, 5}));
    EXPECT_TRUE(contains(annulus, {50, 0, 5}));
    EXPECT_TRUE(contains(annulus, {0, 30, 10}));
    EXPECT_FALSE(contains(annulus, {0, 30, 10.001}));
    // T05's wedge |theta - gap| < 35 deg is open: the sector keeps its edges.
    const double a = 35 * kPi / 180;
    const Solid sector = make_solid(TwistedSector{{0, 0}, 30, 50, a, 0.0, 0.0, 0, 10});
    EXPECT_FALSE(contains(sector, {40, 0, 0}));
    EXPECT_TRUE(contains(sector, {-40, 0, 0}));
    EXPECT_TRUE(contains(sector, {40 * std::cos(a + 1e-9), 40 * std::sin(a + 1e-9), 0}));
    EXPECT_FALSE(contains(sector, {30, 0.0001, 0}));
}

TEST(Solids, SlantedCylinderCentreMovesWithZ) {
    const Solid c = make_solid(Cylinder{{20, 32}, 15, 0, 16, {5, 0}});
    EXPECT_TRUE(contains(c, {20, 32, 0}));
    EXPECT_TRUE(contains(c, {40, 32, 4}));
    EXPECT_TRUE(contains(c, {100 + 15, 32, 16}));
    EXPECT_FALSE(contains(c, {20, 32, 4}));
    EXPECT_NEAR(signed_distance(c, {40, 32 + 15, 4}), 0.0, 1e-9);
}

TEST(Solids, RasterisationEqualsPerPixelMembership) {
    const Vec3 centre{50, 45, 2};
    std::vector<std::pair<std::string, Solid>> all = exact_solids(centre);
    for (auto& s : bound_solids(centre)) {
        all.push_back(std::move(s));
    }
    std::vector<Solid> balls;
    for (int i = 0; i < 30; ++i) {
        balls.push_back(make_solid(Ball{{5.0 + 3.1 * i, 40 + 20 * std::sin(i), 3}, 1.5 + i % 5}));
    }
    all.emplace_back("many balls", unite(std::move(balls)));
    all.emplace_back("nested csg",
                     subtract(unite({make_solid(Box{{10, 10, 0}, {60, 50, 9}, {true, true, false}}),
                                     make_solid(Ball{{70, 30, 4}, 12})}),
                              intersect({make_solid(Cylinder{{30, 30}, 9, 2, 7, {}}),
                                         make_solid(HalfSpace{{0, 1, 0}, 33})})));
    // Pixel centres exactly on flat bounds: x = 20.5, z = 2 and z = 9.
    all.emplace_back("box on pixel centres",
                     make_solid(Box{{20.5, 10, 2}, {60.5, 50, 9}, {false, true, false}}));
    const std::uint32_t w = 100, h = 90;
    for (const auto& [name, solid] : all) {
        SCOPED_TRACE(name);
        for (double z : {-3.0, 0.0, 2.0, 3.5, 5.0, 9.0, 14.0}) {
            const std::vector<std::uint8_t> mask = rasterize_solid_slice(solid, z, w, h);
            int differences = 0;
            int inside = 0;
            for (std::uint32_t j = 0; j < h; ++j) {
                for (std::uint32_t i = 0; i < w; ++i) {
                    const bool in = contains(solid, {i + 0.5, j + 0.5, z});
                    inside += in;
                    differences += (mask[j * w + i] != 0) != in;
                }
            }
            EXPECT_EQ(differences, 0) << "z = " << z << ", " << inside << " pixels inside";
        }
    }
}

TEST(Solids, RasterisationOfLargeRadialWaveMatchesMembership) {
    // T32-like: boundary wiggles much faster than the radius; check a band of rows.
    const Solid w =
        make_solid(RadialWave{{300, 300}, 250, {{40, 60, 0, 0}, {15, 173, 0, 0.3 / 4.0}}, 0, 36});
    const std::uint32_t size = 600;
    const std::vector<std::uint8_t> mask = rasterize_solid_slice(w, 8.0, size, size);
    int differences = 0;
    for (std::uint32_t j = 0; j < size; j += 3) {
        for (std::uint32_t i = 0; i < size; ++i) {
            differences += (mask[j * size + i] != 0) != contains(w, {i + 0.5, j + 0.5, 8.0});
        }
    }
    EXPECT_EQ(differences, 0);
}

TEST(Solids, BoundingBoxHoldsEveryInsidePoint) {
    std::vector<std::pair<std::string, Solid>> all = exact_solids();
    for (auto& s : bound_solids()) {
        if (s.first != "intersection") {
            all.push_back(std::move(s));
        }
    }
    for (const auto& [name, solid] : all) {
        SCOPED_TRACE(name);
        const Bounds3 b = bounding_box(solid);
        for (const Vec3& p : query_points(solid, 2000, 17, 10.0)) {
            if (contains(solid, p)) {
                for (int a = 0; a < 3; ++a) {
                    EXPECT_GE(p[a], b.min[a]);
                    EXPECT_LE(p[a], b.max[a]);
                }
            }
        }
    }
}

TEST(Solids, GaussianSumMatchesTheFormula) {
    const GaussianLevelSet g{{{{10, 20, 30}, 5, 0.9}, {{14, 18, 33}, 7, 1.1}}, 0.5};
    const Vec3 p{12.5, 19.5, 31};
    double expected = 0.0;
    for (const GaussianBlob& b : g.blobs) {
        const Vec3 d = p - b.centre;
        expected += b.weight * std::exp(-dot(d, d) / (2 * b.sigma * b.sigma));
    }
    EXPECT_NEAR(evaluate_gaussian_sum(g, p), expected, 1e-14);
    EXPECT_EQ(contains(make_solid(g), p), expected >= 0.5);
}

TEST(Solids, ExactnessIsRecordedPerSolid) {
    EXPECT_TRUE(has_exact_distance(make_solid(Ball{{0, 0, 0}, 1})));
    EXPECT_TRUE(has_exact_distance(make_solid(HalfSpace{{0, 0, 2}, 1})));
    EXPECT_TRUE(has_exact_distance(unite({make_solid(Ball{{0, 0, 0}, 1})})));
    EXPECT_FALSE(has_exact_distance(
        unite({make_solid(Ball{{0, 0, 0}, 1}), make_solid(Ball{{1, 0, 0}, 1})})));
    EXPECT_FALSE(has_exact_distance(make_solid(Cylinder{{0, 0}, 2, 0, 4, {1, 0}})));
    EXPECT_FALSE(has_exact_distance(make_solid(StarMorph{})));
    EXPECT_FALSE(has_exact_distance(Solid{}));
}

TEST(Solids, InvalidParametersAreRejected) {
    auto expect_invalid = [](auto make, const std::string& fragment) {
        try {
            make();
            ADD_FAILURE() << "expected Error containing " << fragment;
        } catch (const Error& e) {
            EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
            EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
        }
    };
    expect_invalid([] { return make_solid(Ball{{0, 0, 0}, -1}); }, "ball: radius is -1");
    expect_invalid([] { return make_solid(Ball{{0, 0, NAN}, 1}); }, "centre is not finite");
    expect_invalid(
        [] {
            return make_solid(Torus{{0, 0, 0}, {0, 0, 0}, 3, 1});
        },
        "torus: axis is the zero vector");
    expect_invalid(
        [] {
            return make_solid(Torus{{0, 0, 0}, {0, 0, 1}, 1, 3});
        },
        "major_radius must exceed minor_radius");
    expect_invalid(
        [] {
            return make_solid(Ellipsoid{{0, 0, 0}, {1, 2, 3}, {{{1, 1, 0}, {0, 1, 0}, {0, 0, 1}}}});
        },
        "rotation is not orthonormal");
    expect_invalid([] { return make_solid(Cylinder{{0, 0}, 2, 5, 1, {}}); }, "is reversed");
    expect_invalid([] { return make_solid(Csg{}); }, "use unite");
    expect_invalid([] { return unite({}); }, "union: needs at least one operand");
    expect_invalid(
        [] {
            return make_solid(RadialWave{{0, 0}, 10, {{11, 3, 0, 0}}, 0, 1});
        },
        "radius can reach zero");
    expect_invalid([] { return make_solid(GaussianLevelSet{}); }, "no blobs");
}

}  // namespace
}  // namespace strata

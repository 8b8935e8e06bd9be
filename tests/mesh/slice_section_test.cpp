#include "support/slice_section.h"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "support/mesh_shapes.h"

namespace strata {
namespace {

using test::compare_slice_section;
using test::SectionReport;
using Polygon = std::vector<Vec2>;

constexpr double kSpacing = 1.5;  // slice spacing d, px

std::string describe(const SectionReport& report) {
    std::string out = std::to_string(report.mesh_segments) + " section segments, " +
                      std::to_string(report.contour_edges) + " contour edges, max mesh->contour " +
                      std::to_string(report.max_mesh_to_contour_px) + ", contour->mesh " +
                      std::to_string(report.max_contour_to_mesh_px) + "\n";
    for (const auto& m : report.mismatches) {
        out += "  " + m.what + " at (" + std::to_string(m.where.x) + ", " +
               std::to_string(m.where.y) + ")\n";
    }
    return out;
}

bool mentions(const SectionReport& report, const std::string& fragment) {
    for (const auto& m : report.mismatches) {
        if (m.what.find(fragment) != std::string::npos) {
            return true;
        }
    }
    return false;
}

Polygon shifted(Polygon polygon, Vec2 offset) {
    for (Vec2& p : polygon) {
        p = p + offset;
    }
    return polygon;
}

/// Appends the vertices of `ring` at height z; returns the index of the first.
std::uint32_t add_ring(TriMesh& mesh, const Polygon& ring, double z) {
    const auto base = static_cast<std::uint32_t>(mesh.positions.size());
    for (Vec2 p : ring) {
        mesh.positions.push_back({p.x, p.y, z});
    }
    return base;
}

/// Quads between two rings of n vertices each (vertex i of one above vertex i of the other).
void add_band(TriMesh& mesh, std::uint32_t lower, std::uint32_t upper, std::uint32_t n) {
    for (std::uint32_t i = 0; i < n; ++i) {
        const std::uint32_t j = (i + 1) % n;
        test::add_quad(mesh, lower + i, lower + j, upper + j, upper + i);
    }
}

/// Fan from the ring's first vertex (convex rings); `up` faces +z.
void add_fan(TriMesh& mesh, std::uint32_t base, std::uint32_t n, bool up) {
    for (std::uint32_t i = 1; i + 1 < n; ++i) {
        if (up) {
            mesh.triangles.push_back({base, base + i, base + i + 1});
        } else {
            mesh.triangles.push_back({base, base + i + 1, base + i});
        }
    }
}

/// Closed prism: ring k at zs[k] (all rings with the same vertex count), walls between
/// consecutive rings, fan caps at both ends.
TriMesh stacked_prism(const std::vector<Polygon>& rings, const std::vector<double>& zs) {
    TriMesh mesh;
    const auto n = static_cast<std::uint32_t>(rings[0].size());
    std::vector<std::uint32_t> bases;
    for (std::size_t k = 0; k < rings.size(); ++k) {
        bases.push_back(add_ring(mesh, rings[k], zs[k]));
    }
    for (std::size_t k = 0; k + 1 < bases.size(); ++k) {
        add_band(mesh, bases[k], bases[k + 1], n);
    }
    add_fan(mesh, bases.front(), n, false);
    add_fan(mesh, bases.back(), n, true);
    return mesh;
}

/// Closed tube: `outer` and `inner` (same vertex count) extruded from z0 to z1, the end caps are
/// the bands between them.
TriMesh extruded_annulus(const Polygon& outer, const Polygon& inner, double z0, double z1) {
    TriMesh mesh;
    const auto n = static_cast<std::uint32_t>(outer.size());
    const std::uint32_t o0 = add_ring(mesh, outer, z0), o1 = add_ring(mesh, outer, z1);
    const std::uint32_t i0 = add_ring(mesh, inner, z0), i1 = add_ring(mesh, inner, z1);
    add_band(mesh, o0, o1, n);
    add_band(mesh, i1, i0, n);
    add_band(mesh, i0, o0, n);
    add_band(mesh, o1, i1, n);
    return mesh;
}

/// A convex pentagon with a vertical edge (x = 6), on the half-pixel grid.
const Polygon kPentagon{{0, 0}, {6, 0}, {6, 4}, {2.5, 5.5}, {-0.5, 3}};

TEST(SliceSection, PrismMiddlePlaneEqualsPolygon) {
    const TriMesh mesh = stacked_prism({kPentagon, kPentagon}, {0, 2 * kSpacing});
    const SectionReport report = compare_slice_section(mesh, kSpacing, {kPentagon});
    EXPECT_TRUE(report.ok()) << describe(report);
    EXPECT_EQ(report.mesh_segments, 10u);  // one per wall triangle, all crossing
    EXPECT_EQ(report.contour_edges, 5u);
    EXPECT_LT(report.max_mesh_to_contour_px, 1e-12);
    EXPECT_LT(report.max_contour_to_mesh_px, 1e-12);
    // the oracle sees a sub-tolerance-sized change
    const SectionReport moved =
        compare_slice_section(mesh, kSpacing, {shifted(kPentagon, {0, 1e-3})});
    EXPECT_FALSE(moved.ok());
    EXPECT_NEAR(moved.max_contour_to_mesh_px, 1e-3, 1e-9);
}

TEST(SliceSection, InPlaneRingBetweenWallsEqualsPolygon) {
    // the middle ring lies in the plane: its edges have one face below and one above
    const TriMesh mesh =
        stacked_prism({kPentagon, kPentagon, kPentagon}, {0, kSpacing, 2 * kSpacing});
    const SectionReport report = compare_slice_section(mesh, kSpacing, {kPentagon});
    EXPECT_TRUE(report.ok()) << describe(report);
    EXPECT_EQ(report.mesh_segments, 5u);
    EXPECT_EQ(report.max_mesh_to_contour_px, 0.0);
    EXPECT_EQ(report.max_contour_to_mesh_px, 0.0);
}

TEST(SliceSection, CapPlaneEqualsPolygon) {
    const TriMesh mesh = stacked_prism({kPentagon, kPentagon}, {0, 2 * kSpacing});
    for (double z : {0.0, 2 * kSpacing}) {
        SCOPED_TRACE(z);
        const SectionReport report = compare_slice_section(mesh, z, {kPentagon});
        EXPECT_TRUE(report.ok()) << describe(report);
        // the fan diagonals join two coplanar cap triangles: not part of the section
        EXPECT_EQ(report.mesh_segments, 5u);
        // a polygon lacking a vertex is told apart
        const Polygon cut{{0, 0}, {6, 0}, {6, 4}, {-0.5, 3}};
        EXPECT_FALSE(compare_slice_section(mesh, z, {cut}).ok());
    }
}

TEST(SliceSection, ShiftedMiddleRingIsReportedWithItsDistance) {
    const Polygon moved = shifted(kPentagon, {0.3, 0});
    const TriMesh mesh = stacked_prism({kPentagon, moved, kPentagon}, {0, kSpacing, 2 * kSpacing});
    const SectionReport report = compare_slice_section(mesh, kSpacing, {kPentagon});
    EXPECT_FALSE(report.ok());
    // the vertical edge x = 6 moved to x = 6.3: both directed distances are 0.3
    EXPECT_NEAR(report.max_mesh_to_contour_px, 0.3, 1e-9) << describe(report);
    EXPECT_NEAR(report.max_contour_to_mesh_px, 0.3, 1e-9) << describe(report);
    ASSERT_FALSE(report.mismatches.empty());
    bool found = false;
    for (const auto& m : report.mismatches) {
        if (std::abs(m.distance_px - 0.3) < 1e-9 && m.where.x > 5.9 && m.where.x < 6.4) {
            found = true;
        }
    }
    EXPECT_TRUE(found) << describe(report);
    EXPECT_TRUE(compare_slice_section(mesh, kSpacing, {moved}).ok());
    // between the rings the section is interpolated: 0.15 at half height
    const SectionReport half = compare_slice_section(mesh, 0.5 * kSpacing, {kPentagon});
    EXPECT_NEAR(half.max_mesh_to_contour_px, 0.15, 1e-9) << describe(half);
}

const Polygon kOuterSquare{{0, 0}, {8, 0}, {8, 8}, {0, 8}};
const Polygon kInnerQuad{{3, 2.5}, {5.5, 3}, {5, 5.5}, {2.5, 5}};

TEST(SliceSection, ExtrudedAnnulusGivesBothRings) {
    const TriMesh mesh = extruded_annulus(kOuterSquare, kInnerQuad, 0, 2 * kSpacing);
    for (double z : {0.0, kSpacing, 2 * kSpacing}) {
        SCOPED_TRACE(z);
        const SectionReport report = compare_slice_section(mesh, z, {kOuterSquare, kInnerQuad});
        EXPECT_TRUE(report.ok()) << describe(report);
        EXPECT_EQ(report.contour_edges, 8u);
        // without the hole, the inner ring is off the contours: on its edge (3, 2.5) -> (5.5, 3),
        // at t = 5/6 the distances to y = 0 and x = 8 are equal, 2.5 + 5/12 px
        const SectionReport no_hole = compare_slice_section(mesh, z, {kOuterSquare});
        EXPECT_FALSE(no_hole.ok());
        EXPECT_NEAR(no_hole.max_mesh_to_contour_px, 35.0 / 12.0, 1e-12) << describe(no_hole);
        EXPECT_EQ(no_hole.max_contour_to_mesh_px, 0.0);
    }
}

TEST(SliceSection, MissingHoleIsReported) {
    const TriMesh mesh = stacked_prism({kOuterSquare, kOuterSquare}, {0, 2 * kSpacing});
    const SectionReport report = compare_slice_section(mesh, kSpacing, {kOuterSquare, kInnerQuad});
    EXPECT_FALSE(report.ok());
    EXPECT_EQ(report.mismatches.size(), 4u) << describe(report);
    EXPECT_TRUE(mentions(report, "of polygon 1 not covered by the section")) << describe(report);
    EXPECT_EQ(report.max_mesh_to_contour_px, 0.0);
    EXPECT_NEAR(report.max_contour_to_mesh_px, 35.0 / 12.0, 1e-12);
}

TEST(SliceSection, MissingWallLeavesContourEdgeUncovered) {
    TriMesh mesh = stacked_prism({kPentagon, kPentagon}, {0, 2 * kSpacing});
    // the two wall triangles of edge 1, (6, 0) -> (6, 4)
    mesh.triangles.erase(mesh.triangles.begin() + 2, mesh.triangles.begin() + 4);
    const SectionReport report = compare_slice_section(mesh, kSpacing, {kPentagon});
    EXPECT_FALSE(report.ok());
    EXPECT_TRUE(mentions(report, "mesh not manifold at edge")) << describe(report);
    EXPECT_TRUE(mentions(report, "contour edge 1 of polygon 0 not covered")) << describe(report);
    // the middle of the 4 px edge is 2 px from the rest of the section
    EXPECT_NEAR(report.max_contour_to_mesh_px, 2.0, 1e-12) << describe(report);
    EXPECT_EQ(report.max_mesh_to_contour_px, 0.0);
}

/// `profile` (x, z), a polygon star-shaped from its vertex `center`, extruded along y over [0, 3]:
/// the walls are quads, the end faces fans from `center`.
TriMesh extruded_profile(const Polygon& profile, std::uint32_t center) {
    TriMesh mesh;
    const auto n = static_cast<std::uint32_t>(profile.size());
    for (double y : {0.0, 3.0}) {
        for (Vec2 p : profile) {
            mesh.positions.push_back({p.x, y, p.y});
        }
    }
    add_band(mesh, 0, n, n);
    for (std::uint32_t base : {0u, n}) {
        for (std::uint32_t k = 1; k + 1 < n; ++k) {
            const std::uint32_t i = (center + k) % n, j = (center + k + 1) % n;
            mesh.triangles.push_back({base + center, base + i, base + j});
        }
    }
    return mesh;
}

TEST(SliceSection, EdgeTouchingThePlaneFromOneSideGivesNoSegment) {
    // a box [0, 6] x [0, 2] in (x, z) with a valley whose bottom edge (3, y, 1) touches the plane
    // z = 1 from above, while the walls cross it
    const TriMesh valley = extruded_profile({{0, 0}, {6, 0}, {6, 2}, {3, 1}, {0, 2}}, 3);
    const Polygon rectangle{{0, 0}, {6, 0}, {6, 3}, {0, 3}};
    const SectionReport report = compare_slice_section(valley, 1.0, {rectangle});
    EXPECT_TRUE(report.ok()) << describe(report);
    for (const auto& s : test::slice_section_segments(valley, 1.0)) {
        EXPECT_FALSE(s[0].x == 3 && s[1].x == 3) << "segment along the valley edge";
    }
    EXPECT_FALSE(compare_slice_section(valley, 1.0, {rectangle, {{3, 0}, {3, 3}}}).ok());
    // upside down: the valley is a ridge touching z = -1 from below
    const TriMesh ridge = test::transformed(valley, [](Vec3 p) { return Vec3{p.x, p.y, -p.z}; });
    EXPECT_TRUE(compare_slice_section(ridge, -1.0, {rectangle}).ok());
    // a roof touching the plane only along its ridge: empty section
    const TriMesh roof = extruded_profile({{0, 0}, {6, 0}, {3, 1}}, 0);
    const SectionReport at_ridge = compare_slice_section(roof, 1.0, {});
    EXPECT_TRUE(at_ridge.ok()) << describe(at_ridge);
    EXPECT_EQ(at_ridge.mesh_segments, 0u);
    EXPECT_FALSE(compare_slice_section(roof, 1.0, {{{3, 0}, {3, 3}}}).ok());
}

TEST(SliceSection, VerticalTrianglesAreHandled) {
    // a tetrahedron with apex D straight above A; its vertical edge AD is split at M (z = d), so
    // the plane z = d holds a vertex of four triangles, two of them vertical
    TriMesh mesh;
    mesh.positions = {{0, 0, 0},             // A
                      {4, 0, 0},             // B
                      {0, 4, 0},             // C
                      {0, 0, 2 * kSpacing},  // D
                      {0, 0, kSpacing}};     // M
    mesh.triangles = {{0, 2, 1}, {0, 1, 4}, {4, 1, 3}, {0, 4, 2}, {4, 3, 2}, {1, 2, 3}};
    const SectionReport middle = compare_slice_section(mesh, kSpacing, {{{0, 0}, {2, 0}, {0, 2}}});
    EXPECT_TRUE(middle.ok()) << describe(middle);
    EXPECT_EQ(middle.mesh_segments, 3u);
    const SectionReport low =
        compare_slice_section(mesh, 0.5 * kSpacing, {{{0, 0}, {3, 0}, {0, 3}}});
    EXPECT_TRUE(low.ok()) << describe(low);
    const SectionReport base = compare_slice_section(mesh, 0, {{{0, 0}, {4, 0}, {0, 4}}});
    EXPECT_TRUE(base.ok()) << describe(base);
    EXPECT_EQ(base.mesh_segments, 3u);
    const SectionReport apex = compare_slice_section(mesh, 2 * kSpacing, {});
    EXPECT_TRUE(apex.ok()) << describe(apex);
    EXPECT_EQ(apex.mesh_segments, 0u);
    EXPECT_FALSE(compare_slice_section(mesh, kSpacing, {{{0, 0}, {2.01, 0}, {0, 2}}}).ok());
}

/// Inner ring at z = 0, outer ring at z = d, the annulus between them triangulated in 2D by
/// merging the rings by angle (every triangle has vertices on both rings) and lifted; closed by a
/// fan over the inner ring at z = 0 and one over the outer ring at z = d.
TriMesh lifted_band(const Polygon& inner, const Polygon& outer) {
    TriMesh mesh;
    const auto ni = static_cast<std::uint32_t>(inner.size());
    const auto no = static_cast<std::uint32_t>(outer.size());
    const std::uint32_t bi = add_ring(mesh, inner, 0), bo = add_ring(mesh, outer, kSpacing);
    auto angle = [](Vec2 p, std::uint32_t turns) {
        const double a = std::atan2(p.y, p.x);
        return (a < 0 ? a + 2 * std::numbers::pi : a) + 2 * std::numbers::pi * turns;
    };
    std::uint32_t i = 0, o = 0;
    while (i < ni || o < no) {
        const double next_inner = i < ni ? angle(inner[(i + 1) % ni], (i + 1) / ni) : 1e9;
        const double next_outer = o < no ? angle(outer[(o + 1) % no], (o + 1) / no) : 1e9;
        if (next_inner < next_outer) {
            mesh.triangles.push_back({bi + i % ni, bo + o % no, bi + (i + 1) % ni});
            ++i;
        } else {
            mesh.triangles.push_back({bi + i % ni, bo + o % no, bo + (o + 1) % no});
            ++o;
        }
    }
    add_fan(mesh, bi, ni, false);
    add_fan(mesh, bo, no, true);
    return mesh;
}

// both start at the smallest angle in [0, 2 pi), counter-clockwise
const Polygon kInnerRing{{2, 1}, {-1, 2}, {-2, -1}, {1, -2}};
const Polygon kOuterRing{{6, 0}, {4, 4}, {0, 6}, {-4, 4}, {-6, 0}, {-4, -4}, {0, -6}, {4, -4}};

TEST(SliceSection, LiftedHeightFieldBandGivesInnerAndOuterRings) {
    const TriMesh mesh = lifted_band(kInnerRing, kOuterRing);
    ASSERT_EQ(mesh.triangles.size(), 12u + 2u + 6u);
    const SectionReport bottom = compare_slice_section(mesh, 0, {kInnerRing});
    EXPECT_TRUE(bottom.ok()) << describe(bottom);
    EXPECT_EQ(bottom.mesh_segments, 4u);
    const SectionReport top = compare_slice_section(mesh, kSpacing, {kOuterRing});
    EXPECT_TRUE(top.ok()) << describe(top);
    EXPECT_EQ(top.mesh_segments, 8u);
    EXPECT_FALSE(compare_slice_section(mesh, 0, {kOuterRing}).ok());
    EXPECT_FALSE(compare_slice_section(mesh, kSpacing, {kInnerRing}).ok());
    EXPECT_FALSE(compare_slice_section(mesh, kSpacing, {kOuterRing, kInnerRing}).ok());
}

TEST(SliceSection, FlatTriangleOnTopOfACapIsReported) {
    // a band triangle with all three vertices on the outer ring lies in the plane z = d, on top
    // of the cap: the surface overlaps itself there, and the section follows the combinatorial
    // definition (its chord counts, the two ring edges it shares with the cap do not)
    TriMesh mesh;
    const std::uint32_t bi = add_ring(mesh, kInnerRing, 0);
    const std::uint32_t bo = add_ring(mesh, kOuterRing, kSpacing);
    mesh.triangles = {{bo + 1, bo + 2, bo + 3}};  // flat, replaces the ring path 1-2-3
    const std::vector<std::array<std::uint32_t, 2>> band{
        {0, 0}, {0, 1}, {1, 1}, {1, 3}, {2, 3}, {2, 4}, {2, 5}, {3, 5}, {3, 6}, {3, 7}, {0, 7}};
    for (std::size_t k = 0; k < band.size(); ++k) {
        const auto [i, o] = band[k];
        const auto [i2, o2] = band[(k + 1) % band.size()];
        if (i2 != i) {
            mesh.triangles.push_back({bi + i, bo + o, bi + i2});
        } else {
            mesh.triangles.push_back({bi + i, bo + o, bo + o2});
        }
    }
    add_fan(mesh, bi, 4, false);
    add_fan(mesh, bo, 8, true);
    const SectionReport top = compare_slice_section(mesh, kSpacing, {kOuterRing});
    EXPECT_FALSE(top.ok());
    EXPECT_TRUE(mentions(top, "in-plane edge (5, 7)")) << describe(top);
    EXPECT_TRUE(compare_slice_section(mesh, 0, {kInnerRing}).ok());
}

Polygon regular_polygon(int n, double radius) {
    Polygon out;
    for (int i = 0; i < n; ++i) {
        const double a = 2 * std::numbers::pi * i / n;
        out.push_back({radius * std::cos(a), radius * std::sin(a)});
    }
    return out;
}

TEST(SliceSection, DistancesAreExactAgainstManyEdges) {
    // the square [-1.1, 2.9] x [-1.3, 2.7] inside a regular 64-gon of radius 20 centred at the
    // origin: the square point farthest from the 64-gon is (-1.1, 0), where the two nearest
    // 64-gon edges tie at (20 - 1.1) cos(pi / 64) (not at a dyadic fraction of the side, so
    // bisection does not hit it by chance); the 64-gon point farthest from the square is the
    // vertex (-20, 0), 18.9 px away. Sampling would miss the tie; 64 edges take the
    // branch-and-bound path.
    const Polygon square{{-1.1, -1.3}, {2.9, -1.3}, {2.9, 2.7}, {-1.1, 2.7}};
    const TriMesh mesh = stacked_prism({square, square}, {0, 2 * kSpacing});
    const SectionReport report = compare_slice_section(mesh, kSpacing, {regular_polygon(64, 20.0)});
    EXPECT_NEAR(report.max_mesh_to_contour_px, 18.9 * std::cos(std::numbers::pi / 64), 1e-12);
    EXPECT_NEAR(report.max_contour_to_mesh_px, 18.9, 1e-12);
    EXPECT_EQ(report.mismatches.size(), 20u);
}

TEST(SliceSection, FineCircleMatchesBetweenSlices) {
    const Polygon circle = shifted(regular_polygon(512, 100.0), {128.5, 130.25});
    const TriMesh mesh = stacked_prism({circle, circle}, {3 * kSpacing, 4 * kSpacing});
    for (double z : {3 * kSpacing, 3.37 * kSpacing, 4 * kSpacing}) {
        SCOPED_TRACE(z);
        const SectionReport report = compare_slice_section(mesh, z, {circle});
        EXPECT_TRUE(report.ok()) << describe(report);
        EXPECT_LT(report.max_mesh_to_contour_px, 1e-9);
        EXPECT_LT(report.max_contour_to_mesh_px, 1e-9);
    }
    const SectionReport smaller = compare_slice_section(
        mesh, 3.5 * kSpacing, {shifted(regular_polygon(512, 99.99), {128.5, 130.25})});
    EXPECT_FALSE(smaller.ok());
    EXPECT_NEAR(smaller.max_mesh_to_contour_px, 0.01, 1e-9);
}

TEST(SliceSection, NonManifoldEdgeIsReported) {
    const SectionReport report =
        compare_slice_section(test::two_cubes_sharing_edge(), 0.5,
                              {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}, {{1, 1}, {2, 1}, {2, 2}, {1, 2}}});
    EXPECT_TRUE(mentions(report, "mesh not manifold at edge")) << describe(report);
    EXPECT_EQ(report.max_mesh_to_contour_px, 0.0);
    EXPECT_EQ(report.max_contour_to_mesh_px, 0.0);
}

TEST(SliceSection, MismatchListIsCapped) {
    const TriMesh mesh = test::torus(24, 8, 20.0, 5.0);
    const SectionReport report = compare_slice_section(mesh, 0, {kOuterSquare});
    ASSERT_EQ(report.mismatches.size(), 20u) << describe(report);
    EXPECT_NE(report.mismatches.back().what.find("more mismatches not listed"), std::string::npos);
}

TEST(SliceSection, SimplifiedPolygonsPickTheSimplifiedVertices) {
    SliceContourSet set;
    Contour outer;
    outer.label = 2;
    outer.points = {{0, 0}, {1, 0}, {2, 0}, {2, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}};
    outer.simplified = {0, 2, 4, 6};
    Contour other = outer;
    other.label = 3;
    set.contours = {outer, other};
    const auto polygons = test::simplified_polygons(set, 2);
    ASSERT_EQ(polygons.size(), 1u);
    EXPECT_EQ(polygons[0], (Polygon{{0, 0}, {2, 0}, {2, 2}, {0, 2}}));
    set.contours[0].simplified = {0, 2, 9};
    try {
        test::simplified_polygons(set, 2);
        FAIL() << "expected strata::Error";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("simplified index 9, expected < 8"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace strata

#include "support/cut_error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/report.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/mesh_shapes.h"
#include "support/slice_section.h"

namespace strata {
namespace {

using test::CutErrorReport;
using test::measure_cut_error;
using Polygon = std::vector<Vec2>;

constexpr double kSpacing = 2.0;  // slice spacing d, px

std::string describe(const CutErrorReport& r) {
    std::string out =
        "section " + std::to_string(r.max_section_px) + " px, cap " + std::to_string(r.max_cap_px) +
        " px, coverage " + std::to_string(r.max_coverage_px) + " px, worst slice " +
        std::to_string(r.worst_slice) + " at (" + std::to_string(r.worst_point.x) + ", " +
        std::to_string(r.worst_point.y) + "), " + std::to_string(r.slices_met) + " slices met, " +
        std::to_string(r.cap_triangles) + " cap triangles\n";
    for (const std::string& p : r.problems) {
        out += "  " + p + "\n";
    }
    return out;
}

/// Contour points along the pixel edges of the rectangle [x0, x1] x [y0, y1] (integers), one px
/// apart, counter-clockwise; clockwise when `hole`.
Contour rectangle_contour(int x0, int y0, int x1, int y1, bool hole = false) {
    Contour c;
    c.label = 1;
    c.is_hole = hole;
    for (int x = x0; x < x1; ++x) {
        c.points.push_back({double(x), double(y0)});
    }
    for (int y = y0; y < y1; ++y) {
        c.points.push_back({double(x1), double(y)});
    }
    for (int x = x1; x > x0; --x) {
        c.points.push_back({double(x), double(y1)});
    }
    for (int y = y1; y > y0; --y) {
        c.points.push_back({double(x0), double(y)});
    }
    if (hole) {
        std::reverse(c.points.begin(), c.points.end());
    }
    return c;
}

Contour polygon_contour(const Polygon& points) {
    Contour c;
    c.label = 1;
    c.points = points;
    return c;
}

/// Contours with the given contours on each slice.
SliceContours stack_of(const std::vector<std::vector<Contour>>& slices) {
    SliceContours out;
    out.width = out.height = 64;
    for (const auto& contours : slices) {
        out.slices.push_back({contours, {}});
    }
    return out;
}

/// Closed prism through rings of equally many vertices at the given heights, fan caps at the
/// ends (rings counter-clockwise seen from above).
TriMesh stacked_prism(const std::vector<Polygon>& rings, const std::vector<double>& heights) {
    TriMesh mesh;
    const auto n = static_cast<std::uint32_t>(rings.front().size());
    for (std::size_t r = 0; r < rings.size(); ++r) {
        for (Vec2 p : rings[r]) {
            mesh.positions.push_back({p.x, p.y, heights[r]});
        }
    }
    for (std::uint32_t r = 0; r + 1 < rings.size(); ++r) {
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t j = (i + 1) % n;
            test::add_quad(mesh, r * n + i, r * n + j, (r + 1) * n + j, (r + 1) * n + i);
        }
    }
    const auto top = static_cast<std::uint32_t>(rings.size() - 1) * n;
    for (std::uint32_t i = 1; i + 1 < n; ++i) {
        mesh.triangles.push_back({0, i + 1, i});
        mesh.triangles.push_back({top, top + i, top + i + 1});
    }
    return mesh;
}

const Polygon kSquare{{0, 0}, {10, 0}, {10, 10}, {0, 10}};

/// Max over points of the section of `mesh` by slice planes of the distance to the original
/// polylines, sampled every 0.01 px by brute force: a check of the exact maximum (which it may
/// undershoot by 0.005 px at most).
double sampled_section_max(const TriMesh& mesh,
                           const SliceContours& contours,
                           std::uint16_t label,
                           double spacing) {
    double worst = 0;
    for (std::uint32_t k = 0; k < contours.slices.size(); ++k) {
        const auto polygons = test::original_polygons(contours.slices[k], label);
        for (const auto& s : test::slice_section_segments(mesh, k * spacing)) {
            const int n = std::max(1, static_cast<int>(std::ceil(norm(s[1] - s[0]) / 0.01)));
            for (int i = 0; i <= n; ++i) {
                const Vec2 p = s[0] + (static_cast<double>(i) / n) * (s[1] - s[0]);
                double d = std::numeric_limits<double>::infinity();
                for (const Polygon& polygon : polygons) {
                    for (std::size_t j = 0; j < polygon.size(); ++j) {
                        const Vec2 a = polygon[j], b = polygon[(j + 1) % polygon.size()];
                        const double t =
                            std::clamp(dot(p - a, b - a) / dot(b - a, b - a), 0.0, 1.0);
                        d = std::min(d, norm(p - (a + t * (b - a))));
                    }
                }
                worst = std::max(worst, d);
            }
        }
    }
    return worst;
}

/// Default options without the multiresolution stage: only the full-resolution surface is used.
ReconstructOptions full_resolution_options() {
    ReconstructOptions options;
    options.simplify = false;
    return options;
}

Polygon shifted(Polygon polygon, Vec2 offset) {
    for (Vec2& p : polygon) {
        p = p + offset;
    }
    return polygon;
}

TEST(CutError, WallOffsetIsMeasuredExactly) {
    const SliceContours contours = stack_of({{rectangle_contour(0, 0, 10, 10)},
                                             {rectangle_contour(0, 0, 10, 10)},
                                             {rectangle_contour(0, 0, 10, 10)}});
    const TriMesh exact = stacked_prism({kSquare, kSquare, kSquare}, {0, kSpacing, 2 * kSpacing});
    const CutErrorReport fit = measure_cut_error(exact, contours, 1, kSpacing);
    EXPECT_EQ(fit.max_px(), 0.0) << describe(fit);
    EXPECT_EQ(fit.slices_met, 3u);
    EXPECT_EQ(fit.cap_triangles, 4u);
    EXPECT_TRUE(fit.problems.empty()) << describe(fit);

    // the middle ring moved by (0.3, -0.4): its corner (10, 0) is 0.5 from the corner
    const TriMesh moved = stacked_prism({kSquare, shifted(kSquare, {0.3, -0.4}), kSquare},
                                        {0, kSpacing, 2 * kSpacing});
    const CutErrorReport off = measure_cut_error(moved, contours, 1, kSpacing);
    EXPECT_NEAR(off.max_section_px, 0.5, 1e-12) << describe(off);
    EXPECT_EQ(off.max_cap_px, 0.0);
    EXPECT_EQ(off.worst_slice, 1u);
    EXPECT_NEAR(off.worst_point.x, 10.3, 0.01) << describe(off);
    EXPECT_NEAR(off.worst_point.y, -0.4, 0.01) << describe(off);
}

TEST(CutError, ContourPartTheMeshLostIsMeasuredByCoverage) {
    // the prism covers the square on every slice; slice 1 also has a small square 20-22 px to
    // the right of it that no triangle reaches
    const SliceContours contours =
        stack_of({{rectangle_contour(0, 0, 10, 10)},
                  {rectangle_contour(0, 0, 10, 10), rectangle_contour(30, 4, 32, 6)},
                  {rectangle_contour(0, 0, 10, 10)}});
    const TriMesh prism = stacked_prism({kSquare, kSquare, kSquare}, {0, kSpacing, 2 * kSpacing});
    const CutErrorReport r = measure_cut_error(prism, contours, 1, kSpacing);
    EXPECT_EQ(r.max_section_px, 0.0) << describe(r);
    EXPECT_EQ(r.max_cap_px, 0.0) << describe(r);
    EXPECT_NEAR(r.max_coverage_px, 22.0, 1e-9) << describe(r);
    EXPECT_EQ(r.worst_slice, 1u);
    EXPECT_NEAR(r.worst_point.x, 32.0, 1e-9) << describe(r);
    EXPECT_EQ(r.max_px(), r.max_coverage_px);

    // without the small square, the prism covers every contour point
    const SliceContours square = stack_of({{rectangle_contour(0, 0, 10, 10)},
                                           {rectangle_contour(0, 0, 10, 10)},
                                           {rectangle_contour(0, 0, 10, 10)}});
    EXPECT_EQ(measure_cut_error(prism, square, 1, kSpacing).max_coverage_px, 0.0);
    // a prism 1.5 px narrower on the right: the contour's right side is 1.5 px away
    Polygon narrow = kSquare;
    narrow[1].x = narrow[2].x = 8.5;
    const TriMesh inner = stacked_prism({narrow, narrow, narrow}, {0, kSpacing, 2 * kSpacing});
    EXPECT_NEAR(measure_cut_error(inner, square, 1, kSpacing).max_coverage_px, 1.5, 1e-9);
}

TEST(CutError, CapPartlyOutsideSquareGivesApexDistance) {
    // one triangle in the plane of slice 0, its apex 3 px above the square's top edge
    TriMesh mesh;
    mesh.positions = {{2, 2, 0}, {8, 2, 0}, {5, 13, 0}};
    mesh.triangles = {{0, 1, 2}};
    const SliceContours contours = stack_of({{rectangle_contour(0, 0, 10, 10)}});
    const CutErrorReport r = measure_cut_error(mesh, contours, 1, kSpacing);
    EXPECT_NEAR(r.max_cap_px, 3.0, 0.05) << describe(r);
    EXPECT_LE(r.max_cap_px, 3.0 + 1e-12);
    // an isolated triangle has no section (its in-plane edges have one coplanar face)
    EXPECT_EQ(r.max_section_px, 0.0) << describe(r);
    EXPECT_EQ(r.cap_triangles, 1u);
    // the square's top corners are farthest from the triangle: 46 / sqrt(130) px from the slanted
    // edges (the distance to a convex set is convex along each side, so corners are the sup)
    const double corner = 46.0 / std::sqrt(130.0);
    EXPECT_NEAR(r.max_coverage_px, corner, 1e-9) << describe(r);
    EXPECT_NEAR(r.worst_point.y, 10.0, 1e-9) << describe(r);

    // inside the square it measures nothing
    mesh.positions[2] = {5, 9, 0};
    EXPECT_EQ(measure_cut_error(mesh, contours, 1, kSpacing).max_cap_px, 0.0);
}

TEST(CutError, CapOverHoleMeasuresDistanceToHoleBoundary) {
    // a 20 x 20 square with a 6 x 6 hole; the cap covers the whole square, so its points in the
    // hole are up to 3 px (the hole's centre) from the inside region
    const SliceContours contours =
        stack_of({{rectangle_contour(0, 0, 20, 20), rectangle_contour(7, 7, 13, 13, true)}});
    TriMesh mesh;
    mesh.positions = {{0, 0, 0}, {20, 0, 0}, {20, 20, 0}, {0, 20, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    const CutErrorReport r = measure_cut_error(mesh, contours, 1, kSpacing);
    EXPECT_NEAR(r.max_cap_px, 3.0, 0.05) << describe(r);
    EXPECT_LE(r.max_cap_px, 3.0 + 1e-12);
    EXPECT_NEAR(r.worst_point.x, 10.0, 0.1) << describe(r);
    EXPECT_NEAR(r.worst_point.y, 10.0, 0.1) << describe(r);
}

TEST(CutError, TouchingVertexIsMeasuredAgainstContour) {
    // a tetrahedron whose base is a cap on slice 1 and whose apex touches slice 0's plane at
    // (13, 14), 5 px from the corner (10, 10) of slice 0's square
    const Polygon base{{0, 0}, {10, 0}, {0, 10}};
    const SliceContours contours =
        stack_of({{rectangle_contour(0, 0, 10, 10)}, {polygon_contour(base)}});
    TriMesh mesh;
    mesh.positions = {{0, 0, kSpacing}, {10, 0, kSpacing}, {0, 10, kSpacing}, {13, 14, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}, {2, 3, 0}};
    const CutErrorReport r = measure_cut_error(mesh, contours, 1, kSpacing);
    EXPECT_NEAR(r.max_section_px, 5.0, 1e-12) << describe(r);
    EXPECT_EQ(r.max_cap_px, 0.0) << describe(r);
    EXPECT_EQ(r.worst_slice, 0u);
    EXPECT_EQ(r.worst_point, (Vec2{13, 14}));
}

TEST(CutError, PlaneWithoutContourIsAProblem) {
    // a prism from slice 0 to slice 2 crosses slice 1, where label 1 has no contour (label 2
    // has one there)
    Contour other = rectangle_contour(0, 0, 10, 10);
    other.label = 2;
    const SliceContours contours =
        stack_of({{rectangle_contour(0, 0, 10, 10)}, {other}, {rectangle_contour(0, 0, 10, 10)}});
    const TriMesh mesh = stacked_prism({kSquare, kSquare}, {0, 2 * kSpacing});
    const CutErrorReport r = measure_cut_error(mesh, contours, 1, kSpacing);
    ASSERT_EQ(r.problems.size(), 1u) << describe(r);
    EXPECT_NE(r.problems[0].find("slice 1"), std::string::npos) << r.problems[0];
    EXPECT_NE(r.problems[0].find("no contour"), std::string::npos) << r.problems[0];
    EXPECT_EQ(r.max_section_px, std::numeric_limits<double>::infinity());
    EXPECT_EQ(r.worst_slice, 1u);
    // label 2 sees the same mesh crossing slices 0 and 2 without contours
    EXPECT_EQ(measure_cut_error(mesh, contours, 2, kSpacing).problems.size(), 2u);
}

TEST(CutError, RejectsBadSpacing) {
    const SliceContours contours = stack_of({{rectangle_contour(0, 0, 10, 10)}});
    EXPECT_THROW(measure_cut_error(TriMesh{}, contours, 1, 0.0), Error);
    EXPECT_THROW(
        measure_cut_error(TriMesh{}, contours, 1, std::numeric_limits<double>::quiet_NaN()), Error);
}

// The exact section maximum (slice_section.cpp's envelope search) agrees with brute-force
// sampling on a real surface moved off its contours.
TEST(CutError, SectionMaximumMatchesDenseSampling) {
    const Phantom phantom = make_phantom("t01_sphere");
    Report log;
    const Reconstruction result = reconstruct(phantom.stack, full_resolution_options(), log);
    ASSERT_EQ(result.surfaces.size(), 1u);
    const ObjectSurface& surface = result.surfaces[0];
    const TriMesh moved = test::translated(surface.mesh, {0.6, -0.35, 0});
    const CutErrorReport r =
        measure_cut_error(moved, result.contours, surface.label, result.slice_spacing_px);
    const double sampled =
        sampled_section_max(moved, result.contours, surface.label, result.slice_spacing_px);
    EXPECT_GT(sampled, 0.6);
    EXPECT_LE(sampled, r.max_section_px + 1e-9) << describe(r);
    EXPECT_GE(sampled, r.max_section_px - 0.005 - 1e-9) << describe(r);
}

class CutErrorCatalogue : public testing::TestWithParam<std::string> {};

// The full-resolution surface's sections are the simplified contours (or the originals on the
// fallback slices), which deviate at most the simplification tolerance 0.5 px from the
// original polylines; moving it sideways by 0.75 px must show.
TEST_P(CutErrorCatalogue, FullResolutionSurfaceWithinTolerance) {
    const Phantom phantom = make_phantom(GetParam());
    Report log;
    const Reconstruction result = reconstruct(phantom.stack, full_resolution_options(), log);
    ASSERT_FALSE(result.surfaces.empty());
    for (const ObjectSurface& surface : result.surfaces) {
        SCOPED_TRACE("label " + std::to_string(surface.label));
        const auto start = std::chrono::steady_clock::now();
        const CutErrorReport r = measure_cut_error(surface.mesh, result.contours, surface.label,
                                                   result.slice_spacing_px);
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::cout << GetParam() << " label " << surface.label << ": "
                  << surface.mesh.triangles.size() << " triangles, " << seconds << " s, "
                  << describe(r);
        EXPECT_TRUE(r.problems.empty()) << describe(r);
        EXPECT_GT(r.max_section_px, 0.0) << describe(r);
        EXPECT_LE(r.max_section_px, result.contours.tolerance_px + 1e-9) << describe(r);
        EXPECT_LE(r.max_cap_px, result.contours.tolerance_px + 1e-9) << describe(r);

        const TriMesh moved = test::translated(surface.mesh, {0.75, 0, 0});
        const CutErrorReport m =
            measure_cut_error(moved, result.contours, surface.label, result.slice_spacing_px);
        std::cout << "  shifted by 0.75 px: " << describe(m);
        EXPECT_GE(m.max_px(), 0.7) << describe(m);
        // the exact section maximum agrees with brute-force sampling
        const double sampled =
            sampled_section_max(moved, result.contours, surface.label, result.slice_spacing_px);
        EXPECT_LE(sampled, m.max_section_px + 1e-9);
        EXPECT_GE(sampled, m.max_section_px - 0.005 - 1e-9);
    }
}

// note: the prefix makes --gtest_filter='CutError*' select these too
INSTANTIATE_TEST_SUITE_P(CutError,
                         CutErrorCatalogue,
                         testing::Values("t01_sphere", "t18_torus_on_side", "t10_internal_cavity"),
                         [](const testing::TestParamInfo<std::string>& name) {
                             return name.param;
                         });

}  // namespace
}  // namespace strata

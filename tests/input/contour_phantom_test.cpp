// Planar contours through the whole pipeline, on phantoms with exact truth: a ball and a torus
// sliced analytically into polygons on unevenly spaced planes (one plane missing). Checked
// independently of the pipeline: every input plane's section of the world mesh against the input
// polygons (exact segment distances, tests/support/slice_section.h), closed outward manifolds
// with the solids' genus, the distance of the surface between planes to the true surface, and
// every level's declared bound in the model's frame, where the planes are unevenly spaced, by the
// cut-error oracle (tests/support/cut_error.h) against the input polygons.

#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "mesh/mesh_checks.h"
#include "pipeline/reconstruct_contours.h"
#include "simplify/multires_dag.h"
#include "support/cut_error.h"
#include "support/slice_section.h"

namespace strata {
namespace {

constexpr double kPi = std::numbers::pi;

/// A circle of radius r around c as a polygon with vertices on the circle, edges <= 0.5 mm.
std::vector<Vec3> circle(Vec2 c, double r, double z, bool clockwise) {
    const int n = std::max(12, int(std::ceil(2 * kPi * r / 0.5)));
    std::vector<Vec3> p;
    for (int i = 0; i < n; ++i) {
        const double a = (clockwise ? -2.0 : 2.0) * kPi * i / n;
        p.push_back({c.x + r * std::cos(a), c.y + r * std::sin(a), z});
    }
    return p;
}

struct Phantom {
    RawContourSet raw;
    std::vector<double> planes;
};

constexpr Vec3 kBall{0, 0, 0};
constexpr double kBallRadius = 20.0;
constexpr Vec3 kTorus{60, 0, 0};
constexpr double kMajor = 22.0;
constexpr double kMinor = 9.0;

double ball_distance(Vec3 p) {
    return norm(p - kBall) - kBallRadius;
}
double torus_distance(Vec3 p) {
    const Vec3 q = p - kTorus;
    const double ring = std::hypot(q.x, q.y) - kMajor;
    return std::hypot(ring, q.z) - kMinor;
}

Phantom make_phantom() {
    Phantom ph;
    ph.raw.source = "contour phantom";
    ph.raw.frame = "LPS";
    // uneven gaps 2, 3.5, 2.5, 4, 3 mm, repeating, from z = -23; the plane after z = 0 is missing
    const double gaps[5] = {2.0, 3.5, 2.5, 4.0, 3.0};
    double z = -23.0;
    for (int i = 0; z < 23.0; ++i) {
        ph.planes.push_back(z);
        z += gaps[i % 5];
    }
    const auto missing = std::upper_bound(ph.planes.begin(), ph.planes.end(), 0.0);
    ph.planes.erase(missing);
    RawRoi ball;
    ball.number = 1;
    ball.name = "ball";
    ball.color = ColorSrgb8{200, 60, 60};
    RawRoi torus;
    torus.number = 2;
    torus.name = "torus";
    torus.color = ColorSrgb8{60, 60, 200};
    for (const double w : ph.planes) {
        const double dz = w - kBall.z;
        if (std::abs(dz) < kBallRadius) {
            RawContour c;
            c.points = circle({kBall.x, kBall.y}, std::sqrt(kBallRadius * kBallRadius - dz * dz), w,
                              false);
            ball.contours.push_back(c);
        }
        const double tz = w - kTorus.z;
        if (std::abs(tz) < kMinor) {
            const double h = std::sqrt(kMinor * kMinor - tz * tz);
            RawContour outer;
            outer.points = circle({kTorus.x, kTorus.y}, kMajor + h, w, false);
            RawContour hole;  // a separate contour, same orientation: the even-odd rule decides
            hole.points = circle({kTorus.x, kTorus.y}, kMajor - h, w, false);
            torus.contours.push_back(outer);
            torus.contours.push_back(hole);
        }
    }
    ph.raw.rois = {ball, torus};
    return ph;
}

TEST(ContourPhantom, SectionsMatchTheInputPolygonsAndTheTruthBetweenPlanes) {
    const Phantom ph = make_phantom();
    Report report;
    const PlanarContours contours = clean_planar_contours(ph.raw, {}, report);
    ContourGridOptions grid;
    grid.pitch_mm = 0.25;  // a quarter of a 1 mm CT pixel
    const ContourFrame frame = contour_frame(contours, grid, report);
    ReconstructOptions options;
    options.simplify = true;
    const Reconstruction result = reconstruct_contours(contours, frame, grid, options, report);
    ASSERT_EQ(result.surfaces.size(), 2u);
    ASSERT_EQ(result.models.size(), 2u);

    const auto truth = [](std::size_t i, Vec3 p) {
        return i == 0 ? ball_distance(p) : torus_distance(p);
    };
    for (std::size_t i = 0; i < 2; ++i) {
        const ObjectSurface& surface = result.surfaces[i];
        EXPECT_TRUE(surface.verification.ok()) << surface.verification.problem;
        const TriMesh mesh = surface_to_world(frame.stack, frame.slice_spacing_px, surface.mesh);
        const MeshReport check = check_mesh(mesh);
        ASSERT_TRUE(is_closed_manifold(check));
        EXPECT_GT(check.signed_volume, 0.0);
        EXPECT_EQ(component_genera(check), std::vector<int>{int(i)});  // ball 0, torus 1

        // Every input plane: the section against the input polygons, both directions, within
        // the declared full-resolution bound (simplification + grid + scan conversion).
        const double bound_mm =
            (surface.contour_deviation_px + surface.grid_shift_px + kScanConversionPx) *
            frame.pitch_mm;
        EXPECT_NEAR(result.models[i].full_resolution_error_px,
                    surface.contour_deviation_px + surface.grid_shift_px + kScanConversionPx, 1e-9);
        std::size_t planes_checked = 0;
        double worst = 0.0;
        for (const double w : ph.planes) {
            std::vector<std::vector<Vec2>> polygons;
            for (const RawContour& c : ph.raw.rois[i].contours) {
                if (std::abs(c.points[0].z - w) < 1e-9) {
                    std::vector<Vec2> poly;
                    for (const Vec3 p : c.points) {
                        poly.push_back({p.x, p.y});
                    }
                    polygons.push_back(poly);
                }
            }
            if (polygons.empty()) {
                continue;
            }
            const test::SectionReport section =
                test::compare_slice_section(mesh, w, polygons, bound_mm + 1e-9);
            EXPECT_TRUE(section.ok())
                << ph.raw.rois[i].name << " plane " << w << ": "
                << (section.mismatches.empty() ? "" : section.mismatches.front().what) << " at "
                << section.max_mesh_to_contour_px << " / " << section.max_contour_to_mesh_px
                << " mm, bound " << bound_mm;
            worst =
                std::max({worst, section.max_mesh_to_contour_px, section.max_contour_to_mesh_px});
            ++planes_checked;
        }
        EXPECT_GT(planes_checked, 4u);
        // At most the bound (checked above), and not trivially small: the scan conversion and
        // simplification leave some deviation.
        EXPECT_GT(worst, 0.0);

        // Between planes: the distance of triangle centroids strictly between two planes to the
        // true surface (printed; scripts/bench-contours.sh compares it with rasterise-then-mesh).
        // Shape-based interpolation follows a sphere or torus only approximately; it must at
        // least stay within half the widest plane gap (4 mm, the missing plane's 7 mm) of it.
        double sum = 0.0;
        double largest = 0.0;
        std::size_t samples = 0;
        const auto between = [&](Vec3 p) {
            for (const double w : ph.planes) {
                if (std::abs(p.z - w) < 1e-6) {
                    return false;
                }
            }
            return p.z > ph.planes.front() && p.z < ph.planes.back();
        };
        for (const auto& t : mesh.triangles) {
            const Vec3 c =
                (1.0 / 3.0) * (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]);
            if (between(c)) {
                const double e = std::abs(truth(i, c));
                sum += e;
                largest = std::max(largest, e);
                ++samples;
            }
        }
        ASSERT_GT(samples, 100u);
        const double mean = sum / double(samples);
        std::printf(
            "%s: %zu planes, section worst %.3f mm (bound %.3f), between planes: mean %.3f "
            "max %.3f mm over %zu centroids\n",
            ph.raw.rois[i].name.c_str(), planes_checked, worst, bound_mm, mean, largest, samples);
        EXPECT_LT(largest, 0.5 * 7.0);
    }
}

TEST(ContourPhantom, TiltedPlanesKeepTheirSections) {
    // A ball sliced on planes tilted 15 degrees about x (gantry tilt), 3 mm apart: the world mesh,
    // taken into the planes' frame, must cut every plane in its input polygon within the bound.
    const double a = 15.0 * kPi / 180.0;
    const Vec3 n{0, -std::sin(a), std::cos(a)};
    const Vec3 v{0, std::cos(a), std::sin(a)};
    RawContourSet raw;
    raw.source = "tilted phantom";
    RawRoi ball;
    ball.number = 1;
    ball.name = "tilted ball";
    std::vector<double> planes;
    for (int k = -6; k <= 6; ++k) {
        const double w = 3.0 * k + 0.7;
        const double r = std::sqrt(kBallRadius * kBallRadius - w * w);
        RawContour c;
        for (const Vec3 q : circle({0, 0}, r, 0.0, false)) {
            c.points.push_back(q.x * Vec3{1, 0, 0} + q.y * v + w * n);
        }
        ball.contours.push_back(c);
        planes.push_back(w);
    }
    raw.rois = {ball};
    Report report;
    const PlanarContours contours = clean_planar_contours(raw, {}, report);
    ASSERT_LT(norm(contours.normal - n), 1e-9);
    ContourGridOptions grid;
    grid.pitch_mm = 0.25;
    const ContourFrame frame = contour_frame(contours, grid, report);
    const Reconstruction result = reconstruct_contours(contours, frame, grid, {}, report);
    ASSERT_EQ(result.surfaces.size(), 1u);
    const ObjectSurface& surface = result.surfaces[0];
    EXPECT_TRUE(surface.verification.ok()) << surface.verification.problem;
    TriMesh mesh = surface_to_world(frame.stack, frame.slice_spacing_px, surface.mesh);
    for (Vec3& p : mesh.positions) {  // world -> (u, v, w) of the planes, by the known tilt
        p = {p.x, dot(p, v), dot(p, n)};
    }
    const double bound_mm =
        (surface.contour_deviation_px + surface.grid_shift_px + kScanConversionPx) * frame.pitch_mm;
    for (std::size_t k = 0; k < planes.size(); ++k) {
        std::vector<Vec2> polygon;
        for (const Vec3 p : raw.rois[0].contours[k].points) {
            polygon.push_back({p.x, dot(p, v)});
        }
        const test::SectionReport section =
            test::compare_slice_section(mesh, planes[k], {polygon}, bound_mm + 1e-9);
        EXPECT_TRUE(section.ok()) << "plane " << planes[k] << ": " << section.max_mesh_to_contour_px
                                  << " / " << section.max_contour_to_mesh_px << " mm, bound "
                                  << bound_mm;
    }
}

TEST(ContourPhantom, EveryLevelKeepsItsBoundBetweenUnevenPlanes) {
    // The pipeline simplifies on evenly spaced slices; the model maps them onto the real planes
    // (gaps 2 to 6.5 mm). Every level's cut, in the model's frame, must stay within the bound the
    // model declares for it, in both directions, against the input polygons: measured by the
    // cut-error oracle with the planes where they really are.
    const Phantom ph = make_phantom();
    Report report;
    const PlanarContours contours = clean_planar_contours(ph.raw, {}, report);
    ContourGridOptions grid;
    grid.pitch_mm = 0.25;
    const ContourFrame frame = contour_frame(contours, grid, report);
    ReconstructOptions options;
    options.simplify = true;
    const Reconstruction result = reconstruct_contours(contours, frame, grid, options, report);
    ASSERT_EQ(result.models.size(), 2u);
    const double pitch = frame.pitch_mm;
    for (std::size_t i = 0; i < 2; ++i) {
        // the input polygons in the frame's px (pixel i covers [i, i + 1], x = 0 at u0), one
        // slice per plane of this structure, at its z in the frame
        SliceContours input;
        std::vector<double> plane_z;
        for (const double w : ph.planes) {
            SliceContourSet set;
            for (const RawContour& c : ph.raw.rois[i].contours) {
                if (std::abs(c.points[0].z - w) < 1e-9) {
                    Contour contour;
                    contour.label = 1;
                    for (const Vec3 p : c.points) {
                        contour.points.push_back(
                            {(p.x - frame.u0) / pitch, (p.y - frame.v0) / pitch});
                    }
                    set.contours.push_back(contour);
                }
            }
            if (!set.contours.empty()) {
                input.slices.push_back(set);
                plane_z.push_back((w - frame.first_w) / pitch);
            }
        }
        const MultiresMesh& model = result.models[i];
        const std::uint32_t levels = level_count(model);
        ASSERT_GE(levels, 3u) << ph.raw.rois[i].name;
        double ratio = 0.0;  // the largest measured / declared over the coarser levels
        for (std::uint32_t level = 0; level < levels; ++level) {
            const MultiresCut cut = select_cut_at_level(model, level);
            const TriMesh mesh = cut_mesh(model, cut);
            const test::CutErrorReport measured = test::measure_cut_error(mesh, input, 1, plane_z);
            EXPECT_TRUE(measured.problems.empty())
                << ph.raw.rois[i].name << " level " << level << ": "
                << (measured.problems.empty() ? "" : measured.problems.front());
            EXPECT_LE(measured.max_px(), cut.error_px + 1e-9)
                << ph.raw.rois[i].name << " level " << level << ": section "
                << measured.max_section_px << " px, cap " << measured.max_cap_px << " px, coverage "
                << measured.max_coverage_px << " px, worst on plane " << measured.worst_slice
                << " at (" << measured.worst_point.x << ", " << measured.worst_point.y << ")";
            if (level > 0) {
                ratio = std::max(ratio, measured.max_px() / cut.error_px);
            }
            std::printf(
                "%s level %u: %zu triangles, measured %.3f px (section %.3f, coverage "
                "%.3f), declared %.3f px\n",
                ph.raw.rois[i].name.c_str(), level, mesh.triangles.size(), measured.max_px(),
                measured.max_section_px, measured.max_coverage_px, cut.error_px);
        }
        // Bounds that hold but say nothing are no bounds: the coarser levels' worst measured
        // error is a fair part of what they declare.
        EXPECT_GT(ratio, 0.25) << ph.raw.rois[i].name;
    }
}

}  // namespace
}  // namespace strata

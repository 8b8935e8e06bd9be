#include "quantize/snap_to_grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "pipeline/repair.h"
#include "support/surface_checks.h"

namespace strata {
namespace {

bool is_multiple(double value, double step) {
    const double q = value / step;
    return q == std::nearbyint(q);
}

/// z / d is a multiple of `step` up to the rounding of z = (q step) d.
bool is_slice_multiple(double z, double d, double step) {
    const double q = z / d / step;
    return std::abs(q - std::nearbyint(q)) < 1e-9 * (1.0 + std::abs(q));
}

/// Random vertices: a third on slice planes at contour-grid points (multiples of 1/2), a third on
/// planes anywhere, a third between planes at least 0.05 slices away from them.
TriMesh random_vertices(std::uint32_t seed, double d, std::size_t count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> coordinate(-300.0, 300.0);
    std::uniform_int_distribution<int> slice(0, 40);
    std::uniform_real_distribution<double> between(0.05, 0.95);
    TriMesh mesh;
    for (std::size_t i = 0; i < count; ++i) {
        const int k = slice(rng);
        switch (i % 3) {
            case 0:
                mesh.positions.push_back({std::nearbyint(2.0 * coordinate(rng)) / 2.0,
                                          std::nearbyint(2.0 * coordinate(rng)) / 2.0, k * d});
                break;
            case 1:
                mesh.positions.push_back({coordinate(rng), coordinate(rng), k * d});
                break;
            default:
                mesh.positions.push_back(
                    {coordinate(rng), coordinate(rng), (k + between(rng)) * d});
        }
    }
    return mesh;
}

TEST(SnapToGrid, VerticesLandOnTheGridWithinHalfAStepAndPlanesAreKept) {
    for (const double d : {1.0, 2.5, 3.0 / 0.7, 10.0}) {
        const TriMesh mesh = random_vertices(7, d, 3000);
        GridSnap snap;
        std::string why;
        ASSERT_TRUE(snap_to_grid(mesh, d, 1.0 / 16.0, snap, why)) << why;
        ASSERT_EQ(snap.mesh.positions.size(), mesh.positions.size());
        double plane_shift = 0.0;
        for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
            const Vec3 p = mesh.positions[v];
            const Vec3 q = snap.mesh.positions[v];
            EXPECT_TRUE(is_multiple(q.x, snap.step) && is_multiple(q.y, snap.step)) << v;
            EXPECT_TRUE(is_slice_multiple(q.z, d, snap.step)) << v << " z " << q.z / d;
            EXPECT_LE(std::abs(q.x - p.x), snap.step / 2.0);
            EXPECT_LE(std::abs(q.y - p.y), snap.step / 2.0);
            EXPECT_LE(std::abs(q.z - p.z), snap.step / 2.0 * d * (1.0 + 1e-12));
            const double k = std::nearbyint(p.z / d);
            const bool on_plane = k * d == p.z;
            if (on_plane) {
                EXPECT_EQ(q.z, p.z) << "a slice-plane vertex left its plane";
                plane_shift = std::max(plane_shift, std::hypot(q.x - p.x, q.y - p.y));
            } else {
                EXPECT_NE(std::nearbyint(q.z / d) * d, q.z) << "landed on a plane";
            }
            if (v % 3 == 0) {
                EXPECT_EQ(p, q) << "a contour-grid point moved";
            }
        }
        EXPECT_EQ(snap.max_plane_shift_px, plane_shift);
        EXPECT_LE(snap.max_plane_shift_px, snap.step / std::sqrt(2.0));
    }
}

/// The angle between the normals of the faces (a, b, e) and (b, a, c) of the edge a-b (degrees).
double ridge_angle_deg(const std::vector<Vec3>& p) {
    auto normal = [&](int i, int j, int k) {
        const Vec3 u = p[std::size_t(j)] - p[std::size_t(i)];
        const Vec3 w = p[std::size_t(k)] - p[std::size_t(i)];
        return Vec3{u.y * w.z - u.z * w.y, u.z * w.x - u.x * w.z, u.x * w.y - u.y * w.x};
    };
    const Vec3 n0 = normal(0, 1, 3);
    const Vec3 n1 = normal(1, 0, 2);
    const double c = (n0.x * n1.x + n0.y * n1.y + n0.z * n1.z) /
                     std::sqrt((n0.x * n0.x + n0.y * n0.y + n0.z * n0.z) *
                               (n1.x * n1.x + n1.y * n1.y + n1.z * n1.z));
    return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / 3.14159265358979323846;
}

// A ridge 2 w = 2.375 px wide over slice 0 of a slab 6.4 px deep, its crest at 1.15 px: 88.5
// degrees between its faces. At step 1/16 the z grid is 0.4 px, and the nearest grid height of
// the crest, 1.2 px, folds it over 90 degrees; the snap takes the one below (0.8 px), one step.
TEST(SnapToGrid, RoundsBetweenPlanesTheWayThatDoesNotFold) {
    const double d = 6.4;
    const double step = 1.0 / 16.0;
    const double w = 19.0 / 16.0;
    TriMesh mesh;
    // (a face up to slice 1 puts the ridge between the surface's first and last planes, where
    // the rounding may choose)
    mesh.positions = {
        {-1.0, 0.0, 1.15}, {1.0, 0.0, 1.15}, {0.0, -w, 0.0}, {0.0, w, 0.0}, {10.0, 10.0, d}};
    mesh.triangles = {{0, 1, 3}, {1, 0, 2}, {2, 4, 3}};
    ASSERT_LT(ridge_angle_deg(mesh.positions), 90.0);
    std::vector<Vec3> nearest = mesh.positions;
    for (Vec3& p : nearest) {
        p.z = std::nearbyint(p.z / d / step) * step * d;
    }
    ASSERT_GT(ridge_angle_deg(nearest), 90.0) << "the case does not fold when rounded nearest";
    GridSnap snap;
    std::string why;
    ASSERT_TRUE(snap_to_grid(mesh, d, step, snap, why)) << why;
    EXPECT_LT(ridge_angle_deg(snap.mesh.positions), 90.0);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        const Vec3 p = mesh.positions[v];
        const Vec3 q = snap.mesh.positions[v];
        EXPECT_TRUE(is_multiple(q.x, step) && is_multiple(q.y, step)) << v;
        EXPECT_TRUE(is_slice_multiple(q.z, d, step)) << v;
        EXPECT_LT(std::abs(q.z - p.z), step * d) << v;
    }
    EXPECT_EQ(snap.mesh.positions[2], mesh.positions[2]);
    EXPECT_EQ(snap.mesh.positions[3], mesh.positions[3]);
    EXPECT_GE(snap.max_shift_px, 1.15 - 0.8 - 1e-12);
}

TEST(SnapToGrid, RefusesMergingVertices) {
    TriMesh mesh;
    mesh.positions = {{1.0, 1.0, 0.0}, {1.01, 1.0, 0.0}, {5.0, 5.0, 0.0}};
    mesh.triangles = {{0, 1, 2}};
    GridSnap snap;
    std::string why;
    EXPECT_FALSE(snap_to_grid(mesh, 1.0, 1.0 / 16.0, snap, why));
    EXPECT_NE(why.find("would share the grid point"), std::string::npos) << why;
    EXPECT_TRUE(snap_to_grid(mesh, 1.0, 1.0 / 256.0, snap, why)) << why;
}

TEST(SnapToGrid, RefusesVerticesThatWouldLandOnAPlane) {
    TriMesh mesh;
    mesh.positions = {{0.0, 0.0, 0.0}, {4.0, 0.0, 2.0 * 0.99}, {0.0, 4.0, 2.0}};
    mesh.triangles = {{0, 1, 2}};
    GridSnap snap;
    std::string why;
    EXPECT_FALSE(snap_to_grid(mesh, 2.0, 1.0 / 16.0, snap, why));
    EXPECT_NE(why.find("would land on plane 1"), std::string::npos) << why;
    EXPECT_TRUE(snap_to_grid(mesh, 2.0, 1.0 / 128.0, snap, why)) << why;
}

TEST(SnapToGrid, RejectsStepsThatAreNotPowersOfTwo) {
    TriMesh mesh;
    GridSnap snap;
    std::string why;
    EXPECT_THROW(snap_to_grid(mesh, 1.0, 0.1, snap, why), Error);
    EXPECT_THROW(snap_to_grid(mesh, 1.0, 1.0, snap, why), Error);
    EXPECT_THROW(snap_to_grid(mesh, 0.0, 1.0 / 16.0, snap, why), Error);
}

// The pipeline snaps every catalogue surface used here and the snapped surface is valid by the
// independent checks (support/surface_checks.h: mesh core, exact self-intersection, brute-force
// reference topology), not by the pipeline's own verification alone. The step is the default one
// or, where two vertices would share a grid point (t36_organ_like: two Steiner points 1/32 px
// apart), a finer one. Against the same surface built unsnapped: same triangles, every vertex
// within half a step per axis, slice-plane vertices kept in their plane, and the declared shift
// (grid_shift_px, added to the error bound) at least the largest in-plane move measured here.
TEST(SnapToGrid, PipelineSurfacesAreSnappedAndVerified) {
    for (const char* name : {"torus", "t36_organ_like", "branching", "hollow_sphere"}) {
        SCOPED_TRACE(name);
        const Phantom phantom = make_phantom(name);
        ReconstructOptions options;
        options.simplify = false;
        Report report;
        const Reconstruction result = reconstruct(phantom.stack, options, report);
        ReconstructOptions unsnapped_options = options;
        unsnapped_options.quantize.enabled = false;
        Report unsnapped_report;
        const Reconstruction unsnapped =
            reconstruct(phantom.stack, unsnapped_options, unsnapped_report);
        ASSERT_EQ(result.surfaces.size(), unsnapped.surfaces.size());
        const double d = result.slice_spacing_px;
        for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
            const ObjectSurface& surface = result.surfaces[i];
            const TriMesh& before = unsnapped.surfaces[i].mesh;
            SCOPED_TRACE("label " + std::to_string(surface.label));
            const double halvings = std::log2(options.quantize.step / surface.grid_step);
            EXPECT_TRUE(halvings == std::round(halvings) && halvings >= 0.0 &&
                        halvings <= options.quantize.max_halvings)
                << "step " << surface.grid_step;
            const std::string problem = test::independent_problem(phantom.stack, surface);
            EXPECT_TRUE(problem.empty()) << problem;
            EXPECT_TRUE(surface.verification.ok()) << surface.verification.problem;
            ASSERT_EQ(surface.mesh.triangles, before.triangles);
            ASSERT_EQ(surface.mesh.positions.size(), before.positions.size());
            double plane_shift = 0.0;
            for (std::size_t v = 0; v < before.positions.size(); ++v) {
                const Vec3 p = before.positions[v];
                const Vec3 q = surface.mesh.positions[v];
                ASSERT_TRUE(is_multiple(q.x, surface.grid_step) &&
                            is_multiple(q.y, surface.grid_step) &&
                            is_slice_multiple(q.z, d, surface.grid_step))
                    << "vertex " << v;
                EXPECT_LE(std::abs(q.x - p.x), surface.grid_step / 2.0) << "vertex " << v;
                EXPECT_LE(std::abs(q.y - p.y), surface.grid_step / 2.0) << "vertex " << v;
                // z: the nearest grid height, or between planes the other one around it
                // (the rounding that unfolds)
                EXPECT_LT(std::abs(q.z - p.z), surface.grid_step * d * (1.0 + 1e-12))
                    << "vertex " << v;
                if (std::nearbyint(p.z / d) * d == p.z) {
                    EXPECT_EQ(q.z, p.z) << "vertex " << v << " left its slice plane";
                    plane_shift = std::max(plane_shift, std::hypot(q.x - p.x, q.y - p.y));
                }
            }
            std::cout << name << " label " << surface.label << ": step " << surface.grid_step
                      << ", declared shift " << surface.grid_shift_px << " px, measured "
                      << plane_shift << " px\n";
            EXPECT_GE(surface.grid_shift_px, plane_shift);
            EXPECT_LE(surface.grid_shift_px, surface.grid_step / std::sqrt(2.0));
        }
    }
}

TEST(SnapToGrid, RepairsCheckTheStoredGridFrame) {
    // Corners on slice planes 0, 1, 3 at x = 0, 1, 3: collinear in the grid frame files store
    // (z in slices), but not in slice space, where 3 d rounds differently from 3 x (1 d).
    const double d = 0.1;
    ObjectSurface surface;
    surface.label = 1;
    surface.mesh.positions = {{0.0, 0.0, 0.0}, {1.0, 0.0, 1.0 * d}, {3.0, 0.0, 3.0 * d}};
    surface.mesh.triangles = {{0, 1, 2}};
    const auto corners = [](const std::vector<Vec3>& p) {
        return std::array<Vec3, 3>{p[0], p[1], p[2]};
    };
    ASSERT_FALSE(has_self_intersections(surface.mesh));
    QuantizeOptions options;
    GridSnap snap;
    std::string why;
    ASSERT_TRUE(snap_to_grid(surface.mesh, d, options.step, snap, why)) << why;
    ASSERT_FALSE(triangle_is_degenerate(corners(snap.mesh.positions)));
    ASSERT_TRUE(triangle_is_degenerate(
        corners(grid_frame_positions(snap.mesh.positions, d, options.step))));

    // no verification (the stack is not read): the snap fails at every step, the surface stays
    // unsnapped and says why
    const SliceStack stack;
    const std::string unsnapped = quantize_with_repairs(stack, d, options, false, surface);
    EXPECT_NE(unsnapped.find("degenerate triangle in the stored grid frame"), std::string::npos)
        << unsnapped;
    EXPECT_EQ(surface.grid_step, 0.0);
    EXPECT_EQ(surface.mesh.positions[2].z, 3.0 * d);
}

}  // namespace
}  // namespace strata

#include "mesh/shading_normals.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "core/error.h"
#include "support/mesh_shapes.h"

namespace strata {
namespace {

double angle_deg(Vec3 a, Vec3 b) {
    return std::atan2(norm(cross(a, b)), dot(a, b)) * 180.0 / std::numbers::pi;
}

/// Torus of radii 2 and 0.5 whose minor radius is 1 + `ripple` times larger on every third
/// ring around the tube: ridges, like the crease at every slice plane.
TriMesh rippled_torus(double ripple) {
    TriMesh mesh = test::torus(96, 48, 2.0, 0.5);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        const int j = int(v % 48);
        const Vec3 p = mesh.positions[v];
        const double ring = std::hypot(p.x, p.y);
        const Vec3 centre{2.0 * p.x / ring, 2.0 * p.y / ring, 0.0};
        const double s = 1.0 + (j % 3 == 0 ? ripple : 0.0);
        mesh.positions[v] = centre + s * (p - centre);
    }
    return mesh;
}

/// The smooth torus's outward normal at the point nearest p.
Vec3 torus_normal(Vec3 p) {
    const double ring = std::hypot(p.x, p.y);
    const Vec3 centre{2.0 * p.x / ring, 2.0 * p.y / ring, 0.0};
    return p - centre;
}

TEST(ShadingNormals, AngleWeightedCubeCornersPointAlongTheDiagonal) {
    const TriMesh cube = test::cube({0, 0, 0}, 2.0);
    const std::vector<Vec3> n = shading_normals(cube, 0);
    ASSERT_EQ(n.size(), 8u);
    for (std::size_t v = 0; v < 8; ++v) {
        const Vec3 diagonal = cube.positions[v] - Vec3{1, 1, 1};
        EXPECT_LT(angle_deg(n[v], diagonal), 1e-9) << "vertex " << v;
        EXPECT_NEAR(norm(n[v]), 1.0, 1e-12);
    }
}

TEST(ShadingNormals, FollowTheAnalyticNormalOfASmoothTorus) {
    const TriMesh torus = test::torus(96, 48, 2.0, 0.5);
    const std::vector<Vec3> n = shading_normals(torus);
    double worst = 0.0;
    for (std::size_t v = 0; v < n.size(); ++v) {
        worst = std::max(worst, angle_deg(n[v], torus_normal(torus.positions[v])));
        EXPECT_NEAR(norm(n[v]), 1.0, 1e-12);
    }
    // The 3-ring spans +-3 of 96 and 48 steps: a symmetric grid averages to the true normal
    // up to the curvature's asymmetry across the tube.
    EXPECT_LT(worst, 2.0);
}

TEST(ShadingNormals, RingsHideRidgesThatAngleWeightingShows) {
    const TriMesh torus = rippled_torus(0.05);
    const std::vector<Vec3> plain = shading_normals(torus, 0);
    const std::vector<Vec3> smooth = shading_normals(torus);
    double plain_error = 0.0;
    double smooth_error = 0.0;
    for (std::size_t v = 0; v < torus.positions.size(); ++v) {
        const Vec3 truth = torus_normal(torus.positions[v]);
        plain_error += angle_deg(plain[v], truth);
        smooth_error += angle_deg(smooth[v], truth);
    }
    plain_error /= double(torus.positions.size());
    smooth_error /= double(torus.positions.size());
    EXPECT_GT(plain_error, 5.0);  // a ridge 0.025 high over steps of 0.065: faces tilt ~20 deg
    EXPECT_LT(smooth_error, 0.5 * plain_error);
}

TEST(ShadingNormals, ThinBarKeepsEachEdgeItsOwnDirection) {
    // A bar one voxel thick: the rings of a vertex reach around it to the other edges,
    // whose normals would cancel its own in a plain sum.
    const TriMesh bar = test::voxel_surface(24, 1, 1, [](int, int, int) { return true; });
    const std::vector<Vec3> n = shading_normals(bar);
    std::size_t checked = 0;
    for (std::size_t v = 0; v < bar.positions.size(); ++v) {
        const Vec3 p = bar.positions[v];
        if (p.x < 4.0 || p.x > 20.0) {
            continue;  // the ends' corners
        }
        // the opposite edge is left out; the two beside it (90 degrees away) balance up to the
        // triangulation's diagonals
        const Vec3 edge{0.0, p.y > 0.5 ? 1.0 : -1.0, p.z > 0.5 ? 1.0 : -1.0};
        EXPECT_LT(angle_deg(n[v], edge), 20.0)
            << "vertex " << v << " at " << p.x << ", " << p.y << ", " << p.z;
        ++checked;
    }
    EXPECT_EQ(checked, 4u * 17u);
}

TEST(ShadingNormals, ScaleInvariantAndFlippedWithTheOrientation) {
    const TriMesh torus = rippled_torus(0.02);
    const std::vector<Vec3> n = shading_normals(torus);
    const std::vector<Vec3> scaled =
        shading_normals(test::transformed(torus, [](Vec3 p) { return 7.5 * p; }));
    const std::vector<Vec3> flipped = shading_normals(test::flipped(torus));
    for (std::size_t v = 0; v < n.size(); ++v) {
        EXPECT_LT(angle_deg(n[v], scaled[v]), 1e-6);
        EXPECT_LT(angle_deg(-1.0 * n[v], flipped[v]), 1e-6);
    }
}

TEST(ShadingNormals, UnreferencedAndDegenerateVerticesGetPlusZ) {
    TriMesh mesh = test::tetrahedron();
    mesh.positions.push_back({5, 5, 5});  // unreferenced
    mesh.positions.push_back({6, 6, 6});
    mesh.positions.push_back({7, 7, 7});
    const auto last = std::uint32_t(mesh.positions.size());
    mesh.triangles.push_back({last - 2, last - 1, last - 2});  // degenerate only
    const std::vector<Vec3> n = shading_normals(mesh);
    EXPECT_EQ(n[last - 3], (Vec3{0, 0, 1}));
    EXPECT_EQ(n[last - 2], (Vec3{0, 0, 1}));
    EXPECT_EQ(n[last - 1], (Vec3{0, 0, 1}));
}

TEST(ShadingNormals, RejectsAnIndexOutOfRange) {
    TriMesh mesh = test::tetrahedron();
    mesh.triangles.push_back({0, 1, 9});
    EXPECT_THROW(shading_normals(mesh), Error);
}

}  // namespace
}  // namespace strata

#include "triangulate/relax_heights.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace strata {
namespace {

/// The angle (degrees) between the normals of the two faces of every edge with two faces,
/// computed here on its own (a map of directed edges).
std::vector<double> dihedral_angles(const TriMesh& mesh) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::vector<std::size_t>> faces;
    for (std::size_t f = 0; f < mesh.triangles.size(); ++f) {
        const auto& t = mesh.triangles[f];
        for (int i = 0; i < 3; ++i) {
            faces[std::minmax(t[std::size_t(i)], t[std::size_t((i + 1) % 3)])].push_back(f);
        }
    }
    auto normal = [&](std::size_t f) {
        const auto& t = mesh.triangles[f];
        const Vec3 a = mesh.positions[t[0]];
        const Vec3 n = cross(mesh.positions[t[1]] - a, mesh.positions[t[2]] - a);
        return (1.0 / norm(n)) * n;
    };
    std::vector<double> out;
    for (const auto& [edge, list] : faces) {
        if (list.size() == 2) {
            const double c = std::clamp(dot(normal(list[0]), normal(list[1])), -1.0, 1.0);
            out.push_back(std::acos(c) * 180.0 / std::numbers::pi);
        }
    }
    return out;
}

/// A strip one pixel wide along y on the plane z = 0 (x = -0.5 and x = 0.5), roofed by a ridge
/// of Steiner points at x = 0, `height` above it, in a slab of thickness `d`: the half-slab
/// ridge a one-pixel feature on one slice only got (issue 17). Returns the mesh; `free` gets the
/// ridge vertices.
TriMesh ridge(double height, double d, std::vector<FreeHeightVertex>& free) {
    TriMesh mesh;
    const std::uint32_t n = 6;
    for (std::uint32_t j = 0; j < n; ++j) {
        mesh.positions.push_back({-0.5, double(j), 0.0});  // 3j
        mesh.positions.push_back({0.0, double(j), height});
        mesh.positions.push_back({0.5, double(j), 0.0});
        free.push_back({3 * j + 1, 0.0, d});
    }
    for (std::uint32_t j = 0; j + 1 < n; ++j) {
        const std::uint32_t a = 3 * j;
        const std::uint32_t b = 3 * (j + 1);
        for (std::uint32_t side = 0; side < 2; ++side) {
            // faces up (normal +z side), counter-clockwise from above
            const std::uint32_t o = a + side;
            const std::uint32_t p = b + side;
            mesh.triangles.push_back({o, o + 1, p + 1});
            mesh.triangles.push_back({o, p + 1, p});
        }
    }
    return mesh;
}

TEST(RelaxHeights, UnfoldsAHalfSlabRidgeInZOnlyInsideItsSlab) {
    const double d = 6.4;  // 5 mm slices, 0.78 mm pixels
    std::vector<FreeHeightVertex> free;
    TriMesh mesh = ridge(0.5 * d, d, free);
    const TriMesh before = mesh;
    const std::vector<double> angles = dihedral_angles(before);
    ASSERT_GT(*std::max_element(angles.begin(), angles.end()), 150.0);  // the ridge folds

    RelaxHeightsOptions options;
    const std::size_t moved = relax_fold_heights(mesh, free, options);
    EXPECT_EQ(moved, free.size());
    const std::vector<double> after = dihedral_angles(mesh);
    EXPECT_LT(*std::max_element(after.begin(), after.end()), 90.0);
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        EXPECT_EQ(mesh.positions[v].x, before.positions[v].x);
        EXPECT_EQ(mesh.positions[v].y, before.positions[v].y);
    }
    for (std::size_t v = 0; v < mesh.positions.size(); v += 3) {
        EXPECT_EQ(mesh.positions[v].z, 0.0);  // contour vertices stay
        EXPECT_EQ(mesh.positions[v + 2].z, 0.0);
    }
    for (const FreeHeightVertex& f : free) {
        const double z = mesh.positions[f.id].z;
        EXPECT_GE(z, f.z_low + options.margin * d - 1e-12);
        EXPECT_LE(z, f.z_high - options.margin * d + 1e-12);
        EXPECT_LE(std::abs(z - before.positions[f.id].z), options.max_shift * d + 1e-12);
    }
    EXPECT_EQ(mesh.triangles, before.triangles);

    // Each vertex stays inside its own band (FreeHeightVertex::z_min, z_max), and with a
    // narrow band the ridge still gets lower where the band lets it.
    std::vector<FreeHeightVertex> banded = free;
    for (FreeHeightVertex& f : banded) {
        const double z = before.positions[f.id].z;
        f.z_min = z - 0.3;
        f.z_max = z + 0.3;
    }
    TriMesh narrow = before;
    EXPECT_GT(relax_fold_heights(narrow, banded), 0u);
    for (const FreeHeightVertex& f : banded) {
        const double z = narrow.positions[f.id].z;
        EXPECT_GE(z, f.z_min - 1e-12);
        EXPECT_LE(z, f.z_max + 1e-12);
    }
    // and what it moves folds less: the squared excess of the edges over 50 degrees shrinks
    auto excess = [](const TriMesh& m) {
        double sum = 0.0;
        for (const double a : dihedral_angles(m)) {
            sum += a > 50.0 ? (a - 50.0) * (a - 50.0) : 0.0;
        }
        return sum;
    };
    EXPECT_LT(excess(narrow), excess(before));
}

TEST(RelaxHeights, LeavesAnUnfoldedSurfaceAndTheOffSwitchAlone) {
    const double d = 6.4;
    std::vector<FreeHeightVertex> free;
    TriMesh gentle = ridge(0.05, d, free);  // a low roof: no edge near the angle
    const TriMesh before = gentle;
    EXPECT_EQ(relax_fold_heights(gentle, free), 0u);
    EXPECT_EQ(gentle.positions, before.positions);

    // A roof 0.35 px high on a 1 px strip turns by 2 atan(0.7) = 70 degrees at its top: over
    // the fold angle (50) but not over the angle that starts the unfolding (90), so it stays;
    // with the start at 50 degrees it moves.
    free.clear();
    TriMesh roof = ridge(0.35, d, free);
    const std::vector<double> roof_angles = dihedral_angles(roof);
    const double roof_max = *std::max_element(roof_angles.begin(), roof_angles.end());
    ASSERT_GT(roof_max, 60.0);
    ASSERT_LT(roof_max, 80.0);
    const TriMesh roof_before = roof;
    EXPECT_EQ(relax_fold_heights(roof, free), 0u);
    EXPECT_EQ(roof.positions, roof_before.positions);
    RelaxHeightsOptions early;
    early.unfold_angle_deg = 50.0;
    EXPECT_GT(relax_fold_heights(roof, free, early), 0u);
    EXPECT_NE(roof.positions, roof_before.positions);

    free.clear();
    TriMesh steep = ridge(0.5 * d, d, free);
    const TriMesh steep_before = steep;
    RelaxHeightsOptions off;
    off.fold_angle_deg = 0.0;
    EXPECT_EQ(relax_fold_heights(steep, free, off), 0u);
    EXPECT_EQ(steep.positions, steep_before.positions);
}

}  // namespace
}  // namespace strata

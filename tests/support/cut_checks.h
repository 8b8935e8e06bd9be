#pragma once

// The checks every cut of a multiresolution model must pass, for tests: validity and topology
// (mesh core, exact self-intersection) and the declared error bound against the independent
// oracle (support/cut_error.h).

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/reconstruct.h"
#include "simplify/multires_dag.h"
#include "support/cut_error.h"

namespace strata::test {

/// The sphere through the corners of the box around every vertex of `m`.
inline Sphere box_sphere(const MultiresMesh& m) {
    constexpr double kInfinity = std::numeric_limits<double>::infinity();
    Vec3 lo{kInfinity, kInfinity, kInfinity};
    Vec3 hi = -1.0 * lo;
    for (const Vec3& p : m.positions) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    return {0.5 * (lo + hi), 0.5 * norm(hi - lo)};
}

/// Component genera in increasing order (comparable whatever the component order).
inline std::vector<int> sorted_genera(const MeshReport& report) {
    std::vector<int> genera = component_genera(report);
    std::sort(genera.begin(), genera.end());
    return genera;
}

/// Expects `mesh` to be a closed oriented manifold with the sorted component genera `genera`,
/// positive volume, no self-intersection and no degenerate triangle (exact).
inline void expect_embedded_surface(const TriMesh& mesh, const std::vector<int>& genera) {
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report))
        << (report.problems.empty() ? std::string() : report.problems.front());
    EXPECT_EQ(sorted_genera(report), genera);
    EXPECT_GT(report.signed_volume, 0.0);
    const SelfIntersections hits = find_self_intersections(mesh, 5);
    EXPECT_TRUE(hits.is_free()) << hits.pairs.size() << " pairs, e.g. triangles "
                                << (hits.pairs.empty() ? 0 : hits.pairs[0].first) << " and "
                                << (hits.pairs.empty() ? 0 : hits.pairs[0].second) << ", "
                                << hits.degenerate_triangles.size() << " degenerate";
}

/// Expects `mesh`, a cut of the model of surface `i` of `r` declaring `declared_px`, to be a
/// closed oriented manifold with the sorted component genera `genera`, positive volume and no
/// self-intersection (exact), within `declared_px` of the original contours by the oracle, and
/// within it, and within `declared_fine_px` (its bound against the finest level, when given), of
/// every vertex of the full-resolution surface `r.surfaces[i]`.
/// Returns the oracle's measurement.
inline CutErrorReport expect_valid_cut(
    const TriMesh& mesh,
    const Reconstruction& r,
    std::size_t i,
    const std::vector<int>& genera,
    double declared_px,
    double declared_fine_px = std::numeric_limits<double>::infinity()) {
    expect_embedded_surface(mesh, genera);
    const CutErrorReport measured =
        measure_cut_error(mesh, r.contours, r.surfaces[i].label, r.slice_spacing_px);
    EXPECT_TRUE(measured.problems.empty())
        << (measured.problems.empty() ? std::string() : measured.problems.front());
    EXPECT_LE(measured.max_px(), declared_px + 1e-9)
        << "section " << measured.max_section_px << " px, cap " << measured.max_cap_px
        << " px, worst on slice " << measured.worst_slice << " at (" << measured.worst_point.x
        << ", " << measured.worst_point.y << ")";
    // and every vertex of the full-resolution surface, domes beyond the end slices included
    // (which no section sees), within the bound of the cut
    const double fine = max_point_distance_px(r.surfaces[i].mesh.positions, mesh);
    EXPECT_LE(fine, declared_px + 1e-9)
        << "a full-resolution vertex lies farther from the cut than its bound";
    EXPECT_LE(fine, declared_fine_px + 1e-9)
        << "a full-resolution vertex lies farther from the cut than its finest-level bound";
    return measured;
}

}  // namespace strata::test

#include "simplify/multires_dag.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/report.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "simplify/slice_error.h"
#include "support/cut_checks.h"

namespace strata {
namespace {

using Tri = std::array<std::uint32_t, 3>;

/// A triangle with its corners rotated so the smallest id comes first (orientation kept).
Tri canonical(Tri t) {
    while (t[0] > t[1] || t[0] > t[2]) {
        t = {t[1], t[2], t[0]};
    }
    return t;
}

std::multiset<Tri> triangle_set(const MultiresMesh& mesh, const std::vector<std::uint32_t>& ids) {
    std::multiset<Tri> out;
    for (const std::uint32_t c : ids) {
        const MultiresCluster& cluster = mesh.clusters[c];
        for (const Tri& t : cluster.triangles) {
            out.insert(canonical(
                {cluster.vertices[t[0]], cluster.vertices[t[1]], cluster.vertices[t[2]]}));
        }
    }
    return out;
}

struct Built {
    Reconstruction reconstruction;
};

Built build(const std::string& name, std::size_t cluster_triangles = 256) {
    Built b;
    const Phantom phantom = make_phantom(name);
    Report report;
    ReconstructOptions options;
    options.multires.cluster_triangles = cluster_triangles;
    b.reconstruction = reconstruct(phantom.stack, options, report);
    return b;
}

TEST(MultiresDag, CutsOfTorusAreClosedWithTheRightGenus) {
    const Built b = build("torus");
    ASSERT_EQ(b.reconstruction.models.size(), 1u);
    const MultiresMesh& m = b.reconstruction.models[0];
    const std::vector<int> genera =
        test::sorted_genera(check_mesh(b.reconstruction.surfaces[0].mesh));
    EXPECT_GT(m.groups.size(), 2u);
    std::vector<double> errors;
    for (const MultiresGroup& g : m.groups) {
        errors.push_back(g.error_px);
    }
    errors.push_back(0.0);
    std::sort(errors.begin(), errors.end());
    std::size_t previous = SIZE_MAX;
    for (const double tau : errors) {
        const MultiresCut cut = select_cut_by_error(m, tau);
        EXPECT_LE(cut.error_px, std::max(tau, m.full_resolution_error_px));
        const TriMesh mesh = cut_mesh(m, cut);
        SCOPED_TRACE("tau " + std::to_string(tau));
        const test::CutErrorReport measured = test::expect_valid_cut(
            mesh, b.reconstruction, 0, genera, cut.error_px, cut.fine_error_px);
        std::cout << "tau " << tau << ": declared " << cut.error_px << " measured "
                  << measured.max_section_px << " / cap " << measured.max_cap_px << " px, "
                  << mesh.triangles.size() << " triangles\n";
        EXPECT_LE(mesh.triangles.size(), previous);
        previous = mesh.triangles.size();
    }
    std::cout << "torus: " << b.reconstruction.surfaces[0].mesh.triangles.size() << " -> "
              << cut_mesh(m, select_cut_by_error(m, 1e9)).triangles.size() << " triangles, "
              << m.groups.size() << " groups, root error " << errors.back() << " px\n";
}

TEST(MultiresDag, FinestCutIsTheFullResolutionSurface) {
    const Built b = build("sphere");
    const MultiresMesh& m = b.reconstruction.models[0];
    const MultiresCut cut = select_cut_by_error(m, 0.0);
    std::vector<std::uint32_t> level0;
    for (std::uint32_t c = 0; c < m.clusters.size(); ++c) {
        if (m.clusters[c].level == 0) {
            level0.push_back(c);
        }
    }
    EXPECT_EQ(cut.clusters, level0);
    std::multiset<Tri> full;
    for (const Tri& t : b.reconstruction.surfaces[0].mesh.triangles) {
        full.insert(canonical(t));
    }
    EXPECT_EQ(triangle_set(m, cut.clusters), full);
}

TEST(MultiresDag, GeomorphReproducesCoarseClusters) {
    const Built b = build("torus");
    const MultiresMesh& m = b.reconstruction.models[0];
    for (std::size_t g = 0; g < m.groups.size(); ++g) {
        std::multiset<Tri> moved;
        for (const std::uint32_t c : m.groups[g].consumed) {
            const MultiresCluster& cluster = m.clusters[c];
            for (const Tri& t : cluster.triangles) {
                const Tri u{cluster.coarse_vertices[t[0]], cluster.coarse_vertices[t[1]],
                            cluster.coarse_vertices[t[2]]};
                if (u[0] != u[1] && u[1] != u[2] && u[0] != u[2]) {
                    moved.insert(canonical(u));
                }
            }
        }
        EXPECT_EQ(moved, triangle_set(m, m.groups[g].produced)) << "group " << g;
    }
}

std::size_t triangle_count(const MultiresMesh& mesh, const std::vector<std::uint32_t>& ids) {
    std::size_t n = 0;
    for (const std::uint32_t c : ids) {
        n += mesh.clusters[c].triangles.size();
    }
    return n;
}

TEST(MultiresDag, GroupsShrinkToTheKeepFractionAtMost) {
    const Phantom phantom = make_phantom("torus");
    const std::vector<int> genera = {1};
    for (const double keep : {0.25, 0.5}) {
        SCOPED_TRACE("keep_fraction " + std::to_string(keep));
        Report report;
        ReconstructOptions options;
        options.multires.cluster_triangles = 256;
        options.multires.keep_fraction = keep;
        const Reconstruction r = reconstruct(phantom.stack, options, report);
        const MultiresMesh& m = r.models.at(0);
        ASSERT_GT(m.groups.size(), 4u);
        for (std::size_t g = 0; g < m.groups.size(); ++g) {
            const double before = double(triangle_count(m, m.groups[g].consumed));
            const double after = double(triangle_count(m, m.groups[g].produced));
            // a half-edge collapse removes two triangles: the last one may overshoot by that
            EXPECT_GE(after, std::floor(before * keep) - 2.0) << "group " << g;
            EXPECT_LE(after, before * (1.0 - options.multires.min_reduction)) << "group " << g;
        }
        for (std::uint32_t level = 0; level < level_count(m); ++level) {
            SCOPED_TRACE("level " + std::to_string(level));
            const MultiresCut cut = select_cut_at_level(m, level);
            test::expect_valid_cut(cut_mesh(m, cut), r, 0, genera, cut.error_px, cut.fine_error_px);
        }
    }
}

TEST(MultiresDag, ThinSpikeIsKeptWhileTheBoundIsShorterThanIt) {
    // A disc (radius 12 px) on slices 1-6 with a spike 2 px wide reaching to x = 70 on slices
    // 2-5. Flattening the spike keeps every section close to the contours (the one-sided
    // error stays about 1 px), so only the converse direction (contour to surface) stops it.
    constexpr double kTip = 70.0;
    SliceStack stack;
    stack.width = 80;
    stack.height = 60;
    stack.depth = 8;
    stack.labels.assign(std::size_t(stack.width) * stack.height * stack.depth, 0);
    for (std::uint32_t k = 1; k <= 6; ++k) {
        for (std::uint32_t j = 0; j < stack.height; ++j) {
            for (std::uint32_t i = 0; i < stack.width; ++i) {
                const double x = i + 0.5 - 20.0, y = j + 0.5 - 30.0;
                const bool disc = x * x + y * y <= 144.0;
                const bool spike = k >= 2 && k <= 5 && (j == 29 || j == 30) && i >= 30 && i < kTip;
                if (disc || spike) {
                    stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = 1;
                }
            }
        }
    }
    stack.index_to_world.linear = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 2}}};
    stack.label_table.push_back({1, "spike", {200, 80, 80}});
    stack.source = "test";
    Report report;
    ReconstructOptions options;
    options.multires.cluster_triangles = 32;
    options.multires.root_triangles = 16;
    const Reconstruction r = reconstruct(stack, options, report);
    ASSERT_EQ(r.models.size(), 1u);
    const MultiresMesh& m = r.models[0];
    ASSERT_GT(level_count(m), 3u);
    const std::vector<int> genera = test::sorted_genera(check_mesh(r.surfaces[0].mesh));
    for (std::uint32_t level = 0; level < level_count(m); ++level) {
        SCOPED_TRACE("level " + std::to_string(level));
        const MultiresCut cut = select_cut_at_level(m, level);
        const TriMesh mesh = cut_mesh(m, cut);
        test::expect_valid_cut(mesh, r, 0, genera, cut.error_px, cut.fine_error_px);
        // the spike's tip is a contour point: the surface must reach within the bound of it
        double reach = 0.0;
        for (const Vec3& p : mesh.positions) {
            reach = std::max(reach, p.x);
        }
        EXPECT_GE(reach, kTip - cut.error_px)
            << mesh.triangles.size() << " triangles, declared " << cut.error_px << " px";
        std::cout << "level " << level << ": " << mesh.triangles.size() << " triangles, declared "
                  << cut.error_px << " px, reaches x = " << reach << "\n";
    }
}

TEST(MultiresDag, RejectsKeepFractionOutsideZeroOne) {
    const Built b = build("sphere");
    const Reconstruction& r = b.reconstruction;
    const SliceErrorMeter meter(r.contours, r.fields, r.surfaces[0].label, r.slice_spacing_px);
    for (const double keep : {0.0, 1.0, -0.5, std::nan("")}) {
        MultiresOptions options;
        options.keep_fraction = keep;
        EXPECT_THROW(build_multires_mesh(r.surfaces[0].mesh, meter, 0.5, options), Error) << keep;
    }
}

TEST(MultiresDag, FineBoundsAreMonotoneAndLeaveOutTheFullResolutionBound) {
    // The bound against the finest level never exceeds the slice bound and grows along the DAG.
    // It leaves out the full-resolution surface's own bound: declared loose (4 px, as coarse
    // voxels give), every group's slice bound is at least 4 px while some first-level group's
    // bound against the finest level is below 95 % of its slice bound (at 3 px, the torus'
    // first-level groups reach 2.80-2.99 px since the balanced contour vertices,
    // SimplifyOptions::balance_reach; at 4 px 3.60 px and up since the end slabs bend as the
    // domes do, 3.40 before). Every level's cut is
    // within its bound of every full-resolution vertex (and every cut of the tests above:
    // expect_valid_cut).
    const Built b = build("torus");
    const Reconstruction& r = b.reconstruction;
    const SliceErrorMeter meter(r.contours, r.fields, r.surfaces[0].label, r.slice_spacing_px);
    MultiresOptions options;
    options.cluster_triangles = 256;
    const MultiresMesh m = build_multires_mesh(r.surfaces[0].mesh, meter, 4.0, options);
    ASSERT_GT(m.groups.size(), 2u);
    std::size_t level_one = 0;
    for (const MultiresGroup& g : m.groups) {
        EXPECT_LE(g.fine_error_px, g.error_px);
        EXPECT_GE(g.error_px, 4.0);
        EXPECT_GT(g.fine_error_px, 0.0);
        for (const std::uint32_t c : g.consumed) {
            const std::int32_t p = m.clusters[c].producer;
            if (p >= 0) {
                EXPECT_GE(g.fine_error_px, m.groups[std::size_t(p)].fine_error_px);
            }
        }
        if (g.level == 1 && g.fine_error_px < 0.95 * g.error_px) {
            ++level_one;
        }
    }
    EXPECT_GT(level_one, 0u) << "no first-level group below 95 % of its slice bound";
    // and every cut within its bound of every full-resolution vertex
    for (std::uint32_t level = 0; level < level_count(m); ++level) {
        const MultiresCut cut = select_cut_at_level(m, level);
        EXPECT_LE(test::max_point_distance_px(r.surfaces[0].mesh.positions, cut_mesh(m, cut)),
                  cut.fine_error_px + 1e-9)
            << "level " << level;
    }
}

TEST(MultiresDag, FirstLevelBoundKeepsVerticesNearFullResolution) {
    // first_level_px: the first level's groups keep the vertices their result would leave
    // farther than it from full resolution, unless they then cannot shrink. So more first-level
    // groups lie within it than without the option, and every cut still lies within its bound
    // of every full-resolution vertex (measured point by point). (At 0.4 px: 2 of 8 groups
    // against none without it; at 0.3 px none either way since the tube's end slabs bend as
    // their domes do.)
    const Built b = build("torus");
    const Reconstruction& r = b.reconstruction;
    const SliceErrorMeter meter(r.contours, r.fields, r.surfaces[0].label, r.slice_spacing_px);
    const double bound = 0.4;
    std::vector<std::size_t> within;
    for (const double first : {std::numeric_limits<double>::infinity(), bound}) {
        MultiresOptions options;
        options.cluster_triangles = 256;
        options.first_level_px = first;
        const MultiresMesh m = build_multires_mesh(r.surfaces[0].mesh, meter, 0.5, options);
        std::size_t n = 0, level_one = 0;
        for (const MultiresGroup& g : m.groups) {
            level_one += g.level == 1 ? 1 : 0;
            n += g.level == 1 && g.fine_error_px <= bound ? 1 : 0;
        }
        std::cout << "first_level_px " << first << ": " << n << " of " << level_one
                  << " first-level groups within " << bound << " px, " << m.groups.size()
                  << " groups\n";
        within.push_back(n);
        for (std::uint32_t level = 0; level < level_count(m); ++level) {
            const MultiresCut cut = select_cut_at_level(m, level);
            EXPECT_LE(test::max_point_distance_px(r.surfaces[0].mesh.positions, cut_mesh(m, cut)),
                      cut.fine_error_px + 1e-9)
                << "level " << level;
        }
    }
    EXPECT_GT(within[1], within[0]);
}

TEST(MultiresDag, IdenticalForAnyThreadCount) {
    const Phantom phantom = make_phantom("torus");
    std::vector<MultiresMesh> models;
    for (const unsigned threads : {1u, 2u}) {
        Report report;
        ReconstructOptions options;
        options.threads = threads;
        options.multires.cluster_triangles = 128;
        models.push_back(reconstruct(phantom.stack, options, report).models.at(0));
    }
    const MultiresMesh& a = models[0];
    const MultiresMesh& b = models[1];
    ASSERT_EQ(a.clusters.size(), b.clusters.size());
    ASSERT_EQ(a.groups.size(), b.groups.size());
    EXPECT_GT(a.groups.size(), 8u);
    for (std::size_t c = 0; c < a.clusters.size(); ++c) {
        EXPECT_EQ(a.clusters[c].vertices, b.clusters[c].vertices) << "cluster " << c;
        EXPECT_EQ(a.clusters[c].triangles, b.clusters[c].triangles) << "cluster " << c;
        EXPECT_EQ(a.clusters[c].coarse_vertices, b.clusters[c].coarse_vertices) << "cluster " << c;
    }
    for (std::size_t g = 0; g < a.groups.size(); ++g) {
        EXPECT_EQ(a.groups[g].error_px, b.groups[g].error_px) << "group " << g;
        EXPECT_EQ(a.groups[g].fine_error_px, b.groups[g].fine_error_px) << "group " << g;
        EXPECT_EQ(a.groups[g].consumed, b.groups[g].consumed) << "group " << g;
    }
}

}  // namespace
}  // namespace strata

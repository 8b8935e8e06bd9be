// The triangulation's repair chain, one small fixture per step (docs/architecture.md section 3):
// two slices whose simplified contours overlap unlike the pixels, each needing one more step
// than the one before: contours at pixel corners, original points near the neighbouring
// contours, whole original contours, the split at the AND layer. Found among the random stacks
// of surface_property_test (seed and slice pair named), cropped with a background margin. Each
// surface is checked independently: closed, outward, no self-intersection (exact), and the
// components and genus of the reference volume R by the brute-force labeller.

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/report.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/reconstruct.h"
#include "support/reference_topology.h"
#include "triangulate/surface.h"

namespace strata {
namespace {

/// Two slices drawn as text: 'a' on slice 0 only, 'b' on slice 1 only, 'X' on both, '.' on
/// neither; a margin of 2 background pixels all round; slice spacing d px.
SliceStack two_slices(const std::vector<std::string>& rows, double d) {
    constexpr std::uint32_t kMargin = 2;
    SliceStack stack;
    stack.width = static_cast<std::uint32_t>(rows.front().size()) + 2 * kMargin;
    stack.height = static_cast<std::uint32_t>(rows.size()) + 2 * kMargin;
    stack.depth = 2;
    stack.labels.assign(std::size_t(stack.width) * stack.height * 2, 0);
    for (std::uint32_t j = 0; j < rows.size(); ++j) {
        for (std::uint32_t i = 0; i < rows[j].size(); ++i) {
            const char c = rows[j][i];
            for (std::uint32_t k = 0; k < 2; ++k) {
                if (c == 'X' || (c == 'a' && k == 0) || (c == 'b' && k == 1)) {
                    stack.labels[(std::size_t(k) * stack.height + j + kMargin) * stack.width + i +
                                 kMargin] = 1;
                }
            }
        }
    }
    stack.index_to_world.linear = {{{1, 0, 0}, {0, 1, 0}, {0, 0, d}}};
    stack.label_table.push_back({1, "blob", {200, 80, 80}});
    stack.source = "test";
    return stack;
}

/// The stack reconstructed from its unsimplified contours, one thread.
Reconstruction reconstructed(const SliceStack& stack) {
    Report report;
    ReconstructOptions options;
    options.simplify = false;
    options.threads = 1;
    return reconstruct(stack, options, report);
}

/// The repair steps taken on label 1, whose surface is checked against R independently of the
/// pipeline's own verification.
RepairRecord checked_surface(const SliceStack& stack) {
    const Reconstruction result = reconstructed(stack);
    EXPECT_EQ(result.surfaces.size(), 1u);
    if (result.surfaces.empty()) {
        return {};
    }
    const ObjectSurface& surface = result.surfaces.front();
    const MeshReport check = check_mesh(surface.mesh);
    EXPECT_TRUE(is_closed_manifold(check)) << (check.problems.empty() ? "" : check.problems[0]);
    EXPECT_GT(check.signed_volume, 0.0);
    EXPECT_FALSE(has_self_intersections(surface.mesh));
    std::vector<int> genus;
    for (const MeshComponent& c : check.components) {
        genus.push_back(c.genus.value_or(-1));
    }
    std::sort(genus.rbegin(), genus.rend());
    std::vector<int> expected;
    for (const test::ReferenceSurface& s :
         test::reference_topology_brute_force(stack, 1).surfaces) {
        expected.push_back(s.genus);
    }
    std::sort(expected.rbegin(), expected.rend());
    EXPECT_EQ(genus, expected);
    EXPECT_TRUE(surface.verification.ok()) << surface.verification.problem;
    EXPECT_EQ(surface.topology_mismatches, 0u);
    return result.repairs.front();
}

TEST(FallbackSteps, ContoursAtPixelCornersSuffice) {
    // seed 68334472 of surface_property_test, slices 5-6 (found again with the balanced contour
    // vertices, SimplifyOptions::balance_reach: seed 1882953283's slices 4-5 no longer need the
    // fallback)
    // clang-format off
    const RepairRecord s = checked_surface(two_slices(
        {
            "...a........",
            "..aaa.......",
            "..XXa.......",
            ".aXXX.......",
            ".aXXXaaa....",
            ".XXXXaaaa...",
            ".XXXXaaaaa..",
            ".XXXXXaaaaa.",
            ".XbXXXaaaaa.",
            ".bbbbXaaaaa.",
            ".b..bbaaaaaa",
            ".b..bbaaaaaa",
            ".bbbbXaaaaa.",
            "aXbbXXaaaaa.",
            "aXXXXXaaaaa.",
            ".XXXXXaaaa..",
            ".XXXXXaaa...",
            ".XXXXX......",
            ".XXXXa......",
            ".aXXXa......",
            ".aXXX.......",
            "..XXa.......",
            "..aaa.......",
            "...a........",
        },
        2.0));
    // clang-format on
    EXPECT_FALSE(s.corner_slices.empty());
    EXPECT_TRUE(s.near_neighbour_slices.empty());
    EXPECT_TRUE(s.original_slices.empty());
    EXPECT_EQ(s.split_slabs, 0u);
}

TEST(FallbackSteps, OriginalPointsNearTheNeighbouringContours) {
    // seed 916483116, slices 5-6
    const RepairRecord s = checked_surface(two_slices(
        {
            "....bXXXXXX.....",
            "a.XXaaaaXXXXXb..",
            "aXaaaaaaaaXXXXX.",
            "XXaaaaaaaaXXXXXb",
            "XXaaaaaaaaaXXXXX",
            "XXaaaaaaaaXXXXXX",
            "XXaaaaaaaaXXXXX.",
            "aXXaaaaaaXXXXXb.",
            "a.XXXaaXXXXXX...",
            ".....bXXXXb.....",
        },
        3.0));
    EXPECT_FALSE(s.near_neighbour_slices.empty());
    EXPECT_TRUE(s.original_slices.empty());
    EXPECT_EQ(s.split_slabs, 0u);
}

TEST(FallbackSteps, WholeOriginalContours) {
    // seed 3556634808, slices 0-1
    const RepairRecord s = checked_surface(two_slices(
        {
            "..aaaa.....aaaa..",
            "aaaaaX.....baaaaa",
            ".aaaaa......aaaa.",
        },
        8.0));
    EXPECT_FALSE(s.original_slices.empty());
    EXPECT_EQ(s.split_slabs, 0u);
}

/// seed 4114208135 of surface_property_test, slices 0-1: needs the split at the AND layer.
SliceStack split_fixture() {
    return two_slices(
        {
            "..bXaaaaaXXb..",
            ".Xa.......aXb.",
            "bXXa.....aXXXb",
            "bXXXXXXXXXXXXb",
            ".XXXXXXXXXXXb.",
            "..bXXXXXXXXb..",
        },
        4.0);
}

TEST(FallbackSteps, SplitAtTheAndLayer) {
    const RepairRecord s = checked_surface(split_fixture());
    EXPECT_GT(s.split_slabs, 0u);
}

// The surface split at the AND layer goes on past the stack's end slices by d/2, as every
// other surface does (caps.cpp, stack_end): its end slices are not flat caps in their planes.
// (The TotalSegmentator liver, split at slab 17, had flat end caps folding over 90 degrees
// against the slabs that overhang them.)
TEST(FallbackSteps, SplitSurfaceExtendsPastTheStackEnds) {
    const Reconstruction result = reconstructed(split_fixture());
    ASSERT_EQ(result.surfaces.size(), 1u);
    ASSERT_GT(result.repairs.front().split_slabs, 0u);
    double lo = 1e300;
    double hi = -1e300;
    for (const Vec3& p : result.surfaces.front().mesh.positions) {
        lo = std::min(lo, p.z);
        hi = std::max(hi, p.z);
    }
    // d = 4 px, slices at z = 0 and 4
    EXPECT_EQ(lo, -2.0);
    EXPECT_EQ(hi, 6.0);
}

/// `stack`'s two slices alternating, `depth` slices in all.
SliceStack alternating(const SliceStack& stack, std::uint32_t depth) {
    SliceStack out = stack;
    out.depth = depth;
    out.labels.clear();
    for (std::uint32_t k = 0; k < depth; ++k) {
        const auto slice = stack.slice(k % 2);
        out.labels.insert(out.labels.end(), slice.begin(), slice.end());
    }
    return out;
}

/// Label 1 of `r` triangulated in `mode` on `threads` threads.
LabelTriangulation triangulated(const Reconstruction& r, TriangulateMode mode, unsigned threads) {
    TriangulateOptions options;
    options.slice_spacing_px = r.slice_spacing_px;
    options.threads = threads;
    return triangulate_label(r.contours, r.fields, r.medial_axes, options, 1, mode);
}

// The repairs check their attempts' contours with TriangulateMode::kMismatchesOnly and stop a
// first build at its first mismatch (kSurfaceIfMatched): both must name the slabs the whole
// build names, on any thread count, and without a mismatch kSurfaceIfMatched must give the
// whole build's surface.
TEST(FallbackSteps, EveryModeNamesTheSameMismatchedSlabs) {
    for (const std::uint32_t depth : {2u, 5u}) {
        const Reconstruction r = reconstructed(alternating(split_fixture(), depth));
        const std::vector<std::uint32_t> whole =
            triangulated(r, TriangulateMode::kSurface, 1).mismatched_slabs;
        ASSERT_FALSE(whole.empty()) << depth;
        for (const unsigned threads : {1u, 3u}) {
            for (const TriangulateMode mode :
                 {TriangulateMode::kSurfaceIfMatched, TriangulateMode::kMismatchesOnly}) {
                EXPECT_EQ(triangulated(r, mode, threads).mismatched_slabs, whole)
                    << depth << " slices, " << threads << " threads";
            }
        }
    }
    // clang-format off
    const Reconstruction clean = reconstructed(alternating(two_slices(
        {
            "aaaaa...",
            "aXXXXbb.",
            "aXXXXbb.",
            "aXXXXbb.",
            "..bbbbb.",
        },
        2.0), 5));
    // clang-format on
    for (const unsigned threads : {1u, 3u}) {
        const LabelTriangulation whole = triangulated(clean, TriangulateMode::kSurface, threads);
        ASSERT_TRUE(whole.mismatched_slabs.empty());
        const LabelTriangulation matched =
            triangulated(clean, TriangulateMode::kSurfaceIfMatched, threads);
        EXPECT_TRUE(matched.mismatched_slabs.empty());
        EXPECT_EQ(matched.surface.mesh.positions, whole.surface.mesh.positions);
        EXPECT_EQ(matched.surface.mesh.triangles, whole.surface.mesh.triangles);
        EXPECT_EQ(matched.surface.slabs, whole.surface.slabs);
    }
}

}  // namespace
}  // namespace strata

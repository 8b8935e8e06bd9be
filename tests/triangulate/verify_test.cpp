// The pipeline's verification (verify_surface) against surfaces whose defect the independent
// checks see: each check must report its own defect even when every other check passes.
#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "input/slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/reconstruct.h"
#include "support/mesh_shapes.h"
#include "support/surface_checks.h"

namespace strata {
namespace {

/// Label 1: two separate 2 x 2 pixel squares on each of 3 slices, so R is two solids of genus 0.
SliceStack two_blocks() {
    SliceStack stack;
    stack.width = 10;
    stack.height = 10;
    stack.depth = 3;
    stack.labels.assign(std::size_t(stack.width) * stack.height * stack.depth, 0);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        for (const std::uint32_t o : {1u, 6u}) {
            for (std::uint32_t j = o; j < o + 2; ++j) {
                for (std::uint32_t i = o; i < o + 2; ++i) {
                    stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = 1;
                }
            }
        }
    }
    stack.label_table.push_back({1, "blocks", {200, 80, 80}});
    stack.source = "test";
    return stack;
}

// Two overlapping cubes: closed, oriented, outward, two genus-0 components like R, but
// intersecting each other. Only the self-intersection check can reject it.
TEST(Verify, ReportsSelfIntersectionWhenAllElsePasses) {
    const SliceStack stack = two_blocks();
    ObjectSurface surface;
    surface.label = 1;
    surface.mesh = test::cube({1, 1, 0}, 2.0);
    test::append(surface.mesh, test::cube({2, 2, 1}, 2.0));
    const MeshReport report = check_mesh(surface.mesh);
    ASSERT_TRUE(is_closed_manifold(report));
    ASSERT_GT(report.signed_volume, 0.0);
    ASSERT_TRUE(has_self_intersections(surface.mesh));
    verify_surface(stack, surface);
    EXPECT_TRUE(surface.verification.done);
    EXPECT_TRUE(surface.verification.closed_manifold);
    EXPECT_TRUE(surface.verification.outward);
    EXPECT_TRUE(surface.verification.topology_as_reference) << surface.verification.reference;
    EXPECT_FALSE(surface.verification.self_intersection_free);
    EXPECT_FALSE(surface.verification.ok());
    EXPECT_FALSE(test::independent_problem(stack, surface).empty());
}

// The same two cubes apart: every check passes, and the independent ones agree.
TEST(Verify, AcceptsTheSameCubesApart) {
    const SliceStack stack = two_blocks();
    ObjectSurface surface;
    surface.label = 1;
    surface.mesh = test::cube({1, 1, 0}, 2.0);
    test::append(surface.mesh, test::cube({6, 6, 0}, 2.0));
    verify_surface(stack, surface);
    EXPECT_TRUE(surface.verification.ok()) << surface.verification.problem;
    EXPECT_EQ(test::independent_problem(stack, surface), "");
}

// A torus plus a cube: closed, outward, two components like R and no intersection, but one of
// genus 1 where R has two of genus 0.
TEST(Verify, ReportsAnotherGenusWithTheSameComponentCount) {
    const SliceStack stack = two_blocks();
    ObjectSurface surface;
    surface.label = 1;
    surface.mesh = test::translated(test::torus(), {2, 2, 1});
    test::append(surface.mesh, test::cube({6, 6, 0}, 2.0));
    const MeshReport report = check_mesh(surface.mesh);
    ASSERT_TRUE(is_closed_manifold(report));
    ASSERT_GT(report.signed_volume, 0.0);
    ASSERT_FALSE(has_self_intersections(surface.mesh));
    verify_surface(stack, surface);
    EXPECT_TRUE(surface.verification.self_intersection_free);
    EXPECT_FALSE(surface.verification.topology_as_reference);
    EXPECT_FALSE(surface.verification.ok());
    EXPECT_FALSE(test::independent_problem(stack, surface).empty());
}

// One cube inside out: closed and free of intersections, but facing inwards.
TEST(Verify, ReportsInwardFacingSurface) {
    const SliceStack stack = two_blocks();
    ObjectSurface surface;
    surface.label = 1;
    surface.mesh = test::flipped(test::cube({1, 1, 0}, 2.0));
    test::append(surface.mesh, test::cube({6, 6, 0}, 2.0));
    surface.mesh = test::flipped(surface.mesh);
    verify_surface(stack, surface);
    EXPECT_FALSE(surface.verification.ok());
    EXPECT_FALSE(test::independent_problem(stack, surface).empty());
}

}  // namespace
}  // namespace strata

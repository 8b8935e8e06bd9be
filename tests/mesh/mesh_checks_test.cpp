#include "mesh/mesh_checks.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include <gtest/gtest.h>

#include "support/mesh_shapes.h"

namespace strata {
namespace {

using test::Triangle;

/// True when some problem (or note) line contains `fragment`.
bool mentions(const std::vector<std::string>& lines, const std::string& fragment) {
    for (const std::string& line : lines) {
        if (line.find(fragment) != std::string::npos) {
            return true;
        }
    }
    return false;
}

std::string joined(const std::vector<std::string>& lines) {
    std::string out;
    for (const std::string& line : lines) {
        out += line + "\n";
    }
    return out;
}

TEST(MeshChecks, TetrahedronIsClosedGenusZeroWithVolumeOneSixth) {
    const MeshReport report = check_mesh(test::tetrahedron());
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_TRUE(report.problems.empty());
    EXPECT_TRUE(report.notes.empty());
    EXPECT_EQ(report.edge_count, 6u);
    EXPECT_EQ(report.euler_characteristic, 2);
    ASSERT_EQ(report.components.size(), 1u);
    EXPECT_EQ(report.components[0].genus, 0);
    EXPECT_NEAR(report.signed_volume, 1.0 / 6.0, 1e-15);
    EXPECT_NEAR(report.area, 1.5 + std::sqrt(3.0) / 2.0, 1e-14);
}

TEST(MeshChecks, UnitCubeHasVolumeOne) {
    const MeshReport report = check_mesh(test::cube());
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_EQ(report.edge_count, 18u);
    EXPECT_DOUBLE_EQ(report.signed_volume, 1.0);
    EXPECT_DOUBLE_EQ(report.area, 6.0);
    EXPECT_EQ(component_genera(report), std::vector<int>{0});
}

TEST(MeshChecks, VolumeIsTranslationInvariantFarFromOrigin) {
    const MeshReport report = check_mesh(test::cube({1e6, -2e6, 3e6}, 2.0));
    EXPECT_DOUBLE_EQ(report.signed_volume, 8.0);
}

TEST(MeshChecks, InwardFacingCubeHasNegativeVolume) {
    const MeshReport report = check_mesh(test::flipped(test::cube()));
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_DOUBLE_EQ(report.signed_volume, -1.0);
}

TEST(MeshChecks, NestedCavityIsSubtractedFromVolume) {
    const MeshReport report = check_mesh(test::nested_cubes());
    EXPECT_TRUE(is_closed_manifold(report));
    ASSERT_EQ(report.components.size(), 2u);
    EXPECT_DOUBLE_EQ(report.components[0].signed_volume, 27.0);
    EXPECT_DOUBLE_EQ(report.components[1].signed_volume, -1.0);
    EXPECT_DOUBLE_EQ(report.signed_volume, 26.0);
}

TEST(MeshChecks, OctahedronIsGenusZero) {
    const MeshReport report = check_mesh(test::octahedron());
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_EQ(component_genera(report), std::vector<int>{0});
    EXPECT_NEAR(report.signed_volume, 4.0 / 3.0, 1e-15);
}

TEST(MeshChecks, TorusIsGenusOne) {
    const MeshReport report = check_mesh(test::torus(12, 8));
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_EQ(report.euler_characteristic, 0);
    EXPECT_EQ(component_genera(report), std::vector<int>{1});
    // Inscribed polygons: a bit less than 2 pi^2 R r^2 = 9.87, clearly positive.
    EXPECT_GT(report.signed_volume, 8.0);
    EXPECT_LT(report.signed_volume, 2 * std::numbers::pi * std::numbers::pi * 2.0 * 0.25);
}

TEST(MeshChecks, SlabWithTwoHolesIsGenusTwo) {
    const MeshReport report = check_mesh(test::slab_with_holes(2));
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_EQ(report.euler_characteristic, -2);
    EXPECT_EQ(component_genera(report), std::vector<int>{2});
    EXPECT_DOUBLE_EQ(report.signed_volume, 13.0);  // 5 x 3 voxels minus 2 holes
}

TEST(MeshChecks, SlabWithThreeHolesIsGenusThree) {
    EXPECT_EQ(component_genera(check_mesh(test::slab_with_holes(3))), std::vector<int>{3});
}

TEST(MeshChecks, GenusIsPerComponentInTriangleOrder) {
    TriMesh mesh = test::torus();
    test::append(mesh, test::translated(test::cube(), {10, 0, 0}));
    test::append(mesh, test::translated(test::slab_with_holes(2), {-10, 0, 0}));
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_EQ(component_genera(report), (std::vector<int>{1, 0, 2}));
    EXPECT_EQ(report.components[1].first_triangle, test::torus().triangles.size());
    EXPECT_EQ(report.components[1].triangle_count, 12u);
    EXPECT_EQ(report.components[1].vertex_count, 8u);
    EXPECT_EQ(report.components[1].edge_count, 18u);
}

TEST(MeshChecks, OpenBoxHasFourBoundaryEdgesAndNoGenus) {
    const MeshReport report = check_mesh(test::open_box());
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.boundary_edges, 4u);
    EXPECT_EQ(report.non_manifold_edges, 0u);
    EXPECT_EQ(report.non_manifold_vertices, 0u);
    EXPECT_EQ(report.misoriented_edges, 0u);
    ASSERT_EQ(report.components.size(), 1u);
    EXPECT_FALSE(report.components[0].is_closed());
    EXPECT_FALSE(report.components[0].genus.has_value());
    EXPECT_EQ(report.euler_characteristic, 1);  // a disc
    EXPECT_TRUE(mentions(report.problems, "4 boundary edges (the surface is open), e.g. ("))
        << joined(report.problems);
}

TEST(MeshChecks, EdgeSharedByTwoCubesIsNonManifold) {
    const MeshReport report = check_mesh(test::two_cubes_sharing_edge());
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.non_manifold_edges, 1u);
    EXPECT_EQ(report.boundary_edges, 0u);
    EXPECT_EQ(report.misoriented_edges, 0u);
    EXPECT_EQ(report.components.size(), 1u);
    EXPECT_FALSE(report.components[0].genus.has_value());
    EXPECT_TRUE(mentions(report.problems, "1 non-manifold edge (used by more than 2 triangles)"))
        << joined(report.problems);
    EXPECT_TRUE(mentions(report.problems, "in 4 triangles")) << joined(report.problems);
}

TEST(MeshChecks, VertexSharedByTwoTetrahedraIsNonManifold) {
    const MeshReport report = check_mesh(test::two_tetrahedra_sharing_vertex());
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.non_manifold_vertices, 1u);
    EXPECT_EQ(report.non_manifold_edges, 0u);
    EXPECT_EQ(report.boundary_edges, 0u);
    EXPECT_EQ(report.misoriented_edges, 0u);
    // Connected through the shared vertex: one component, V - E + F = 7 - 12 + 8.
    ASSERT_EQ(report.components.size(), 1u);
    EXPECT_EQ(report.components[0].euler_characteristic, 3);
    EXPECT_FALSE(report.components[0].genus.has_value());
    EXPECT_NEAR(report.signed_volume, 2.0 / 6.0, 1e-15);
    EXPECT_TRUE(mentions(report.problems, "vertex 0 (2 fans)")) << joined(report.problems);
}

TEST(MeshChecks, FlippedTriangleIsDetected) {
    const MeshReport report = check_mesh(test::cube_with_flipped_triangle());
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.misoriented_edges, 3u);
    EXPECT_EQ(report.boundary_edges, 0u);
    EXPECT_EQ(report.non_manifold_edges, 0u);
    EXPECT_FALSE(report.components[0].is_oriented());
    EXPECT_FALSE(report.components[0].genus.has_value());
    EXPECT_TRUE(mentions(report.problems, "3 edges are used twice in the same direction"))
        << joined(report.problems);
    EXPECT_TRUE(mentions(report.problems, "in triangles 0 and ")) << joined(report.problems);
}

TEST(MeshChecks, OutOfRangeIndexIsReportedNotFatal) {
    TriMesh mesh = test::cube();
    mesh.triangles.push_back({0, 1, 99});
    mesh.triangles.push_back({std::numeric_limits<std::uint32_t>::max(), 0, 1});
    const MeshReport report = check_mesh(mesh);
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.out_of_range_triangles, 2u);
    // The invalid triangles take no part in the topology: the cube is still closed.
    EXPECT_EQ(report.boundary_edges, 0u);
    EXPECT_EQ(component_genera(report), std::vector<int>{0});
    EXPECT_TRUE(mentions(report.problems, "triangle 12 (0, 1, 99)")) << joined(report.problems);
    EXPECT_TRUE(mentions(report.problems, "(vertex count 8)")) << joined(report.problems);
}

TEST(MeshChecks, RepeatedVertexInTriangleIsReported) {
    TriMesh mesh = test::cube();
    mesh.triangles.push_back({4, 4, 7});
    const MeshReport report = check_mesh(mesh);
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.repeated_vertex_triangles, 1u);
    EXPECT_TRUE(
        mentions(report.problems, "1 triangle repeats a vertex, e.g. triangle 12 (4, 4, 7)"))
        << joined(report.problems);
}

TEST(MeshChecks, DuplicateTrianglesAreReportedInAnyOrientation) {
    TriMesh mesh = test::tetrahedron();
    mesh.triangles.push_back({2, 1, 0});  // reversed copy of triangle 0 (0, 2, 1)
    mesh.triangles.push_back({1, 3, 0});  // rotated copy of triangle 1 (0, 1, 3)
    const MeshReport report = check_mesh(mesh);
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.duplicate_triangles, 2u);
    EXPECT_TRUE(mentions(report.problems, "triangle 4 repeats triangle 0"))
        << joined(report.problems);
    EXPECT_TRUE(mentions(report.problems, "triangle 5 repeats triangle 1"))
        << joined(report.problems);
}

TEST(MeshChecks, NonFiniteCoordinateIsReported) {
    TriMesh mesh = test::cube();
    mesh.positions[5].y = std::numeric_limits<double>::quiet_NaN();
    mesh.positions[6].z = std::numeric_limits<double>::infinity();
    const MeshReport report = check_mesh(mesh);
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_EQ(report.non_finite_vertices, 2u);
    EXPECT_TRUE(std::isfinite(report.area));
    EXPECT_TRUE(std::isfinite(report.signed_volume));
    EXPECT_TRUE(mentions(report.problems,
                         "2 vertices have a non-finite coordinate, e.g. vertex 5; "
                         "vertex 6"))
        << joined(report.problems);
}

TEST(MeshChecks, UnreferencedVerticesAndZeroAreaAreNotesOnly) {
    TriMesh mesh = test::tetrahedron();
    mesh.positions.push_back({5, 5, 5});
    mesh.positions.push_back({6, 6, 6});
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_EQ(report.unreferenced_vertices, 2u);
    EXPECT_TRUE(mentions(report.notes, "2 unreferenced vertices, e.g. vertex 4; vertex 5"))
        << joined(report.notes);

    // A flat but topologically fine closed surface: the apex lies in the base plane.
    TriMesh flat = test::tetrahedron();
    flat.positions[3] = {0.25, 0.25, 0.0};
    const MeshReport flat_report = check_mesh(flat);
    EXPECT_TRUE(is_closed_manifold(flat_report));
    EXPECT_EQ(flat_report.signed_volume, 0.0);
    EXPECT_EQ(flat_report.zero_area_triangles, 0u);  // flat, but no single triangle is
}

TEST(MeshChecks, CollinearTriangleHasZeroArea) {
    TriMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
    mesh.triangles = {{0, 1, 2}};
    const MeshReport report = check_mesh(mesh);
    EXPECT_EQ(report.zero_area_triangles, 1u);
    EXPECT_EQ(report.boundary_edges, 3u);
    EXPECT_TRUE(mentions(report.notes, "1 zero-area triangle, e.g. triangle 0 (0, 1, 2)"));
}

TEST(MeshChecks, LabelsOfWrongSizeAreReported) {
    TriMesh mesh = test::cube();
    mesh.labels = {1, 2};
    const MeshReport report = check_mesh(mesh);
    EXPECT_FALSE(is_closed_manifold(report));
    EXPECT_TRUE(mentions(report.problems, "labels: 2 entries, expected 0 or 12"));
    mesh.labels.assign(12, 7);
    EXPECT_TRUE(is_closed_manifold(check_mesh(mesh)));
}

TEST(MeshChecks, EmptyMeshIsTriviallyClosed) {
    const MeshReport report = check_mesh(TriMesh{});
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_TRUE(report.components.empty());
    EXPECT_TRUE(mentions(report.notes, "no triangles"));
}

TEST(MeshChecks, ExamplesAreLimitedToTheFirstFew) {
    TriMesh mesh;
    for (std::uint32_t i = 0; i < 20; ++i) {
        mesh.positions.push_back({double(i), 0, 0});
        mesh.triangles.push_back({i, i, i});
    }
    const MeshReport report = check_mesh(mesh);
    EXPECT_EQ(report.repeated_vertex_triangles, 20u);
    ASSERT_TRUE(mentions(report.problems, "20 triangles repeat a vertex"));
    EXPECT_TRUE(mentions(report.problems, "triangle 4 (4, 4, 4); ...")) << joined(report.problems);
    EXPECT_FALSE(mentions(report.problems, "triangle 5 ")) << joined(report.problems);
}

TEST(MeshChecks, MillionTriangleTorusIsCheckedQuickly) {
    const TriMesh mesh = test::torus(1000, 500, 10.0, 3.0);
    ASSERT_EQ(mesh.triangles.size(), 1'000'000u);
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report)) << joined(report.problems);
    EXPECT_EQ(component_genera(report), std::vector<int>{1});
    EXPECT_EQ(report.edge_count, 1'500'000u);
}

}  // namespace
}  // namespace strata

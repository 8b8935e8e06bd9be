#include "mesh/self_intersection.h"

#include <algorithm>
#include <limits>

#include <gtest/gtest.h>

#include "mesh/mesh_checks.h"
#include "support/mesh_shapes.h"

namespace strata {
namespace {

using Pair = std::pair<std::uint32_t, std::uint32_t>;

TriMesh two_triangles(std::vector<Vec3> positions, std::vector<test::Triangle> triangles) {
    TriMesh mesh;
    mesh.positions = std::move(positions);
    mesh.triangles = std::move(triangles);
    return mesh;
}

TEST(SelfIntersection, ClosedShapesAreFree) {
    for (const TriMesh& mesh : {test::tetrahedron(), test::cube(), test::octahedron(),
                                test::torus(), test::slab_with_holes(2)}) {
        const SelfIntersections found = find_self_intersections(mesh);
        EXPECT_TRUE(found.is_free());
        EXPECT_TRUE(found.pairs.empty());
        EXPECT_FALSE(found.truncated);
        EXPECT_FALSE(has_self_intersections(mesh));
    }
}

TEST(SelfIntersection, InterpenetratingCubesIntersectBetweenComponents) {
    const TriMesh mesh = test::interpenetrating_cubes();
    ASSERT_EQ(check_mesh(mesh).components.size(), 2u);
    const SelfIntersections found = find_self_intersections(mesh, 0);
    ASSERT_FALSE(found.pairs.empty());
    EXPECT_FALSE(found.truncated);
    EXPECT_TRUE(found.degenerate_triangles.empty());
    EXPECT_TRUE(std::is_sorted(found.pairs.begin(), found.pairs.end()));
    for (const auto& [a, b] : found.pairs) {
        EXPECT_LT(a, 12u);  // one triangle from each cube
        EXPECT_GE(b, 12u);
    }
    EXPECT_TRUE(has_self_intersections(mesh));
}

TEST(SelfIntersection, MaxPairsTruncatesTheSearch) {
    const TriMesh mesh = test::interpenetrating_cubes();
    const std::size_t all = find_self_intersections(mesh, 0).pairs.size();
    ASSERT_GT(all, 2u);
    const SelfIntersections found = find_self_intersections(mesh, 2);
    EXPECT_EQ(found.pairs.size(), 2u);
    EXPECT_TRUE(found.truncated);
}

TEST(SelfIntersection, FoldedStripIntersectsWithinOneComponent) {
    const TriMesh mesh = test::folded_strip();
    ASSERT_EQ(check_mesh(mesh).components.size(), 1u);
    const SelfIntersections found = find_self_intersections(mesh);
    // Panel 0 is triangles 0 and 1, panel 2 is triangles 4 and 5; the crossing line x = 1, z = 0
    // runs along the diagonals, so every triangle of one panel meets one of the other.
    ASSERT_FALSE(found.pairs.empty());
    for (const auto& [a, b] : found.pairs) {
        EXPECT_LE(a, 1u);
        EXPECT_GE(b, 4u);
    }
    EXPECT_TRUE(has_self_intersections(mesh));
}

TEST(SelfIntersection, NestedDisjointAndVertexTouchingMeshesAreFree) {
    EXPECT_TRUE(find_self_intersections(test::nested_cubes()).is_free());
    EXPECT_TRUE(find_self_intersections(test::disjoint_cubes()).is_free());
    EXPECT_TRUE(find_self_intersections(test::two_tetrahedra_sharing_vertex()).is_free());
    EXPECT_TRUE(find_self_intersections(test::two_cubes_sharing_edge()).is_free());
    EXPECT_FALSE(has_self_intersections(test::nested_cubes()));
    EXPECT_FALSE(has_self_intersections(test::two_tetrahedra_sharing_vertex()));
}

TEST(SelfIntersection, FaceTouchingCubesIntersectWithOrWithoutWelding) {
    // Coplanar faces at x = 1 overlap: touching counts unless it is a shared vertex or edge.
    const SelfIntersections apart = find_self_intersections(test::face_touching_cubes());
    EXPECT_FALSE(apart.pairs.empty());
    const SelfIntersections welded =
        find_self_intersections(test::weld_exact(test::face_touching_cubes()));
    EXPECT_FALSE(welded.pairs.empty());
}

TEST(SelfIntersection, UnweldedSoupOfACubeIsFree) {
    // Every triangle with its own three vertices: equal coordinates still count as shared.
    const TriMesh cube = test::cube();
    TriMesh soup;
    for (const auto& t : cube.triangles) {
        const auto base = static_cast<std::uint32_t>(soup.positions.size());
        for (std::uint32_t v : t) {
            soup.positions.push_back(cube.positions[v]);
        }
        soup.triangles.push_back({base, base + 1, base + 2});
    }
    EXPECT_FALSE(has_self_intersections(soup));
}

TEST(SelfIntersection, EdgeNeighboursIntersectOnlyWhenFoldedFlat) {
    const std::vector<Vec3> flat{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    // A flat quad: the triangles lie on both sides of the shared edge (1,0,0)-(0,1,0).
    EXPECT_FALSE(has_self_intersections(two_triangles(flat, {{0, 1, 2}, {1, 3, 2}})));
    // Folded flat: the fourth corner on the same side of the shared edge as the third.
    const std::vector<Vec3> folded{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.2, 0}};
    const SelfIntersections found =
        find_self_intersections(two_triangles(folded, {{0, 1, 2}, {1, 3, 2}}));
    EXPECT_EQ(found.pairs, (std::vector<Pair>{{0, 1}}));
    // Bent out of the plane: only the edge is shared.
    const std::vector<Vec3> bent{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2, 0.2, 0.5}};
    EXPECT_FALSE(has_self_intersections(two_triangles(bent, {{0, 1, 2}, {1, 3, 2}})));
}

TEST(SelfIntersection, VertexNeighboursIntersectOnlyWhenOneCrossesTheOther) {
    const Vec3 o{0, 0, 0};
    // The second triangle passes through the first's plane along (0,0,0)-(1,1,0), inside it.
    const TriMesh piercing =
        two_triangles({o, {2, 0, 0}, {0, 2, 0}, {1, 1, -1}, {1, 1, 1}}, {{0, 1, 2}, {0, 3, 4}});
    EXPECT_EQ(find_self_intersections(piercing).pairs, (std::vector<Pair>{{0, 1}}));
    // Pointing away: the triangles share the vertex only.
    const TriMesh away =
        two_triangles({o, {2, 0, 0}, {0, 2, 0}, {-1, -1, -1}, {-1, -1, 1}}, {{0, 1, 2}, {0, 3, 4}});
    EXPECT_FALSE(has_self_intersections(away));
}

TEST(SelfIntersection, DuplicateTriangleIntersects) {
    TriMesh mesh = test::tetrahedron();
    mesh.triangles.push_back({3, 2, 1});  // triangle 3 reversed
    EXPECT_EQ(find_self_intersections(mesh).pairs, (std::vector<Pair>{{3, 4}}));
}

TEST(SelfIntersection, DegenerateTrianglesAreReportedNotTested) {
    TriMesh mesh = test::tetrahedron();
    mesh.positions.push_back({2, 2, 2});                                         // 4
    mesh.positions.push_back({3, 3, 3});                                         // 5
    mesh.positions.push_back({std::numeric_limits<double>::quiet_NaN(), 0, 0});  // 6
    mesh.triangles.push_back({0, 4, 5});                                         // 4: collinear
    mesh.triangles.push_back({1, 1, 2});   // 5: repeated vertex
    mesh.triangles.push_back({0, 1, 77});  // 6: out of range
    mesh.triangles.push_back({0, 1, 6});   // 7: non-finite corner
    mesh.triangles.push_back({1, 2, 3});   // 8: duplicate of 3, still tested
    const SelfIntersections found = find_self_intersections(mesh);
    EXPECT_EQ(found.degenerate_triangles, (std::vector<std::uint32_t>{4, 5, 6, 7}));
    EXPECT_EQ(found.pairs, (std::vector<Pair>{{3, 8}}));
    EXPECT_FALSE(found.is_free());
    EXPECT_TRUE(has_self_intersections(mesh));
}

TEST(SelfIntersection, EmptyMeshIsFree) {
    EXPECT_TRUE(find_self_intersections(TriMesh{}).is_free());
    EXPECT_FALSE(has_self_intersections(TriMesh{}));
}

TEST(SelfIntersection, FineTorusIsFree) {
    // 4k thin triangles with many near-coplanar neighbours; kept small because CGAL is slow
    // in Debug builds (1M triangles take about 2 s in Release).
    const TriMesh mesh = test::torus(64, 32, 10.0, 3.0);
    EXPECT_FALSE(has_self_intersections(mesh));
    EXPECT_TRUE(find_self_intersections(mesh).is_free());
}

}  // namespace
}  // namespace strata

#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// What `find_self_intersections` found.
struct SelfIntersections {
    /// Intersecting triangle pairs (first < second), sorted; at most `max_pairs` of them.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
    /// Triangles that could not be tested, sorted: an index out of range, a non-finite corner,
    /// or three collinear corners (a repeated vertex included). Not limited by `max_pairs`.
    std::vector<std::uint32_t> degenerate_triangles;
    /// True when the search stopped at `max_pairs`: more intersecting pairs may exist.
    bool truncated = false;

    /// True when the mesh is certified free of self-intersections: no pair, no degenerate
    /// triangle (which, like CGAL's `does_self_intersect`, cannot be certified).
    bool is_free() const { return pairs.empty() && degenerate_triangles.empty(); }
};

/// Finds pairs of triangles of a triangle soup that intersect, exactly (CGAL exact predicates
/// on the double coordinates, no tolerance).
///
/// Input: any `TriMesh`, including several components, non-manifold and inconsistently oriented
/// ones; intersections between different components are found like any other. Vertices with
/// exactly equal coordinates are treated as one vertex. Two triangles sharing a vertex or an edge
/// intersect only if they overlap beyond that shared feature (CGAL's definition): two triangles
/// of a flat quad do not intersect, a triangle folded flat onto its edge neighbour does, and
/// triangles that merely touch without sharing a vertex (coplanar faces of two cubes put side by
/// side) do. Degenerate triangles are listed, not tested, and never abort.
/// `max_pairs`: stop after this many pairs (0: no limit).
/// Cost: O(n log^2 n + k) for n triangles and k box overlaps (CGAL box_self_intersection_d).
SelfIntersections find_self_intersections(const TriMesh& mesh, std::size_t max_pairs = 100);

/// True unless the mesh is certified free of self-intersections (see
/// `SelfIntersections::is_free`); stops at the first intersecting pair or degenerate triangle.
bool has_self_intersections(const TriMesh& mesh);

/// True when the corners of `t` are collinear (a repeated corner included), exactly: the
/// triangles `find_self_intersections` lists as degenerate.
bool triangle_is_degenerate(const std::array<Vec3, 3>& t);

/// The pairwise test of `find_self_intersections` for two triangles given by their corners and
/// vertex ids: true when they intersect beyond the vertices and edges they share (equal ids), or
/// when either is degenerate (three collinear corners). Exact (CGAL predicates on the doubles).
bool triangles_intersect(const std::array<Vec3, 3>& a,
                         const std::array<std::uint32_t, 3>& a_ids,
                         const std::array<Vec3, 3>& b,
                         const std::array<std::uint32_t, 3>& b_ids);

}  // namespace strata

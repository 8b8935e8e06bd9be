#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// One connected component of a mesh: a maximal set of triangles connected through shared
/// vertices (two triangles touching only at a vertex are in the same component). Only valid
/// triangles count (indices in range, three distinct vertices); see `MeshReport`.
struct MeshComponent {
    std::uint32_t first_triangle = 0;     ///< smallest triangle index in the component
    std::size_t triangle_count = 0;       ///< F
    std::size_t vertex_count = 0;         ///< V: vertices referenced by the component's triangles
    std::size_t edge_count = 0;           ///< E: distinct undirected edges
    std::size_t boundary_edge_count = 0;  ///< edges in exactly 1 triangle
    std::size_t non_manifold_edge_count = 0;    ///< edges in more than 2 triangles
    std::size_t non_manifold_vertex_count = 0;  ///< vertices whose triangles form several fans
    std::size_t misoriented_edge_count = 0;  ///< edges in 2 triangles, both in the same direction
    std::int64_t euler_characteristic = 0;   ///< V - E + F
    /// (2 - chi) / 2 when the component is a closed, oriented 2-manifold; empty otherwise.
    std::optional<int> genus;
    /// Volume enclosed by the component (divergence theorem), positive when its triangles face
    /// outwards, in cubed position units; meaningful only for closed components.
    double signed_volume = 0.0;
    double area = 0.0;  ///< total triangle area, in squared position units

    bool is_closed() const { return boundary_edge_count == 0; }
    bool is_manifold() const {
        return non_manifold_edge_count == 0 && non_manifold_vertex_count == 0;
    }
    bool is_oriented() const { return misoriented_edge_count == 0; }
};

/// Everything `check_mesh` finds out about a mesh. Counts of zero mean "no such problem".
///
/// Triangles with an index out of range or a repeated vertex are "invalid": they are counted
/// and reported but take no part in the topology (edges, fans, components) nor in area and
/// volume. Triangles touching a vertex with a non-finite coordinate are left out of area and
/// volume only.
struct MeshReport {
    std::size_t vertex_count = 0;    ///< positions.size()
    std::size_t triangle_count = 0;  ///< triangles.size()

    // Validity.
    std::size_t out_of_range_triangles = 0;     ///< triangles with an index >= vertex_count
    std::size_t repeated_vertex_triangles = 0;  ///< valid indices, but two corners equal
    std::size_t duplicate_triangles = 0;    ///< same vertex set as an earlier triangle (any order)
    std::size_t non_finite_vertices = 0;    ///< vertices with a NaN or infinite coordinate
    std::size_t unreferenced_vertices = 0;  ///< vertices no valid triangle uses (a note only)
    std::size_t zero_area_triangles = 0;    ///< valid triangles whose computed area is 0 (a note)
    bool labels_size_mismatch = false;      ///< labels neither empty nor one per triangle

    // Topology over the valid triangles.
    std::size_t edge_count = 0;             ///< distinct undirected edges
    std::size_t boundary_edges = 0;         ///< edges in exactly 1 triangle
    std::size_t non_manifold_edges = 0;     ///< edges in more than 2 triangles
    std::size_t non_manifold_vertices = 0;  ///< vertices whose triangle fan is split
    std::size_t misoriented_edges = 0;      ///< edges in 2 triangles in the same direction
    std::int64_t euler_characteristic = 0;  ///< V - E + F over referenced vertices

    std::vector<MeshComponent> components;  ///< ordered by first triangle

    double signed_volume = 0.0;  ///< sum over components; see MeshComponent::signed_volume
    double area = 0.0;           ///< total area of the valid triangles

    /// One line per kind of defect that makes the mesh invalid or not a closed oriented
    /// manifold, with the first few offending indices:
    /// "3 edges are used twice in the same direction (inconsistent orientation), e.g. (0, 1)
    /// in triangles 2 and 7". Empty exactly when `is_closed_manifold` holds.
    std::vector<std::string> problems;
    /// Noteworthy but harmless findings (unreferenced vertices, zero-area triangles, no
    /// triangles at all), same format.
    std::vector<std::string> notes;
};

/// Checks validity, topology and basic geometry of a triangle mesh.
///
/// Input: any `TriMesh`, including broken ones: out-of-range indices, repeated vertices,
/// duplicate triangles and non-finite coordinates are reported, never crash or throw.
/// Definitions: an edge is manifold when exactly 2 triangles use it, a vertex when its
/// triangles form one fan (connected through the edges at that vertex), closed means no edge is
/// used by a single triangle, oriented means every 2-triangle edge is used once in each
/// direction. Components are connected through shared vertices.
/// Cost: O(n log n) time, O(n) memory in the number of triangles and vertices.
MeshReport check_mesh(const TriMesh& mesh);

/// True when the mesh is valid (indices in range, no repeated vertex in a triangle, no
/// duplicate triangles, finite coordinates, labels sized right) and a closed, consistently
/// oriented, edge- and vertex-manifold surface. Unreferenced and zero-area triangles do not
/// matter here. An empty mesh is a (trivial) closed manifold.
bool is_closed_manifold(const MeshReport& report);

/// Genus of every component in order, or -1 for components that are not closed oriented
/// 2-manifolds. A sphere gives {0}, a torus {1}, a sphere and a torus {0, 1}.
std::vector<int> component_genera(const MeshReport& report);

}  // namespace strata

#pragma once

// Slice-fidelity oracle for tests: the section of a closed triangle mesh by a slice plane,
// compared exactly (segment against segment, no sampling) with the expected polygons of that
// slice. Independent of the library's distance-field, medial-axis and triangulation code: it
// reads only the mesh and the contours.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "contours/slice_contours.h"
#include "core/types.h"
#include "mesh/tri_mesh.h"

namespace strata::test {

/// One disagreement between the mesh section and the expected polygons.
struct SectionMismatch {
    std::string what;    ///< e.g. "section segment off the contour", "contour edge not covered"
    Vec2 where;          ///< slice pixels: the worst point of the offending piece
    double distance_px;  ///< distance of `where` from the other side (0 for mesh defects)
};

/// Result of `compare_slice_section`.
struct SectionReport {
    std::size_t mesh_segments = 0;      ///< segments of the mesh section (see below)
    std::size_t contour_edges = 0;      ///< edges of the expected polygons
    double max_mesh_to_contour_px = 0;  ///< sup over section points of the distance to polygons
    double max_contour_to_mesh_px = 0;  ///< sup over polygon points of the distance to section
    /// At most 20 entries; when there are more, the last one says how many were left out.
    std::vector<SectionMismatch> mismatches;

    bool ok() const { return mismatches.empty(); }
};

/// Compares the section of `mesh` by the plane z = `z` with `polygons`, as point sets.
///
/// `mesh`: slice space (x, y in pixels, z = k * spacing for slice k), meant to be a closed
/// 2-manifold; triangles may lie in the plane, touch it at an edge or a vertex, or be vertical.
/// `polygons`: closed polygons (last vertex joins the first), pixels, any orientation; their
/// edges form the expected section. A point is "in the plane" when |p.z - z| <= 1e-9 max(1, |z|).
///
/// The section is the boundary of mesh ∩ plane: the segment of every triangle with vertices
/// strictly on both sides, plus every mesh edge lying in the plane whose two faces are not on the
/// same side (sides: above, below, in the plane); so an edge where the surface only touches the
/// plane, or an edge between two coplanar triangles, is not part of it, while an edge between a
/// planar cap and a wall, or between a triangle above and one below, is. Isolated touching
/// vertices contribute nothing.
///
/// Passes (`ok()`) when every section segment lies on the polygon edges and every polygon edge is
/// covered by section segments, within `tolerance_px`: each segment is cut at the projections of
/// the nearby vertices of the other side, and each piece must have both ends within tolerance of
/// one single segment of the other side. The two maxima are exact directed Hausdorff distances
/// between the segment sets (not sampled). A mesh edge without exactly two faces, a degenerate
/// triangle or a vertex index out of range is reported as a mismatch (the rest is still compared).
/// Example: a prism whose middle ring is shifted by 0.3 px, cut there, reports both maxima 0.3.
SectionReport compare_slice_section(const TriMesh& mesh,
                                    double z,
                                    const std::vector<std::vector<Vec2>>& polygons,
                                    double tolerance_px = 1e-6);

/// The simplified polygons of every contour of `label` in `set` (outer contours and holes, in
/// the set's order): vertex i is points[simplified[i]].
/// \throw strata::Error (Internal) when a simplified index is out of range.
std::vector<std::vector<Vec2>> simplified_polygons(const SliceContourSet& set, std::uint16_t label);

/// The section segments of `mesh` by the plane z = `z` as defined for `compare_slice_section`
/// (each as two endpoints), for diagnostics; mesh defects are ignored here.
std::vector<std::array<Vec2, 2>> slice_section_segments(const TriMesh& mesh, double z);

}  // namespace strata::test

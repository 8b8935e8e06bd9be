#pragma once

// Error oracle for simplified surfaces, for tests: how far the sections of a surface by the input
// slice planes stray from the ORIGINAL contours of its label. Independent of the library's
// distance fields and error meters: it reads only the mesh and the contour points.

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "contours/slice_contours.h"
#include "core/types.h"
#include "mesh/tri_mesh.h"

namespace strata::test {

/// Result of `measure_cut_error`. Distances in slice pixels.
struct CutErrorReport {
    /// Sup over the section points (walls) of the distance to the original contour polylines of
    /// their slice. Infinite when the mesh meets a plane where the label has no contour.
    double max_section_px = 0;
    /// Sup over the points of in-plane (cap) triangles of the distance to their slice's inside
    /// region; sampled, at most 0.03 px below the true sup (see `measure_cut_error`).
    double max_cap_px = 0;
    /// The converse direction: sup over the points of the original contour polylines of the label
    /// (every slice) of their distance (3D, slice space) to the mesh, i.e. how far the data lies
    /// from the surface. Branch and bound, at most 0.01 px below the true sup. Infinite when the
    /// label has a contour and the mesh has no triangle.
    double max_coverage_px = 0;
    std::uint32_t worst_slice = 0;  ///< slice of max_px() (0 when nothing was measured)
    /// A point (px) on that slice where max_px() is reached (for the section: the best of samples
    /// every 0.01 px, so within 0.005 px of the maximum).
    Vec2 worst_point;
    std::uint32_t slices_met = 0;  ///< slice planes the mesh meets
    std::uint32_t cap_triangles = 0;
    /// e.g. "slice 3 (z = 6): the mesh meets the plane (12 triangles), label 1 has no contour".
    std::vector<std::string> problems;

    double max_px() const { return std::max({max_section_px, max_cap_px, max_coverage_px}); }
};

/// Measures how far the surface `mesh` of `label` is from that label's original contours, slice
/// by slice, in both directions. From the mesh to the data: for every input slice plane z = k d
/// (k < contours.slices.size()) the mesh meets,
/// - walls: every point of the section (the boundary of mesh ∩ plane as defined by
///   `compare_slice_section`, slice_section.h), every in-plane mesh edge where the surface only
///   touches the plane, and every in-plane vertex outside the caps is measured against the
///   polylines `Contour::points` of every contour of `label` on slice k (outer and holes);
/// - caps: every point of a triangle with its three vertices in the plane is measured against
///   the inside region of slice k (even-odd interior of those polylines; inside counts 0).
/// A point is in the plane when |p.z - z| <= 1e-9 max(1, |z|), as in slice_section.h.
/// From the data to the mesh (`max_coverage_px`): every point of every original polyline of
/// `label`, at z = k d, against every triangle of the mesh (3D distance).
///
/// `mesh`: slice space (x, y in px on the contour grid, z = k * `slice_spacing_px`), any
/// triangles (need not be closed); `contours`: the contour stage's output, whose original points
/// are read (the simplified indices are not).
///
/// Exactness: the section maximum is the exact directed Hausdorff distance of
/// `compare_slice_section` (not sampled); touching edges are sampled every 0.02 px (at most
/// 0.01 px low; they are rare: a full-resolution surface has none). Caps are searched by branch
/// and bound over 4-way subdivisions of each triangle down to edges of 0.05 px, sampling the
/// vertices of the smallest pieces: since the distance is 1-Lipschitz, the result is at most
/// 0.05 / sqrt(3) < 0.03 px below the true sup. Coverage is searched by branch and bound over
/// halvings of each contour segment: a piece is dropped when the larger of its ends' distances to
/// one triangle (the distance to a triangle is convex along a segment) cannot exceed the largest
/// distance found, and sampled once its pieces are 0.02 px long. All are lower estimates at worst,
/// so a test asserting measured <= declared bound never fails through the oracle. Example: a cap
/// triangle over a square region whose apex is 3 px outside it gives max_cap_px = 3.
///
/// A plane the mesh meets (a vertex in it or a triangle across it) where the label has no
/// contour is a problem and makes max_section_px infinite. A triangle with a vertex index out of
/// range or a non-finite coordinate is a problem too, and is skipped. Cost: O(T log T) for the T
/// triangles meeting each plane, plus grid queries (4 px cells); a 470k-triangle surface with
/// 21k-point contours takes about 3 s.
/// \throw strata::Error (InvalidInput) when `slice_spacing_px` is not positive and finite.
CutErrorReport measure_cut_error(const TriMesh& mesh,
                                 const SliceContours& contours,
                                 std::uint16_t label,
                                 double slice_spacing_px);

/// The same with slice k's plane at z = `plane_z[k]` instead of k * d (planes unevenly spaced,
/// e.g. planar contours in their model's frame); `plane_z` increasing, one per slice.
/// \throw strata::Error (InvalidInput) when `plane_z` is not finite and increasing or its size is
/// not the number of slices.
CutErrorReport measure_cut_error(const TriMesh& mesh,
                                 const SliceContours& contours,
                                 std::uint16_t label,
                                 const std::vector<double>& plane_z);

/// Sup over `points` of their exact distance (3D) to the triangles of `mesh` (infinite when it
/// has none): e.g. how far the full-resolution surface's vertices lie from a coarser cut, which
/// bounds how much of a dome beyond the end slices (which no slice section sees) the cut lost.
double max_point_distance_px(const std::vector<Vec3>& points, const TriMesh& mesh);

/// The original polylines (Contour::points, closed) of every contour of `label` in `set`, in the
/// set's order.
std::vector<std::vector<Vec2>> original_polygons(const SliceContourSet& set, std::uint16_t label);

}  // namespace strata::test

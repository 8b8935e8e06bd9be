#pragma once

#include <vector>

#include "core/types.h"
#include "mesh/tri_mesh.h"

namespace strata {

/// Unit per-vertex normals for display that hide the banding of a surface interpolated between
/// slices (a crease at every slice plane, slivers along the medial axis) without moving a vertex.
/// Compute them on world coordinates (millimetres): slice space is anisotropic.
///
/// Exact definition (the web viewer's plugin computes the same; keep both in step):
/// 1. Face normal n_f = normalize((p1 - p0) x (p2 - p0)) for triangle (p0, p1, p2); a face whose
///    cross product is exactly zero contributes nothing.
/// 2. Angle-weighted normal of vertex v: a(v) = sum over the faces f containing v of
///    theta_f(v) n_f, theta_f(v) the interior angle of f at v (acos of the clamped dot product of
///    the two unit edge vectors leaving v; 0 when one of them has zero length); a^(v) =
///    normalize(a(v)), or zero when a(v) is zero.
/// 3. Rings: N(v) = the vertices that share a triangle with v; the k-ring R_k(v) = {v} and every
///    vertex reached from it by at most k steps through N, each vertex once.
/// 4. n(v) = normalize(sum of w(u) a^(u) over the u in R_rings(v)), w(u) = clamp((a^(u) . a^(v)
///    + 1/2) / 0.1, 0, 1); when that sum is zero, a^(v); when that is zero too (an unreferenced
///    vertex, or only degenerate faces), (0, 0, 1). The weight leaves out normals more than 120
///    degrees from v's own (and fades in those 114-120 degrees off, so one bit of rounding at
///    exactly 120 degrees cannot flip a normal): the other side of a part a few pixels thin, which
///    the rings reach around to (a plain sum cancels there: 40 vertices of the torso liver were
///    60-143 degrees off).
/// With rings = 0 this is the plain angle-weighted normal. The default, 3, measured (scripts/
/// bench-appearance.sh) shading roughness 2.18 degrees/mm on the torso liver (angle-weighted
/// normals: 6.8; Slicer's smoothed surface: 4.6) and 1.89 on the TotalSegmentator liver (4.5;
/// Slicer 2.08); two rings gave 2.54 and 2.16. Angle weighting alone is rougher than area
/// weighting. Deterministic (sums in vertex order).
/// \pre every triangle index is below mesh.positions.size() (else Error{InvalidInput}).
std::vector<Vec3> shading_normals(const TriMesh& mesh, unsigned rings = 3);

}  // namespace strata

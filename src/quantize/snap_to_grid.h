#pragma once

#include <string>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// Options of the quantize stage (pipeline): snapping each surface to a grid before simplification,
/// so every level of its multiresolution model lies on that grid.
struct QuantizeOptions {
    bool enabled = true;
    /// Grid step (px in x, y; slices in z), a power of two. 1/16 moves a contour vertex by at most
    /// 0.044 px (points of the pixel grid not at all) and keeps vertices between slices off the
    /// planes (the triangulation keeps them at least 0.05 slices away).
    double step = 1.0 / 16.0;
    /// When a surface does not snap (vertices would merge) or its snapped form fails verification
    /// while the original passes, the step is halved up to this many times; then the surface is
    /// kept unsnapped and a warning says so.
    unsigned max_halvings = 3;
};

/// A surface whose vertices lie on a dyadic grid (the quantize stage's output).
struct GridSnap {
    TriMesh mesh;  ///< the snapped surface, same vertices and triangles
    /// Grid step: x, y are multiples of `step` px and z of `step * d` (slice units of `step`);
    /// a power of two.
    double step = 0.0;
    /// Largest in-plane move of a vertex lying on a slice plane (those stay on their plane).
    double max_plane_shift_px = 0.0;
    double max_shift_px = 0.0;  ///< largest move of any vertex, slice space
};

/// Snaps every vertex of `mesh` (slice space: x, y px, slice k at z = k d) to the grid of
/// `step` (a power of two, at most 1/2 px): x and y to the nearest multiple of `step`, z to the
/// nearest multiple of `step * d`, except where that folds the surface: a vertex between planes on
/// a face of an edge folded over 90 degrees, between the surface's first and last slice planes,
/// takes the multiple on the other side of its height (within one step) when that shrinks the
/// squared excess over 90 degrees of its faces' edges (a
/// slab of 6.4 px has a z step of 0.4 px at 1/16, and nearest rounding folded the torso liver's
/// small faces near contours). Vertices on a slice plane stay on it, so the mesh meets the
/// planes in the same polylines moved by at most `max_plane_shift_px`, and contour points of the
/// pixel grid (multiples of 1/2) do not move at all. With every vertex on one grid, a
/// quantizing encoder (Draco) whose grid is this one stores positions losslessly, and clusters
/// that share a vertex store bit-identical coordinates.
///
/// Returns false, with the reason in `why`, when the step is too coarse for the mesh: two
/// vertices would land on one grid point, or a vertex between planes would land on a plane. It
/// does not check self-intersection (the caller verifies the snapped surface).
/// \throw Error{InvalidInput} when `step` is not a power of two in (0, 1/2] or d <= 0.
bool snap_to_grid(
    const TriMesh& mesh, double slice_spacing_px, double step, GridSnap& out, std::string& why);

/// `positions` (slice space: x, y in px, z = slice index times `slice_spacing_px`) in the grid
/// frame of step `grid_step` (snap_to_grid): x and y unchanged, z the slice index
/// rounded to the step, so that a snapped surface's coordinates are exact (small dyadic numbers)
/// and predicates there are the truth about what a file stores, where z * spacing is rounded.
/// Degeneracy and intersection are invariant under the affine map back to slice space, up to
/// that rounding. `grid_step` 0 (not snapped): the positions unchanged.
std::vector<Vec3> grid_frame_positions(const std::vector<Vec3>& positions,
                                       double slice_spacing_px,
                                       double grid_step);

}  // namespace strata

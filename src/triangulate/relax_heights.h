#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// A vertex between two slice planes whose height is free: a Steiner point of one slab, which
/// lies on the graph of that slab's surface over its planar triangulation.
struct FreeHeightVertex {
    std::uint32_t id = 0;  ///< index into TriMesh::positions
    double z_low = 0.0;    ///< the slab's lower plane (slice space, px)
    double z_high = 0.0;   ///< its upper plane
    /// The heights it may take (besides the slab's margins): those where its own error against
    /// the slices' distance fields stays within what that allows (height_t's band).
    double z_min = -HUGE_VAL;
    double z_max = HUGE_VAL;
};

/// Options of relax_fold_heights.
struct RelaxHeightsOptions {
    /// Edges whose dihedral angle (between the two faces' normals) exceeds this are penalised
    /// (degrees); 0 turns the relaxation off.
    double fold_angle_deg = 50.0;
    /// The farthest a vertex moves from its interpolated height, as a fraction of the slab.
    double max_shift = 0.45;
    /// A free vertex stays this fraction of the slab away from both planes.
    double margin = 0.05;
    /// Only vertices on an edge over this angle (degrees) start moving, and their neighbours
    /// once they move: the folds that look like folds, not a smooth surface's coarse slabs.
    double unfold_angle_deg = 90.0;
    /// How much farther than the slices' distance fields put it a free vertex may go, as the
    /// interpolated field's value at its new height (px, in-plane distance): its band
    /// (FreeHeightVertex::z_min, z_max) is the heights where |field| is within the field's
    /// value at its interpolated height plus this. Set by the triangulation (height_t).
    double field_tolerance_px = 0.35;
    unsigned sweeps = 16;  ///< Gauss-Seidel sweeps over the vertices near folds
};

/// Moves the free vertices along z only, within their slab, to unfold the surface: each, in
/// turn, takes the height among a few candidates that minimises the sum over the edges whose
/// dihedral angle it changes of (angle - fold_angle_deg)^2 where positive, plus a small cost of
/// leaving its interpolated height. Every slab's surface is a graph over its planar
/// triangulation (with vertical triangles above crossing points), so moving its Steiner points
/// in z inside the open slab keeps it embedded and changes no slice-plane section.
/// Only vertices on an edge over unfold_angle_deg start moving, and their neighbours in later
/// sweeps; each stays within its own band [z_min, z_max]. Deterministic (vertex order). Returns the
/// number of vertices moved.
std::size_t relax_fold_heights(TriMesh& mesh,
                               const std::vector<FreeHeightVertex>& free,
                               const RelaxHeightsOptions& options = {});

}  // namespace strata

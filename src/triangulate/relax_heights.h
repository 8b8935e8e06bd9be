#pragma once

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
    /// The farthest a vertex moves along its surface normal (the z shift times the normal's z
    /// component, from the faces around it before any move), in slice-space px: at coarse
    /// slices a shift of a slab fraction moves sloped parts far from the interpolated surface.
    double max_normal_shift = 0.5;
    unsigned sweeps = 16;  ///< Gauss-Seidel sweeps over the vertices near folds
};

/// Moves the free vertices along z only, within their slab, to unfold the surface: each, in
/// turn, takes the height among a few candidates that minimises the sum over the edges whose
/// dihedral angle it changes of (angle - fold_angle_deg)^2 where positive, plus a small cost of
/// leaving its interpolated height. Every slab's surface is a graph over its planar
/// triangulation (with vertical triangles above crossing points), so moving its Steiner points
/// in z inside the open slab keeps it embedded and changes no slice-plane section.
/// Only vertices on a triangle with an edge over the angle are moved, and their neighbours in
/// later sweeps. Deterministic (vertex order). Returns the number of vertices moved.
std::size_t relax_fold_heights(TriMesh& mesh,
                               const std::vector<FreeHeightVertex>& free,
                               const RelaxHeightsOptions& options = {});

}  // namespace strata

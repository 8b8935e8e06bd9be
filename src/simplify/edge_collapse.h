#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/types.h"
#include "simplify/slice_error.h"

namespace strata {

/// Options of `collapse_edges`.
struct CollapseOptions {
    /// Stop once this many triangles or fewer remain.
    std::size_t target_triangles = 0;
    /// Never perform a collapse whose error bound (SliceErrorMeter, px) exceeds this.
    double max_error_px = std::numeric_limits<double>::infinity();
    /// Refuse collapses that turn a triangle's normal by more than acos(min_normal_cos)
    /// (0.1: about 84 degrees); 180-degree turns (flips) are always refused.
    double min_normal_cos = 0.1;
    /// Errors up to this bound (px) are not told apart: a collapse costs at least this much, and
    /// the error reads skip everything that cannot exceed it (paper section 7.2). Set it to the
    /// error the piece already has (its inputs' bound), which the result keeps anyway.
    double error_floor_px = 0.0;
};

/// A piece of a closed surface to simplify, plus what it must not run into. Vertex ids index
/// `positions`, which collapses never change (half-edge collapses create no vertex).
struct CollapseProblem {
    const std::vector<Vec3>* positions = nullptr;
    /// The same vertices in the frame where the surface is exact (`grid_frame_positions`: the
    /// grid coordinates files store, where a vertex lies exactly on an edge or plane if it does
    /// at all); degeneracy and intersection are decided there. Null: `positions`.
    const std::vector<Vec3>* exact_positions = nullptr;
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< the piece, outward CCW
    std::vector<double> triangle_error_px;  ///< current error bound of each triangle (px)
    /// Vertices that must stay where they are with their edges to other locked vertices: the
    /// piece's boundary with the rest of the surface. Sorted.
    std::vector<std::uint32_t> locked;
    /// Triangles outside the piece that may be shown together with it (in some cut of the
    /// multiresolution model): no triangle the simplification creates may intersect them.
    std::vector<std::array<std::uint32_t, 3>> obstacles;
    /// Contour pieces the piece must stay close to (the converse of the meter's error: data to
    /// surface), null for none. Each is attached to one triangle that bounds its distance.
    const std::vector<ContourPiece>* pieces = nullptr;
    /// (index into `triangles`, index into `*pieces`): where each piece of this part of the
    /// surface is attached. A collapse moves the pieces of the triangles it changes or removes to
    /// the nearest of the changed ones, and costs at least their distance (piece_distance_px).
    std::vector<std::pair<std::uint32_t, std::uint32_t>> piece_triangles;
};

/// What `collapse_edges` did.
struct CollapseResult {
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< the simplified piece
    std::vector<double> triangle_error_px;                ///< bound of each of them (px)
    /// The collapses in order: vertex `first` removed, its triangles moved to vertex `second`.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> collapses;
    double max_error_px = 0.0;  ///< largest entry of triangle_error_px
    /// (index into `triangles`, index into the problem's pieces): the pieces' new attachments,
    /// sorted. A triangle's error bound covers the distance of its pieces.
    std::vector<std::pair<std::uint32_t, std::uint32_t>> piece_triangles;
};

/// Simplifies a piece of a closed, oriented 2-manifold by half-edge collapses (paper section 7:
/// no new vertices; the cheapest collapse first, cost = largest error bound of the triangles it
/// creates, measured against the original contours by `meter`, and of the distance from the
/// contour pieces it moves to the triangles they move to, so that the surface cannot leave the
/// data behind either: a thin part is not flattened away while its contours are farther from the
/// rest than the allowed error).
///
/// Preserved: the locked vertices and every edge between two of them (so the piece still fits
/// any neighbour that kept the same boundary), manifoldness and orientation (link condition,
/// no vertex left with fewer than 3 edges), topology (genus, components), no triangle turned by
/// more than allowed, no fold added (an edge whose triangles' normals point apart, a crease over
/// 90 degrees: the slice sections do not see it, a viewer does; a collapse may keep or remove
/// folds, never add one), no degenerate (collinear) triangle, and embedding: no new triangle
/// intersects a triangle of the piece or an obstacle (exact predicates, on `exact_positions`).
/// Not preserved: volume, normals, vertex count.
/// Deterministic: ties are broken by vertex ids.
/// \throw Error{InvalidInput} when a triangle refers to a vertex outside `positions` or an edge
///        is used by more than two triangles of the piece.
CollapseResult collapse_edges(const CollapseProblem& problem,
                              const SliceErrorMeter& meter,
                              const CollapseOptions& options);

}  // namespace strata

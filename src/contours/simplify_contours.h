#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "contours/slice_contours.h"
#include "core/types.h"

namespace strata {

/// Tunables of contour simplification.
struct SimplifyOptions {
    double tolerance_px = 0.5;  ///< max distance of an original point from its simplified edge, px
    /// Simplified vertices may sit at the midpoints of unit pixel edges: where Douglas-Peucker
    /// would split at a staircase step (a pixel corner whose neighbouring corner across a unit
    /// edge turns the other way), it splits at the neighbouring edge midpoint nearer the segment
    /// instead. On a sloped boundary the staircase's corners spread over a band 0.7 px wide or
    /// more, wider than the 0.5 px tolerance, so corner vertices zig-zag across it about every
    /// pixel; the midpoints lie inside the band, and the simplified contour gets far fewer,
    /// straighter edges. Corners of convex runs (a single pixel, a rectangle) stay.
    bool edge_midpoints = true;
    /// After Douglas-Peucker, each simplified vertex (but a contour's first) may move to an
    /// original point at most this many points away along the contour where that balances its
    /// two edges (the original points on both sides of each, by signed area), within the
    /// tolerance: Douglas-Peucker leaves every original point of a convex run outside its chords,
    /// so the simplified contour lies inside the boundary. With 8, bash
    /// scripts/bench-accuracy.sh measured (mean error / bias, px) sphere d = 2: 0.130 / -0.086 ->
    /// 0.103 / -0.038, torus d = 2: 0.162 / -0.112 -> 0.107 / -0.023, branching d = 2:
    /// 0.145 -> 0.096, every phantom and d better in mean, bias and max (2 and 4 gain less, 16
    /// the same as 8). The fallback to pixel-corner vertices (edge_midpoints off) balances too:
    /// original points are pixel corners.
    std::uint32_t balance_reach = 8;
};

/// Douglas-Peucker simplification of an open polyline in O(n log n) (Hershberger-Snoeyink path
/// hull; exact textbook Douglas-Peucker for simple chains, up to ties). Returns the indices of
/// the kept points, strictly increasing, first and last included (empty for empty input). Every
/// original point lies within `tolerance_px` of the kept segment that replaces it, measured to the
/// segment (not its line): with tolerance 0.5, a one-pixel-wide spike is kept although it doubles
/// back along the segment's line. `deviation_px`, if given, receives one entry per kept segment
/// (kept.size() - 1): the exact largest distance of the original points it replaces, px. Repeated
/// points and self-intersecting chains are fine (the bound holds; the path hull then may pick other
/// split points than textbook Douglas-Peucker, and chains doubling back cost O(range) per extra
/// split). Throws Error{InvalidInput} for a negative or non-finite tolerance or a non-finite point.
std::vector<std::uint32_t> simplify_polyline(std::span<const Vec2> points,
                                             double tolerance_px,
                                             std::vector<double>* deviation_px = nullptr);

/// The same for a closed polyline (the last point connects to the first; not repeated). The
/// chain is split at point 0 and the point farthest from it, both kept; at least 3 points are
/// kept (all of them if there are fewer). `deviation_px` gets one entry per kept edge, the last
/// for the edge from the last kept point back to the first. The result may self-intersect; see
/// `simplify_contours` for the topology-safe version. Throws as `simplify_polyline`.
std::vector<std::uint32_t> simplify_closed_polyline(std::span<const Vec2> points,
                                                    double tolerance_px,
                                                    std::vector<double>* deviation_px = nullptr);

/// Simplifies all contours of one slice (paper section 3): fills `simplified` and
/// `edge_deviation_px` of every contour and, with `options.edge_midpoints`, inserts into
/// `points` the midpoints of unit pixel edges that became simplified vertices (the polygon is
/// unchanged); the rest is left untouched.
///
/// Input: the slice's contours, each closed with at least 3 points; the contours of one label
/// are simple polygons, pairwise disjoint (as extract_contours makes them); contours of
/// different labels are independent and may share boundaries.
/// Guarantees: every original point lies within `options.tolerance_px` of the simplified edge
/// that replaces it (`edge_deviation_px` holds the exact maxima); each simplified contour is
/// simple with at least 3 vertices (nonzero area for contours of nonzero area); simplified
/// contours of the same label neither cross nor touch. Where plain Douglas-Peucker would
/// break that, original vertices are re-inserted (the farthest point of each offending edge,
/// then Douglas-Peucker of the two halves) until the contours are clean; the intersection tests
/// are exact (integer arithmetic on the half-pixel grid, exact predicates otherwise).
/// Returns the number of vertices re-inserted for topology. Deterministic.
/// Throws Error{InvalidInput} for a negative or non-finite tolerance, a contour with fewer than
/// 3 points or a non-finite point, or when the repair reaches original edges that intersect
/// (the input contours were not simple and disjoint).
std::size_t simplify_contours(std::vector<Contour>& contours, const SimplifyOptions& options);

/// Simplifies the contours of `label` in `set` again with `options` (`simplify_contours` on
/// them alone, in place; contours of other labels are independent). Returns whether any
/// simplified polygon changed. The fallbacks use it to put a label's vertices back at pixel
/// corners (`edge_midpoints` off).
bool resimplify_label(SliceContourSet& set, std::uint16_t label, const SimplifyOptions& options);

}  // namespace strata

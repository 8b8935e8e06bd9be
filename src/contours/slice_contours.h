#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "core/types.h"

namespace strata {

/// One closed contour of one label on one slice, in slice pixels.
///
/// Points lie on the boundary between foreground and background pixels: pixel (i, j) covers
/// [i, i+1] x [j, j+1], so contour points are pixel corners (integers), plus edge midpoints
/// (half-integers) where a saddle corner is cut (foreground 8-connected, background
/// 4-connected: the contour turns right at a saddle and cuts the corner across the background
/// pixel, keeping every contour a simple polygon, disjoint from every other contour of the label).
/// Orientation is measured in the (x, y) frame by the shoelace formula: outer contours have
/// positive signed area (counter-clockwise, foreground on the left), holes negative (clockwise).
struct Contour {
    std::uint16_t label = 0;   ///< label value of the object
    bool is_hole = false;      ///< true for a boundary of a background region inside the object
    std::int32_t parent = -1;  ///< index (in the same slice's contour list) of the enclosing
                               ///< contour of the other kind, -1 for top-level outer contours
    std::uint32_t depth = 0;   ///< nesting depth: 0 outer, 1 hole, 2 island in a hole, ...
    std::uint32_t region = 0;  ///< foreground component (outer) or background component (hole)
                               ///< index of this slice and label, see SliceLabelRegions
    /// The original contour: closed (the last point connects to the first, not repeated), no
    /// repeated points; consecutive points are 1 apart along pixel edges, or 0.5 and sqrt(1/2)
    /// around a cut saddle. Simplification adds the midpoints of the pixel edges where
    /// simplified vertices sit (SimplifyOptions::edge_midpoints), 0.5 from their neighbours; the
    /// polygon is the same.
    std::vector<Vec2> points;
    /// Indices into `points` of the simplified polygon's vertices, strictly increasing, at least
    /// 3. Simplified edge e runs from points[simplified[e]] to points[simplified[e + 1]] (the
    /// last edge wraps to simplified[0]) and replaces the original points between them.
    std::vector<std::uint32_t> simplified;
    /// Per simplified edge: the largest distance (px) of the original points it replaces from the
    /// edge segment. At most the simplification tolerance.
    std::vector<double> edge_deviation_px;
};

/// The regions (connected components) of one label on one slice. Contours refer to them.
struct SliceLabelRegions {
    std::uint16_t label = 0;
    std::uint32_t foreground_count = 0;       ///< 8-connected foreground components
    std::uint32_t background_count = 0;       ///< 4-connected background components; index 0 is the
                                              ///< unbounded outside, the others are holes
    std::vector<std::int32_t> outer_contour;  ///< per foreground component: its outer contour
    std::vector<std::int32_t> hole_contour;   ///< per background component: the contour enclosing
                                              ///< it (-1 for the outside)
};

/// One contour set: every contour of every label on one slice.
struct SliceContourSet {
    std::vector<Contour> contours;          ///< sorted by label, then by first point (row-major)
    std::vector<SliceLabelRegions> labels;  ///< one per label present on the slice
};

/// A connection between regions of consecutive slices k and k+1 of one label, following the
/// reference volume R (docs/test-catalogue.md): one link per connected piece of the foreground
/// overlap (slice k AND slice k+1, 8-connected), and one per connected piece of the background
/// union (slice k OR-background slice k+1, 4-connected) that touches a hole on either slice.
struct RegionLink {
    std::uint32_t lower_slice = 0;  ///< k; the link joins slice k and k+1
    std::uint16_t label = 0;
    bool is_background = false;
    std::vector<std::uint32_t> lower_regions;  ///< region indices on slice k (foreground: one)
    std::vector<std::uint32_t> upper_regions;  ///< region indices on slice k+1 (foreground: one)
    std::uint64_t pixels = 0;                  ///< size of the overlap piece
};

/// Contours of a whole stack: the output of the contour stage.
struct SliceContours {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    double tolerance_px = 0.5;            ///< simplification tolerance used
    std::vector<SliceContourSet> slices;  ///< one per slice
    std::vector<RegionLink> links;        ///< between consecutive slices, sorted by slice, label
};

/// Sorted distinct labels that have contours on some slice.
inline std::vector<std::uint16_t> contour_labels(const SliceContours& contours) {
    std::vector<std::uint16_t> labels;
    for (const SliceContourSet& set : contours.slices) {
        for (const SliceLabelRegions& regions : set.labels) {
            labels.push_back(regions.label);
        }
    }
    std::sort(labels.begin(), labels.end());
    labels.erase(std::unique(labels.begin(), labels.end()), labels.end());
    return labels;
}

/// For every 16-bit label, its index in `labels`, or -1 when absent.
inline std::vector<std::int32_t> index_of_labels(const std::vector<std::uint16_t>& labels) {
    std::vector<std::int32_t> index(65536, -1);
    for (std::size_t i = 0; i < labels.size(); ++i) {
        index[labels[i]] = static_cast<std::int32_t>(i);
    }
    return index;
}

}  // namespace strata

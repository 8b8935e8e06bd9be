#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "contours/slice_contours.h"
#include "core/pixel_box.h"
#include "core/progress.h"
#include "input/slice_stack.h"

namespace strata {

/// A position on an original contour of one slice: point `point` of contour `contour` (index
/// into SliceContourSet::contours), or the midpoint of the segment from that point to the next
/// when `is_midpoint`.
struct ContourSite {
    std::uint32_t contour = 0;
    std::uint32_t point = 0;
    bool is_midpoint = false;

    friend bool operator==(const ContourSite&, const ContourSite&) = default;
};

/// Signed Euclidean distance of one label on one slice, with its feature transform, sampled on
/// the half-pixel grid: node (i, j) lies at (origin_x + i / 2, origin_y + j / 2) px, so pixel
/// corners, edge midpoints and pixel centres are all nodes (origin is a pixel corner).
///
/// The sites are every node on the label's original contours: the contour points and the
/// midpoints of their unit segments (all contour points lie on this grid; the sqrt(1/2) chamfers
/// at cut saddles and the 0.5 half-edges have no interior node). `at` is the exact Euclidean
/// distance to the nearest site (rounded once to float), negative inside the label, zero exactly
/// on the sites; `closest` names that site. Ties: among the sites at exactly the smallest
/// distance, `closest` is the one with the smallest index in `sites`.
/// Stored compactly (docs/architecture.md section 6): about 2 bytes per node, the closest site and
/// the side (see node_value); the distance is not stored but recomputed, bit-identical, from the
/// node and its site.
/// Inside/outside follows the mask, pixels outside the image being background: a pixel centre
/// takes its pixel's value, a non-site edge midpoint or corner the common value of the pixels
/// around it, except a saddle corner (diagonal pattern), which is cut off by the contour and is
/// inside. This is the even-odd inside of the label's contour polygons.
/// The field covers a window of the slice (the label's extent on this and the neighbouring
/// slices plus a margin); `outside_window_px` is a lower bound of |distance| for any point
/// outside the window: every site lies in the label's pixel box B on this slice, so a point
/// beyond a window side is farther than that side's gap to B from every site. The smallest of the
/// four gaps is stored; it is at least the margin, and no constant bound is larger (B's side
/// carries a site, right across the gap).
struct DistanceField {
    std::uint16_t label = 0;
    std::uint32_t slice = 0;
    double origin_x = 0.0;  ///< px, a pixel corner (integer)
    double origin_y = 0.0;  ///< px, a pixel corner (integer)
    std::uint32_t nx = 0;   ///< nodes per row
    std::uint32_t ny = 0;   ///< node rows
    /// The nodes' values (node_value), packed: per node (nx * ny, row-major) its closest site's
    /// offset from its block's base site (the low 15 bits) and kOffsetInside when inside; per
    /// block of kBlockNodes consecutive nodes the base site, or kWideBlock | w when the block's
    /// sites span 2^15 or more: block w of `wide_values` then holds its nodes' values.
    /// note: closest sites change little from node to node, except across the medial axis and
    /// where a contour's numbering starts: 2 bytes a node, not 4 (T32: 1.55 -> 0.8 GB of fields)
    std::vector<std::uint16_t> node_offsets;
    std::vector<std::uint32_t> block_bases;
    std::vector<std::uint32_t> wide_values;
    std::vector<ContourSite> sites;  ///< the sites, sorted by (contour, point, midpoint)
    /// per site its node (column, row): sites lie on nodes
    std::vector<std::array<std::int32_t, 2>> site_nodes;
    double outside_window_px = 0.0;

    static constexpr double kCellPx = 0.5;  ///< node spacing, px
    static constexpr std::uint32_t kInside = std::uint32_t(1) << 31;
    static constexpr std::size_t kBlockNodes = 64;
    static constexpr std::uint32_t kWideBlock = std::uint32_t(1) << 31;
    static constexpr std::uint16_t kOffsetInside = std::uint16_t(1) << 15;

    Vec2 node_position(std::uint32_t i, std::uint32_t j) const {
        return {origin_x + kCellPx * i, origin_y + kCellPx * j};
    }
    std::size_t node_index(std::uint32_t i, std::uint32_t j) const {
        return std::size_t(j) * nx + i;
    }
    /// Node `node` (node_index): its closest site (index into `sites`), or'ed with kInside when
    /// the node is inside the label (never for a site).
    std::uint32_t node_value(std::size_t node) const {
        const std::uint32_t base = block_bases[node / kBlockNodes];
        if ((base & kWideBlock) != 0) {
            return wide_values[std::size_t(base & ~kWideBlock) * kBlockNodes + node % kBlockNodes];
        }
        const std::uint32_t offset = node_offsets[node];
        return (base + (offset & ~std::uint32_t(kOffsetInside))) |
               ((offset & kOffsetInside) != 0 ? kInside : 0);
    }
    /// Index into `sites` of the closest site of node `node` (node_index).
    std::uint32_t closest(std::size_t node) const { return node_value(node) & ~kInside; }
    /// Signed distance (px) of node (i, j): float(|node - site| / 2, node units), negated inside;
    /// exactly what the distance transform computed.
    float at(std::uint32_t i, std::uint32_t j) const {
        const std::uint32_t v = node_value(node_index(i, j));
        const std::array<std::int32_t, 2>& s = site_nodes[v & ~kInside];
        const double dx = double(std::int64_t(i) - s[0]);
        const double dy = double(std::int64_t(j) - s[1]);
        const float r = static_cast<float>(0.5 * std::sqrt(dx * dx + dy * dy));
        return (v & kInside) != 0 ? -r : r;
    }
    float distance(std::size_t node) const {
        return at(static_cast<std::uint32_t>(node % nx), static_cast<std::uint32_t>(node / nx));
    }
    /// The signed distances (as `at`) of nodes [i0, i0 + count) of row j, into `out`.
    void distance_row(std::uint32_t j, std::uint32_t i0, std::uint32_t count, float* out) const;
};

/// Position (px) of a site on the contours it was taken from (`set`: the field's slice).
inline Vec2 site_position(const SliceContourSet& set, const ContourSite& site) {
    const std::vector<Vec2>& points = set.contours[site.contour].points;
    const Vec2 a = points[site.point];
    if (!site.is_midpoint) {
        return a;
    }
    const Vec2 b = points[(site.point + 1) % points.size()];
    return {0.5 * (a.x + b.x), 0.5 * (a.y + b.y)};
}

/// The fields of one slice: one per label present on it, sorted by label.
struct SliceDistanceFields {
    std::vector<DistanceField> fields;
};

/// The pixel box of every label with contours on every slice (empty where it is absent), found
/// by one scan of the stack; compute_distance_fields reads its windows from them.
struct LabelBoxes {
    std::vector<std::uint16_t> labels;         ///< contour_labels of the contours
    std::vector<std::vector<PixelBox>> boxes;  ///< [slice][index in labels]
};

/// LabelBoxes of `stack` for the labels of `contours`, slices in parallel on `threads` (0: all
/// cores).
LabelBoxes compute_label_boxes(const SliceStack& stack,
                               const SliceContours& contours,
                               unsigned threads);

/// Options of the distance stage.
struct DistanceOptions {
    double margin_px = 4.0;  ///< extra border around the labels' extent, px (rounded up to whole
                             ///< pixels); also the least outside_window_px
    unsigned threads = 0;    ///< worker threads, 0 = all cores; output identical for any count
    ProgressFn progress;     ///< called per slice (may be empty)
    /// compute_distance_fields: the labels to compute, increasing; empty: every label with
    /// contours. Each label's fields are the same whichever others are computed.
    std::vector<std::uint16_t> labels;
    /// compute_distance_fields: the boxes of the same stack and contours when already known
    /// (batches of labels share one scan); null: scanned here.
    const LabelBoxes* boxes = nullptr;
};

/// Computes the distance field of `label` on slice `k` (see DistanceField) over the window
/// covering the label's pixels on slices k-1, k, k+1 (those that exist) plus `margin_px` rounded
/// up to whole pixels; the window may extend beyond the image (pixels there are background).
/// Exact and linear in the number of nodes: separable Felzenszwalb-Huttenlocher lower envelopes
/// in doubled integer coordinates with argmin tracking. `set` is slice k's traced contour set
/// (trace_slice_contours or extract_contours; only the original points are used).
/// Example: a disc of radius 30 px gives about -30 at its centre, 0 on its contour.
/// Memory: about 2 bytes per node in the result (and 20 per site), 4 more while it is computed; the
/// calling thread keeps about 1 byte per window pixel (and some per row, column and site) of
/// scratch for its next call. \throw Error{InvalidInput} when k is out of range, the label is
/// absent on slice k (no pixel
///        or no contour), `margin_px` is negative, not finite or makes the window too large
///        (over 2^30 nodes), or the contours do not match the label image (a contour point off
///        the half-pixel grid or outside the window, a step other than 1, 0.5 or sqrt(1/2) px,
///        two contours through one node, a node on a contour with equal pixels around it, or a
///        boundary node on no contour).
DistanceField compute_distance_field(const SliceStack& stack,
                                     const SliceContourSet& set,
                                     std::uint32_t k,
                                     std::uint16_t label,
                                     const DistanceOptions& options);

/// The distance stage: the field of every label of SliceContourSet::labels on every slice (one
/// entry per slice, fields sorted by label; a slice without labels gets none), in parallel over
/// slices; identical output for any thread count. `progress` is called once per slice
/// ("distance slices").
/// \throw Error{InvalidInput} when `contours` does not belong to `stack` (size or slice count)
///        or as compute_distance_field.
std::vector<SliceDistanceFields> compute_distance_fields(const SliceStack& stack,
                                                         const SliceContours& contours,
                                                         const DistanceOptions& options);

}  // namespace strata

#pragma once

// Distances to planar contours as they were given (float polygons), without rasterising them:
// the first part of a polygon-native contour route (docs/planar-contours.md). Used today to
// measure the bounds of contour models against the input polygons (reconstruct_contours.cpp).

#include <array>
#include <cstdint>
#include <vector>

#include "core/types.h"

namespace strata {

/// A point on a polygon edge: edge `edge` of polygon `polygon` (from its vertex `edge` to the
/// next), at parameter t in [0, 1] along it.
struct PolygonSite {
    std::uint32_t polygon = 0;
    std::uint32_t edge = 0;
    double t = 0.0;
};

/// The closest point of a set of polygons to a query point.
struct PolygonClosest {
    double distance = 0.0;  ///< Euclidean, >= 0; infinite when there are no edges
    PolygonSite site;
    Vec2 point;  ///< the closest point itself
};

/// The edges of one plane's closed polygons (any orientation, holes as separate polygons, the
/// even-odd rule giving the inside), bucketed in square cells for exact nearest-edge queries.
class PolygonEdges {
public:
    /// `polygons`: closed (the last vertex joins the first), each at least 2 vertices to count.
    explicit PolygonEdges(std::vector<std::vector<Vec2>> polygons);

    bool empty() const { return edges_.empty(); }
    const std::vector<std::vector<Vec2>>& polygons() const { return polygons_; }

    /// The nearest point on any edge (exact point-segment distances; ties: the first edge in
    /// polygon, then edge order).
    PolygonClosest closest(Vec2 p) const;
    double distance(Vec2 p) const { return closest(p).distance; }
    /// Even-odd inside (a point on an edge counts as inside or outside by the half-open rule of
    /// row crossings: edges are crossed where exactly one end lies above the row).
    bool inside(Vec2 p) const;
    /// The x of every edge crossing of the row at height y, sorted (the even-odd spans are
    /// [x0, x1], [x2, x3], ...).
    std::vector<double> row_crossings(double y) const;

private:
    struct Edge {
        Vec2 a, b;
        std::uint32_t polygon, index;
    };
    std::int64_t column(double x) const;
    std::int64_t row(double y) const;

    std::vector<std::vector<Vec2>> polygons_;
    std::vector<Edge> edges_;
    std::vector<std::vector<std::uint32_t>> cells_;
    Vec2 origin_;
    double cell_ = 1.0;
    std::int64_t columns_ = 0;
    std::int64_t rows_ = 0;
};

/// The signed distance to a plane's polygons and its closest points, on the half-pixel node grid
/// the label-image route's distance fields use: node (i, j) at (origin_x + i / 2, origin_y + j / 2)
/// px. Negative inside (even-odd), the exact Euclidean distance to the nearest polygon edge.
struct PolygonDistanceField {
    double origin_x = 0.0;
    double origin_y = 0.0;
    std::uint32_t nx = 0;
    std::uint32_t ny = 0;
    std::vector<float> distance;       ///< nx * ny, row-major, signed
    std::vector<PolygonSite> closest;  ///< nx * ny: the closest edge point of each node

    static constexpr double kCellPx = 0.5;
    Vec2 node_position(std::uint32_t i, std::uint32_t j) const {
        return {origin_x + kCellPx * i, origin_y + kCellPx * j};
    }
};

/// The field of `edges` over the nodes of [x0, x1] x [y0, y1] px (half-pixel steps from (x0, y0)).
/// Sign from the row crossings (one sorted crossing list per node row), distance and closest point
/// from PolygonEdges::closest. Cost: one nearest query per node.
/// \throw Error{InvalidInput} when the window is empty, not finite or over 2^30 nodes.
PolygonDistanceField polygon_distance_field(
    const PolygonEdges& edges, double x0, double y0, double x1, double y1);

}  // namespace strata

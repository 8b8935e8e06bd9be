#include "pipeline/contour_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"

namespace strata {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

/// The closest point of segment ab to p, as its parameter along ab.
double segment_parameter(Vec2 p, Vec2 a, Vec2 b) {
    const Vec2 ab = b - a;
    const double length2 = dot(ab, ab);
    return length2 > 0.0 ? std::clamp(dot(p - a, ab) / length2, 0.0, 1.0) : 0.0;
}

}  // namespace

PolygonEdges::PolygonEdges(std::vector<std::vector<Vec2>> polygons)
    : polygons_(std::move(polygons)) {
    Vec2 lo{kInfinity, kInfinity};
    Vec2 hi{-kInfinity, -kInfinity};
    for (std::uint32_t k = 0; k < polygons_.size(); ++k) {
        const std::vector<Vec2>& polygon = polygons_[k];
        if (polygon.size() < 2) {
            continue;
        }
        for (std::uint32_t i = 0; i < polygon.size(); ++i) {
            const Vec2 a = polygon[i];
            const Vec2 b = polygon[(i + 1) % polygon.size()];
            edges_.push_back({a, b, k, i});
            lo = {std::min({lo.x, a.x, b.x}), std::min({lo.y, a.y, b.y})};
            hi = {std::max({hi.x, a.x, b.x}), std::max({hi.y, a.y, b.y})};
        }
    }
    if (edges_.empty()) {
        return;
    }
    origin_ = lo;
    // about 64 cells across the larger side, at least 1 px each
    cell_ = std::max(1.0, std::max(hi.x - lo.x, hi.y - lo.y) / 64.0);
    columns_ = std::int64_t((hi.x - lo.x) / cell_) + 1;
    rows_ = std::int64_t((hi.y - lo.y) / cell_) + 1;
    cells_.assign(std::size_t(columns_ * rows_), {});
    for (std::uint32_t e = 0; e < edges_.size(); ++e) {
        const Edge& edge = edges_[e];
        const std::int64_t x0 = column(std::min(edge.a.x, edge.b.x));
        const std::int64_t x1 = column(std::max(edge.a.x, edge.b.x));
        const std::int64_t y0 = row(std::min(edge.a.y, edge.b.y));
        const std::int64_t y1 = row(std::max(edge.a.y, edge.b.y));
        for (std::int64_t y = y0; y <= y1; ++y) {
            for (std::int64_t x = x0; x <= x1; ++x) {
                cells_[std::size_t(y * columns_ + x)].push_back(e);
            }
        }
    }
}

std::int64_t PolygonEdges::column(double x) const {
    return std::clamp<std::int64_t>(std::int64_t(std::floor((x - origin_.x) / cell_)), 0,
                                    columns_ - 1);
}

std::int64_t PolygonEdges::row(double y) const {
    return std::clamp<std::int64_t>(std::int64_t(std::floor((y - origin_.y) / cell_)), 0,
                                    rows_ - 1);
}

PolygonClosest PolygonEdges::closest(Vec2 p) const {
    PolygonClosest best;
    best.distance = kInfinity;
    if (edges_.empty()) {
        return best;
    }
    std::uint32_t best_edge = 0;
    const std::int64_t cx = column(p.x);
    const std::int64_t cy = row(p.y);
    for (std::int64_t ring = 0;; ++ring) {
        for (std::int64_t y = cy - ring; y <= cy + ring; ++y) {
            if (y < 0 || y >= rows_) {
                continue;
            }
            const bool edge_row = y == cy - ring || y == cy + ring;
            for (std::int64_t x = cx - ring; x <= cx + ring; x += edge_row ? 1 : 2 * ring) {
                if (x >= 0 && x < columns_) {
                    for (const std::uint32_t e : cells_[std::size_t(y * columns_ + x)]) {
                        const Edge& edge = edges_[e];
                        const double t = segment_parameter(p, edge.a, edge.b);
                        const Vec2 q = edge.a + t * (edge.b - edge.a);
                        const double d = norm(p - q);
                        if (d < best.distance || (d == best.distance && e < best_edge)) {
                            best.distance = d;
                            best.site = {edge.polygon, edge.index, t};
                            best.point = q;
                            best_edge = e;
                        }
                    }
                }
                if (ring == 0) {
                    break;
                }
            }
        }
        // every edge not seen yet lies in a cell outside the searched box: farther than the
        // box's nearest side (a side at the grid's border has nothing beyond it)
        const double gx = p.x - origin_.x;
        const double gy = p.y - origin_.y;
        double reach = kInfinity;
        if (cx - ring > 0) {
            reach = std::min(reach, gx - double(cx - ring) * cell_);
        }
        if (cx + ring < columns_ - 1) {
            reach = std::min(reach, double(cx + ring + 1) * cell_ - gx);
        }
        if (cy - ring > 0) {
            reach = std::min(reach, gy - double(cy - ring) * cell_);
        }
        if (cy + ring < rows_ - 1) {
            reach = std::min(reach, double(cy + ring + 1) * cell_ - gy);
        }
        if (best.distance <= reach) {
            return best;
        }
    }
}

std::vector<double> PolygonEdges::row_crossings(double y) const {
    std::vector<double> crossings;
    for (const Edge& edge : edges_) {
        if ((edge.a.y > y) != (edge.b.y > y)) {
            crossings.push_back(edge.a.x +
                                (y - edge.a.y) * (edge.b.x - edge.a.x) / (edge.b.y - edge.a.y));
        }
    }
    std::sort(crossings.begin(), crossings.end());
    return crossings;
}

bool PolygonEdges::inside(Vec2 p) const {
    std::size_t left = 0;
    for (const double x : row_crossings(p.y)) {
        left += x < p.x ? 1 : 0;
    }
    return left % 2 == 1;
}

PolygonDistanceField polygon_distance_field(
    const PolygonEdges& edges, double x0, double y0, double x1, double y1) {
    const double k = PolygonDistanceField::kCellPx;
    if (!std::isfinite(x0) || !std::isfinite(y0) || !std::isfinite(x1) || !std::isfinite(y1) ||
        !(x1 >= x0) || !(y1 >= y0) || (x1 - x0) / k + 1 > 32768.0 || (y1 - y0) / k + 1 > 32768.0) {
        throw Error(ErrorCode::InvalidInput,
                    "polygon_distance_field: window [" + std::to_string(x0) + ", " +
                        std::to_string(x1) + "] x [" + std::to_string(y0) + ", " +
                        std::to_string(y1) +
                        "] px; expected finite, non-empty, at most 2^30 nodes");
    }
    PolygonDistanceField field;
    field.origin_x = x0;
    field.origin_y = y0;
    field.nx = std::uint32_t(std::floor((x1 - x0) / k)) + 1;
    field.ny = std::uint32_t(std::floor((y1 - y0) / k)) + 1;
    field.distance.resize(std::size_t(field.nx) * field.ny);
    field.closest.resize(field.distance.size());
    for (std::uint32_t j = 0; j < field.ny; ++j) {
        const double y = field.node_position(0, j).y;
        const std::vector<double> crossings = edges.row_crossings(y);
        std::size_t left = 0;  // crossings left of the node
        for (std::uint32_t i = 0; i < field.nx; ++i) {
            const Vec2 p = field.node_position(i, j);
            while (left < crossings.size() && crossings[left] < p.x) {
                ++left;
            }
            const PolygonClosest c = edges.closest(p);
            const std::size_t n = std::size_t(j) * field.nx + i;
            const auto d = static_cast<float>(c.distance);
            field.distance[n] = left % 2 == 1 ? -d : d;
            field.closest[n] = c.site;
        }
    }
    return field;
}

}  // namespace strata

// Error of simplified triangles against the original contours, read from the slice distance
// fields (Klein, Schilling, Strasser, section 7.1: the triangle's intersection with every slice
// plane it spans is drawn into that slice's distance field; 7.2: stretches that cannot beat the
// error already reached are skipped, since the distance grows by at most 1 px per px).
//
// The fields are sampled on the half-pixel grid and store, per node, the closest contour site.
// Instead of trusting interpolated samples, every piece [a, b] of a segment is charged
// max(|a - s|, |b - s|) for one site s: |p - s| is convex along the piece and s lies on the
// contour, so this bounds dist(p, contour) for every p of the piece. Choosing s from the field's
// nearest node makes the bound tight to a few hundredths of a pixel on short pieces, and a piece
// may run as far as the disc of radius `known` around s reaches (the skipping).
#include "simplify/slice_error.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

namespace strata {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
/// Length of a piece that must be charged on its own (px).
constexpr double kStepPx = 0.25;
/// Least advance worth a disc step (px); shorter exits fall back to a charged piece.
constexpr double kMinAdvancePx = 1e-3;
/// Half the diagonal of a field cell: every point of a cell is this close to one of its corners.
constexpr double kHalfCellDiagonalPx = 0.35355339059327379;
/// Largest gap between a contour point and its nearest site (half the sqrt(1/2) chamfer).
constexpr double kSiteGapPx = 0.35355339059327379;
/// A cell whose four corners are this deep inside lies inside the region entirely.
constexpr double kInsideDepthPx = kHalfCellDiagonalPx + kSiteGapPx + 1e-9;
/// Caps larger than this many field cells are refused (error infinity) rather than scanned.
constexpr double kMaxCapCells = 4.0e6;

double distance(Vec2 a, Vec2 b) {
    return norm(a - b);
}

/// A convex polygon of at most 7 corners (a triangle clipped by up to four axis lines).
struct Polygon {
    std::array<Vec2, 8> p{};
    int n = 0;
};

/// Sutherland-Hodgman clip of a convex polygon to coordinate `axis` >= bound, or <= bound when
/// `keep_below`.
Polygon clip(const Polygon& polygon, int axis, double bound, bool keep_below) {
    Polygon out;
    auto coord = [&](Vec2 p) { return axis == 0 ? p.x : p.y; };
    auto inside = [&](Vec2 p) { return keep_below ? coord(p) <= bound : coord(p) >= bound; };
    for (int i = 0; i < polygon.n; ++i) {
        const Vec2 a = polygon.p[i];
        const Vec2 b = polygon.p[(i + 1) % polygon.n];
        const bool ina = inside(a);
        const bool inb = inside(b);
        if (ina) {
            out.p[out.n++] = a;
        }
        if (ina != inb) {
            const double t = (bound - coord(a)) / (coord(b) - coord(a));
            Vec2 p = a + t * (b - a);
            (axis == 0 ? p.x : p.y) = bound;
            out.p[out.n++] = p;
        }
    }
    return out;
}

}  // namespace

SliceErrorMeter::SliceErrorMeter(const SliceContours& contours,
                                 const std::vector<SliceDistanceFields>& fields,
                                 std::uint16_t label,
                                 double slice_spacing_px)
    : spacing_(slice_spacing_px) {
    slices_.resize(fields.size());
    for (std::size_t k = 0; k < fields.size(); ++k) {
        for (const DistanceField& field : fields[k].fields) {
            if (field.label != label || field.sites.empty()) {
                continue;
            }
            Slice& slice = slices_[k];
            slice.field = &field;
            slice.sites.reserve(field.sites.size());
            for (const ContourSite& site : field.sites) {
                slice.sites.push_back(site_position(contours.slices[k], site));
            }
        }
    }
    for (std::size_t k = 0; k < contours.slices.size(); ++k) {
        const double z = double(k) * slice_spacing_px;
        for (const Contour& contour : contours.slices[k].contours) {
            if (contour.label != label || contour.points.empty()) {
                continue;
            }
            // note: a contour without a simplification stands for itself, edge by edge
            const std::vector<std::uint32_t>& kept = contour.simplified;
            const bool simplified =
                kept.size() >= 2 && kept.size() == contour.edge_deviation_px.size();
            const auto n = std::uint32_t(contour.points.size());
            const std::size_t count = simplified ? kept.size() : n;
            for (std::size_t e = 0; e < count; ++e) {
                const std::uint32_t first = simplified ? kept[e] : std::uint32_t(e);
                const std::uint32_t last =
                    simplified ? kept[(e + 1) % count] : std::uint32_t((e + 1) % n);
                const Vec2 a = contour.points[first];
                const Vec2 b = contour.points[last];
                pieces_.push_back({{a.x, a.y, z},
                                   {b.x, b.y, z},
                                   simplified ? contour.edge_deviation_px[e] : 0.0,
                                   &contour.points,
                                   first,
                                   (last + n - first) % n});
            }
        }
    }
}

std::vector<ContourPiece> ContourPiece::original_edges() const {
    if (points == nullptr) {
        return {*this};
    }
    std::vector<ContourPiece> out;
    out.reserve(edges);
    for (std::uint32_t e = 0; e < edges; ++e) {
        const Vec2 p = (*points)[(first + e) % points->size()];
        const Vec2 q = (*points)[(first + e + 1) % points->size()];
        out.push_back({{p.x, p.y, a.z}, {q.x, q.y, a.z}, 0.0});
    }
    return out;
}

namespace {

/// Distance from p to triangle abc (closest point by Voronoi regions: Ericson, "Real-time
/// collision detection", 5.1.5).
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        return norm(ap);
    }
    const Vec3 bp = p - b;
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
        return norm(bp);
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        return norm(ap - v * ab);
    }
    const Vec3 cp = p - c;
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
        return norm(cp);
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double w = d2 / (d2 - d6);
        return norm(ap - w * ac);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return norm(bp - w * (c - b));
    }
    const double denom = va + vb + vc;
    if (!(denom > 0.0)) {
        // note: degenerate triangle: its points are on its edges
        return std::min({norm(ap), norm(bp), norm(cp)});
    }
    const double v = vb / denom, w = vc / denom;
    return norm(ap - v * ab - w * ac);
}

}  // namespace

double point_triangle_distance_px(const Vec3& p, const std::array<Vec3, 3>& triangle) {
    // note: a hair above the rounding of the distance, so the result stays a bound
    return point_triangle_distance(p, triangle[0], triangle[1], triangle[2]) * (1.0 + 1e-12) +
           1e-12;
}

double piece_distance_px(const ContourPiece& piece,
                         const std::array<Vec3, 3>& triangle,
                         double cutoff,
                         double good_enough) {
    // note: every bound below is at least the distance of each end
    const double da = point_triangle_distance_px(piece.a, triangle);
    if (da >= cutoff) {
        return piece.deviation_px + da;
    }
    const double ends = std::max(da, point_triangle_distance_px(piece.b, triangle));
    const double capsule = piece.deviation_px + ends;
    if (capsule <= good_enough || piece.points == nullptr || piece.deviation_px == 0.0 ||
        ends >= cutoff) {
        return capsule;
    }
    // note: the original points between the ends
    double reached = ends;
    const std::vector<Vec2>& points = *piece.points;
    for (std::uint32_t e = 1; e < piece.edges && reached < cutoff; ++e) {
        const Vec2 p = points[(piece.first + e) % points.size()];
        reached = std::max(reached, point_triangle_distance_px({p.x, p.y, piece.a.z}, triangle));
    }
    return std::min(capsule, reached);
}

double SliceErrorMeter::segment_error_px(
    std::uint32_t k, Vec2 p, Vec2 q, double known_px, double cutoff) const {
    if (k >= slices_.size() || slices_[k].field == nullptr) {
        return kInfinity;
    }
    const Slice& slice = slices_[k];
    const DistanceField& f = *slice.field;
    double reached = known_px;
    const double length = distance(p, q);
    if (!(length < kInfinity)) {
        return kInfinity;
    }
    const Vec2 dir = length > 0.0 ? (1.0 / length) * (q - p) : Vec2{1.0, 0.0};

    // The site of the node nearest to a (clamped to the window). note: the hot loop of
    // simplification, so the field's constants are read once.
    const double origin_x = f.origin_x;
    const double origin_y = f.origin_y;
    const double last_i = double(f.nx - 1);
    const double last_j = double(f.ny - 1);
    const std::size_t nx = f.nx;
    const Vec2* const sites = slice.sites.data();
    auto nearest_site = [&](Vec2 a) {
        const double fx = std::floor((a.x - origin_x) / DistanceField::kCellPx + 0.5);
        const double fy = std::floor((a.y - origin_y) / DistanceField::kCellPx + 0.5);
        const double i = std::clamp(fx, 0.0, last_i);
        const double j = std::clamp(fy, 0.0, last_j);
        const auto node =
            static_cast<std::uint32_t>(std::size_t(std::uint32_t(j)) * nx + std::uint32_t(i));
        return sites[f.closest(node)];
    };

    // The smallest bound over the sites of the four field nodes around a for the piece [a, b]
    // (the nearest node's site first: when it stays within `reached` the piece is settled).
    auto charge = [&](Vec2 a, Vec2 b) {
        const Vec2 near = nearest_site(a);
        const double first = std::max(distance(a, near), distance(b, near));
        if (first <= reached) {
            return first;
        }
        const double cx = (a.x - f.origin_x) / DistanceField::kCellPx;
        const double cy = (a.y - f.origin_y) / DistanceField::kCellPx;
        const double i0 = std::clamp(std::floor(cx), 0.0, double(f.nx - 1));
        const double j0 = std::clamp(std::floor(cy), 0.0, double(f.ny - 1));
        const double i1 = std::min(i0 + 1.0, double(f.nx - 1));
        const double j1 = std::min(j0 + 1.0, double(f.ny - 1));
        double best = first;
        for (const double i : {i0, i1}) {
            for (const double j : {j0, j1}) {
                const Vec2 s =
                    slice.sites[f.closest(f.node_index(std::uint32_t(i), std::uint32_t(j)))];
                best = std::min(best, std::max(distance(a, s), distance(b, s)));
            }
        }
        return best;
    };

    double t = 0.0;
    for (;;) {
        const Vec2 a = p + t * dir;
        if (t >= length) {
            reached = std::max(reached, charge(q, q));
            break;
        }
        const Vec2 s = nearest_site(a);
        const Vec2 w = a - s;
        const double c = dot(w, w) - reached * reached;
        if (c <= 0.0) {
            // a lies in the disc of radius `reached` around s: the piece up to the disc's far side
            // cannot exceed the error already reached.
            const double wd = dot(w, dir);
            const double h = -wd + std::sqrt(std::max(0.0, wd * wd - c));
            if (h >= kMinAdvancePx) {
                if (t + h >= length) {
                    break;  // q lies in the disc too
                }
                t += h;
                continue;
            }
        }
        const double h = std::min(kStepPx, length - t);
        const Vec2 b = p + (t + h) * dir;
        reached = std::max(reached, charge(a, b));
        if (reached > cutoff) {
            break;
        }
        t += h;
        if (h < kStepPx) {
            break;
        }
    }
    return reached;
}

double SliceErrorMeter::cap_error_px(std::uint32_t k, const std::array<Vec2, 3>& triangle) const {
    if (k >= slices_.size() || slices_[k].field == nullptr) {
        return kInfinity;
    }
    const Slice& slice = slices_[k];
    const DistanceField& f = *slice.field;
    double x0 = kInfinity, y0 = kInfinity, x1 = -kInfinity, y1 = -kInfinity;
    for (const Vec2& v : triangle) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y)) {
            return kInfinity;
        }
        x0 = std::min(x0, v.x);
        y0 = std::min(y0, v.y);
        x1 = std::max(x1, v.x);
        y1 = std::max(y1, v.y);
    }
    const double c = DistanceField::kCellPx;
    const double ci0 = std::floor((x0 - f.origin_x) / c);
    const double ci1 = std::floor((x1 - f.origin_x) / c);
    const double cj0 = std::floor((y0 - f.origin_y) / c);
    const double cj1 = std::floor((y1 - f.origin_y) / c);
    if ((ci1 - ci0 + 1) * (cj1 - cj0 + 1) > kMaxCapCells) {
        return kInfinity;
    }
    Polygon polygon;
    polygon.n = 3;
    std::copy(triangle.begin(), triangle.end(), polygon.p.begin());
    double worst = 0.0;
    for (double cj = cj0; cj <= cj1; ++cj) {
        const double ya = f.origin_y + cj * c;
        const Polygon row = clip(clip(polygon, 1, ya, false), 1, ya + c, true);
        if (row.n == 0) {
            continue;
        }
        // note: the row's x extent limits the cells to visit.
        double rx0 = kInfinity, rx1 = -kInfinity;
        for (int i = 0; i < row.n; ++i) {
            rx0 = std::min(rx0, row.p[i].x);
            rx1 = std::max(rx1, row.p[i].x);
        }
        const double ri0 = std::max(ci0, std::floor((rx0 - f.origin_x) / c));
        const double ri1 = std::min(ci1, std::floor((rx1 - f.origin_x) / c));
        for (double ci = ri0; ci <= ri1; ++ci) {
            // The four corner nodes (clamped to the window); a cell deep inside costs nothing.
            std::array<std::size_t, 4> nodes{};
            bool deep_inside = true;
            int count = 0;
            for (const double dj : {0.0, 1.0}) {
                for (const double di : {0.0, 1.0}) {
                    const double ni = ci + di;
                    const double nj = cj + dj;
                    const bool in_window = ni >= 0 && nj >= 0 && ni < f.nx && nj < f.ny;
                    const std::uint32_t i = std::uint32_t(std::clamp(ni, 0.0, double(f.nx - 1)));
                    const std::uint32_t j = std::uint32_t(std::clamp(nj, 0.0, double(f.ny - 1)));
                    nodes[count++] = f.node_index(i, j);
                    if (!in_window || f.distance(nodes[count - 1]) > -kInsideDepthPx) {
                        deep_inside = false;
                    }
                }
            }
            if (deep_inside) {
                continue;
            }
            const double xa = f.origin_x + ci * c;
            const Polygon piece = clip(clip(row, 0, xa, false), 0, xa + c, true);
            if (piece.n == 0) {
                continue;
            }
            double best = kInfinity;
            for (const std::size_t node : nodes) {
                const Vec2 s = slice.sites[f.closest(node)];
                double far = 0.0;
                for (int i = 0; i < piece.n; ++i) {
                    far = std::max(far, distance(piece.p[i], s));
                }
                best = std::min(best, far);
            }
            worst = std::max(worst, best);
        }
    }
    return worst;
}

double SliceErrorMeter::triangle_error_px(const std::array<Vec3, 3>& triangle,
                                          double known_px) const {
    return triangle_error(triangle, nullptr, nullptr, known_px, kInfinity);
}

double SliceErrorMeter::triangle_error_px(const std::array<Vec3, 3>& triangle,
                                          const std::array<std::uint32_t, 3>& ids,
                                          SectionCache& cache) const {
    return triangle_error(triangle, &ids, &cache, cache.known_px(), cache.cutoff_px());
}

double SliceErrorMeter::triangle_error(const std::array<Vec3, 3>& triangle,
                                       const std::array<std::uint32_t, 3>* ids,
                                       SectionCache* cache,
                                       double known_px,
                                       double cutoff) const {
    double zmin = kInfinity, zmax = -kInfinity;
    for (const Vec3& v : triangle) {
        if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
            return kInfinity;
        }
        zmin = std::min(zmin, v.z);
        zmax = std::max(zmax, v.z);
    }
    // note: the same "in the plane" rule as the slice sections of the tests.
    auto on_plane = [](double z, double plane) {
        return std::abs(z - plane) <= 1e-9 * std::max(1.0, std::abs(plane));
    };
    double reached = known_px;
    const double k0 = std::ceil(zmin / spacing_ - 1e-9);
    const double k1 = std::floor(zmax / spacing_ + 1e-9);
    for (double kk = std::max(k0, 0.0); kk <= k1 && reached <= cutoff; ++kk) {
        const double plane = kk * spacing_;
        if (kk >= double(slices_.size())) {
            break;  // no input slice there
        }
        const std::uint32_t k = static_cast<std::uint32_t>(kk);
        std::array<bool, 3> in{};
        int count = 0;
        for (int i = 0; i < 3; ++i) {
            in[i] = on_plane(triangle[i].z, plane);
            count += in[i];
        }
        if (count == 3) {
            reached = std::max(reached, cap_error_px(k, {Vec2{triangle[0].x, triangle[0].y},
                                                         Vec2{triangle[1].x, triangle[1].y},
                                                         Vec2{triangle[2].x, triangle[2].y}}));
            continue;
        }
        Vec2 ends[3];
        int n = 0;
        for (int i = 0; i < 3; ++i) {
            const Vec3& a = triangle[i];
            const Vec3& b = triangle[(i + 1) % 3];
            if (in[i]) {
                ends[n++] = {a.x, a.y};
            } else if (!in[(i + 1) % 3] && (a.z - plane) * (b.z - plane) < 0.0) {
                const double t = (plane - a.z) / (b.z - a.z);
                ends[n++] = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
            }
        }
        if (n == 0) {
            continue;  // only within the tolerance of the plane's rounding
        }
        if (cache != nullptr && count == n) {
            // The section is a mesh edge or vertex lying in the plane: read it once.
            int first = 0;
            while (!in[first]) {
                ++first;
            }
            int second = first;
            for (int i = first + 1; i < 3; ++i) {
                if (in[i]) {
                    second = i;
                }
            }
            const std::uint32_t a = std::min((*ids)[first], (*ids)[second]);
            const std::uint32_t b = std::max((*ids)[first], (*ids)[second]);
            const std::uint64_t key = std::uint64_t(a) << 32 | b;
            auto it = cache->bounds_.find(key);
            if (it == cache->bounds_.end()) {
                // note: walked from the smaller id's end, so the bound stored does not depend on
                // which triangle reads the edge first (the walk's pieces depend on its direction).
                const Vec2 from = ends[(*ids)[first] <= (*ids)[second] ? 0 : n - 1];
                const Vec2 to = ends[(*ids)[first] <= (*ids)[second] ? n - 1 : 0];
                it = cache->bounds_
                         .emplace(key, segment_error_px(k, from, to, cache->known_px(), cutoff))
                         .first;
            }
            reached = std::max(reached, it->second);
            continue;
        }
        reached =
            std::max(reached, segment_error_px(k, ends[0], ends[n == 1 ? 0 : 1], reached, cutoff));
    }
    return reached;
}

}  // namespace strata

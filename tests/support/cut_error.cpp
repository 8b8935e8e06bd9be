#include "support/cut_error.h"

// Cut-error oracle: per slice plane, the triangles meeting it (bucketed once), their section
// measured by the exact segment-set comparison of slice_section.cpp, and the caps searched by
// branch and bound on a uniform grid over the contour segments.
//
// Distance queries: segments are listed in every grid cell (kCellPx) their bounding box meets;
// a query visits square rings of cells around the point's (clamped) cell and stops once the ring
// distance reaches the best distance found, so the answer is exact. Inside tests: even-odd
// crossing count of a ray towards +x, over the segments of the point's row of cells.
//
// Coverage (contour -> mesh): the mesh's triangles in a uniform 3D grid; a point query visits
// cubic shells of cells around the point's (clamped) cell until the shell distance reaches the
// best distance found. Point-triangle distance: the distance to the plane when the point projects
// inside the triangle, else the nearest of the three edges.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <utility>

#include "core/error.h"
#include "support/slice_section.h"

namespace strata::test {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kCellPx = 4.0;          // grid cell of the distance queries
constexpr double kCapEdgePx = 0.05;      // cap pieces are not split below this edge length
constexpr double kTouchStepPx = 0.02;    // sampling step along touching edges
constexpr double kSectionStepPx = 0.01;  // sampling step when locating the worst section point
constexpr double kCoverStepPx = 0.02;    // coverage pieces are not split below this length

struct Segment {
    Vec2 a;
    Vec2 b;
};

Vec2 xy(Vec3 p) {
    return {p.x, p.y};
}

double point_segment_distance(Vec2 p, const Segment& s) {
    const Vec2 w = s.b - s.a;
    const double ww = dot(w, w);
    const double u = ww > 0 ? std::clamp(dot(p - s.a, w) / ww, 0.0, 1.0) : 0.0;
    return norm(p - (s.a + u * w));
}

/// Closed polylines of one slice, indexed for exact distance and even-odd inside queries.
class PolylineIndex {
public:
    explicit PolylineIndex(const std::vector<std::vector<Vec2>>& polylines) {
        for (const auto& line : polylines) {
            for (std::size_t i = 0; i < line.size(); ++i) {
                segments_.push_back({line[i], line[(i + 1) % line.size()]});
            }
        }
        if (segments_.empty()) {
            return;
        }
        Vec2 lo{kInf, kInf}, hi{-kInf, -kInf};
        for (const Segment& s : segments_) {
            for (Vec2 p : {s.a, s.b}) {
                lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
                hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
            }
        }
        origin_ = lo;
        nx_ = static_cast<int>(std::floor((hi.x - lo.x) / kCellPx)) + 1;
        ny_ = static_cast<int>(std::floor((hi.y - lo.y) / kCellPx)) + 1;

        // cells: counting pass, then fill (compressed rows)
        cell_start_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
        row_start_.assign(static_cast<std::size_t>(ny_) + 1, 0);
        for (int pass = 0; pass < 2; ++pass) {
            std::vector<std::uint32_t> cell_fill, row_fill;
            if (pass == 1) {
                for (std::size_t c = 1; c < cell_start_.size(); ++c) {
                    cell_start_[c] += cell_start_[c - 1];
                }
                for (std::size_t r = 1; r < row_start_.size(); ++r) {
                    row_start_[r] += row_start_[r - 1];
                }
                cell_segments_.resize(cell_start_.back());
                row_segments_.resize(row_start_.back());
                cell_fill.assign(cell_start_.begin(), cell_start_.end() - 1);
                row_fill.assign(row_start_.begin(), row_start_.end() - 1);
            }
            for (std::uint32_t i = 0; i < segments_.size(); ++i) {
                const Segment& s = segments_[i];
                const int x0 = cell_x(std::min(s.a.x, s.b.x)), x1 = cell_x(std::max(s.a.x, s.b.x));
                const int y0 = cell_y(std::min(s.a.y, s.b.y)), y1 = cell_y(std::max(s.a.y, s.b.y));
                for (int y = y0; y <= y1; ++y) {
                    if (pass == 0) {
                        ++row_start_[y + 1];
                    } else {
                        row_segments_[row_fill[y]++] = i;
                    }
                    for (int x = x0; x <= x1; ++x) {
                        const std::size_t c = static_cast<std::size_t>(y) * nx_ + x;
                        if (pass == 0) {
                            ++cell_start_[c + 1];
                        } else {
                            cell_segments_[cell_fill[c]++] = i;
                        }
                    }
                }
            }
        }
    }

    bool empty() const { return segments_.empty(); }
    const std::vector<Segment>& segments() const { return segments_; }

    /// Exact distance from `p` to the union of the polylines; infinite when there are none.
    double distance(Vec2 p) const {
        if (segments_.empty()) {
            return kInf;
        }
        const int cx = cell_x(p.x), cy = cell_y(p.y);
        double best = kInf;
        for (int r = 0;; ++r) {
            for (int y = cy - r; y <= cy + r; ++y) {
                if (y < 0 || y >= ny_) {
                    continue;
                }
                const bool edge_row = y == cy - r || y == cy + r;
                const int step = edge_row || r == 0 ? 1 : 2 * r;
                for (int x = cx - r; x <= cx + r; x += step) {
                    if (x < 0 || x >= nx_) {
                        continue;
                    }
                    const std::size_t c = static_cast<std::size_t>(y) * nx_ + x;
                    for (std::uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
                        best =
                            std::min(best, point_segment_distance(p, segments_[cell_segments_[k]]));
                    }
                }
            }
            // note: unvisited segments lie outside the (2r+1)^2 block around the (clamped) cell
            // of p, at least r cells away from p (clamping only moves p away from them)
            const bool whole_grid =
                cx - r <= 0 && cy - r <= 0 && cx + r >= nx_ - 1 && cy + r >= ny_ - 1;
            if (best <= r * kCellPx || whole_grid) {
                return best;
            }
        }
    }

    /// Even-odd interior of the polylines (a point on a polyline may go either way).
    bool inside(Vec2 p) const {
        if (segments_.empty()) {
            return false;
        }
        const double fy = std::floor((p.y - origin_.y) / kCellPx);
        if (fy < 0 || fy >= ny_) {
            return false;
        }
        const int y = static_cast<int>(fy);
        bool in = false;
        for (std::uint32_t k = row_start_[y]; k < row_start_[y + 1]; ++k) {
            const Segment& s = segments_[row_segments_[k]];
            if ((s.a.y > p.y) != (s.b.y > p.y)) {
                const double x = s.a.x + (p.y - s.a.y) / (s.b.y - s.a.y) * (s.b.x - s.a.x);
                if (x > p.x) {
                    in = !in;
                }
            }
        }
        return in;
    }

    /// Distance from `p` to the inside region: 0 inside, else the distance to the polylines.
    double region_distance(Vec2 p) const { return inside(p) ? 0.0 : distance(p); }

private:
    int cell_x(double x) const {
        return static_cast<int>(
            std::clamp(std::floor((x - origin_.x) / kCellPx), 0.0, static_cast<double>(nx_ - 1)));
    }
    int cell_y(double y) const {
        return static_cast<int>(
            std::clamp(std::floor((y - origin_.y) / kCellPx), 0.0, static_cast<double>(ny_ - 1)));
    }

    std::vector<Segment> segments_;
    Vec2 origin_;
    int nx_ = 0, ny_ = 0;
    std::vector<std::uint32_t> cell_start_, cell_segments_;
    std::vector<std::uint32_t> row_start_, row_segments_;
};

/// Distance from p to segment ab in 3D.
double point_segment_distance_3d(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 w = b - a;
    const double ww = dot(w, w);
    const double u = ww > 0 ? std::clamp(dot(p - a, w) / ww, 0.0, 1.0) : 0.0;
    return norm(p - (a + u * w));
}

/// Distance from p to the triangle abc (a closed set in 3D).
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const Vec3 n = cross(b - a, c - a);
    const double nn = dot(n, n);
    if (nn > 0) {
        const double h = dot(p - a, n) / nn;
        const Vec3 q = p - h * n;  // projection onto the plane
        const bool inside = dot(cross(b - a, q - a), n) >= 0 && dot(cross(c - b, q - b), n) >= 0 &&
                            dot(cross(a - c, q - c), n) >= 0;
        if (inside) {
            return std::abs(h) * std::sqrt(nn);
        }
    }
    return std::min({point_segment_distance_3d(p, a, b), point_segment_distance_3d(p, b, c),
                     point_segment_distance_3d(p, c, a)});
}

/// The triangles of a mesh, indexed for exact point distance queries.
class MeshIndex {
public:
    explicit MeshIndex(const TriMesh& mesh) : mesh_(mesh) {
        const auto n = static_cast<std::uint32_t>(mesh.positions.size());
        for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f) {
            const auto& t = mesh.triangles[f];
            bool ok = t[0] < n && t[1] < n && t[2] < n;
            for (int i = 0; ok && i < 3; ++i) {
                const Vec3 p = mesh.positions[t[i]];
                ok = std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
            }
            if (ok) {
                faces_.push_back(f);
            }
        }
        if (faces_.empty()) {
            return;
        }
        Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
        for (std::uint32_t f : faces_) {
            for (std::uint32_t v : mesh.triangles[f]) {
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], mesh.positions[v][a]);
                    hi[a] = std::max(hi[a], mesh.positions[v][a]);
                }
            }
        }
        origin_ = lo;
        for (int a = 0; a < 3; ++a) {
            size_[a] = std::max(1, static_cast<int>(std::floor((hi[a] - lo[a]) / kCellPx)) + 1);
        }
        std::vector<std::array<int, 6>> ranges(faces_.size());
        cell_start_.assign(cell_count() + 1, 0);
        for (std::size_t i = 0; i < faces_.size(); ++i) {
            const auto& t = mesh.triangles[faces_[i]];
            for (int a = 0; a < 3; ++a) {
                const double mn = std::min(
                    {mesh.positions[t[0]][a], mesh.positions[t[1]][a], mesh.positions[t[2]][a]});
                const double mx = std::max(
                    {mesh.positions[t[0]][a], mesh.positions[t[1]][a], mesh.positions[t[2]][a]});
                ranges[i][a] = cell(a, mn);
                ranges[i][3 + a] = cell(a, mx);
            }
            for_range(ranges[i], [&](std::size_t c) { ++cell_start_[c + 1]; });
        }
        for (std::size_t c = 0; c < cell_count(); ++c) {
            cell_start_[c + 1] += cell_start_[c];
        }
        cell_faces_.resize(cell_start_.back());
        std::vector<std::uint32_t> fill(cell_start_.begin(), cell_start_.end() - 1);
        for (std::size_t i = 0; i < faces_.size(); ++i) {
            for_range(ranges[i], [&](std::size_t c) { cell_faces_[fill[c]++] = faces_[i]; });
        }
    }

    bool empty() const { return faces_.empty(); }

    /// Exact distance from p to the mesh and a triangle where it is reached (infinite, 0 when the
    /// mesh has no valid triangle).
    std::pair<double, std::uint32_t> nearest(const Vec3& p) const {
        std::pair<double, std::uint32_t> best{kInf, 0};
        if (faces_.empty()) {
            return best;
        }
        const std::array<int, 3> home{cell(0, p.x), cell(1, p.y), cell(2, p.z)};
        const int most = std::max({size_[0], size_[1], size_[2]});
        for (int r = 0; r <= most; ++r) {
            // the shell of cells at Chebyshev distance r from home
            std::array<int, 6> range{};
            for (int a = 0; a < 3; ++a) {
                range[a] = std::max(0, home[a] - r);
                range[3 + a] = std::min(size_[a] - 1, home[a] + r);
            }
            for (int x = range[0]; x <= range[3]; ++x) {
                for (int y = range[1]; y <= range[4]; ++y) {
                    for (int z = range[2]; z <= range[5]; ++z) {
                        const int shell = std::max(
                            {std::abs(x - home[0]), std::abs(y - home[1]), std::abs(z - home[2])});
                        if (shell != r) {
                            continue;
                        }
                        const std::size_t c = index(x, y, z);
                        for (std::uint32_t i = cell_start_[c]; i < cell_start_[c + 1]; ++i) {
                            const std::uint32_t f = cell_faces_[i];
                            const auto& t = mesh_.triangles[f];
                            const double d = point_triangle_distance(p, mesh_.positions[t[0]],
                                                                     mesh_.positions[t[1]],
                                                                     mesh_.positions[t[2]]);
                            if (d < best.first) {
                                best = {d, f};
                            }
                        }
                    }
                }
            }
            // note: every unvisited cell is at least r cells away along some axis, and the point
            // lies in (or beyond, on the far side of) its home cell, so it is >= r * kCellPx away
            if (best.first <= r * kCellPx) {
                break;
            }
        }
        return best;
    }

    double distance(const Vec3& p, std::uint32_t f) const {
        const auto& t = mesh_.triangles[f];
        return point_triangle_distance(p, mesh_.positions[t[0]], mesh_.positions[t[1]],
                                       mesh_.positions[t[2]]);
    }

private:
    int cell(int axis, double v) const {
        const double c = std::floor((v - origin_[axis]) / kCellPx);
        return static_cast<int>(std::clamp(c, 0.0, static_cast<double>(size_[axis] - 1)));
    }
    std::size_t cell_count() const {
        return std::size_t(size_[0]) * std::size_t(size_[1]) * std::size_t(size_[2]);
    }
    std::size_t index(int x, int y, int z) const {
        return (std::size_t(z) * std::size_t(size_[1]) + std::size_t(y)) * std::size_t(size_[0]) +
               std::size_t(x);
    }
    template <class Fn>
    void for_range(const std::array<int, 6>& r, Fn&& fn) const {
        for (int x = r[0]; x <= r[3]; ++x) {
            for (int y = r[1]; y <= r[4]; ++y) {
                for (int z = r[2]; z <= r[5]; ++z) {
                    fn(index(x, y, z));
                }
            }
        }
    }

    const TriMesh& mesh_;
    std::vector<std::uint32_t> faces_;  ///< valid triangles
    Vec3 origin_;
    std::array<int, 3> size_{1, 1, 1};
    std::vector<std::uint32_t> cell_start_, cell_faces_;
};

/// Largest distance to the mesh found on the contour piece pq (slice space) by branch and bound;
/// `dp`, `fp`: p's distance and nearest triangle, likewise for q. Raises `worst` (in (x, y)).
void search_coverage(const MeshIndex& index,
                     const Vec3& p,
                     const Vec3& q,
                     std::pair<double, std::uint32_t> dp,
                     std::pair<double, std::uint32_t> dq,
                     double& worst,
                     Vec3& worst_point) {
    if (dp.first > worst) {
        worst = dp.first;
        worst_point = p;
    }
    if (dq.first > worst) {
        worst = dq.first;
        worst_point = q;
    }
    // note: the distance to one triangle is convex along the piece, so the piece is within the
    // larger of its ends' distances to either end's nearest triangle; and 1-Lipschitz, so within
    // (dp + dq + |pq|) / 2
    const double length = norm(q - p);
    const double bound = std::min({std::max(dp.first, index.distance(q, dp.second)),
                                   std::max(dq.first, index.distance(p, dq.second)),
                                   0.5 * (dp.first + dq.first + length)});
    if (bound <= worst || length <= kCoverStepPx) {
        return;
    }
    const Vec3 m = 0.5 * (p + q);
    const auto dm = index.nearest(m);
    search_coverage(index, p, m, dp, dm, worst, worst_point);
    search_coverage(index, m, q, dm, dq, worst, worst_point);
}

struct Worst {
    double distance = 0;
    Vec2 point;
    void offer(double d, Vec2 p) {
        if (d > distance) {
            distance = d;
            point = p;
        }
    }
};

/// Branch and bound over 4-way subdivisions of a cap triangle; raises `worst`.
void search_cap(const PolylineIndex& index, Vec2 a, Vec2 b, Vec2 c, Worst& worst) {
    const Vec2 m = (1.0 / 3.0) * (a + b + c);
    const double radius = std::max({norm(a - m), norm(b - m), norm(c - m)});
    const bool in = index.inside(m);
    const double to_lines = index.distance(m);
    const double g = in ? 0.0 : to_lines;
    worst.offer(g, m);
    // note: the distance to the region is 1-Lipschitz, so nothing in the piece exceeds g + radius;
    // and a piece inside the disc of radius `to_lines` around an inside point is all inside
    if ((in && to_lines >= radius) || g + radius <= worst.distance) {
        return;
    }
    const double longest = std::max({norm(b - a), norm(c - b), norm(a - c)});
    if (longest <= kCapEdgePx) {
        for (Vec2 p : {a, b, c}) {
            worst.offer(index.region_distance(p), p);
        }
        return;
    }
    const Vec2 ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
    search_cap(index, a, ab, ca, worst);
    search_cap(index, ab, b, bc, worst);
    search_cap(index, ca, bc, c, worst);
    search_cap(index, ab, bc, ca, worst);
}

/// Samples segment pq every `step` px (ends included) against the polylines; raises `worst`.
void sample_segment(const PolylineIndex& index, Vec2 p, Vec2 q, double step, Worst& worst) {
    const int n = std::max(1, static_cast<int>(std::ceil(norm(q - p) / step)));
    for (int i = 0; i <= n; ++i) {
        const Vec2 s = p + (static_cast<double>(i) / n) * (q - p);
        worst.offer(index.distance(s), s);
    }
}

std::string format_z(double z) {
    std::ostringstream text;
    text << z;
    return text.str();
}

struct SliceWorst {
    Worst worst;
    std::uint32_t slice = 0;
    bool set = false;
    void offer(const Worst& w, std::uint32_t k) {
        if (!set || w.distance > worst.distance) {
            worst = w;
            slice = k;
            set = true;
        }
    }
};

}  // namespace

double max_point_distance_px(const std::vector<Vec3>& points, const TriMesh& mesh) {
    const MeshIndex index(mesh);
    if (index.empty()) {
        return points.empty() ? 0.0 : kInf;
    }
    double worst = 0.0;
    for (const Vec3& p : points) {
        worst = std::max(worst, index.nearest(p).first);
    }
    return worst;
}

std::vector<std::vector<Vec2>> original_polygons(const SliceContourSet& set, std::uint16_t label) {
    std::vector<std::vector<Vec2>> out;
    for (const Contour& contour : set.contours) {
        if (contour.label == label) {
            out.push_back(contour.points);
        }
    }
    return out;
}

CutErrorReport measure_cut_error(const TriMesh& mesh,
                                 const SliceContours& contours,
                                 std::uint16_t label,
                                 double slice_spacing_px) {
    if (!(slice_spacing_px > 0) || !std::isfinite(slice_spacing_px)) {
        throw Error(ErrorCode::InvalidInput, "measure_cut_error: slice spacing " +
                                                 format_z(slice_spacing_px) +
                                                 " px, expected positive and finite");
    }
    std::vector<double> plane_z(contours.slices.size());
    for (std::size_t k = 0; k < plane_z.size(); ++k) {
        plane_z[k] = static_cast<double>(k) * slice_spacing_px;
    }
    return measure_cut_error(mesh, contours, label, plane_z);
}

CutErrorReport measure_cut_error(const TriMesh& mesh,
                                 const SliceContours& contours,
                                 std::uint16_t label,
                                 const std::vector<double>& plane_z) {
    if (plane_z.size() != contours.slices.size()) {
        throw Error(ErrorCode::InvalidInput,
                    "measure_cut_error: " + std::to_string(plane_z.size()) + " plane positions, " +
                        std::to_string(contours.slices.size()) + " slices");
    }
    for (std::size_t k = 0; k < plane_z.size(); ++k) {
        if (!std::isfinite(plane_z[k]) || (k > 0 && !(plane_z[k] > plane_z[k - 1]))) {
            throw Error(ErrorCode::InvalidInput, "measure_cut_error: plane " + std::to_string(k) +
                                                     " at z = " + format_z(plane_z[k]) +
                                                     ", expected finite and increasing");
        }
    }
    CutErrorReport report;
    const auto slice_count = static_cast<std::uint32_t>(contours.slices.size());
    const auto vertex_count = static_cast<std::uint32_t>(mesh.positions.size());
    auto plane_eps = [](double z) { return 1e-9 * std::max(1.0, std::abs(z)); };

    // triangles meeting each slice plane
    std::vector<std::vector<std::uint32_t>> meeting(slice_count);
    for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f) {
        const auto& t = mesh.triangles[f];
        if (t[0] >= vertex_count || t[1] >= vertex_count || t[2] >= vertex_count) {
            report.problems.push_back("triangle " + std::to_string(f) +
                                      ": vertex index out of range, skipped");
            continue;
        }
        double z0 = kInf, z1 = -kInf;
        bool finite = true;
        for (std::uint32_t v : t) {
            const Vec3 p = mesh.positions[v];
            finite = finite && std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
            z0 = std::min(z0, p.z);
            z1 = std::max(z1, p.z);
        }
        if (!finite) {
            report.problems.push_back("triangle " + std::to_string(f) +
                                      ": non-finite coordinate, skipped");
            continue;
        }
        // the planes within the triangle's z range (plane_eps grows with |z|: start one early)
        auto k = static_cast<std::size_t>(std::lower_bound(plane_z.begin(), plane_z.end(), z0) -
                                          plane_z.begin());
        k = k > 0 ? k - 1 : 0;
        for (; k < slice_count && plane_z[k] - plane_eps(plane_z[k]) <= z1; ++k) {
            const double z = plane_z[k];
            if (z0 <= z + plane_eps(z) && z1 >= z - plane_eps(z)) {
                meeting[k].push_back(f);
            }
        }
    }

    SliceWorst section_worst, cap_worst;
    std::vector<std::uint32_t> local(vertex_count, UINT32_MAX);
    for (std::uint32_t k = 0; k < slice_count; ++k) {
        const std::vector<std::uint32_t>& faces = meeting[k];
        if (faces.empty()) {
            continue;
        }
        ++report.slices_met;
        const double z = plane_z[k];
        const double eps = plane_eps(z);
        const auto polygons = original_polygons(contours.slices[k], label);
        if (polygons.empty()) {
            report.problems.push_back("slice " + std::to_string(k) + " (z = " + format_z(z) +
                                      "): the mesh meets the plane (" +
                                      std::to_string(faces.size()) + " triangles), label " +
                                      std::to_string(label) + " has no contour");
            if (report.max_section_px < kInf) {
                report.max_section_px = kInf;
                Worst w;
                w.distance = kInf;
                w.point = xy(mesh.positions[mesh.triangles[faces.front()][0]]);
                section_worst.offer(w, k);
            }
            continue;
        }

        // the triangles meeting the plane, as a mesh of their own
        TriMesh part;
        std::vector<std::uint32_t> used;
        for (std::uint32_t f : faces) {
            std::array<std::uint32_t, 3> t{};
            for (int i = 0; i < 3; ++i) {
                const std::uint32_t v = mesh.triangles[f][i];
                if (local[v] == UINT32_MAX) {
                    local[v] = static_cast<std::uint32_t>(part.positions.size());
                    part.positions.push_back(mesh.positions[v]);
                    used.push_back(v);
                }
                t[i] = local[v];
            }
            part.triangles.push_back(t);
        }
        for (std::uint32_t v : used) {
            local[v] = UINT32_MAX;
        }

        // walls: exact, by the segment-set comparison (mesh defects of `part`, such as its cut
        // boundary, do not change the section: every face of an in-plane edge meets the plane)
        const SectionReport section = compare_slice_section(part, z, polygons);
        Worst wall;
        wall.distance = section.max_mesh_to_contour_px;
        wall.point = {kInf, kInf};  // located below, once, for the worst slice

        const PolylineIndex index(polygons);
        std::vector<int> side(part.positions.size());
        for (std::size_t i = 0; i < part.positions.size(); ++i) {
            const double dz = part.positions[i].z - z;
            side[i] = dz > eps ? 1 : (dz < -eps ? -1 : 0);
        }

        // caps, and the in-plane edges and vertices the section does not cover
        Worst cap;
        std::vector<bool> in_cap(part.positions.size(), false);
        // (lower vertex, upper vertex, side of the face's third vertex; 2 for a cap face)
        std::vector<std::array<std::uint32_t, 3>> plane_edges;
        for (const auto& t : part.triangles) {
            const bool is_cap = side[t[0]] == 0 && side[t[1]] == 0 && side[t[2]] == 0;
            if (is_cap) {
                ++report.cap_triangles;
                for (std::uint32_t v : t) {
                    in_cap[v] = true;
                }
                search_cap(index, xy(part.positions[t[0]]), xy(part.positions[t[1]]),
                           xy(part.positions[t[2]]), cap);
            }
            for (int i = 0; i < 3; ++i) {
                const std::uint32_t u = t[i], v = t[(i + 1) % 3], w = t[(i + 2) % 3];
                if (side[u] == 0 && side[v] == 0) {
                    plane_edges.push_back({std::min(u, v), std::max(u, v),
                                           is_cap ? 2u : static_cast<std::uint32_t>(side[w] + 1)});
                }
            }
        }
        std::sort(plane_edges.begin(), plane_edges.end());
        for (std::size_t i = 0; i < plane_edges.size();) {
            std::size_t j = i;
            bool cap_face = false, mixed = false;
            while (j < plane_edges.size() && plane_edges[j][0] == plane_edges[i][0] &&
                   plane_edges[j][1] == plane_edges[i][1]) {
                cap_face = cap_face || plane_edges[j][2] == 2;
                mixed = mixed || plane_edges[j][2] != plane_edges[i][2];
                ++j;
            }
            if (!cap_face && !mixed) {
                // the surface only touches the plane along this edge
                sample_segment(index, xy(part.positions[plane_edges[i][0]]),
                               xy(part.positions[plane_edges[i][1]]), kTouchStepPx, wall);
            }
            i = j;
        }
        for (std::size_t v = 0; v < part.positions.size(); ++v) {
            if (side[v] == 0 && !in_cap[v]) {
                const Vec2 p = xy(part.positions[v]);
                wall.offer(index.distance(p), p);
            }
        }

        report.max_section_px = std::max(report.max_section_px, wall.distance);
        report.max_cap_px = std::max(report.max_cap_px, cap.distance);
        if (wall.distance > 0) {
            section_worst.offer(wall, k);
        }
        if (cap.distance > 0) {
            cap_worst.offer(cap, k);
        }
    }

    // where the worst section point is, when the exact comparison found it (by sampling the
    // section of that slice finely: the point reported is within 0.005 px of the sup)
    if (section_worst.set && section_worst.worst.point.x == kInf) {
        const std::uint32_t k = section_worst.slice;
        TriMesh part;
        part.positions = mesh.positions;
        for (std::uint32_t f : meeting[k]) {
            part.triangles.push_back(mesh.triangles[f]);
        }
        const PolylineIndex index(original_polygons(contours.slices[k], label));
        Worst located;
        located.distance = -1;
        for (const auto& s : slice_section_segments(part, plane_z[k])) {
            sample_segment(index, s[0], s[1], kSectionStepPx, located);
        }
        section_worst.worst.point = located.point;
    }
    // coverage: every original contour point of the label against the whole mesh
    const MeshIndex mesh_index(mesh);
    double cover = 0;
    Vec3 cover_point;
    std::uint32_t cover_slice = 0;
    for (std::uint32_t k = 0; k < slice_count; ++k) {
        const double z = plane_z[k];
        const double before = cover;
        for (const auto& polygon : original_polygons(contours.slices[k], label)) {
            if (polygon.empty()) {
                continue;
            }
            if (mesh_index.empty()) {
                cover = kInf;
                cover_point = {polygon[0].x, polygon[0].y, z};
                break;
            }
            std::vector<std::pair<double, std::uint32_t>> nearest(polygon.size());
            for (std::size_t i = 0; i < polygon.size(); ++i) {
                nearest[i] = mesh_index.nearest({polygon[i].x, polygon[i].y, z});
            }
            for (std::size_t i = 0; i < polygon.size(); ++i) {
                const std::size_t j = (i + 1) % polygon.size();
                search_coverage(mesh_index, {polygon[i].x, polygon[i].y, z},
                                {polygon[j].x, polygon[j].y, z}, nearest[i], nearest[j], cover,
                                cover_point);
            }
        }
        if (cover > before) {
            cover_slice = k;
        }
    }
    report.max_coverage_px = cover;

    const bool cap_wins =
        cap_worst.set && (!section_worst.set || report.max_cap_px > report.max_section_px);
    if (cover > std::max(report.max_section_px, report.max_cap_px)) {
        report.worst_slice = cover_slice;
        report.worst_point = xy(cover_point);
    } else if (cap_wins) {
        report.worst_slice = cap_worst.slice;
        report.worst_point = cap_worst.worst.point;
    } else if (section_worst.set) {
        report.worst_slice = section_worst.slice;
        report.worst_point = section_worst.worst.point;
    }
    return report;
}

}  // namespace strata::test

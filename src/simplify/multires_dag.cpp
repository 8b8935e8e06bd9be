// The multiresolution model as a DAG of cluster groups (docs/architecture.md section 4; the
// structure of Nexus, Cignoni et al. "Batched multi triangulation", IEEE Vis 2005, and of Nanite,
// Karis, "Nanite: a deep dive", SIGGRAPH 2021), with the paper's error-bounded edge collapses
// (section 7) inside each group. Selective refinement (paper section 6.2) becomes the choice of a
// cut.
//
// One file: DagBuilder's steps (grouping, per-group collapses, contour-piece attachment,
// bounds) are members of one class that update the same mesh, piece lists and grids, helped by
// the file-local geometry (Box, spheres, PieceFinder); the cut selection after it is short and
// reads only the DAG it builds. Apart, the builder's state would be exported.
#include "simplify/multires_dag.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <map>
#include <numeric>
#include <string>
#include <unordered_map>

#include "core/error.h"
#include "core/parallel.h"
#include "mesh/self_intersection.h"
#include "quantize/snap_to_grid.h"
#include "simplify/detail/triangle_grid.h"
#include "simplify/detail/triangle_hash.h"
#include "simplify/edge_collapse.h"

namespace strata {

namespace {

using Tri = std::array<std::uint32_t, 3>;
/// (triangle index, contour piece id): where a contour piece is attached.
using PieceAttachment = std::pair<std::uint32_t, std::uint32_t>;

/// Contour pieces are split until they fit one full-resolution triangle this well (px) ...
constexpr double kPieceFitPx = 0.01;
/// ... or are this short (px).
constexpr double kShortestPiecePx = 1.0 / 16.0;
/// No triangle (yet).
constexpr std::uint32_t kNoTriangle = 0xffffffffu;
/// Simplifications of a first-level group that lock the vertices left too far (MultiresOptions::
/// first_level_px) before its result is taken as it is.
constexpr int kFirstLevelRounds = 4;

using detail::TriangleHash;

/// Hash of a position's exact coordinates (-0 and +0 alike).
struct PositionHash {
    std::size_t operator()(const Vec3& p) const {
        std::uint64_t h = 0;
        for (const double c : {p.x, p.y, p.z}) {
            h = (h ^ std::bit_cast<std::uint64_t>(c + 0.0)) * 0x9e3779b97f4a7c15ull;
        }
        return std::size_t(h ^ (h >> 29));
    }
};

struct Box {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
            -std::numeric_limits<double>::infinity()};

    void add(const Vec3& p) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    bool overlaps(const Box& o) const {
        for (int a = 0; a < 3; ++a) {
            if (hi[a] < o.lo[a] || o.hi[a] < lo[a]) {
                return false;
            }
        }
        return true;
    }
};

/// Squared distance from p to box b (a lower bound of the squared distance to anything inside).
inline double box_distance2(const Vec3& p, const Box& b) {
    double sum = 0.0;
    for (int a = 0; a < 3; ++a) {
        const double d = std::max({b.lo[a] - p[a], 0.0, p[a] - b.hi[a]});
        sum += d * d;
    }
    return sum;
}

/// Slack (px) of a box's distance as a lower bound of point_triangle_distance_px: far above the
/// rounding of either at slice-space magnitudes (coordinates below 1e5 px).
constexpr double kBoxSlackPx = 1e-9;

/// Whether the distance whose square is `distance2` is at least `bound` + kBoxSlackPx (no square
/// root taken: the slack covers the rounding of the squares as well).
inline bool at_least(double distance2, double bound) {
    const double r = bound + kBoxSlackPx;
    return r <= 0.0 || distance2 >= r * r;
}

Vec3 centroid(const std::vector<Vec3>& positions, const Tri& t) {
    return (1.0 / 3.0) * (positions[t[0]] + positions[t[1]] + positions[t[2]]);
}

/// Splits triangles [begin, end) of `items` into `parts` spatially compact sets by recursive
/// bisection at the median centroid along the longest axis.
void bisect(const std::vector<Vec3>& positions,
            std::vector<Tri>& items,
            std::size_t begin,
            std::size_t end,
            std::size_t parts,
            std::vector<std::vector<Tri>>& out) {
    if (parts <= 1 || end - begin <= 1) {
        out.emplace_back(items.begin() + std::ptrdiff_t(begin),
                         items.begin() + std::ptrdiff_t(end));
        return;
    }
    Box box;
    for (std::size_t i = begin; i < end; ++i) {
        box.add(centroid(positions, items[i]));
    }
    int axis = 0;
    for (int a = 1; a < 3; ++a) {
        if (box.hi[a] - box.lo[a] > box.hi[axis] - box.lo[axis]) {
            axis = a;
        }
    }
    const std::size_t left_parts = parts / 2;
    const std::size_t mid = begin + (end - begin) * left_parts / parts;
    std::nth_element(items.begin() + std::ptrdiff_t(begin), items.begin() + std::ptrdiff_t(mid),
                     items.begin() + std::ptrdiff_t(end), [&](const Tri& a, const Tri& b) {
                         const double ca = centroid(positions, a)[axis];
                         const double cb = centroid(positions, b)[axis];
                         return ca != cb ? ca < cb : a < b;
                     });
    bisect(positions, items, begin, mid, left_parts, out);
    bisect(positions, items, mid, end, parts - left_parts, out);
}

Sphere bounding_sphere(const std::vector<Vec3>& positions, const std::vector<std::uint32_t>& ids) {
    Box box;
    for (const std::uint32_t v : ids) {
        box.add(positions[v]);
    }
    Sphere s;
    if (ids.empty()) {
        return s;
    }
    s.center = 0.5 * (box.lo + box.hi);
    for (const std::uint32_t v : ids) {
        s.radius = std::max(s.radius, norm(positions[v] - s.center));
    }
    return s;
}

/// The smallest sphere around `a` that also contains `b` (not the minimal enclosing sphere).
Sphere enclose(const Sphere& a, const Sphere& b) {
    const double d = norm(b.center - a.center);
    if (d + b.radius <= a.radius) {
        return a;
    }
    if (d + a.radius <= b.radius) {
        return b;
    }
    const double radius = 0.5 * (d + a.radius + b.radius);
    const Vec3 center = a.center + ((radius - a.radius) / d) * (b.center - a.center);
    return {center, radius * (1.0 + 1e-12) + 1e-12};
}

/// The triangle nearest to both ends of a contour piece and how near its ends come to any
/// triangle (PieceFinder::nearest).
struct PieceFit {
    double best = std::numeric_limits<double>::infinity();  ///< deviation + farther end's distance
    double nearest_a = std::numeric_limits<double>::infinity();
    double nearest_b = std::numeric_limits<double>::infinity();
    std::uint32_t triangle = 0;
};

/// Finds, for DagBuilder::attach_pieces, the triangle of `triangles` nearest to both ends of a
/// contour piece: first among the triangles around the vertex at its first end, then in the
/// grid over growing boxes around it.
class PieceFinder {
public:
    PieceFinder(const std::vector<Vec3>& positions, const std::vector<Tri>& triangles, double cell)
        : positions_(positions),
          triangles_(triangles),
          grid_(cell),
          boxes_(triangles.size()),
          seen_(triangles.size(), 0),
          around_(positions.size()) {
        Box all;
        for (std::uint32_t t = 0; t < triangles_.size(); ++t) {
            grid_.insert(t, corners(t));
            for (const std::uint32_t v : triangles_[t]) {
                all.add(positions_[v]);
                boxes_[t].add(positions_[v]);
            }
        }
        reach_ = norm(all.hi - all.lo);
        // note: most pieces are mesh edges (the surface runs through the simplified contours):
        // the triangles around the vertex at a piece's first end settle them without the grid
        for (std::uint32_t t = 0; t < triangles_.size(); ++t) {
            for (const std::uint32_t v : triangles_[t]) {
                vertex_at_.emplace(positions_[v], v);
                around_[v].push_back(t);
            }
        }
    }

    /// The vertex of the triangles at `p`, kNoTriangle when none is.
    std::uint32_t vertex_at(const Vec3& p) const {
        const auto it = vertex_at_.find(p);
        return it == vertex_at_.end() ? kNoTriangle : it->second;
    }

    std::array<Vec3, 3> corners(std::uint32_t t) const {
        const Tri& ids = triangles_[t];
        return std::array<Vec3, 3>{positions_[ids[0]], positions_[ids[1]], positions_[ids[2]]};
    }

    PieceFit nearest(const ContourPiece& piece) const {
        PieceFit found;
        double& best = found.best;
        double& nearest_a = found.nearest_a;
        double& nearest_b = found.nearest_b;
        std::uint32_t& best_triangle = found.triangle;
        // note: a triangle whose box is no nearer to either end than what is known cannot
        // change anything (the box distance is below the triangle's, and kBoxSlackPx covers the
        // rounding of both)
        auto cannot_change = [&](const Box& b) {
            const double la2 = box_distance2(piece.a, b);
            if (!at_least(la2, nearest_a)) {
                return false;
            }
            const double lb2 = box_distance2(piece.b, b);
            return at_least(lb2, nearest_b) &&
                   at_least(std::max(la2, lb2), best - piece.deviation_px);
        };
        auto offer = [&](std::uint32_t t) {
            if (cannot_change(boxes_[t])) {
                return;
            }
            const std::array<Vec3, 3> c = corners(t);
            const double da = point_triangle_distance_px(piece.a, c);
            const double db = point_triangle_distance_px(piece.b, c);
            if (piece.deviation_px + std::max(da, db) < best) {
                best = piece.deviation_px + std::max(da, db);
                best_triangle = t;
            }
            nearest_a = std::min(nearest_a, da);
            nearest_b = std::min(nearest_b, db);
        };
        if (const auto a = vertex_at_.find(piece.a); a != vertex_at_.end()) {
            const auto b = vertex_at_.find(piece.b);
            for (const std::uint32_t t : around_[a->second]) {
                const Tri& ids = triangles_[t];
                if (b != vertex_at_.end() &&
                    (ids[0] == b->second || ids[1] == b->second || ids[2] == b->second)) {
                    // the piece is an edge of t
                    best = piece.deviation_px;
                    best_triangle = t;
                    nearest_a = nearest_b = 0.0;
                    break;
                }
                offer(t);
            }
        }
        // note: a triangle offered once is not offered again for a wider box (what it could
        // change it did: `best` and the nearest ends only decrease)
        ++query_;
        for (double r = 1.0; best - piece.deviation_px > kPieceFitPx; r *= 2.0) {
            Vec3 lo = piece.a, hi = piece.a;
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(piece.a[a], piece.b[a]) - r;
                hi[a] = std::max(piece.a[a], piece.b[a]) + r;
            }
            grid_.query({lo, hi, hi}, [&](std::uint32_t t) {
                if (seen_[t] == query_) {
                    return;
                }
                seen_[t] = query_;
                offer(t);
            });
            // note: a triangle within r of both ends meets the box, so `best` is final
            if (best - piece.deviation_px <= r || r > reach_) {
                break;
            }
        }
        return found;
    }

private:
    const std::vector<Vec3>& positions_;
    const std::vector<Tri>& triangles_;
    detail::TriangleGrid grid_;
    std::vector<Box> boxes_;
    double reach_ = 0.0;
    mutable std::vector<std::uint32_t> seen_;  // the last query that met each triangle
    mutable std::uint32_t query_ = 0;
    std::unordered_map<Vec3, std::uint32_t, PositionHash> vertex_at_;
    std::vector<std::vector<std::uint32_t>> around_;
};

class DagBuilder {
public:
    DagBuilder(const TriMesh& surface,
               const SliceErrorMeter& meter,
               double base_error_px,
               const MultiresOptions& options)
        : meter_(meter), options_(options) {
        mesh_.positions = surface.positions;
        exact_ =
            grid_frame_positions(surface.positions, meter.slice_spacing_px(), options.grid_step);
        mesh_.full_resolution_error_px = base_error_px;
        for (const Tri& t : surface.triangles) {
            for (const std::uint32_t v : t) {
                if (v >= surface.positions.size()) {
                    throw Error(ErrorCode::InvalidInput,
                                "multiresolution: triangle vertex " + std::to_string(v) +
                                    " out of range (" + std::to_string(surface.positions.size()) +
                                    " vertices)");
                }
            }
        }
        std::vector<Tri> all = surface.triangles;
        double edge_sum = 0.0;
        for (const Tri& t : all) {
            edge_sum += norm(exact_[t[0]] - exact_[t[1]]);
        }
        grid_cell_ = std::max(1e-3, 4.0 * edge_sum / double(std::max<std::size_t>(all.size(), 1)));
        const std::vector<PieceAttachment> attached = attach_pieces(all);
        const auto index = index_of(all);
        for (std::vector<Tri>& part : split(all)) {
            const std::uint32_t c = add_cluster(0, -1, part);
            attach_to_cluster(c, part, index, attached);
            frontier_.push_back(c);
        }
    }

    MultiresMesh run() {
        for (std::uint32_t level = 1; level <= options_.max_levels; ++level) {
            if (frontier_.size() <= 1 && frontier_triangles() <= options_.root_triangles) {
                break;
            }
            const std::vector<std::vector<std::uint32_t>> groups = make_groups();
            // Every group is simplified in parallel against the clusters of earlier levels; then,
            // in group order, a result whose new triangles meet those of an earlier group of this
            // level is redone against everything recorded so far. Same output for any thread
            // count.
            const std::size_t snapshot = mesh_.clusters.size();
            std::vector<Attempt> attempts(groups.size());
            parallel_for(groups.size(), options_.threads,
                         [&](std::size_t i) { attempts[i] = attempt_group(groups[i], snapshot); });
            std::vector<std::uint32_t> next;
            bool progress = false;
            detail::TriangleGrid level_grid(grid_cell_);
            std::vector<Tri> level_created;
            for (std::size_t i = 0; i < groups.size(); ++i) {
                Attempt& attempt = attempts[i];
                if (attempt.shrunk && conflicts(attempt, level_grid, level_created)) {
                    attempt = attempt_group(groups[i], mesh_.clusters.size());
                }
                if (!attempt.shrunk) {
                    next.insert(next.end(), groups[i].begin(), groups[i].end());
                    continue;
                }
                for (const Tri& t : attempt.created) {
                    level_grid.insert(std::uint32_t(level_created.size()),
                                      {exact_[t[0]], exact_[t[1]], exact_[t[2]]});
                    level_created.push_back(t);
                }
                record_group(level, groups[i], attempt, next);
                progress = true;
            }
            std::sort(next.begin(), next.end());
            frontier_ = std::move(next);
            if (options_.progress) {
                options_.progress("simplify levels", level, options_.max_levels);
            }
            if (!progress) {
                break;
            }
        }
        return std::move(mesh_);
    }

private:
    std::size_t frontier_triangles() const {
        std::size_t n = 0;
        for (const std::uint32_t c : frontier_) {
            n += mesh_.clusters[c].triangles.size();
        }
        return n;
    }

    /// Attaches the meter's contour pieces to the full-resolution `triangles`: each to the triangle
    /// nearest to both its ends (piece_distance_px). Where that is clearly worse than the ends' own
    /// nearest triangles (the surface does not run along the simplified edge: it follows the
    /// original contour there, or splits the edge), the piece is replaced by its original edges,
    /// and those by their halves. Fills `pieces_` and raises the full-resolution bound to the
    /// largest distance. Returns (index into `triangles`, piece) pairs, sorted.
    std::vector<PieceAttachment> attach_pieces(const std::vector<Tri>& triangles) {
        std::vector<PieceAttachment> attached;
        if (triangles.empty()) {
            return attached;
        }
        const PieceFinder finder(mesh_.positions, triangles, grid_cell_);
        std::vector<ContourPiece> work(meter_.contour_pieces().rbegin(),
                                       meter_.contour_pieces().rend());
        double worst = 0.0;
        while (!work.empty()) {
            const ContourPiece piece = work.back();
            work.pop_back();
            const PieceFit found = finder.nearest(piece);
            if (!(found.best < std::numeric_limits<double>::infinity())) {
                continue;  // note: no triangle at all (not reached: triangles is not empty)
            }
            const double fit =
                found.best - piece.deviation_px - std::max(found.nearest_a, found.nearest_b);
            if (fit > kPieceFitPx && piece.points != nullptr) {
                const std::vector<ContourPiece> edges = piece.original_edges();
                work.insert(work.end(), edges.rbegin(), edges.rend());
                continue;
            }
            if (fit > kPieceFitPx && norm(piece.b - piece.a) > kShortestPiecePx) {
                const Vec3 mid = 0.5 * (piece.a + piece.b);
                work.push_back({mid, piece.b, piece.deviation_px});
                work.push_back({piece.a, mid, piece.deviation_px});
                continue;
            }
            attached.emplace_back(found.triangle, std::uint32_t(pieces_.size()));
            pieces_.push_back(piece);
            // note: the original points may lie closer than the capsule around the piece says
            worst = std::max(worst, piece_distance_px(piece, finder.corners(found.triangle)));
        }
        mesh_.full_resolution_error_px = std::max(mesh_.full_resolution_error_px, worst);
        attach_vertices(triangles, attached);
        std::sort(attached.begin(), attached.end());
        // which piece ends are full-resolution vertices, and their distance at level 0
        piece_vertex_ends_.assign(pieces_.size(), 0);
        piece_vertices_.assign(pieces_.size(), {kNoTriangle, kNoTriangle});
        for (std::size_t i = 0; i < pieces_.size(); ++i) {
            piece_vertices_[i] = {finder.vertex_at(pieces_[i].a), finder.vertex_at(pieces_[i].b)};
            piece_vertex_ends_[i] = char((piece_vertices_[i][0] != kNoTriangle ? 1 : 0) |
                                         (piece_vertices_[i][1] != kNoTriangle ? 2 : 0));
        }
        for (const auto& [t, piece] : attached) {
            fine_floor_px_ =
                std::max(fine_floor_px_, vertex_end_distance_px(piece, finder.corners(t)));
        }
        return attached;
    }

    /// Attaches every vertex of `triangles` that is not a contour vertex (domes and stack-end
    /// extensions beyond the end slices, vertices between slices, points inside planar caps) as a
    /// piece of its own to a triangle of its star, appending to `pieces_` and `attached`: no
    /// coarser level may flatten a dome, which the slice sections do not see, by more than its
    /// bound. (The contour vertices are ends of the contour pieces already.)
    void attach_vertices(const std::vector<Tri>& triangles,
                         std::vector<PieceAttachment>& attached) {
        std::unordered_map<Vec3, char, PositionHash> contour_vertex;
        for (const ContourPiece& piece : meter_.contour_pieces()) {
            contour_vertex.emplace(piece.a, 0);
            contour_vertex.emplace(piece.b, 0);
        }
        std::vector<std::uint32_t> star(mesh_.positions.size(), kNoTriangle);
        for (std::uint32_t t = 0; t < triangles.size(); ++t) {
            for (const std::uint32_t v : triangles[t]) {
                if (star[v] == kNoTriangle) {
                    star[v] = t;
                }
            }
        }
        for (std::uint32_t v = 0; v < star.size(); ++v) {
            const Vec3& p = mesh_.positions[v];
            if (star[v] != kNoTriangle && !contour_vertex.contains(p)) {
                attached.emplace_back(star[v], std::uint32_t(pieces_.size()));
                pieces_.push_back({p, p, 0.0});
            }
        }
    }

    /// The largest distance from `triangle` of the ends of piece `piece` that are full-resolution
    /// vertices (0 when neither is).
    double vertex_end_distance_px(std::uint32_t piece, const std::array<Vec3, 3>& triangle) const {
        const ContourPiece& p = pieces_[piece];
        const char ends = piece_vertex_ends_[piece];
        double d = 0.0;
        if ((ends & 1) != 0) {
            d = point_triangle_distance_px(p.a, triangle);
        }
        if ((ends & 2) != 0) {
            d = std::max(d, point_triangle_distance_px(p.b, triangle));
        }
        return d;
    }

    /// Position of every triangle in `triangles`.
    static std::unordered_map<Tri, std::uint32_t, TriangleHash> index_of(
        const std::vector<Tri>& triangles) {
        std::unordered_map<Tri, std::uint32_t, TriangleHash> index;
        index.reserve(triangles.size());
        for (std::uint32_t i = 0; i < triangles.size(); ++i) {
            index.emplace(triangles[i], i);
        }
        return index;
    }

    /// Records, for cluster `c` made of `part`, the pieces `attached` (sorted pairs of an index
    /// into the triangles `index` was made of, and a piece) holds for its triangles.
    void attach_to_cluster(std::uint32_t c,
                           const std::vector<Tri>& part,
                           const std::unordered_map<Tri, std::uint32_t, TriangleHash>& index,
                           const std::vector<PieceAttachment>& attached) {
        std::vector<PieceAttachment>& out = cluster_pieces_[c];
        for (std::uint32_t j = 0; j < part.size() && !attached.empty(); ++j) {
            const std::uint32_t i = index.at(part[j]);
            auto it = std::lower_bound(attached.begin(), attached.end(), PieceAttachment{i, 0});
            for (; it != attached.end() && it->first == i; ++it) {
                out.emplace_back(j, it->second);
            }
        }
    }

    std::vector<std::vector<Tri>> split(std::vector<Tri>& triangles) const {
        const std::size_t size = std::max<std::size_t>(options_.cluster_triangles, 1);
        const std::size_t parts = std::max<std::size_t>(1, (triangles.size() + size / 2) / size);
        std::vector<std::vector<Tri>> out;
        bisect(mesh_.positions, triangles, 0, triangles.size(), parts, out);
        return out;
    }

    std::uint32_t add_cluster(std::uint32_t level, std::int32_t producer, std::vector<Tri> tris) {
        MultiresCluster c;
        c.level = level;
        c.producer = producer;
        for (const Tri& t : tris) {
            c.vertices.insert(c.vertices.end(), t.begin(), t.end());
        }
        std::sort(c.vertices.begin(), c.vertices.end());
        c.vertices.erase(std::unique(c.vertices.begin(), c.vertices.end()), c.vertices.end());
        c.triangles.reserve(tris.size());
        Box box;
        for (const Tri& t : tris) {
            Tri local{};
            for (int i = 0; i < 3; ++i) {
                local[i] =
                    std::uint32_t(std::lower_bound(c.vertices.begin(), c.vertices.end(), t[i]) -
                                  c.vertices.begin());
            }
            c.triangles.push_back(local);
        }
        for (const std::uint32_t v : c.vertices) {
            box.add(exact_[v]);
        }
        c.bounds = bounding_sphere(mesh_.positions, c.vertices);
        mesh_.clusters.push_back(std::move(c));
        boxes_.push_back(box);
        cluster_pieces_.emplace_back();
        return std::uint32_t(mesh_.clusters.size() - 1);
    }

    std::vector<Tri> global_triangles(std::uint32_t c) const {
        const MultiresCluster& cluster = mesh_.clusters[c];
        std::vector<Tri> out;
        out.reserve(cluster.triangles.size());
        for (const Tri& t : cluster.triangles) {
            out.push_back({cluster.vertices[t[0]], cluster.vertices[t[1]], cluster.vertices[t[2]]});
        }
        return out;
    }

    double cluster_error(std::uint32_t c) const {
        const std::int32_t p = mesh_.clusters[c].producer;
        return p < 0 ? mesh_.full_resolution_error_px : mesh_.groups[std::size_t(p)].error_px;
    }

    /// Groups of about `group_clusters` adjacent frontier clusters: rounds of greedy matching on
    /// shared edges, edges between clusters of different producers weighing more (so borders of
    /// the last level's groups fall inside the new ones).
    std::vector<std::vector<std::uint32_t>> make_groups() const {
        // unit of each frontier cluster (index into `units`)
        std::vector<std::vector<std::uint32_t>> units;
        std::unordered_map<std::uint32_t, std::uint32_t> unit_of;
        for (const std::uint32_t c : frontier_) {
            unit_of[c] = std::uint32_t(units.size());
            units.push_back({c});
        }
        // shared edge weights between clusters
        std::unordered_map<std::uint64_t, std::uint32_t> edge_owner;
        std::map<std::pair<std::uint32_t, std::uint32_t>, double> weight;
        for (const std::uint32_t c : frontier_) {
            for (const Tri& t : global_triangles(c)) {
                for (int i = 0; i < 3; ++i) {
                    const std::uint32_t a = std::min(t[i], t[(i + 1) % 3]);
                    const std::uint32_t b = std::max(t[i], t[(i + 1) % 3]);
                    const std::uint64_t key = std::uint64_t(a) << 32 | b;
                    const auto [it, inserted] = edge_owner.emplace(key, c);
                    if (!inserted && it->second != c) {
                        const std::uint32_t o = it->second;
                        const bool different =
                            mesh_.clusters[c].producer < 0 ||
                            mesh_.clusters[c].producer != mesh_.clusters[o].producer;
                        weight[{std::min(c, o), std::max(c, o)}] += different ? 4.0 : 1.0;
                    }
                }
            }
        }
        for (std::size_t size = 1; size < options_.group_clusters; size *= 2) {
            // weights between current units
            std::map<std::pair<std::uint32_t, std::uint32_t>, double> unit_weight;
            for (const auto& [pair, w] : weight) {
                const std::uint32_t a = unit_of.at(pair.first);
                const std::uint32_t b = unit_of.at(pair.second);
                if (a != b) {
                    unit_weight[{std::min(a, b), std::max(a, b)}] += w;
                }
            }
            std::vector<std::pair<double, std::pair<std::uint32_t, std::uint32_t>>> order;
            for (const auto& [pair, w] : unit_weight) {
                order.push_back({-w, pair});
            }
            std::sort(order.begin(), order.end());
            std::vector<bool> matched(units.size(), false);
            std::vector<std::vector<std::uint32_t>> merged;
            std::vector<std::uint32_t> new_index(units.size(), 0);
            for (const auto& [w, pair] : order) {
                if (matched[pair.first] || matched[pair.second]) {
                    continue;
                }
                matched[pair.first] = matched[pair.second] = true;
                std::vector<std::uint32_t> both = units[pair.first];
                both.insert(both.end(), units[pair.second].begin(), units[pair.second].end());
                new_index[pair.first] = new_index[pair.second] = std::uint32_t(merged.size());
                merged.push_back(std::move(both));
            }
            for (std::uint32_t u = 0; u < units.size(); ++u) {
                if (!matched[u]) {
                    new_index[u] = std::uint32_t(merged.size());
                    merged.push_back(units[u]);
                }
            }
            for (auto& [c, u] : unit_of) {
                u = new_index[u];
            }
            units = std::move(merged);
        }
        for (std::vector<std::uint32_t>& u : units) {
            std::sort(u.begin(), u.end());
        }
        std::sort(units.begin(), units.end());
        return units;
    }

    /// Marks `members` and every cluster below them (the clusters a group's results replace).
    std::vector<char> descendants(const std::vector<std::uint32_t>& members) const {
        std::vector<char> below(mesh_.clusters.size(), 0);
        std::vector<std::uint32_t> stack = members;
        while (!stack.empty()) {
            const std::uint32_t c = stack.back();
            stack.pop_back();
            if (below[c] != 0) {
                continue;
            }
            below[c] = 1;
            const std::int32_t p = mesh_.clusters[c].producer;
            if (p >= 0) {
                const MultiresGroup& g = mesh_.groups[std::size_t(p)];
                stack.insert(stack.end(), g.consumed.begin(), g.consumed.end());
            }
        }
        return below;
    }

    /// One group's simplification before it is recorded.
    struct Attempt {
        bool shrunk = false;
        double children_error = 0.0;
        CollapseResult result;
        std::vector<Tri> created;  ///< triangles of the result that were not in the input
    };

    /// Simplifies the group of `members` against the triangles of clusters [0, cluster_limit)
    /// that can be drawn with its results. Reads the builder's state only.
    Attempt attempt_group(const std::vector<std::uint32_t>& members,
                          std::size_t cluster_limit) const {
        Attempt attempt;
        CollapseProblem problem;
        problem.positions = &mesh_.positions;
        problem.exact_positions = &exact_;
        Box box;
        for (const std::uint32_t c : members) {
            const double e = cluster_error(c);
            attempt.children_error = std::max(attempt.children_error, e);
            const auto offset = std::uint32_t(problem.triangles.size());
            for (const auto& [t, piece] : cluster_pieces_[c]) {
                problem.piece_triangles.emplace_back(offset + t, piece);
            }
            for (const Tri& t : global_triangles(c)) {
                problem.triangles.push_back(t);
                problem.triangle_error_px.push_back(e);
                for (const std::uint32_t v : t) {
                    box.add(exact_[v]);
                }
            }
        }
        const std::size_t before = problem.triangles.size();
        if (before < 8) {
            return attempt;
        }
        // Border: vertices of edges used once within the group.
        std::vector<std::pair<std::uint32_t, std::uint32_t>> edges;
        edges.reserve(before * 3);
        for (const Tri& t : problem.triangles) {
            for (int i = 0; i < 3; ++i) {
                edges.emplace_back(std::min(t[i], t[(i + 1) % 3]), std::max(t[i], t[(i + 1) % 3]));
            }
        }
        std::sort(edges.begin(), edges.end());
        for (std::size_t i = 0; i < edges.size();) {
            std::size_t j = i;
            while (j < edges.size() && edges[j] == edges[i]) {
                ++j;
            }
            if (j - i == 1) {
                problem.locked.push_back(edges[i].first);
                problem.locked.push_back(edges[i].second);
            }
            i = j;
        }
        std::sort(problem.locked.begin(), problem.locked.end());
        problem.locked.erase(std::unique(problem.locked.begin(), problem.locked.end()),
                             problem.locked.end());
        // Obstacles: triangles of every cluster that can be drawn with this group's results
        // (all but the group's own and those below it) near the group.
        const std::vector<char> below = descendants(members);
        for (std::uint32_t c = 0; c < cluster_limit; ++c) {
            if ((c < below.size() && below[c] != 0) || !boxes_[c].overlaps(box)) {
                continue;
            }
            for (const Tri& t : global_triangles(c)) {
                Box tb;
                for (const std::uint32_t v : t) {
                    tb.add(exact_[v]);
                }
                if (tb.overlaps(box)) {
                    problem.obstacles.push_back(t);
                }
            }
        }

        problem.pieces = &pieces_;
        CollapseOptions collapse;
        collapse.target_triangles = std::size_t(double(before) * options_.keep_fraction);
        collapse.error_floor_px = attempt.children_error;
        collapse.max_error_px = std::min(
            options_.max_error_px,
            std::max(options_.error_growth * attempt.children_error, attempt.children_error + 0.5));
        const bool first_level = std::isfinite(options_.first_level_px) &&
                                 std::all_of(members.begin(), members.end(), [&](std::uint32_t c) {
                                     return mesh_.clusters[c].level == 0;
                                 });
        // The first level stays within first_level_px of every full-resolution vertex: the
        // vertices the result leaves farther away are kept (locked) and the group simplified
        // again, a few rounds (what is still farther is recorded in fine_error_px all the same).
        // A group that cannot shrink so is simplified by the rule above alone.
        const std::vector<std::uint32_t> border = problem.locked;
        for (int round = 0;; ++round) {
            attempt.result = collapse_edges(problem, meter_, collapse);
            if (!first_level || round == kFirstLevelRounds) {
                break;
            }
            const std::size_t locked = problem.locked.size();
            for (const auto& [t, piece] : attempt.result.piece_triangles) {
                const Tri& ids = attempt.result.triangles[t];
                const std::array<Vec3, 3> corners{mesh_.positions[ids[0]], mesh_.positions[ids[1]],
                                                  mesh_.positions[ids[2]]};
                for (int end = 0; end < 2; ++end) {
                    const std::uint32_t v = piece_vertices_[piece][std::size_t(end)];
                    if (v != kNoTriangle &&
                        point_triangle_distance_px(mesh_.positions[v], corners) >
                            options_.first_level_px) {
                        problem.locked.push_back(v);
                    }
                }
            }
            if (problem.locked.size() == locked) {
                break;
            }
            std::sort(problem.locked.begin(), problem.locked.end());
            problem.locked.erase(std::unique(problem.locked.begin(), problem.locked.end()),
                                 problem.locked.end());
        }
        attempt.shrunk = double(attempt.result.triangles.size()) <=
                         double(before) * (1.0 - options_.min_reduction);
        if (first_level && !attempt.shrunk && problem.locked.size() > border.size()) {
            problem.locked = border;
            attempt.result = collapse_edges(problem, meter_, collapse);
            attempt.shrunk = double(attempt.result.triangles.size()) <=
                             double(before) * (1.0 - options_.min_reduction);
        }
        if (attempt.shrunk) {
            std::vector<Tri> input = problem.triangles;
            std::sort(input.begin(), input.end());
            for (const Tri& t : attempt.result.triangles) {
                if (!std::binary_search(input.begin(), input.end(), t)) {
                    attempt.created.push_back(t);
                }
            }
        }
        return attempt;
    }

    /// Whether a triangle `attempt` created intersects one of `others` (created by other groups of
    /// the same level, which the attempt did not see).
    bool conflicts(const Attempt& attempt,
                   const detail::TriangleGrid& grid,
                   const std::vector<Tri>& others) const {
        auto corners = [&](const Tri& t) {
            return std::array<Vec3, 3>{exact_[t[0]], exact_[t[1]], exact_[t[2]]};
        };
        for (const Tri& t : attempt.created) {
            const std::array<Vec3, 3> a = corners(t);
            bool hit = false;
            grid.query(a, [&](std::uint32_t id) {
                if (!hit) {
                    const std::array<Vec3, 3> b = corners(others[id]);
                    hit = detail::boxes_overlap(a, b) && triangles_intersect(a, t, b, others[id]);
                }
            });
            if (hit) {
                return true;
            }
        }
        return false;
    }

    /// Records a shrunk group: its produced clusters (appended to `next`), the geomorph targets
    /// of its consumed clusters, its error and bounds.
    void record_group(std::uint32_t level,
                      const std::vector<std::uint32_t>& members,
                      Attempt& attempt,
                      std::vector<std::uint32_t>& next) {
        CollapseResult& result = attempt.result;
        MultiresGroup group;
        group.level = level;
        group.consumed = members;
        group.error_px = std::max(result.max_error_px, attempt.children_error);
        // the finest level: the vertices attached to the result's triangles, the groups below
        group.fine_error_px = fine_floor_px_;
        for (const auto& [t, piece] : result.piece_triangles) {
            const Tri& ids = result.triangles[t];
            group.fine_error_px = std::max(
                group.fine_error_px,
                vertex_end_distance_px(piece, {mesh_.positions[ids[0]], mesh_.positions[ids[1]],
                                               mesh_.positions[ids[2]]}));
        }
        for (const std::uint32_t c : members) {
            const std::int32_t p = mesh_.clusters[c].producer;
            if (p >= 0) {
                group.fine_error_px =
                    std::max(group.fine_error_px, mesh_.groups[std::size_t(p)].fine_error_px);
            }
        }
        // note: a piece's distance covers its ends', so this only guards the order of the bounds
        group.error_px = std::max(group.error_px, group.fine_error_px);
        const std::int32_t id = std::int32_t(mesh_.groups.size());
        // Where every vertex of the group goes: follow the collapses to the survivor.
        std::unordered_map<std::uint32_t, std::uint32_t> onto;
        for (const auto& [removed, kept] : result.collapses) {
            onto[removed] = kept;
        }
        auto survivor = [&](std::uint32_t v) {
            for (auto it = onto.find(v); it != onto.end(); it = onto.find(v)) {
                v = it->second;
            }
            return v;
        };
        for (const std::uint32_t c : members) {
            MultiresCluster& cluster = mesh_.clusters[c];
            cluster.consumer = id;
            cluster.coarse_vertices.resize(cluster.vertices.size());
            for (std::size_t i = 0; i < cluster.vertices.size(); ++i) {
                cluster.coarse_vertices[i] = survivor(cluster.vertices[i]);
            }
        }
        mesh_.groups.push_back(group);
        const auto index = index_of(result.triangles);
        for (std::vector<Tri>& part : split(result.triangles)) {
            const std::uint32_t c = add_cluster(level, id, part);
            attach_to_cluster(c, part, index, result.piece_triangles);
            mesh_.groups[std::size_t(id)].produced.push_back(c);
            next.push_back(c);
        }
        // Bounds: the produced and consumed clusters and every group below.
        MultiresGroup& g = mesh_.groups[std::size_t(id)];
        g.bounds = mesh_.clusters[g.produced.front()].bounds;
        for (const std::uint32_t c : g.produced) {
            g.bounds = enclose(g.bounds, mesh_.clusters[c].bounds);
        }
        for (const std::uint32_t c : g.consumed) {
            const std::int32_t p = mesh_.clusters[c].producer;
            g.bounds = enclose(
                g.bounds, p >= 0 ? mesh_.groups[std::size_t(p)].bounds : mesh_.clusters[c].bounds);
        }
    }

    const SliceErrorMeter& meter_;
    const MultiresOptions& options_;
    MultiresMesh mesh_;
    /// mesh_.positions in the grid frame (grid_frame_positions): where intersections are decided.
    std::vector<Vec3> exact_;
    std::vector<Box> boxes_;            ///< per cluster, in the grid frame
    std::vector<ContourPiece> pieces_;  ///< the label's contour pieces (attach_pieces)
    /// Per piece: bit 1 when its end a is a full-resolution vertex, bit 2 when b is.
    std::vector<char> piece_vertex_ends_;
    /// Per piece: the full-resolution vertices at its ends a and b (kNoTriangle: not a vertex).
    std::vector<std::array<std::uint32_t, 2>> piece_vertices_;
    /// Largest distance of a full-resolution vertex that ends a piece from the level-0 triangle
    /// the piece is attached to: a floor of every group's fine_error_px.
    double fine_floor_px_ = 0.0;
    /// Per cluster: (triangle index in the cluster, piece) for the pieces attached to it.
    std::vector<std::vector<PieceAttachment>> cluster_pieces_;
    std::vector<std::uint32_t> frontier_;
    double grid_cell_ = 1.0;  ///< cell of the grids over a level's new triangles
};

}  // namespace

MultiresMesh build_multires_mesh(const TriMesh& surface,
                                 const SliceErrorMeter& meter,
                                 double full_resolution_error_px,
                                 const MultiresOptions& options) {
    if (!(options.keep_fraction > 0.0 && options.keep_fraction < 1.0)) {
        throw Error(ErrorCode::InvalidInput, "multiresolution: keep_fraction " +
                                                 std::to_string(options.keep_fraction) +
                                                 ", expected a fraction between 0 and 1");
    }
    if (!(options.first_level_px > 0.0)) {
        throw Error(ErrorCode::InvalidInput, "multiresolution: first_level_px " +
                                                 std::to_string(options.first_level_px) +
                                                 ", expected > 0");
    }
    DagBuilder builder(surface, meter, full_resolution_error_px, options);
    return builder.run();
}

MultiresCut select_cut(const MultiresMesh& mesh,
                       const std::function<bool(const MultiresGroup&)>& refine) {
    // Groups come after their children: one pass makes "refined" closed upwards.
    std::vector<bool> refined(mesh.groups.size(), false);
    for (std::size_t g = 0; g < mesh.groups.size(); ++g) {
        refined[g] = refine(mesh.groups[g]);
    }
    for (std::size_t g = 0; g < mesh.groups.size(); ++g) {
        if (!refined[g]) {
            continue;
        }
        for (const std::uint32_t c : mesh.groups[g].produced) {
            const std::int32_t parent = mesh.clusters[c].consumer;
            if (parent >= 0) {
                refined[std::size_t(parent)] = true;
            }
        }
    }
    MultiresCut cut;
    for (std::uint32_t c = 0; c < mesh.clusters.size(); ++c) {
        const MultiresCluster& cluster = mesh.clusters[c];
        const bool producer_refined =
            cluster.producer >= 0 && refined[std::size_t(cluster.producer)];
        const bool consumer_refined =
            cluster.consumer < 0 || refined[std::size_t(cluster.consumer)];
        if (!producer_refined && consumer_refined) {
            cut.clusters.push_back(c);
            cut.error_px =
                std::max(cut.error_px, cluster.producer < 0
                                           ? mesh.full_resolution_error_px
                                           : mesh.groups[std::size_t(cluster.producer)].error_px);
            if (cluster.producer >= 0) {
                cut.fine_error_px = std::max(
                    cut.fine_error_px, mesh.groups[std::size_t(cluster.producer)].fine_error_px);
            }
        }
    }
    return cut;
}

MultiresCut select_cut_by_error(const MultiresMesh& mesh, double max_error_px) {
    return select_cut(mesh, [&](const MultiresGroup& g) { return g.error_px > max_error_px; });
}

MultiresCut select_cut_at_level(const MultiresMesh& mesh, std::uint32_t level) {
    return select_cut(mesh, [&](const MultiresGroup& g) { return g.level > level; });
}

std::uint32_t level_count(const MultiresMesh& mesh) {
    std::uint32_t top = 0;
    for (const MultiresGroup& g : mesh.groups) {
        top = std::max(top, g.level);
    }
    return top + 1;
}

double screen_space_error_px(const ScreenCamera& camera, const Sphere& bounds, double error) {
    const double distance = norm(bounds.center - camera.position) - bounds.radius;
    if (!(distance > 0.0)) {
        return std::numeric_limits<double>::infinity();
    }
    return error * camera.viewport_height_px / (distance * 2.0 * std::tan(0.5 * camera.fovy_rad));
}

MultiresCut select_cut_for_camera(const MultiresMesh& mesh,
                                  const ScreenCamera& camera,
                                  double max_screen_error_px) {
    return select_cut(mesh, [&](const MultiresGroup& g) {
        return screen_space_error_px(camera, g.bounds, g.error_px) > max_screen_error_px;
    });
}

MultiresCut select_cut_in_region(const MultiresMesh& mesh,
                                 const Sphere& region,
                                 double inside_error_px,
                                 double outside_error_px) {
    return select_cut(mesh, [&](const MultiresGroup& g) {
        const bool inside =
            norm(g.bounds.center - region.center) <= g.bounds.radius + region.radius;
        return g.error_px > (inside ? inside_error_px : outside_error_px);
    });
}

TriMesh cut_mesh(const MultiresMesh& mesh, const MultiresCut& cut) {
    TriMesh out;
    std::unordered_map<std::uint32_t, std::uint32_t> index;
    for (const std::uint32_t c : cut.clusters) {
        const MultiresCluster& cluster = mesh.clusters[c];
        for (const Tri& t : cluster.triangles) {
            Tri o{};
            for (int i = 0; i < 3; ++i) {
                const std::uint32_t v = cluster.vertices[t[i]];
                const auto [it, inserted] = index.emplace(v, std::uint32_t(out.positions.size()));
                if (inserted) {
                    out.positions.push_back(mesh.positions[v]);
                }
                o[i] = it->second;
            }
            out.triangles.push_back(o);
        }
    }
    return out;
}

}  // namespace strata

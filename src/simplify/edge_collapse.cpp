// Error-bounded half-edge collapses (Klein, Schilling, Strasser, section 7; Hoppe, "Progressive
// meshes", SIGGRAPH 1996, for the collapse itself). The cost of a collapse is the error bound of
// the triangles it creates, read from the slice distance fields (slice_error.cpp), so the error
// never accumulates: it is always measured against the original contours.
//
// Topology is kept by the link condition (Dey, Edelsbrunner, Guha, Nekhayev, "Topology preserving
// edge contraction", 1999): for a closed surface, contracting edge uv keeps the surface's topology
// iff the vertices adjacent to both u and v are exactly the two opposite the edge, and neither of
// those is left with fewer than three edges. Embedding is kept by testing every triangle a
// collapse creates against its neighbourhood (a uniform grid over the triangles) exactly.
//
// One file: the tests a collapse must pass (link condition, folds, error cost, intersections)
// are members of one Collapser and read and update the same state inside its priority-queue
// loop (local vertex ids, neighbour lists, the triangle-error cache, the scratch buffers); apart,
// each would export that state.
#include "simplify/edge_collapse.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <queue>
#include <string>
#include <unordered_map>

#include "core/error.h"
#include "mesh/self_intersection.h"
#include "simplify/detail/triangle_grid.h"
#include "simplify/detail/triangle_hash.h"

namespace strata {

namespace {

using detail::boxes_overlap;
using detail::TriangleGrid;
using Tri = std::array<std::uint32_t, 3>;
constexpr std::uint32_t kNone = 0xffffffffu;

struct Candidate {
    double cost = 0.0;
    std::uint32_t u = 0;  ///< local vertex removed
    std::uint32_t v = 0;  ///< local vertex kept
    std::uint32_t stamp = 0;
    /// What `cost` is: a lower bound (the floor), the bound of the new triangles' sections (a
    /// lower bound too), or the collapse's cost (with the contour pieces' distances).
    enum Stage : std::uint8_t { kFloor, kSections, kExact } stage = kFloor;

    /// Min-heap order on (cost, u, v).
    friend bool operator<(const Candidate& a, const Candidate& b) {
        if (a.cost != b.cost) {
            return a.cost > b.cost;
        }
        if (a.u != b.u) {
            return a.u > b.u;
        }
        return a.v > b.v;
    }
};

/// Error bounds of triangles by their vertex ids in order: open addressing with linear probing
/// (a node per entry made allocation the cost of the memo).
class TriangleErrors {
public:
    /// The bound stored for `t`, or null.
    const double* find(const Tri& t) const {
        if (entries_.empty()) {
            return nullptr;
        }
        for (std::size_t i = slot(t);; i = (i + 1) & mask()) {
            const Entry& e = entries_[i];
            // note: element by element; std::array's == calls memcmp here.
            if (e.ids[0] == t[0] && e.ids[1] == t[1] && e.ids[2] == t[2]) {
                return &e.error;
            }
            if (e.ids[0] == kNone) {
                return nullptr;
            }
        }
    }
    /// Stores the bound of `t` (not stored yet; no id may be kNone).
    void insert(const Tri& t, double error) {
        if (2 * (size_ + 1) > entries_.size()) {
            grow();
        }
        std::size_t i = slot(t);
        while (entries_[i].ids[0] != kNone) {
            i = (i + 1) & mask();
        }
        entries_[i] = {t, error};
        ++size_;
    }

private:
    struct Entry {
        Tri ids{kNone, kNone, kNone};
        double error = 0.0;
    };
    std::size_t mask() const { return entries_.size() - 1; }
    std::size_t slot(const Tri& t) const {
        const std::size_t h = detail::TriangleHash{}(t);
        return h & mask();
    }
    void grow() {
        std::vector<Entry> old(std::max<std::size_t>(1024, 2 * entries_.size()));
        old.swap(entries_);
        size_ = 0;
        for (const Entry& e : old) {
            if (e.ids[0] != kNone) {
                insert(e.ids, e.error);
            }
        }
    }
    std::vector<Entry> entries_;  ///< size a power of two (or 0)
    std::size_t size_ = 0;
};

/// A contour piece attached to a triangle, with the bound of its distance to it.
struct Attached {
    std::uint32_t piece = 0;
    double distance = 0.0;
};

Vec3 normal_of(const Vec3& a, const Vec3& b, const Vec3& c) {
    return cross(b - a, c - a);
}

/// Squared distance from p to the bounding box of t (0 inside it): no more than p's squared
/// distance to t.
double box_distance2(const Vec3& p, const std::array<Vec3, 3>& t) {
    auto gap = [&](double c, double a, double b, double d) {
        const double lo = std::min({a, b, d});
        const double hi = std::max({a, b, d});
        return c < lo ? lo - c : (c > hi ? c - hi : 0.0);
    };
    const double gx = gap(p.x, t[0].x, t[1].x, t[2].x);
    const double gy = gap(p.y, t[0].y, t[1].y, t[2].y);
    const double gz = gap(p.z, t[0].z, t[1].z, t[2].z);
    return gx * gx + gy * gy + gz * gz;
}

/// True when piece_distance_px(piece, t, ...) is certainly at least `bound`: the piece's first
/// end is farther than that from t's box, and that distance bounds its own from below.
/// note: a margin far above the rounding of either distance, so the filter only skips reads
/// whose result could not have been below `bound`.
bool certainly_not_nearer(const ContourPiece& piece, const std::array<Vec3, 3>& t, double bound) {
    const double margin = bound * (1.0 + 1e-9) + 1e-9;
    return margin < std::numeric_limits<double>::infinity() &&
           box_distance2(piece.a, t) > margin * margin;
}

/// Relative error allowed for the float filter ahead of the exact intersection tests (Shewchuk's
/// static bounds for the same orientation determinants are below 1e-15).
constexpr double kFilterError = 1e-12;

/// A triangle's plane for the float filter: n . (p - a) is the orientation of p, and its rounding
/// error stays below kFilterError * scale . |p - a| (`scale`: the permanents of n's minors).
struct FilterPlane {
    Vec3 a;
    Vec3 n;
    Vec3 scale;
    bool proper = false;  ///< certainly not degenerate (a component of n certainly nonzero)
};

FilterPlane filter_plane(const std::array<Vec3, 3>& t) {
    const Vec3 e1 = t[1] - t[0];
    const Vec3 e2 = t[2] - t[0];
    FilterPlane f;
    f.a = t[0];
    f.n = cross(e1, e2);
    f.scale = {std::abs(e1.y * e2.z) + std::abs(e1.z * e2.y),
               std::abs(e1.z * e2.x) + std::abs(e1.x * e2.z),
               std::abs(e1.x * e2.y) + std::abs(e1.y * e2.x)};
    f.proper = std::abs(f.n.x) > kFilterError * f.scale.x ||
               std::abs(f.n.y) > kFilterError * f.scale.y ||
               std::abs(f.n.z) > kFilterError * f.scale.z;
    return f;
}

/// Whether the corners of t that the plane's triangle (ids `plane_ids`) lacks all lie certainly
/// on one side of the plane: then t meets that triangle at most in the corners they share.
bool certainly_beside(const FilterPlane& f,
                      const Tri& plane_ids,
                      const std::array<Vec3, 3>& t,
                      const Tri& ids) {
    double side = 0.0;
    for (int k = 0; k < 3; ++k) {
        if (ids[k] == plane_ids[0] || ids[k] == plane_ids[1] || ids[k] == plane_ids[2]) {
            continue;
        }
        const Vec3 w = t[k] - f.a;
        const double d = dot(f.n, w);
        const double bound = kFilterError * (f.scale.x * std::abs(w.x) + f.scale.y * std::abs(w.y) +
                                             f.scale.z * std::abs(w.z));
        if (!(std::abs(d) > bound) || d * side < 0.0) {
            return false;
        }
        side = d;
    }
    return side != 0.0;
}

/// True when triangles a and b (vertex ids) certainly do not intersect beyond the corners and
/// edge they share, which is what triangles_intersect decides exactly; false: not certain.
/// note: a float filter with a generous error bound, so that most neighbours (which share a
/// corner and lie on one side of each other) skip the exact predicates.
bool certainly_apart(const std::array<Vec3, 3>& a,
                     const FilterPlane& fa,
                     const Tri& ia,
                     const std::array<Vec3, 3>& b,
                     const Tri& ib) {
    if (!fa.proper) {
        return false;
    }
    const FilterPlane fb = filter_plane(b);
    return fb.proper && (certainly_beside(fa, ia, b, ib) || certainly_beside(fb, ib, a, ia));
}

class Collapser {
public:
    Collapser(const CollapseProblem& problem,
              const SliceErrorMeter& meter,
              const CollapseOptions& options)
        : positions_(*problem.positions),
          exact_(problem.exact_positions != nullptr ? *problem.exact_positions
                                                    : *problem.positions),
          pieces_(problem.pieces),
          meter_(meter),
          options_(options),
          cache_(options.error_floor_px, options.max_error_px),
          grid_(grid_cell(problem)) {
        if (exact_.size() != positions_.size()) {
            throw Error(ErrorCode::InvalidInput, "edge collapse: " + std::to_string(exact_.size()) +
                                                     " exact positions for " +
                                                     std::to_string(positions_.size()) +
                                                     " vertices");
        }
        // Local vertex ids: the piece's vertices in increasing global id.
        for (const Tri& t : problem.triangles) {
            for (const std::uint32_t g : t) {
                if (g >= positions_.size()) {
                    throw Error(ErrorCode::InvalidInput,
                                "edge collapse: vertex " + std::to_string(g) + " out of range (" +
                                    std::to_string(positions_.size()) + " vertices)");
                }
                global_.push_back(g);
            }
        }
        std::sort(global_.begin(), global_.end());
        global_.erase(std::unique(global_.begin(), global_.end()), global_.end());
        const std::size_t n = global_.size();
        vertex_triangles_.resize(n);
        locked_.assign(n, false);
        stamp_.assign(n, 0);
        pending_.assign(n, false);
        neighbours_.resize(n);
        neighbours_stamp_.assign(n, kNone);
        for (const std::uint32_t g : problem.locked) {
            const std::uint32_t v = local(g);
            if (v != kNone) {
                locked_[v] = true;
            }
        }
        triangles_.reserve(problem.triangles.size());
        for (std::size_t i = 0; i < problem.triangles.size(); ++i) {
            const Tri& t = problem.triangles[i];
            const Tri lt{local(t[0]), local(t[1]), local(t[2])};
            const std::uint32_t id = static_cast<std::uint32_t>(triangles_.size());
            triangles_.push_back(lt);
            alive_.push_back(true);
            error_.push_back(i < problem.triangle_error_px.size() ? problem.triangle_error_px[i]
                                                                  : 0.0);
            for (const std::uint32_t v : lt) {
                vertex_triangles_[v].push_back(id);
            }
            grid_.insert(id, exact_corners(id));
        }
        alive_count_ = triangles_.size();
        triangle_pieces_.resize(triangles_.size());
        if (!problem.piece_triangles.empty() && problem.pieces == nullptr) {
            throw Error(ErrorCode::InvalidInput, "edge collapse: piece attachments without pieces");
        }
        for (const auto& [t, piece] : problem.piece_triangles) {
            if (t >= triangles_.size() || piece >= problem.pieces->size()) {
                throw Error(ErrorCode::InvalidInput,
                            "edge collapse: contour piece " + std::to_string(piece) +
                                " attached to triangle " + std::to_string(t) + " (" +
                                std::to_string(triangles_.size()) + " triangles, " +
                                std::to_string(problem.pieces->size()) + " pieces)");
            }
            triangle_pieces_[t].push_back(
                {piece, piece_distance_px((*problem.pieces)[piece], corners(t))});
        }
        obstacles_ = problem.obstacles;
        for (std::size_t i = 0; i < obstacles_.size(); ++i) {
            for (const std::uint32_t g : obstacles_[i]) {
                if (g >= positions_.size()) {
                    throw Error(ErrorCode::InvalidInput, "edge collapse: obstacle vertex " +
                                                             std::to_string(g) + " out of range");
                }
            }
            grid_.insert(kObstacleBit | std::uint32_t(i), obstacle_corners(std::uint32_t(i)));
        }
        check_edges();
    }

    CollapseResult run() {
        CollapseResult result;
        for (std::uint32_t u = 0; u < global_.size(); ++u) {
            push_candidates(u);
        }
        while (alive_count_ > options_.target_triangles) {
            if (!floor_vertices_.empty()) {
                // The candidates of u at the floor, in (u, v) order: every queued candidate costs
                // more than the floor, and none is added before one of them collapses (u goes).
                const std::uint32_t u = floor_vertices_.top();
                floor_vertices_.pop();
                pending_[u] = false;
                if (vertex_triangles_[u].empty()) {
                    continue;
                }
                if (options_.error_floor_px > options_.max_error_px) {
                    break;
                }
                const std::vector<std::uint32_t>& nu = neighbours(u);
                for (std::size_t i = 0; i < nu.size(); ++i) {
                    const std::uint32_t v = nu[i];
                    const Candidate c{options_.error_floor_px, u, v, stamp_[u], Candidate::kFloor};
                    if (try_collapse(c, i + 1 < nu.size())) {
                        result.collapses.emplace_back(global_[u], global_[v]);
                        break;  // u is gone, and with it nu's entry
                    }
                }
                continue;
            }
            if (queue_.empty()) {
                break;
            }
            const Candidate c = queue_.top();
            queue_.pop();
            if (c.stamp != stamp_[c.u] || vertex_triangles_[c.u].empty()) {
                continue;  // stale: u's star changed since
            }
            if (c.cost > options_.max_error_px) {
                break;
            }
            if (try_collapse(c, false)) {
                result.collapses.emplace_back(global_[c.u], global_[c.v]);
            }
        }
        for (std::size_t t = 0; t < triangles_.size(); ++t) {
            if (!alive_[t]) {
                continue;
            }
            const Tri& lt = triangles_[t];
            std::vector<Attached>& pieces = triangle_pieces_[t];
            std::sort(pieces.begin(), pieces.end(),
                      [](const Attached& a, const Attached& b) { return a.piece < b.piece; });
            for (const Attached& a : pieces) {
                result.piece_triangles.emplace_back(std::uint32_t(result.triangles.size()),
                                                    a.piece);
            }
            result.triangles.push_back({global_[lt[0]], global_[lt[1]], global_[lt[2]]});
            result.triangle_error_px.push_back(error_[t]);
            result.max_error_px = std::max(result.max_error_px, error_[t]);
        }
        return result;
    }

private:
    static constexpr std::uint32_t kObstacleBit = 0x80000000u;

    static double grid_cell(const CollapseProblem& problem) {
        // About twice the mean edge length (in the exact frame, where the grid lies): a triangle
        // covers a few cells.
        const std::vector<Vec3>& positions =
            problem.exact_positions != nullptr ? *problem.exact_positions : *problem.positions;
        double sum = 0.0;
        std::size_t count = 0;
        for (const Tri& t : problem.triangles) {
            for (int i = 0; i < 3; ++i) {
                const std::uint32_t a = t[i], b = t[(i + 1) % 3];
                if (a < positions.size() && b < positions.size()) {
                    sum += norm(positions[a] - positions[b]);
                    ++count;
                }
            }
        }
        const double mean = count > 0 ? sum / double(count) : 1.0;
        return std::max(2.0 * mean, 1e-3);
    }

    std::uint32_t local(std::uint32_t g) const {
        const auto it = std::lower_bound(global_.begin(), global_.end(), g);
        return it != global_.end() && *it == g ? std::uint32_t(it - global_.begin()) : kNone;
    }
    const Vec3& position(std::uint32_t v) const { return positions_[global_[v]]; }
    std::array<Vec3, 3> corners(std::uint32_t t) const {
        const Tri& lt = triangles_[t];
        return {position(lt[0]), position(lt[1]), position(lt[2])};
    }
    const Vec3& exact(std::uint32_t v) const { return exact_[global_[v]]; }
    std::array<Vec3, 3> exact_corners(std::uint32_t t) const {
        const Tri& lt = triangles_[t];
        return {exact(lt[0]), exact(lt[1]), exact(lt[2])};
    }
    /// Obstacle i in the exact frame.
    std::array<Vec3, 3> obstacle_corners(std::uint32_t i) const {
        const Tri& g = obstacles_[i];
        return {exact_[g[0]], exact_[g[1]], exact_[g[2]]};
    }

    /// Every edge of the piece in at most two triangles, once in each direction.
    void check_edges() const {
        std::vector<std::pair<std::uint64_t, std::uint32_t>> edges;
        edges.reserve(triangles_.size() * 3);
        for (std::uint32_t t = 0; t < triangles_.size(); ++t) {
            const Tri& lt = triangles_[t];
            for (int i = 0; i < 3; ++i) {
                edges.emplace_back(std::uint64_t(lt[i]) << 32 | lt[(i + 1) % 3], t);
            }
        }
        std::sort(edges.begin(), edges.end());
        for (std::size_t i = 1; i < edges.size(); ++i) {
            if (edges[i].first == edges[i - 1].first) {
                throw Error(
                    ErrorCode::InvalidInput,
                    "edge collapse: edge (" + std::to_string(global_[edges[i].first >> 32]) + ", " +
                        std::to_string(global_[edges[i].first & 0xffffffffu]) +
                        ") is used twice in the same direction (triangles " +
                        std::to_string(edges[i - 1].second) + " and " +
                        std::to_string(edges[i].second) + "): expected an oriented manifold piece");
            }
        }
    }

    /// Sorted distinct neighbours of v.
    /// note: kept until v's star changes (its stamp moves on): the candidates of one vertex are
    /// popped together and each asks for the same lists.
    const std::vector<std::uint32_t>& neighbours(std::uint32_t v) const {
        std::vector<std::uint32_t>& result = neighbours_[v];
        if (neighbours_stamp_[v] == stamp_[v]) {
            return result;
        }
        result.clear();
        for (const std::uint32_t t : vertex_triangles_[v]) {
            for (const std::uint32_t w : triangles_[t]) {
                if (w != v) {
                    result.push_back(w);
                }
            }
        }
        std::sort(result.begin(), result.end());
        result.erase(std::unique(result.begin(), result.end()), result.end());
        neighbours_stamp_[v] = stamp_[v];
        return result;
    }

    bool contains(std::uint32_t t, std::uint32_t v) const {
        const Tri& lt = triangles_[t];
        return lt[0] == v || lt[1] == v || lt[2] == v;
    }

    /// Triangle t with u replaced by v, with corners from `frame` (positions_ or exact_).
    std::array<Vec3, 3> moved_in(const std::vector<Vec3>& frame,
                                 std::uint32_t t,
                                 std::uint32_t u,
                                 std::uint32_t v) const {
        const Tri& lt = triangles_[t];
        std::array<Vec3, 3> c{};
        for (int i = 0; i < 3; ++i) {
            c[i] = frame[global_[lt[i] == u ? v : lt[i]]];
        }
        return c;
    }
    std::array<Vec3, 3> moved(std::uint32_t t, std::uint32_t u, std::uint32_t v) const {
        return moved_in(positions_, t, u, v);
    }
    /// The same in the exact frame.
    std::array<Vec3, 3> exact_moved(std::uint32_t t, std::uint32_t u, std::uint32_t v) const {
        return moved_in(exact_, t, u, v);
    }

    /// Local ids of triangle t with u replaced by v.
    Tri local_moved(std::uint32_t t, std::uint32_t u, std::uint32_t v) const {
        Tri ids = triangles_[t];
        for (std::uint32_t& w : ids) {
            w = w == u ? v : w;
        }
        return ids;
    }

    /// Global ids of triangle t with u replaced by v.
    Tri ids_moved(std::uint32_t t, std::uint32_t u, std::uint32_t v) const {
        const Tri& lt = triangles_[t];
        Tri g{};
        for (int i = 0; i < 3; ++i) {
            g[i] = global_[lt[i] == u ? v : lt[i]];
        }
        return g;
    }

    /// Link condition, degrees, locked edges and the 2 triangles of edge uv.
    bool topology_allows(std::uint32_t u, std::uint32_t v) const {
        if (locked_[u]) {
            return false;
        }
        std::array<std::uint32_t, 2> opposite{};
        int found = 0;
        for (const std::uint32_t t : vertex_triangles_[u]) {
            if (contains(t, v)) {
                for (const std::uint32_t w : triangles_[t]) {
                    if (w != u && w != v) {
                        if (found == 2) {
                            return false;  // not a manifold edge
                        }
                        opposite[found++] = w;
                    }
                }
            }
        }
        if (found != 2 || opposite[0] == opposite[1]) {
            return false;  // not an interior manifold edge of the piece
        }
        const std::vector<std::uint32_t>& nu = neighbours(u);
        const std::vector<std::uint32_t>& nv = neighbours(v);
        std::sort(opposite.begin(), opposite.end());
        // Link condition: the common neighbours of u and v are exactly the two opposite vertices.
        std::size_t common = 0;
        for (std::size_t i = 0, j = 0; i < nu.size() && j < nv.size();) {
            if (nu[i] < nv[j]) {
                ++i;
            } else if (nv[j] < nu[i]) {
                ++j;
            } else {
                if (common == 2 || nu[i] != opposite[common]) {
                    return false;
                }
                ++common;
                ++i;
                ++j;
            }
        }
        if (common != 2) {
            return false;
        }
        for (const std::uint32_t w : opposite) {
            // note: a piece's star of w is at most w's degree, so this errs on the safe side.
            if (vertex_triangles_[w].size() <= 3) {
                return false;
            }
        }
        if (nu.size() + nv.size() - 4 < 3) {
            return false;
        }
        if (locked_[v]) {
            // note: an edge between two locked vertices may exist outside the piece in some cut;
            // creating it here could double it there.
            for (const std::uint32_t w : nu) {
                if (w != v && locked_[w] && !std::binary_search(nv.begin(), nv.end(), w)) {
                    return false;
                }
            }
        }
        return true;
    }

    /// Number of folds (edges whose two triangles turn by more than 90 degrees: normals pointing
    /// apart) among the edges of u's star, before collapsing u onto v or after (the edges of the
    /// changed triangles). Edges with a triangle outside the piece are not counted.
    /// note: each edge of the star (or of its moved triangles, M) is met once; its second
    /// triangle is another triangle of M or one beside the star (without u, unchanged by the
    /// collapse) around its first end. The piece is an oriented manifold (check_edges, and the
    /// link condition keeps it one), so an edge has at most two triangles.
    /// Counting stops above `limit` (the count returned is then limit + 1). `moved_normals`: the
    /// normals of the moved triangles in star order, when the caller has them (after only).
    std::size_t folds(std::uint32_t u,
                      std::uint32_t v,
                      bool after,
                      std::size_t limit = std::numeric_limits<std::size_t>::max(),
                      const std::vector<Vec3>* moved_normals = nullptr) const {
        std::vector<FoldTriangle>& star = fold_star_;
        star.clear();
        refresh_star(u);
        const std::vector<std::uint32_t>& triangles = vertex_triangles_[u];
        for (std::size_t i = 0; i < triangles.size(); ++i) {
            const std::uint32_t t = triangles[i];
            if (!after) {
                star.push_back({triangles_[t], star_cache_.normals[i]});
                continue;
            }
            if (contains(t, v)) {
                continue;  // removed by the collapse
            }
            if (moved_normals != nullptr) {
                star.push_back({local_moved(t, u, v), (*moved_normals)[star.size()]});
                continue;
            }
            const std::array<Vec3, 3> c = moved(t, u, v);
            star.push_back({local_moved(t, u, v), normal_of(c[0], c[1], c[2])});
        }
        auto has = [](const Tri& ids, std::uint32_t w) {
            return ids[0] == w || ids[1] == w || ids[2] == w;
        };
        std::size_t count = 0;
        for (std::size_t i = 0; i < star.size(); ++i) {
            const Tri& ids = star[i].ids;
            for (int k = 0; k < 3; ++k) {
                const std::uint32_t a = ids[k], b = ids[(k + 1) % 3];
                bool earlier = false;
                for (std::size_t j = 0; j < i && !earlier; ++j) {
                    earlier = has(star[j].ids, a) && has(star[j].ids, b);
                }
                if (earlier) {
                    continue;  // met with an earlier triangle of M
                }
                const Vec3* other = nullptr;
                for (std::size_t j = i + 1; j < star.size() && other == nullptr; ++j) {
                    if (has(star[j].ids, a) && has(star[j].ids, b)) {
                        other = &star[j].normal;
                    }
                }
                Vec3 beside;
                if (other == nullptr && beside_normal(u, a, b, beside)) {
                    other = &beside;
                }
                if (other != nullptr && dot(star[i].normal, *other) < 0.0 && ++count > limit) {
                    return count;
                }
            }
        }
        return count;
    }

    /// The star of u as it is now (until the next collapse): each triangle's normal and its
    /// length, and the triangles beside it met so far (see beside_normal).
    /// note: every candidate of u reads the same; cost() and folds() ask for them once per
    /// candidate.
    void refresh_star(std::uint32_t u) const {
        StarCache& s = star_cache_;
        if (s.vertex == u && s.collapses == collapses_) {
            return;
        }
        s.vertex = u;
        s.collapses = collapses_;
        s.normals.clear();
        s.lengths.clear();
        s.beside.clear();
        for (const std::uint32_t t : vertex_triangles_[u]) {
            const std::array<Vec3, 3> c = corners(t);
            s.normals.push_back(normal_of(c[0], c[1], c[2]));
            s.lengths.push_back(norm(s.normals.back()));
        }
    }

    /// The normal of the first triangle of a's star that has edge ab and not u, into `normal`;
    /// false when there is none. Read once per (a, b) between two collapses.
    bool beside_normal(std::uint32_t u, std::uint32_t a, std::uint32_t b, Vec3& normal) const {
        refresh_star(u);
        for (const Beside& e : star_cache_.beside) {
            if (e.a == a && e.b == b) {
                normal = e.normal;
                return e.found;
            }
        }
        Beside e{a, b, false, {}};
        for (const std::uint32_t t : vertex_triangles_[a]) {
            const Tri& o = triangles_[t];
            const bool has_u = o[0] == u || o[1] == u || o[2] == u;
            const bool has_b = o[0] == b || o[1] == b || o[2] == b;
            if (!has_u && has_b) {
                const std::array<Vec3, 3> c = corners(t);
                e.normal = normal_of(c[0], c[1], c[2]);
                e.found = true;
                break;
            }
        }
        star_cache_.beside.push_back(e);
        normal = e.normal;
        return e.found;
    }

    /// True when collapsing u onto v adds a fold.
    /// note: the count before does not depend on v and nothing changes between two collapses,
    /// so the candidates of one vertex count it once.
    bool adds_fold(std::uint32_t u,
                   std::uint32_t v,
                   const std::vector<Vec3>* moved_normals = nullptr) const {
        if (folds_before_.vertex != u || folds_before_.collapses != collapses_) {
            folds_before_ = {u, collapses_, folds(u, v, false)};
        }
        return folds(u, v, true, folds_before_.count, moved_normals) > folds_before_.count;
    }

    /// Cost of collapsing u onto v (max error bound of the changed triangles, with the distances
    /// of the contour pieces they take when `pieces`), or nothing when the collapse folds or
    /// degenerates a triangle. `sections`: the bound of the sections, when an earlier
    /// cost(u, v, false) read it and u's star has not changed since (only the pieces are read
    /// then: the triangles' bounds are what it read).
    std::optional<double> cost(std::uint32_t u,
                               std::uint32_t v,
                               bool pieces,
                               const double* sections = nullptr) const {
        double reached = options_.error_floor_px;
        std::vector<std::array<Vec3, 3>>& moved_corners = moved_corners_;
        moved_corners.clear();
        std::vector<std::uint32_t>& own = moved_index_;  // per star triangle, kNone: removed
        own.clear();
        std::vector<Vec3>& moved_normals = moved_normals_;
        moved_normals.clear();
        const std::vector<std::uint32_t>& star = vertex_triangles_[u];
        refresh_star(u);
        // note: every fold is ruled out before any error is read (folds are common, and the
        // errors are the expensive part).
        for (std::size_t i = 0; i < star.size(); ++i) {
            const std::uint32_t t = star[i];
            if (contains(t, v)) {
                own.push_back(kNone);
                continue;
            }
            own.push_back(std::uint32_t(moved_corners.size()));
            const std::array<Vec3, 3> after = moved(t, u, v);
            const Vec3& n0 = star_cache_.normals[i];
            const Vec3 n1 = normal_of(after[0], after[1], after[2]);
            const double l0 = star_cache_.lengths[i], l1 = norm(n1);
            if (!(l1 > 0.0) || !(l0 > 0.0)) {
                return std::nullopt;
            }
            if (dot(n0, n1) < std::max(options_.min_normal_cos, 1e-12) * l0 * l1) {
                return std::nullopt;
            }
            moved_corners.push_back(after);
            moved_normals.push_back(n1);
        }
        if (moved_corners.empty()) {
            return std::nullopt;
        }
        // A fold looks like what it is whatever the slice sections say: a collapse may not add
        // one.
        if (adds_fold(u, v, &moved_normals)) {
            return std::nullopt;
        }
        if (sections != nullptr) {
            return pieces_cost(u, *sections);
        }

        for (std::size_t i = 0; i < star.size(); ++i) {
            if (own[i] == kNone) {
                continue;
            }
            reached = std::max(reached, moved_error(star[i], u, v, moved_corners[own[i]]));
            if (reached > options_.max_error_px) {
                return std::nullopt;
            }
        }
        if (!pieces) {
            return reached;
        }
        return pieces_cost(u, reached);
    }

    /// The rest of cost(u, v, true) after cost(u, v, false) returned `reached` (its scratch,
    /// moved_corners_ and moved_index_, still holding u's star moved onto v).
    std::optional<double> pieces_cost(std::uint32_t u, double reached) const {
        const std::vector<std::array<Vec3, 3>>& moved_corners = moved_corners_;
        const std::vector<std::uint32_t>& own = moved_index_;
        const std::vector<std::uint32_t>& star = vertex_triangles_[u];
        // The contour pieces of u's star move to the nearest changed triangle (their own first).
        // note: only the largest distance counts, so a piece within `reached` of some triangle
        // is done.
        for (std::size_t i = 0; i < star.size(); ++i) {
            for (const Attached& a : triangle_pieces_[star[i]]) {
                const ContourPiece& piece = (*pieces_)[a.piece];
                double best = std::numeric_limits<double>::infinity();
                if (own[i] != kNone) {
                    best = piece_distance_px(piece, moved_corners[own[i]], best, reached);
                }
                for (std::uint32_t m = 0; m < moved_corners.size() && best > reached; ++m) {
                    if (m != own[i] && !certainly_not_nearer(piece, moved_corners[m], best)) {
                        best = std::min(best,
                                        piece_distance_px(piece, moved_corners[m], best, reached));
                    }
                }
                reached = std::max(reached, best);
                if (reached > options_.max_error_px) {
                    return std::nullopt;
                }
            }
        }
        return reached;
    }

    /// Error bound of triangle t with u replaced by v (corners `after`), read once per triangle;
    /// above max_error_px only known to exceed it (the read stops there: such a collapse is
    /// refused whatever the rest).
    /// note: positions never move and the section cache only grows, so a triangle's bound never
    /// changes: the collapses around a vertex meet the same new triangles again and again.
    double moved_error(std::uint32_t t,
                       std::uint32_t u,
                       std::uint32_t v,
                       const std::array<Vec3, 3>& after) const {
        const Tri ids = ids_moved(t, u, v);
        if (const double* known = triangle_errors_.find(ids)) {
            return *known;
        }
        const double error = meter_.triangle_error_px(after, ids, cache_);
        triangle_errors_.insert(ids, error);
        return error;
    }

    /// The least cost a waiting candidate may have (floor candidates first: `more_floor` when the
    /// caller holds more of them), or nothing when none waits.
    std::optional<double> waiting_cost(bool more_floor) const {
        if (more_floor || !floor_vertices_.empty()) {
            return options_.error_floor_px;
        }
        if (queue_.empty()) {
            return std::nullopt;
        }
        return queue_.top().cost;
    }

    /// Collapses c.u onto c.v if allowed and nothing waiting can be cheaper (lazy evaluation: the
    /// cost is read only now, the sections first, then the contour pieces; a candidate that may
    /// lose to a waiting one is queued again with what is known of its cost). True: collapsed.
    bool try_collapse(const Candidate& c, bool more_floor) {
        if (!topology_allows(c.u, c.v)) {
            return false;
        }
        if (c.stage != Candidate::kExact) {
            const bool sections_known = c.stage == Candidate::kSections;
            const std::optional<double> known =
                sections_known ? std::optional<double>(c.cost) : cost(c.u, c.v, false);
            if (!known || *known > options_.max_error_px) {
                return false;
            }
            const std::optional<double> waiting = waiting_cost(more_floor);
            if (!sections_known && waiting && *known > *waiting) {
                queue_.push({*known, c.u, c.v, c.stamp, Candidate::kSections});
                return false;
            }
            // note: straight after cost(c.u, c.v, false) nothing has changed: only the pieces
            // remain to be read
            const std::optional<double> exact =
                sections_known ? cost(c.u, c.v, true, &c.cost) : pieces_cost(c.u, *known);
            if (!exact) {
                return false;
            }
            if (waiting && *exact > *waiting) {
                queue_.push({*exact, c.u, c.v, c.stamp, Candidate::kExact});
                return false;
            }
            if (*exact > options_.max_error_px) {
                return false;
            }
        }
        // note: folds also depend on the triangles across u's link, which can change without
        // u's stamp moving, so a candidate whose cost was read earlier is checked again
        if (c.stage == Candidate::kExact && adds_fold(c.u, c.v)) {
            return false;
        }
        if (creates_intersection(c.u, c.v)) {
            return false;
        }
        apply(c.u, c.v);
        return true;
    }

    void push_candidates(std::uint32_t u) {
        if (locked_[u] || vertex_triangles_[u].empty()) {
            return;
        }
        // note: every collapse costs at least the floor; the real costs are read when u is
        // popped, from its star then (one entry per vertex: its candidates wait together).
        if (!pending_[u]) {
            pending_[u] = true;
            floor_vertices_.push(u);
        }
    }

    bool creates_intersection(std::uint32_t u, std::uint32_t v) {
        std::vector<std::uint32_t> changed;
        for (const std::uint32_t t : vertex_triangles_[u]) {
            if (!contains(t, v)) {
                changed.push_back(t);
            }
        }
        auto ids_after = [&](std::uint32_t t) { return ids_moved(t, u, v); };
        if (seen_.size() < triangles_.size() + obstacles_.size()) {
            seen_.resize(triangles_.size() + obstacles_.size(), 0);
        }
        for (std::size_t a = 0; a < changed.size(); ++a) {
            ++query_;  // each new triangle meets every neighbour once
            const std::array<Vec3, 3> ta = exact_moved(changed[a], u, v);
            const Tri ia = ids_after(changed[a]);
            const FilterPlane fa = filter_plane(ta);
            if (!fa.proper && triangle_is_degenerate(ta)) {
                return true;  // note: a zero-area triangle cannot be certified free either
            }
            auto intersects = [&](const std::array<Vec3, 3>& tb, const Tri& ib) {
                return !certainly_apart(ta, fa, ia, tb, ib) && triangles_intersect(ta, ia, tb, ib);
            };
            // the other new triangles
            for (std::size_t b = a + 1; b < changed.size(); ++b) {
                if (intersects(exact_moved(changed[b], u, v), ids_after(changed[b]))) {
                    return true;
                }
            }
            bool hit = false;
            grid_.query(ta, [&](std::uint32_t id) {
                if (hit) {
                    return;
                }
                const bool obstacle = (id & kObstacleBit) != 0;
                const std::uint32_t index = id & ~kObstacleBit;
                const std::size_t slot = obstacle ? triangles_.size() + index : index;
                if (seen_[slot] == query_) {
                    return;
                }
                seen_[slot] = query_;
                if (obstacle) {
                    const std::array<Vec3, 3> tb = obstacle_corners(index);
                    hit = boxes_overlap(ta, tb) && intersects(tb, obstacles_[index]);
                    return;
                }
                if (!alive_[index] || contains(index, u)) {
                    return;  // removed or replaced by this collapse
                }
                const Tri& lt = triangles_[index];
                const std::array<Vec3, 3> tb = exact_corners(index);
                hit = boxes_overlap(ta, tb) &&
                      intersects(tb, {global_[lt[0]], global_[lt[1]], global_[lt[2]]});
            });
            if (hit) {
                return true;
            }
        }
        return false;
    }

    void apply(std::uint32_t u, std::uint32_t v) {
        ++collapses_;
        // note: only the stars of u's neighbours change (positions never move), so only their
        // candidates need new costs.
        const std::vector<std::uint32_t> touched = neighbours(u);
        std::vector<std::uint32_t> star = vertex_triangles_[u];
        std::vector<std::pair<Attached, std::uint32_t>> moving;  // (piece, its triangle)
        for (const std::uint32_t t : star) {
            for (const Attached& a : triangle_pieces_[t]) {
                moving.emplace_back(a, t);
            }
            triangle_pieces_[t].clear();
        }
        std::vector<std::uint32_t> moved_ids;
        for (const std::uint32_t t : star) {
            if (contains(t, v)) {
                alive_[t] = false;
                --alive_count_;
                for (const std::uint32_t w : triangles_[t]) {
                    if (w != u) {
                        auto& list = vertex_triangles_[w];
                        list.erase(std::find(list.begin(), list.end(), t));
                    }
                }
                continue;
            }
            const std::array<Vec3, 3> after = moved(t, u, v);
            error_[t] = moved_error(t, u, v, after);
            for (std::uint32_t& w : triangles_[t]) {
                if (w == u) {
                    w = v;
                }
            }
            vertex_triangles_[v].push_back(t);
            grid_.insert(t, exact_corners(t));
            moved_ids.push_back(t);
        }
        // Each piece stays on its triangle if that is no farther than before, else moves to the
        // nearest changed triangle.
        for (const auto& [a, from] : moving) {
            const ContourPiece& piece = (*pieces_)[a.piece];
            double best = std::numeric_limits<double>::infinity();
            std::uint32_t to = moved_ids.front();
            const double floor = options_.error_floor_px;
            if (alive_[from]) {
                best = piece_distance_px(piece, corners(from), best, floor);
                to = from;
            }
            if (best > std::max(a.distance, floor)) {
                for (const std::uint32_t t : moved_ids) {
                    const std::array<Vec3, 3> c = corners(t);
                    if (certainly_not_nearer(piece, c, best)) {
                        continue;
                    }
                    const double d = piece_distance_px(piece, c, best, floor);
                    if (d < best) {
                        best = d;
                        to = t;
                    }
                }
            }
            triangle_pieces_[to].push_back({a.piece, best});
            error_[to] = std::max(error_[to], best);
        }
        vertex_triangles_[u].clear();
        ++stamp_[u];
        for (const std::uint32_t w : touched) {
            ++stamp_[w];
        }
        for (const std::uint32_t w : touched) {
            push_candidates(w);
        }
    }

    const std::vector<Vec3>& positions_;
    const std::vector<Vec3>& exact_;  ///< positions for the predicates
    const std::vector<ContourPiece>* pieces_;
    const SliceErrorMeter& meter_;
    const CollapseOptions& options_;
    mutable SectionCache cache_;
    /// Bound of every triangle measured so far, by its global ids in order.
    mutable TriangleErrors triangle_errors_;
    TriangleGrid grid_;
    std::vector<std::uint32_t> global_;  ///< local vertex -> global id
    std::vector<bool> locked_;
    std::vector<std::uint32_t> stamp_;
    std::vector<std::vector<std::uint32_t>> vertex_triangles_;
    std::vector<Tri> triangles_;  ///< local ids
    std::vector<bool> alive_;
    std::vector<double> error_;
    /// Per triangle: the contour pieces attached to it (ids into *pieces_), whose distance its
    /// error bound covers.
    std::vector<std::vector<Attached>> triangle_pieces_;
    mutable std::vector<std::array<Vec3, 3>> moved_corners_;  ///< scratch of cost()
    mutable std::vector<std::uint32_t> moved_index_;          ///< scratch of cost()
    mutable std::vector<Vec3> moved_normals_;                 ///< scratch of cost()
    /// A triangle of the star in folds(), and its normal.
    struct FoldTriangle {
        Tri ids;
        Vec3 normal;
    };
    mutable std::vector<FoldTriangle> fold_star_;  ///< scratch of folds()
    /// The triangle beside edge ab of u's star (see beside_normal).
    struct Beside {
        std::uint32_t a = kNone;
        std::uint32_t b = kNone;
        bool found = false;
        Vec3 normal;
    };
    /// What refresh_star() keeps of `vertex`'s star, valid while `collapses` is collapses_.
    struct StarCache {
        std::uint32_t vertex = kNone;
        std::size_t collapses = 0;
        std::vector<Vec3> normals;    ///< per star triangle, in vertex_triangles_ order
        std::vector<double> lengths;  ///< their lengths
        std::vector<Beside> beside;
    };
    mutable StarCache star_cache_;
    /// Collapses applied so far, and the fold count before collapsing `vertex` at `collapses`.
    std::size_t collapses_ = 0;
    struct FoldsBefore {
        std::uint32_t vertex = kNone;
        std::size_t collapses = 0;
        std::size_t count = 0;
    };
    mutable FoldsBefore folds_before_;  ///< see adds_fold()
    std::size_t alive_count_ = 0;
    std::vector<Tri> obstacles_;  ///< global ids
    /// Candidates whose cost is read: more than the floor each.
    std::priority_queue<Candidate> queue_;
    /// Vertices whose candidates are all at the floor (smallest id first), and which are in it.
    std::priority_queue<std::uint32_t, std::vector<std::uint32_t>, std::greater<>> floor_vertices_;
    std::vector<bool> pending_;
    mutable std::vector<std::vector<std::uint32_t>> neighbours_;  ///< see neighbours()
    mutable std::vector<std::uint32_t> neighbours_stamp_;         ///< stamp of each list
    std::vector<std::uint32_t> seen_;
    std::uint32_t query_ = 0;
};

}  // namespace

CollapseResult collapse_edges(const CollapseProblem& problem,
                              const SliceErrorMeter& meter,
                              const CollapseOptions& options) {
    if (problem.positions == nullptr) {
        throw Error(ErrorCode::Internal, "edge collapse: no positions");
    }
    Collapser collapser(problem, meter, options);
    return collapser.run();
}

}  // namespace strata

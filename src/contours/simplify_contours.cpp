// Contour simplification (paper section 3): Douglas-Peucker with a guaranteed, exactly recorded
// per-edge error, made O(n log n) and topology-safe.
//
// - D. H. Douglas, T. K. Peucker, "Algorithms for the reduction of the number of points required
//   to represent a digitized line or its caricature", The Canadian Cartographer 10(2), 1973.
// - J. Hershberger, J. Snoeyink, "Speeding up the Douglas-Peucker line-simplification
//   algorithm", Proc. 5th Int. Symp. on Spatial Data Handling, 1992: the path hull
//   (detail/path_hull.h) answers "farthest point from the line" in O(log n); after a split only
//   the half away from the tag is rebuilt, so each point is rebuilt O(log n) times.
// - A. A. Melkman, "On-line construction of the convex hull of a simple polyline", IPL 25, 1987.
// - J. R. Shewchuk, "Adaptive precision floating-point arithmetic and fast robust geometric
//   predicates", Discrete & Computational Geometry 18, 1997 (orientation off the pixel grid).
//
// Douglas-Peucker measures distance to the LINE through a segment's ends; the bound we promise
// is to the SEGMENT. So every accepted segment is checked exactly over its range (ranges of
// accepted segments are disjoint: O(n) in all) and split at its worst point if the chain
// doubles back past an end (the contour of a one-pixel-wide line does). Topology is repaired
// afterwards: simplified edges of one label are bucketed in a uniform grid, candidate pairs
// tested exactly, and each offending edge refined at its farthest original point.
//
// One file: the simplification and its topology repair decide with the same exact predicates
// (half-pixel grid, orientation, segment contact) on the same kept-edge records, and the repair
// calls back into the simplification to refine an edge; apart, each would export the other's
// internals.
#include "contours/simplify_contours.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>

#include "contours/detail/path_hull.h"
#include "core/error.h"

namespace strata {

namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// A kept segment of a simplified chain: original indices of its ends and the largest distance
/// of the original points strictly between them from the segment, px.
struct KeptEdge {
    std::uint32_t first = 0;
    std::uint32_t last = 0;
    double deviation_px = 0.0;
};

std::string format_number(double value) {
    std::ostringstream out;
    out << value;
    return out.str();
}

void check_tolerance(const char* function, double tolerance_px) {
    if (!std::isfinite(tolerance_px) || tolerance_px < 0.0) {
        throw Error(ErrorCode::InvalidInput, std::string(function) +
                                                 ": tolerance_px = " + format_number(tolerance_px) +
                                                 ", expected a finite value >= 0");
    }
}

void check_points(const std::string& where, std::span<const Vec2> points) {
    if (points.size() >= kNone) {
        throw Error(ErrorCode::Unsupported, where + ": " + std::to_string(points.size()) +
                                                " points, expected fewer than 2^32 - 1");
    }
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (!std::isfinite(points[i].x) || !std::isfinite(points[i].y)) {
            throw Error(ErrorCode::InvalidInput, where + ": point " + std::to_string(i) + " is (" +
                                                     format_number(points[i].x) + ", " +
                                                     format_number(points[i].y) +
                                                     "), expected finite coordinates");
        }
    }
}

/// Euclidean distance from p to the closed segment [a, b] (a point if a == b).
double segment_distance(Vec2 p, Vec2 a, Vec2 b) {
    const Vec2 d = b - a;
    const Vec2 w = p - a;
    const double length_sq = dot(d, d);
    const double along = dot(w, d);
    if (length_sq == 0.0 || along <= 0.0) {
        return norm(w);
    }
    if (along >= length_sq) {
        return norm(p - b);
    }
    return std::abs(cross(d, w)) / std::sqrt(length_sq);
}

/// True when d is one pixel along an axis (a unit pixel edge).
bool is_unit_step(Vec2 d) {
    return (std::abs(d.x) == 1.0 && d.y == 0.0) || (d.x == 0.0 && std::abs(d.y) == 1.0);
}

/// True when points[i] is the midpoint of a unit pixel edge inserted by `simplify_contours`:
/// the middle of its neighbours, which are one pixel apart along an axis.
bool is_edge_midpoint(std::span<const Vec2> points, std::uint32_t i) {
    const Vec2 a = points[i - 1];
    const Vec2 b = points[i + 1];
    return is_unit_step(b - a) && points[i] == Vec2{0.5 * (a.x + b.x), 0.5 * (a.y + b.y)};
}

/// True when points[i] is a step of a pixel staircase: a corner (turning) between unit edges whose
/// neighbouring corner across one of them turns the other way. Corners of a convex run (a single
/// pixel, a rectangle) turn the same way as their neighbours and are not steps.
bool is_staircase_step(std::span<const Vec2> points, std::uint32_t i) {
    const auto turn = [&](std::size_t k) {
        return cross(points[k] - points[k - 1], points[k + 1] - points[k]);
    };
    if (i < 1 || i + 1 >= points.size()) {
        return false;
    }
    const double here = turn(i);
    if (here == 0.0) {
        return false;
    }
    const bool back = i >= 3 && is_edge_midpoint(points, i - 1) && turn(i - 2) * here < 0.0;
    const bool ahead =
        i + 3 < points.size() && is_edge_midpoint(points, i + 1) && turn(i + 2) * here < 0.0;
    return back || ahead;
}

/// The point strictly between s and t (cyclically, indices modulo points.size()) farthest from
/// the segment [points[s], points[t]]; the first one on ties. `index` is kNone for an empty
/// range.
struct WorstPoint {
    double distance = 0.0;
    std::uint32_t index = kNone;
};

WorstPoint range_deviation(std::span<const Vec2> points, std::uint32_t s, std::uint32_t t) {
    const std::size_t n = points.size();
    const Vec2 a = points[s];
    const Vec2 b = points[t];
    WorstPoint worst;
    for (std::size_t k = s + 1 == n ? 0 : s + 1; k != t; k = k + 1 == n ? 0 : k + 1) {
        const double distance = segment_distance(points[k], a, b);
        if (worst.index == kNone || distance > worst.distance) {
            worst = {distance, static_cast<std::uint32_t>(k)};
        }
    }
    return worst;
}

/// Signed area-like imbalance of the original points strictly between s and t (cyclic) about
/// the chord from points[s] to points[t]: the sum of their signed distances from its line (left
/// positive) times the chord length over their count + 1, i.e. about the area between the chain
/// and the chord (left positive).
double chord_imbalance(std::span<const Vec2> points, std::uint32_t s, std::uint32_t t) {
    const std::size_t n = points.size();
    const Vec2 a = points[s];
    const Vec2 d = points[t] - a;
    const double length = std::sqrt(dot(d, d));
    if (!(length > 0.0)) {
        return 0.0;
    }
    double sum = 0.0;
    std::size_t count = 0;
    for (std::size_t k = s + 1 == n ? 0 : s + 1; k != t; k = k + 1 == n ? 0 : k + 1) {
        const Vec2 w = points[k] - a;
        sum += (d.x * w.y - d.y * w.x) / length;
        ++count;
    }
    return sum * length / double(count + 1);
}

/// Least gain (px^2 of imbalance) worth moving a vertex: the staircase of a straight sloped
/// boundary is balanced to about this already, and its vertices are best left in its middle.
constexpr double kBalanceGainPx2 = 0.5;

/// Moves each simplified vertex but the first (which anchors the chain) to one of the original
/// points within `reach` of it along the chain, where that balances its two edges better: the
/// original points on both sides of each chord, so that chords do not cut convex runs inward
/// (Douglas-Peucker keeps every original point on one side of a convex run's chords). Every
/// original point stays within `tolerance_px` of its edge.
void balance_vertices(std::span<const Vec2> points,
                      double tolerance_px,
                      std::vector<KeptEdge>& edges,
                      std::uint32_t reach) {
    const auto n = static_cast<std::uint32_t>(points.size());
    if (reach == 0 || edges.size() < 3 || n < 8) {
        return;
    }
    for (std::size_t e = 1; e < edges.size(); ++e) {
        KeptEdge& before = edges[e - 1];
        KeptEdge& after = edges[e];
        const std::uint32_t v = after.first;
        double best = std::abs(chord_imbalance(points, before.first, v)) +
                      std::abs(chord_imbalance(points, v, after.last));
        std::uint32_t chosen = v;
        WorstPoint chosen_before{before.deviation_px, kNone},
            chosen_after{after.deviation_px, kNone};
        for (std::uint32_t step = 1; step <= reach; ++step) {
            for (const std::uint32_t w : {(v + n - step) % n, (v + step) % n}) {
                // strictly between the neighbouring vertices; the last edge ends at 0, and
                // edges stay sorted by first index
                const std::uint32_t next = e + 1 < edges.size() ? edges[e + 1].first : n;
                if (!(w > before.first && w < next)) {
                    continue;
                }
                const double cost = std::abs(chord_imbalance(points, before.first, w)) +
                                    std::abs(chord_imbalance(points, w, after.last));
                if (!(cost < best - kBalanceGainPx2)) {
                    continue;
                }
                const WorstPoint db = range_deviation(points, before.first, w);
                const WorstPoint da = range_deviation(points, w, after.last);
                if ((db.index != kNone && db.distance > tolerance_px) ||
                    (da.index != kNone && da.distance > tolerance_px)) {
                    continue;
                }
                best = cost;
                chosen = w;
                chosen_before = db;
                chosen_after = da;
            }
        }
        if (chosen != v) {
            before.last = chosen;
            after.first = chosen;
            before.deviation_px = chosen_before.index == kNone ? 0.0 : chosen_before.distance;
            after.deviation_px = chosen_after.index == kNone ? 0.0 : chosen_after.distance;
        }
    }
}

/// Douglas-Peucker of one open chain over the path hull, with an explicit task stack (the
/// recursion is n deep in the worst case).
class DouglasPeucker {
public:
    /// Appends the kept segments of the chain `points` (indices shifted by `offset`), in no
    /// particular order.
    /// With `midpoints`, a split at a staircase step moves to a neighbouring edge midpoint (the
    /// one nearer the segment if there are two: the middle of the staircase's band; see
    /// SimplifyOptions::edge_midpoints).
    void run(std::span<const Vec2> points,
             double tolerance_px,
             std::uint32_t offset,
             bool midpoints,
             std::vector<KeptEdge>& edges) {
        if (points.size() < 2) {
            return;
        }
        if (points.size() > capacity_) {
            capacity_ = points.size();
            hull_.reserve(capacity_);
        }
        tasks_.assign(1, {0, static_cast<std::uint32_t>(points.size() - 1), false});
        while (!tasks_.empty()) {
            const Task task = tasks_.back();
            tasks_.pop_back();
            if (task.last - task.first < 2) {
                edges.push_back({task.first + offset, task.last + offset, 0.0});
                continue;
            }
            const bool direct = task.last - task.first <= kDirectScanPoints;
            if (!direct && !task.hull_ready) {
                hull_.build(points, task.first, task.last);
            }
            const Vec2 a = points[task.first];
            const Vec2 b = points[task.last];
            std::uint32_t split = kNone;
            if (a == b) {
                // note: no line; the farthest point from the common end is a hull vertex.
                const detail::HullExtreme far =
                    direct ? scan_farthest(points, task, a, b) : hull_.farthest_from_point(a);
                if (far.offset > tolerance_px) {
                    split = far.index;
                }
            } else {
                const detail::HullExtreme far =
                    direct ? scan_farthest(points, task, a, b) : hull_.farthest_from_line(a, b);
                if (far.offset / norm(b - a) > tolerance_px) {
                    split = far.index;
                }
            }
            if (split == kNone) {
                // note: accepted ranges are disjoint, so this costs O(n) in all; a failed check
                // costs O(range) more, only where the chain doubles back.
                const WorstPoint worst = range_deviation(points, task.first, task.last);
                if (worst.distance <= tolerance_px) {
                    edges.push_back({task.first + offset, task.last + offset, worst.distance});
                    continue;
                }
                split = worst.index;  // the chain doubles back past an end of the segment
            }
            if (midpoints) {
                split = midpoint_split(points, task, split, a, b);
            }
            // The half containing the tag keeps its hull; the other half is rebuilt later.
            const std::uint32_t tag = hull_.tag();
            if (direct || split == tag) {
                tasks_.push_back({split, task.last, false});
                tasks_.push_back({task.first, split, false});
            } else if (split > tag) {
                hull_.split(split);
                tasks_.push_back({split, task.last, false});
                tasks_.push_back({task.first, split, true});
            } else {
                hull_.split(split);
                tasks_.push_back({task.first, split, false});
                tasks_.push_back({split, task.last, true});
            }
        }
    }

private:
    // note: below this many points a plain scan beats building hulls (a constant factor: it
    // costs O(n * kDirectScanPoints) at worst).
    static constexpr std::uint32_t kDirectScanPoints = 32;

    struct Task {
        std::uint32_t first;
        std::uint32_t last;
        bool hull_ready;  ///< the path hull holds [first, last]; only ever the top task
    };

    /// `split`, or if it is a staircase step the edge midpoint next to it (strictly inside the
    /// task) nearer to [a, b].
    static std::uint32_t midpoint_split(
        std::span<const Vec2> points, const Task& task, std::uint32_t split, Vec2 a, Vec2 b) {
        if (!is_staircase_step(points, split)) {
            return split;
        }
        const bool before = split - 1 > task.first && is_edge_midpoint(points, split - 1);
        const bool after = split + 1 < task.last && is_edge_midpoint(points, split + 1);
        if (before && after) {
            return segment_distance(points[split - 1], a, b) <=
                           segment_distance(points[split + 1], a, b)
                       ? split - 1
                       : split + 1;
        }
        return before ? split - 1 : after ? split + 1 : split;
    }

    /// The farthest point strictly inside the task from the line through a and b, as
    /// |cross(b - a, p - a)| (or from a itself if a == b); the first one on ties.
    static detail::HullExtreme scan_farthest(std::span<const Vec2> points,
                                             const Task& task,
                                             Vec2 a,
                                             Vec2 b) {
        const Vec2 d = b - a;
        detail::HullExtreme far{task.first, -1.0};
        for (std::uint32_t k = task.first + 1; k < task.last; ++k) {
            const double offset = a == b ? norm(points[k] - a) : std::abs(cross(d, points[k] - a));
            if (offset > far.offset) {
                far = {k, offset};
            }
        }
        return far;
    }

    detail::PathHull hull_;
    std::size_t capacity_ = 0;
    std::vector<Task> tasks_;
};

bool by_first(const KeptEdge& a, const KeptEdge& b) {
    return a.first < b.first;
}

/// Douglas-Peucker of open and closed chains, reusing buffers.
class Simplifier {
public:
    /// `midpoints`: splits move to neighbouring edge midpoints (DouglasPeucker::run).
    explicit Simplifier(bool midpoints = false) : midpoints_(midpoints) {}

    std::vector<KeptEdge> open_edges(std::span<const Vec2> points, double tolerance_px) {
        std::vector<KeptEdge> edges;
        dp_.run(points, tolerance_px, 0, midpoints_, edges);
        std::sort(edges.begin(), edges.end(), by_first);
        return edges;
    }

    /// The edges of the simplified closed chain, sorted by first index; the last one ends at
    /// index 0. At least 3 edges when there are at least 3 points.
    std::vector<KeptEdge> closed_edges(std::span<const Vec2> points, double tolerance_px) {
        const auto n = static_cast<std::uint32_t>(points.size());
        std::vector<KeptEdge> edges;
        if (n <= 3) {
            for (std::uint32_t k = 0; k < n; ++k) {
                edges.push_back({k, k + 1 == n ? 0 : k + 1, 0.0});
            }
            return edges;
        }
        std::uint32_t far = 0;
        double far_distance = 0.0;
        for (std::uint32_t k = 1; k < n; ++k) {
            const double distance = norm(points[k] - points[0]);
            if (distance > far_distance) {
                far = k;
                far_distance = distance;
            }
        }
        if (far == 0) {
            far = n / 2;  // every point coincides with point 0
        }
        scratch_.assign(points.begin(), points.end());
        scratch_.push_back(points[0]);
        const std::span<const Vec2> unrolled(scratch_);
        dp_.run(unrolled.first(far + 1), tolerance_px, 0, midpoints_, edges);
        dp_.run(unrolled.subspan(far), tolerance_px, far, midpoints_, edges);
        for (KeptEdge& edge : edges) {
            if (edge.last == n) {
                edge.last = 0;
            }
        }
        if (edges.size() == 2) {
            // Both halves collapsed to the segment [0, far]: add the point farthest from it.
            const WorstPoint lower = range_deviation(points, 0, far);
            const WorstPoint upper = range_deviation(points, far, 0);
            const bool use_upper =
                upper.index != kNone && (lower.index == kNone || upper.distance > lower.distance);
            const KeptEdge replaced = use_upper ? KeptEdge{far, 0} : KeptEdge{0, far};
            const std::uint32_t k = use_upper ? upper.index : lower.index;
            edges.erase(std::find_if(edges.begin(), edges.end(),
                                     [&](const KeptEdge& e) { return e.first == replaced.first; }));
            refine_edge(points, replaced.first, replaced.last, k, tolerance_px, edges);
        }
        std::sort(edges.begin(), edges.end(), by_first);
        return edges;
    }

    /// Appends the edges replacing the edge [s, t] of the closed chain `points` once point k
    /// (strictly between them) is kept: Douglas-Peucker of [s, k] and of [k, t].
    void refine_edge(std::span<const Vec2> points,
                     std::uint32_t s,
                     std::uint32_t t,
                     std::uint32_t k,
                     double tolerance_px,
                     std::vector<KeptEdge>& out) {
        const auto n = static_cast<std::uint32_t>(points.size());
        for (const auto& [from, to] : {std::pair{s, k}, std::pair{k, t}}) {
            scratch_.clear();
            for (std::uint32_t i = from;; i = i + 1 == n ? 0 : i + 1) {
                scratch_.push_back(points[i]);
                if (i == to) {
                    break;
                }
            }
            const std::size_t before = out.size();
            dp_.run(scratch_, tolerance_px, 0, midpoints_, out);
            for (std::size_t e = before; e < out.size(); ++e) {
                out[e].first = static_cast<std::uint32_t>((from + std::uint64_t{out[e].first}) % n);
                out[e].last = static_cast<std::uint32_t>((from + std::uint64_t{out[e].last}) % n);
            }
        }
    }

private:
    DouglasPeucker dp_;
    std::vector<Vec2> scratch_;
    bool midpoints_ = false;
};

std::vector<std::uint32_t> kept_indices(const std::vector<KeptEdge>& edges,
                                        std::vector<double>* deviation_px) {
    std::vector<std::uint32_t> kept;
    kept.reserve(edges.size() + 1);
    if (deviation_px) {
        deviation_px->clear();
        deviation_px->reserve(edges.size());
    }
    for (const KeptEdge& edge : edges) {
        kept.push_back(edge.first);
        if (deviation_px) {
            deviation_px->push_back(edge.deviation_px);
        }
    }
    return kept;
}

// ---- Exact segment intersection -------------------------------------------------------------

/// A point of the half-pixel grid, doubled: exact integer predicates.
struct GridPoint {
    std::int64_t x = 0;
    std::int64_t y = 0;
};

// note: |2x| <= 2^29 keeps every orientation determinant below 2^62.
constexpr double kGridLimit = 536870912.0;

bool is_on_half_pixel_grid(Vec2 p) {
    const double x = 2.0 * p.x;
    const double y = 2.0 * p.y;
    return x == std::floor(x) && y == std::floor(y) && std::abs(x) <= kGridLimit &&
           std::abs(y) <= kGridLimit;
}

int orientation(GridPoint a, GridPoint b, GridPoint c) {
    const std::int64_t det = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    return (det > 0) - (det < 0);
}

int orientation(Vec2 a, Vec2 b, Vec2 c) {
    return detail::orientation(a, b, c);
}

template <class T>
int compare(T a, T b) {
    return (a > b) - (a < b);
}

/// p within the bounding box of [a, b] (for p collinear with them: p on the segment).
template <class P>
bool in_box(P a, P b, P p) {
    return std::min(a.x, b.x) <= p.x && p.x <= std::max(a.x, b.x) && std::min(a.y, b.y) <= p.y &&
           p.y <= std::max(a.y, b.y);
}

/// The closed segments [a, b] and [c, d] share at least one point.
template <class P>
bool segments_touch(P a, P b, P c, P d) {
    const int o1 = orientation(a, b, c);
    const int o2 = orientation(a, b, d);
    const int o3 = orientation(c, d, a);
    const int o4 = orientation(c, d, b);
    if (o1 * o2 < 0 && o3 * o4 < 0) {
        return true;
    }
    return (o1 == 0 && in_box(a, b, c)) || (o2 == 0 && in_box(a, b, d)) ||
           (o3 == 0 && in_box(c, d, a)) || (o4 == 0 && in_box(c, d, b));
}

/// Consecutive edges [a, v] and [v, b] share more than v (collinear, folding back).
template <class P>
bool folds_back(P a, P v, P b) {
    if (orientation(a, v, b) != 0) {
        return false;
    }
    return compare(a.x, v.x) * compare(b.x, v.x) > 0 || compare(a.y, v.y) * compare(b.y, v.y) > 0;
}

// ---- Topology repair ------------------------------------------------------------------------

/// Uniform grid of edge ids over a bounding box, about one cell per edge; each edge is
/// registered in every cell its segment passes (conservatively, with a margin), so two
/// segments sharing a point share a cell. Cell lists are linked lists in one pool.
class EdgeGrid {
public:
    EdgeGrid(Vec2 lo, Vec2 hi, std::size_t edge_count) : origin_(lo) {
        const double width = hi.x - lo.x;
        const double height = hi.y - lo.y;
        const double count = static_cast<double>(std::max<std::size_t>(edge_count, 1));
        const double extent = std::max({width, height, 1e-300});
        double cell = std::max(std::sqrt(width * height / count), extent / count);
        const double max_cells = 4.0 * count + 16.0;
        while ((std::floor(width / cell) + 1.0) * (std::floor(height / cell) + 1.0) > max_cells) {
            cell *= 1.5;
        }
        inverse_cell_ = 1.0 / cell;
        cols_ = static_cast<std::int64_t>(std::floor(width / cell)) + 1;
        rows_ = static_cast<std::int64_t>(std::floor(height / cell)) + 1;
        head_.assign(static_cast<std::size_t>(cols_ * rows_), kNone);
    }

    void insert(std::uint32_t edge, Vec2 a, Vec2 b) {
        for_each_cell(a, b, [&](std::size_t cell) {
            entries_.push_back({edge, head_[cell]});
            head_[cell] = static_cast<std::uint32_t>(entries_.size() - 1);
        });
    }

    /// Calls f(edge) for every edge registered in a cell that [a, b] passes (with repeats).
    template <class F>
    void for_each_candidate(Vec2 a, Vec2 b, F&& f) const {
        for_each_cell(a, b, [&](std::size_t cell) {
            for (std::uint32_t e = head_[cell]; e != kNone; e = entries_[e].next) {
                f(entries_[e].edge);
            }
        });
    }

private:
    struct Entry {
        std::uint32_t edge;
        std::uint32_t next;
    };

    template <class F>
    void for_each_cell(Vec2 a, Vec2 b, F&& f) const {
        constexpr double kMargin = 1e-7;  // cells; far above the rounding of the mapping
        const double ax = (a.x - origin_.x) * inverse_cell_;
        const double ay = (a.y - origin_.y) * inverse_cell_;
        const double bx = (b.x - origin_.x) * inverse_cell_;
        const double by = (b.y - origin_.y) * inverse_cell_;
        const double y_lo = std::min(ay, by) - kMargin;
        const double y_hi = std::max(ay, by) + kMargin;
        const double x_lo = std::min(ax, bx) - kMargin;
        const double x_hi = std::max(ax, bx) + kMargin;
        const std::int64_t r0 = clamp(y_lo, rows_);
        const std::int64_t r1 = clamp(y_hi, rows_);
        for (std::int64_t r = r0; r <= r1; ++r) {
            double left = x_lo;
            double right = x_hi;
            if (ay != by) {
                // x-extent of the part of the segment within this row
                const double row_lo = r == r0 ? y_lo : static_cast<double>(r);
                const double row_hi = r == r1 ? y_hi : static_cast<double>(r + 1);
                const double t0 = std::clamp((row_lo - ay) / (by - ay), 0.0, 1.0);
                const double t1 = std::clamp((row_hi - ay) / (by - ay), 0.0, 1.0);
                const double x0 = ax + t0 * (bx - ax);
                const double x1 = ax + t1 * (bx - ax);
                left = std::max(x_lo, std::min(x0, x1) - kMargin);
                right = std::min(x_hi, std::max(x0, x1) + kMargin);
            }
            const std::int64_t c0 = clamp(left, cols_);
            const std::int64_t c1 = clamp(right, cols_);
            for (std::int64_t c = c0; c <= c1; ++c) {
                f(static_cast<std::size_t>(r * cols_ + c));
            }
        }
    }

    static std::int64_t clamp(double v, std::int64_t size) {
        const double f = std::floor(v);
        if (!(f >= 0.0)) {
            return 0;
        }
        return f >= static_cast<double>(size - 1) ? size - 1 : static_cast<std::int64_t>(f);
    }

    Vec2 origin_;
    double inverse_cell_ = 1.0;
    std::int64_t cols_ = 1;
    std::int64_t rows_ = 1;
    std::vector<std::uint32_t> head_;
    std::vector<Entry> entries_;
};

/// The contours of one label, their simplified edges, and the repair loop.
class TopologyRepair {
public:
    TopologyRepair(std::vector<Contour>& contours,
                   std::vector<std::size_t> group,
                   std::vector<std::vector<KeptEdge>>& contour_edges,
                   double tolerance_px,
                   Simplifier& simplifier)
        : contours_(contours),
          group_(std::move(group)),
          contour_edges_(contour_edges),
          tolerance_px_(tolerance_px),
          simplifier_(simplifier) {}

    /// Repairs the group; returns the number of re-inserted vertices.
    std::size_t run() {
        bool on_grid = true;
        for (const std::size_t c : group_) {
            for (const Vec2& p : contours_[c].points) {
                on_grid = on_grid && is_on_half_pixel_grid(p);
            }
        }
        return on_grid ? repair<true>() : repair<false>();
    }

private:
    struct Edge {
        std::uint32_t member;  ///< index into group_
        std::uint32_t first;
        std::uint32_t last;
        double deviation_px;
        bool alive;
    };

    std::span<const Vec2> points(const Edge& e) const { return contours_[group_[e.member]].points; }
    bool has_interior(const Edge& e) const {
        const std::size_t n = points(e).size();
        return (e.last + n - e.first) % n > 1;
    }

    template <bool kOnGrid>
    static auto exact(Vec2 p) {
        if constexpr (kOnGrid) {
            return GridPoint{static_cast<std::int64_t>(2.0 * p.x),
                             static_cast<std::int64_t>(2.0 * p.y)};
        } else {
            return p;
        }
    }

    template <bool kOnGrid>
    bool conflict(const Edge& e, const Edge& f) const {
        const auto a = exact<kOnGrid>(points(e)[e.first]);
        const auto b = exact<kOnGrid>(points(e)[e.last]);
        const auto c = exact<kOnGrid>(points(f)[f.first]);
        const auto d = exact<kOnGrid>(points(f)[f.last]);
        if (e.member == f.member) {
            if (e.last == f.first && f.last == e.first) {
                return true;  // a two-edge polygon is never simple
            }
            if (e.last == f.first) {
                return folds_back(a, b, d);
            }
            if (f.last == e.first) {
                return folds_back(c, d, b);
            }
        }
        return segments_touch(a, b, c, d);
    }

    std::string describe(const Edge& e) const {
        const Contour& contour = contours_[group_[e.member]];
        return "contour " + std::to_string(group_[e.member]) + " (label " +
               std::to_string(contour.label) + ") edge " + std::to_string(e.first) + "-" +
               std::to_string(e.last);
    }

    void add_edge(const KeptEdge& kept, std::uint32_t member) {
        const auto id = static_cast<std::uint32_t>(edges_.size());
        edges_.push_back({member, kept.first, kept.last, kept.deviation_px, true});
        const Edge& e = edges_.back();
        grid_->insert(id, points(e)[e.first], points(e)[e.last]);
        queue_.push_back(id);
        seen_.push_back(kNone);
    }

    /// Keeps the farthest original point of edge `id` and re-simplifies both halves.
    void refine(std::uint32_t id) {
        edges_[id].alive = false;
        const Edge e = edges_[id];
        const WorstPoint worst = range_deviation(points(e), e.first, e.last);
        replacement_.clear();
        simplifier_.refine_edge(points(e), e.first, e.last, worst.index, tolerance_px_,
                                replacement_);
        reinserted_ += replacement_.size() - 1;
        for (const KeptEdge& kept : replacement_) {
            add_edge(kept, e.member);
        }
    }

    template <bool kOnGrid>
    std::size_t repair() {
        Vec2 lo{std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
        Vec2 hi{std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
        std::size_t edge_count = 0;
        for (const std::size_t c : group_) {
            for (const Vec2& p : contours_[c].points) {
                lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
                hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
            }
            edge_count += contour_edges_[c].size();
        }
        EdgeGrid grid(lo, hi, edge_count);
        grid_ = &grid;
        for (std::uint32_t m = 0; m < group_.size(); ++m) {
            for (const KeptEdge& kept : contour_edges_[group_[m]]) {
                add_edge(kept, m);
            }
        }
        std::vector<std::uint32_t> partners;
        for (std::size_t q = 0; q < queue_.size(); ++q) {
            const std::uint32_t id = queue_[q];
            if (!edges_[id].alive) {
                continue;
            }
            partners.clear();
            const Edge& e = edges_[id];
            grid.for_each_candidate(points(e)[e.first], points(e)[e.last], [&](std::uint32_t f) {
                if (f == id || !edges_[f].alive || seen_[f] == id) {
                    return;
                }
                seen_[f] = id;
                if (conflict<kOnGrid>(e, edges_[f])) {
                    partners.push_back(f);
                }
            });
            if (partners.empty()) {
                continue;
            }
            const bool refinable = has_interior(e);
            for (const std::uint32_t f : partners) {
                if (!refinable && !has_interior(edges_[f])) {
                    throw Error(ErrorCode::InvalidInput,
                                "simplify_contours: " + describe(e) + " and " +
                                    describe(edges_[f]) +
                                    " intersect in the original contours; expected simple "
                                    "contours, pairwise disjoint within a label");
                }
            }
            if (refinable) {
                refine(id);
            }
            for (const std::uint32_t f : partners) {
                if (edges_[f].alive && has_interior(edges_[f])) {
                    refine(f);
                }
            }
        }
        // Write back, each contour's edges in order of their first point.
        for (const std::size_t c : group_) {
            contour_edges_[c].clear();
        }
        for (const Edge& e : edges_) {
            if (e.alive) {
                contour_edges_[group_[e.member]].push_back({e.first, e.last, e.deviation_px});
            }
        }
        for (const std::size_t c : group_) {
            std::sort(contour_edges_[c].begin(), contour_edges_[c].end(), by_first);
        }
        grid_ = nullptr;
        return reinserted_;
    }

    std::vector<Contour>& contours_;
    std::vector<std::size_t> group_;
    std::vector<std::vector<KeptEdge>>& contour_edges_;
    double tolerance_px_;
    Simplifier& simplifier_;
    EdgeGrid* grid_ = nullptr;
    std::vector<Edge> edges_;
    std::vector<std::uint32_t> queue_;
    std::vector<std::uint32_t> seen_;  ///< per edge: the last edge checked against it
    std::vector<KeptEdge> replacement_;
    std::size_t reinserted_ = 0;
};

}  // namespace

std::vector<std::uint32_t> simplify_polyline(std::span<const Vec2> points,
                                             double tolerance_px,
                                             std::vector<double>* deviation_px) {
    check_tolerance("simplify_polyline", tolerance_px);
    check_points("simplify_polyline", points);
    if (deviation_px) {
        deviation_px->clear();
    }
    if (points.size() <= 1) {
        return points.empty() ? std::vector<std::uint32_t>{} : std::vector<std::uint32_t>{0};
    }
    Simplifier simplifier;
    std::vector<std::uint32_t> kept =
        kept_indices(simplifier.open_edges(points, tolerance_px), deviation_px);
    kept.push_back(static_cast<std::uint32_t>(points.size() - 1));
    return kept;
}

std::vector<std::uint32_t> simplify_closed_polyline(std::span<const Vec2> points,
                                                    double tolerance_px,
                                                    std::vector<double>* deviation_px) {
    check_tolerance("simplify_closed_polyline", tolerance_px);
    check_points("simplify_closed_polyline", points);
    Simplifier simplifier;
    return kept_indices(simplifier.closed_edges(points, tolerance_px), deviation_px);
}

std::size_t simplify_contours(std::vector<Contour>& contours, const SimplifyOptions& options) {
    check_tolerance("simplify_contours", options.tolerance_px);
    for (std::size_t c = 0; c < contours.size(); ++c) {
        const std::string where = "simplify_contours: contour " + std::to_string(c) + " (label " +
                                  std::to_string(contours[c].label) + ")";
        if (contours[c].points.size() < 3) {
            throw Error(ErrorCode::InvalidInput, where + " has " +
                                                     std::to_string(contours[c].points.size()) +
                                                     " points, expected at least 3");
        }
        check_points(where, contours[c].points);
    }
    // Every unit pixel edge gets its midpoint while simplifying; the ones no simplified edge ends
    // at are dropped again at the end.
    std::vector<std::vector<bool>> inserted(contours.size());
    if (options.edge_midpoints) {
        std::vector<Vec2> refined;
        for (std::size_t c = 0; c < contours.size(); ++c) {
            const std::vector<Vec2>& points = contours[c].points;
            refined.clear();
            for (std::size_t i = 0; i < points.size(); ++i) {
                const Vec2 a = points[i];
                const Vec2 b = points[i + 1 == points.size() ? 0 : i + 1];
                refined.push_back(a);
                inserted[c].push_back(false);
                if (is_unit_step(b - a)) {
                    refined.push_back({0.5 * (a.x + b.x), 0.5 * (a.y + b.y)});
                    inserted[c].push_back(true);
                }
            }
            check_points("simplify_contours", refined);
            contours[c].points.assign(refined.begin(), refined.end());
        }
    }
    Simplifier simplifier(options.edge_midpoints);
    std::vector<std::vector<KeptEdge>> edges(contours.size());
    for (std::size_t c = 0; c < contours.size(); ++c) {
        edges[c] = simplifier.closed_edges(contours[c].points, options.tolerance_px);
        balance_vertices(contours[c].points, options.tolerance_px, edges[c], options.balance_reach);
    }
    std::vector<std::size_t> order(contours.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return contours[a].label < contours[b].label;
    });
    std::size_t reinserted = 0;
    for (std::size_t begin = 0; begin < order.size();) {
        std::size_t end = begin + 1;
        while (end < order.size() && contours[order[end]].label == contours[order[begin]].label) {
            ++end;
        }
        std::vector<std::size_t> group(order.begin() + static_cast<std::ptrdiff_t>(begin),
                                       order.begin() + static_cast<std::ptrdiff_t>(end));
        reinserted +=
            TopologyRepair(contours, std::move(group), edges, options.tolerance_px, simplifier)
                .run();
        begin = end;
    }
    for (std::size_t c = 0; c < contours.size(); ++c) {
        Contour& contour = contours[c];
        contour.simplified = kept_indices(edges[c], &contour.edge_deviation_px);
        if (inserted[c].empty()) {
            continue;
        }
        // Keep the original points and the midpoints that became vertices; renumber.
        std::vector<bool> keep(inserted[c].size());
        for (std::size_t i = 0; i < keep.size(); ++i) {
            keep[i] = !inserted[c][i];
        }
        for (const std::uint32_t v : contour.simplified) {
            keep[v] = true;
        }
        std::vector<std::uint32_t> index(keep.size());
        std::size_t kept = 0;
        for (std::size_t i = 0; i < keep.size(); ++i) {
            index[i] = static_cast<std::uint32_t>(kept);
            if (keep[i]) {
                contour.points[kept++] = contour.points[i];
            }
        }
        contour.points.resize(kept);
        for (std::uint32_t& v : contour.simplified) {
            v = index[v];
        }
    }
    return reinserted;
}

bool resimplify_label(SliceContourSet& set, std::uint16_t label, const SimplifyOptions& options) {
    std::vector<Contour*> own;
    std::vector<Contour> subset;
    for (Contour& c : set.contours) {
        if (c.label == label) {
            own.push_back(&c);
            subset.push_back(c);
        }
    }
    if (subset.empty()) {
        return false;
    }
    simplify_contours(subset, options);
    bool changed = false;
    for (std::size_t j = 0; j < own.size(); ++j) {
        changed = changed || subset[j].simplified != own[j]->simplified;
        *own[j] = std::move(subset[j]);
    }
    return changed;
}

}  // namespace strata

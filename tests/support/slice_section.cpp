#include "support/slice_section.h"

// Plane section of a triangle mesh and an exact comparison of two sets of plane segments.
//
// Section: per triangle crossing the plane, and per in-plane mesh edge whose two faces are not on
// the same side (the boundary of mesh ∩ plane as a planar set; see the header).
//
// Comparison: the directed Hausdorff distance from a segment s to a union of segments E is the
// maximum over t in [0, 1] of f(t) = min_e d_e(s(t)). Each d_e is convex in t and d_e^2 is
// piecewise quadratic (at most three pieces: nearest point is an endpoint of e, or inside e), so
// the maximum of the lower envelope f is reached at an end of the interval or where two of these
// quadratics are equal: found by branch and bound over t (upper bound on an interval
// [t0, t1]: min_e max(d_e(t0), d_e(t1)), by convexity; edges farther than it cannot be nearest
// there), then, once few edges remain, by solving every pairwise equation exactly.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <tuple>
#include <utility>

#include "core/error.h"
#include "support/polygon_checks.h"

namespace strata::test {
namespace {

constexpr std::size_t kMaxListed = 20;
constexpr std::size_t kExactEdges = 8;  // solve pairwise once at most this many edges remain
constexpr int kMaxDepth = 60;
constexpr double kInf = std::numeric_limits<double>::infinity();

struct Segment {
    Vec2 a;
    Vec2 b;
    Vec2 at(double t) const { return a + t * (b - a); }
};

struct Section {
    std::vector<Segment> segments;
    std::vector<std::string> origins;  // per segment, for messages
    std::vector<SectionMismatch> defects;
};

double point_segment_distance(Vec2 p, const Segment& e) {
    const Vec2 w = e.b - e.a;
    const double ww = dot(w, w);
    const double u = ww > 0 ? std::clamp(dot(p - e.a, w) / ww, 0.0, 1.0) : 0.0;
    return norm(p - (e.a + u * w));
}

double segment_distance(const Segment& s, const Segment& e) {
    if (segments_touch(s.a, s.b, e.a, e.b)) {
        return 0;
    }
    return std::min({point_segment_distance(s.a, e), point_segment_distance(s.b, e),
                     point_segment_distance(e.a, s), point_segment_distance(e.b, s)});
}

/// Parameter of the projection of `p` onto segment `s`, clamped to [0, 1].
double projection_parameter(const Segment& s, Vec2 p) {
    const Vec2 v = s.b - s.a;
    const double vv = dot(v, v);
    return vv > 0 ? std::clamp(dot(p - s.a, v) / vv, 0.0, 1.0) : 0.0;
}

std::string edge_name(std::uint32_t u, std::uint32_t v) {
    return "(" + std::to_string(u) + ", " + std::to_string(v) + ")";
}

Vec2 xy(Vec3 p) {
    return {p.x, p.y};
}

Section section_of(const TriMesh& mesh, double z) {
    Section out;
    const double eps = 1e-9 * std::max(1.0, std::abs(z));
    std::vector<int> side(mesh.positions.size());
    for (std::size_t i = 0; i < mesh.positions.size(); ++i) {
        const double dz = mesh.positions[i].z - z;
        side[i] = dz > eps ? 1 : (dz < -eps ? -1 : 0);
    }
    const auto n = static_cast<std::uint32_t>(mesh.positions.size());

    // (min vertex, max vertex, triangle) per triangle edge, sorted: the edge adjacency
    std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> edges;
    std::vector<bool> valid(mesh.triangles.size(), false);
    for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f) {
        const auto& t = mesh.triangles[f];
        if (t[0] >= n || t[1] >= n || t[2] >= n) {
            out.defects.push_back(
                {"triangle " + std::to_string(f) + ": vertex index out of range", {}, 0.0});
            continue;
        }
        if (t[0] == t[1] || t[1] == t[2] || t[2] == t[0]) {
            out.defects.push_back({"triangle " + std::to_string(f) + ": repeated vertex",
                                   xy(mesh.positions[t[0]]), 0.0});
            continue;
        }
        valid[f] = true;
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = t[k], v = t[(k + 1) % 3];
            edges.emplace_back(std::min(u, v), std::max(u, v), f);
        }
    }
    std::sort(edges.begin(), edges.end());

    for (std::size_t i = 0; i < edges.size();) {
        const std::uint32_t u = std::get<0>(edges[i]), v = std::get<1>(edges[i]);
        std::size_t j = i;
        while (j < edges.size() && std::get<0>(edges[j]) == u && std::get<1>(edges[j]) == v) {
            ++j;
        }
        const Vec2 pu = xy(mesh.positions[u]), pv = xy(mesh.positions[v]);
        if (j - i != 2) {
            out.defects.push_back({"mesh not manifold at edge " + edge_name(u, v) + ": " +
                                       std::to_string(j - i) + " face(s), expected 2",
                                   0.5 * (pu + pv), 0.0});
        }
        if (side[u] == 0 && side[v] == 0) {
            // sides of the faces: the side of each face's third vertex (0: coplanar)
            bool mixed = false;
            int first = 0;
            for (std::size_t k = i; k < j; ++k) {
                const auto& t = mesh.triangles[std::get<2>(edges[k])];
                const std::uint32_t w =
                    t[0] != u && t[0] != v ? t[0] : (t[1] != u && t[1] != v ? t[1] : t[2]);
                if (k == i) {
                    first = side[w];
                } else if (side[w] != first) {
                    mixed = true;
                }
            }
            if (mixed) {
                out.segments.push_back({pu, pv});
                out.origins.push_back("in-plane edge " + edge_name(u, v));
            }
        }
        i = j;
    }

    for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f) {
        if (!valid[f]) {
            continue;
        }
        const auto& t = mesh.triangles[f];
        const bool above = side[t[0]] > 0 || side[t[1]] > 0 || side[t[2]] > 0;
        const bool below = side[t[0]] < 0 || side[t[1]] < 0 || side[t[2]] < 0;
        if (!above || !below) {
            continue;
        }
        std::vector<Vec2> ends;
        for (int k = 0; k < 3; ++k) {
            const std::uint32_t u = std::min(t[k], t[(k + 1) % 3]);
            const std::uint32_t v = std::max(t[k], t[(k + 1) % 3]);
            if (side[t[k]] == 0) {
                ends.push_back(xy(mesh.positions[t[k]]));
            } else if (side[u] * side[v] < 0) {
                // note: parametrised from the lower index, so both faces of the edge agree exactly
                const Vec3 p = mesh.positions[u], q = mesh.positions[v];
                const double s = (z - p.z) / (q.z - p.z);
                ends.push_back({p.x + s * (q.x - p.x), p.y + s * (q.y - p.y)});
            }
        }
        // a triangle with vertices strictly above and below has exactly two section points
        out.segments.push_back({ends[0], ends[1]});
        out.origins.push_back("triangle " + std::to_string(f));
    }
    return out;
}

struct Box {
    Vec2 lo{kInf, kInf};
    Vec2 hi{-kInf, -kInf};

    void add(Vec2 p) {
        lo = {std::min(lo.x, p.x), std::min(lo.y, p.y)};
        hi = {std::max(hi.x, p.x), std::max(hi.y, p.y)};
    }
    void add(const Box& b) {
        add(b.lo);
        add(b.hi);
    }
};

Box box_of(const Segment& s) {
    Box b;
    b.add(s.a);
    b.add(s.b);
    return b;
}

/// A lower bound of the distance between any point of `a` and any point of `b`.
double box_gap(const Box& a, const Box& b) {
    const double dx = std::max({0.0, a.lo.x - b.hi.x, b.lo.x - a.hi.x});
    const double dy = std::max({0.0, a.lo.y - b.hi.y, b.lo.y - a.hi.y});
    return std::hypot(dx, dy);
}

/// Bounding-box tree over a set of segments, for "which segments are near this one" queries.
class SegmentTree {
public:
    explicit SegmentTree(const std::vector<Segment>& segments) : segments_(segments) {
        order_.resize(segments.size());
        for (std::size_t i = 0; i < order_.size(); ++i) {
            order_[i] = i;
        }
        if (!segments.empty()) {
            build(0, order_.size());
        }
    }

    const std::vector<Segment>& segments() const { return segments_; }

    /// Indices (ascending) of the segments at most `r` from `q`.
    std::vector<std::size_t> within(const Segment& q, double r) const {
        std::vector<std::size_t> out;
        if (!nodes_.empty()) {
            collect(0, q, box_of(q), r, out);
        }
        std::sort(out.begin(), out.end());
        return out;
    }

    /// min over segments e of max(d_e(q.a), d_e(q.b)), infinite when there are none. By
    /// convexity of the distance to e along q, no point of q is farther from the union.
    double endpoint_bound(const Segment& q) const {
        double bound = kInf;
        if (!nodes_.empty()) {
            descend(0, q, box_of(q), bound);
        }
        return bound;
    }

private:
    static constexpr std::size_t kLeafSize = 4;

    struct Node {
        Box box;
        std::size_t begin = 0, end = 0;
        std::size_t left = 0, right = 0;  // children; 0 for a leaf (the root is never a child)
    };

    std::size_t build(std::size_t begin, std::size_t end) {
        const std::size_t index = nodes_.size();
        nodes_.emplace_back();
        Box box;
        for (std::size_t i = begin; i < end; ++i) {
            box.add(box_of(segments_[order_[i]]));
        }
        nodes_[index].box = box;
        nodes_[index].begin = begin;
        nodes_[index].end = end;
        if (end - begin <= kLeafSize) {
            return index;
        }
        const bool by_x = box.hi.x - box.lo.x >= box.hi.y - box.lo.y;
        auto key = [&](std::size_t e) {
            const Vec2 c = segments_[e].a + segments_[e].b;
            return by_x ? c.x : c.y;
        };
        const std::size_t mid = begin + (end - begin) / 2;
        std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                         [&](std::size_t u, std::size_t v) { return key(u) < key(v); });
        const std::size_t left = build(begin, mid);
        const std::size_t right = build(mid, end);
        nodes_[index].left = left;
        nodes_[index].right = right;
        return index;
    }

    void collect(std::size_t n,
                 const Segment& q,
                 const Box& qbox,
                 double r,
                 std::vector<std::size_t>& out) const {
        const Node& node = nodes_[n];
        if (box_gap(qbox, node.box) > r) {
            return;
        }
        if (node.left == 0) {
            for (std::size_t i = node.begin; i < node.end; ++i) {
                if (segment_distance(q, segments_[order_[i]]) <= r) {
                    out.push_back(order_[i]);
                }
            }
            return;
        }
        collect(node.left, q, qbox, r, out);
        collect(node.right, q, qbox, r, out);
    }

    void descend(std::size_t n, const Segment& q, const Box& qbox, double& bound) const {
        const Node& node = nodes_[n];
        if (node.left == 0) {
            for (std::size_t i = node.begin; i < node.end; ++i) {
                const Segment& e = segments_[order_[i]];
                bound = std::min(bound, std::max(point_segment_distance(q.a, e),
                                                 point_segment_distance(q.b, e)));
            }
            return;
        }
        const double gap_left = box_gap(qbox, nodes_[node.left].box);
        const double gap_right = box_gap(qbox, nodes_[node.right].box);
        const bool left_first = gap_left <= gap_right;
        const std::size_t first = left_first ? node.left : node.right;
        const std::size_t second = left_first ? node.right : node.left;
        if (std::min(gap_left, gap_right) < bound) {
            descend(first, q, qbox, bound);
        }
        if (std::max(gap_left, gap_right) < bound) {
            descend(second, q, qbox, bound);
        }
    }

    const std::vector<Segment>& segments_;
    std::vector<std::size_t> order_;
    std::vector<Node> nodes_;
};

struct Quadratic {
    double a = 0, b = 0, c = 0;  // a t^2 + b t + c
};

struct Piece {
    double lo = 0, hi = 0;
    Quadratic q;
    std::size_t edge = 0;
};

/// Pieces of t -> squared distance from s(t) to `e` over [t0, t1].
void add_pieces(const Segment& s,
                const Segment& e,
                std::size_t edge,
                double t0,
                double t1,
                std::vector<Piece>& out) {
    const Vec2 v = s.b - s.a;
    auto to_point = [&](Vec2 c) {
        const Vec2 r = s.a - c;
        return Quadratic{dot(v, v), 2 * dot(r, v), dot(r, r)};
    };
    const Vec2 w = e.b - e.a;
    const double ww = dot(w, w);
    if (ww == 0) {
        out.push_back({t0, t1, to_point(e.a), edge});
        return;
    }
    const Vec2 r = s.a - e.a;
    const double u0 = dot(r, w) / ww, u1 = dot(v, w) / ww;
    const double k0 = cross(w, r), k1 = cross(w, v);
    const Quadratic to_line{k1 * k1 / ww, 2 * k0 * k1 / ww, k0 * k0 / ww};
    std::vector<double> cuts{t0, t1};
    if (u1 != 0) {
        for (double t : {-u0 / u1, (1 - u0) / u1}) {
            if (t > t0 && t < t1) {
                cuts.push_back(t);
            }
        }
    }
    std::sort(cuts.begin(), cuts.end());
    for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
        const double u = u0 + u1 * (0.5 * (cuts[i] + cuts[i + 1]));
        const Quadratic q = u < 0 ? to_point(e.a) : (u > 1 ? to_point(e.b) : to_line);
        out.push_back({cuts[i], cuts[i + 1], q, edge});
    }
}

struct Best {
    double distance = -1;
    double t = 0;
    void offer(double d, double t_at) {
        if (d > distance) {
            distance = d;
            t = t_at;
        }
    }
};

class EnvelopeSearch {
public:
    EnvelopeSearch(const Segment& s, const SegmentTree& onto)
        : s_(s), tree_(onto), onto_(onto.segments()) {}

    /// Max over t in [t0, t1] of the distance from s(t) to the nearest of `onto`, raising `best`
    /// (infinite when `onto` is empty).
    void run(double t0, double t1, Best& best) {
        const Segment piece{s_.at(t0), s_.at(t1)};
        const double bound = tree_.endpoint_bound(piece);
        if (bound == kInf) {
            best.offer(kInf, t0);
            return;
        }
        if (bound <= best.distance) {
            return;
        }
        search(t0, t1, tree_.within(piece, bound + slack(bound)), 0, best);
    }

private:
    double nearest(Vec2 p, const std::vector<std::size_t>& edges) const {
        double d = kInf;
        for (std::size_t e : edges) {
            d = std::min(d, point_segment_distance(p, onto_[e]));
        }
        return d;
    }

    void search(
        double t0, double t1, const std::vector<std::size_t>& edges, int depth, Best& best) const {
        const Vec2 p0 = s_.at(t0), p1 = s_.at(t1);
        double f0 = kInf, f1 = kInf, bound = kInf;
        for (std::size_t e : edges) {
            const double d0 = point_segment_distance(p0, onto_[e]);
            const double d1 = point_segment_distance(p1, onto_[e]);
            f0 = std::min(f0, d0);
            f1 = std::min(f1, d1);
            bound = std::min(bound, std::max(d0, d1));
        }
        best.offer(f0, t0);
        best.offer(f1, t1);
        if (bound <= best.distance || bound == kInf) {
            return;
        }
        // note: by convexity no point of [t0, t1] is farther than `bound` from its nearest edge,
        // so edges farther than `bound` from the whole piece are never nearest on it
        const Segment piece{p0, p1};
        std::vector<std::size_t> near;
        for (std::size_t e : edges) {
            if (segment_distance(piece, onto_[e]) <= bound + slack(bound)) {
                near.push_back(e);
            }
        }
        if (near.size() <= kExactEdges) {
            solve_exact(t0, t1, near, best);
            return;
        }
        if (depth >= kMaxDepth || bound - std::max(f0, f1) <= slack(bound)) {
            return;
        }
        const double mid = 0.5 * (t0 + t1);
        search(t0, mid, near, depth + 1, best);
        search(mid, t1, near, depth + 1, best);
    }

    void solve_exact(double t0,
                     double t1,
                     const std::vector<std::size_t>& edges,
                     Best& best) const {
        std::vector<Piece> pieces;
        for (std::size_t e : edges) {
            add_pieces(s_, onto_[e], e, t0, t1, pieces);
        }
        std::vector<double> candidates;
        for (std::size_t i = 0; i < pieces.size(); ++i) {
            candidates.push_back(pieces[i].lo);
            for (std::size_t j = i + 1; j < pieces.size(); ++j) {
                if (pieces[i].edge == pieces[j].edge) {
                    continue;
                }
                const double lo = std::max(pieces[i].lo, pieces[j].lo);
                const double hi = std::min(pieces[i].hi, pieces[j].hi);
                if (lo > hi) {
                    continue;
                }
                const double a = pieces[i].q.a - pieces[j].q.a;
                const double b = pieces[i].q.b - pieces[j].q.b;
                const double c = pieces[i].q.c - pieces[j].q.c;
                std::vector<double> roots;
                if (a != 0) {
                    // note: the vertex too, so that a tangency lost to rounding is still sampled
                    roots.push_back(-b / (2 * a));
                    const double disc = b * b - 4 * a * c;
                    if (disc >= 0) {
                        const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
                        roots.push_back(q / a);
                        if (q != 0) {
                            roots.push_back(c / q);
                        }
                    }
                }
                if (b != 0) {
                    roots.push_back(-c / b);  // the root when a is only rounding noise
                }
                for (double t : roots) {
                    if (t >= lo && t <= hi) {
                        candidates.push_back(t);
                    }
                }
            }
        }
        candidates.push_back(t1);
        for (double t : candidates) {
            best.offer(nearest(s_.at(t), edges), t);
        }
    }

    static double slack(double bound) { return 1e-12 * (1 + bound); }

    const Segment& s_;
    const SegmentTree& tree_;
    const std::vector<Segment>& onto_;
};

/// Collects mismatches, keeping the first few.
class MismatchList {
public:
    void add(SectionMismatch m) {
        ++count_;
        if (listed_.size() < kMaxListed) {
            listed_.push_back(std::move(m));
        }
    }
    std::vector<SectionMismatch> finish() && {
        if (count_ > kMaxListed) {
            listed_.back() = {
                std::to_string(count_ - kMaxListed + 1) + " more mismatches not listed",
                listed_.back().where, listed_.back().distance_px};
        }
        return std::move(listed_);
    }

private:
    std::vector<SectionMismatch> listed_;
    std::size_t count_ = 0;
};

std::string format_mismatch(const std::string& name, double distance, double tolerance) {
    std::ostringstream text;
    text << name << ": " << distance << " px away, tolerance " << tolerance;
    return text.str();
}

/// Checks that every segment of `from` lies on `onto` (pieces between projections of nearby
/// `onto` endpoints each within tolerance of one `onto` segment); returns the exact directed
/// Hausdorff distance.
double check_cover(const std::vector<Segment>& from,
                   const std::vector<std::string>& names,
                   const std::vector<Segment>& onto,
                   double tolerance_px,
                   MismatchList& mismatches) {
    const SegmentTree tree(onto);
    Best overall;
    overall.distance = 0;
    for (std::size_t i = 0; i < from.size(); ++i) {
        const Segment& s = from[i];
        EnvelopeSearch search(s, tree);
        search.run(0, 1, overall);
        const std::vector<std::size_t> near = tree.within(s, tolerance_px);
        std::vector<double> cuts{0, 1};
        for (std::size_t e : near) {
            for (Vec2 p : {onto[e].a, onto[e].b}) {
                if (point_segment_distance(p, s) <= tolerance_px) {
                    cuts.push_back(projection_parameter(s, p));
                }
            }
        }
        std::sort(cuts.begin(), cuts.end());
        cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
        Best worst;  // the worst uncovered piece of this segment
        for (std::size_t k = 0; k + 1 < cuts.size(); ++k) {
            const double ta = cuts[k], tb = cuts[k + 1];
            const Vec2 pa = s.at(ta), pb = s.at(tb);
            const bool covered = std::any_of(near.begin(), near.end(), [&](std::size_t e) {
                return point_segment_distance(pa, onto[e]) <= tolerance_px &&
                       point_segment_distance(pb, onto[e]) <= tolerance_px;
            });
            if (!covered) {
                Best piece;
                search.run(ta, tb, piece);
                worst.offer(piece.distance, piece.t);
            }
        }
        if (worst.distance >= 0) {
            mismatches.add({format_mismatch(names[i], worst.distance, tolerance_px), s.at(worst.t),
                            worst.distance});
        }
    }
    return overall.distance;
}

}  // namespace

SectionReport compare_slice_section(const TriMesh& mesh,
                                    double z,
                                    const std::vector<std::vector<Vec2>>& polygons,
                                    double tolerance_px) {
    Section section = section_of(mesh, z);
    std::vector<Segment> edges;
    std::vector<std::string> edge_names;
    for (std::size_t p = 0; p < polygons.size(); ++p) {
        const auto& polygon = polygons[p];
        for (std::size_t i = 0; i < polygon.size(); ++i) {
            edges.push_back({polygon[i], polygon[(i + 1) % polygon.size()]});
            edge_names.push_back("contour edge " + std::to_string(i) + " of polygon " +
                                 std::to_string(p) + " not covered by the section");
        }
    }
    for (std::string& name : section.origins) {
        name = "section segment of " + name + " off the contours";
    }

    SectionReport report;
    report.mesh_segments = section.segments.size();
    report.contour_edges = edges.size();
    MismatchList mismatches;
    for (SectionMismatch& defect : section.defects) {
        mismatches.add(std::move(defect));
    }
    report.max_mesh_to_contour_px =
        check_cover(section.segments, section.origins, edges, tolerance_px, mismatches);
    report.max_contour_to_mesh_px =
        check_cover(edges, edge_names, section.segments, tolerance_px, mismatches);
    report.mismatches = std::move(mismatches).finish();
    return report;
}

std::vector<std::vector<Vec2>> simplified_polygons(const SliceContourSet& set,
                                                   std::uint16_t label) {
    std::vector<std::vector<Vec2>> out;
    for (std::size_t c = 0; c < set.contours.size(); ++c) {
        const Contour& contour = set.contours[c];
        if (contour.label != label) {
            continue;
        }
        std::vector<Vec2> polygon;
        for (std::uint32_t index : contour.simplified) {
            if (index >= contour.points.size()) {
                throw Error(ErrorCode::Internal,
                            "contour " + std::to_string(c) + " (label " + std::to_string(label) +
                                "): simplified index " + std::to_string(index) + ", expected < " +
                                std::to_string(contour.points.size()));
            }
            polygon.push_back(contour.points[index]);
        }
        out.push_back(std::move(polygon));
    }
    return out;
}

std::vector<std::array<Vec2, 2>> slice_section_segments(const TriMesh& mesh, double z) {
    std::vector<std::array<Vec2, 2>> out;
    for (const Segment& s : section_of(mesh, z).segments) {
        out.push_back({s.a, s.b});
    }
    return out;
}

}  // namespace strata::test

#pragma once

// The path hull of Hershberger & Snoeyink ("Speeding up the Douglas-Peucker line-simplification
// algorithm", 1992): two Melkman convex-hull deques grown outward from a tag point, each with a
// history stack so that the hull of a prefix can be restored by undoing, plus extreme-point
// queries by binary search. Used by simplify_contours.cpp; here so tests can check the queries
// against brute force.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/types.h"

namespace strata::detail {

/// Error-free transformation: s + e == a + b exactly (Knuth's two-sum).
inline void two_sum(double a, double b, double& s, double& e) {
    s = a + b;
    const double bv = s - a;
    const double av = s - bv;
    e = (a - av) + (b - bv);
}

/// Sign of the determinant |b-a, c-a| computed exactly (Shewchuk's expansion arithmetic), for
/// the rare cases the floating-point filter cannot decide.
inline int orientation_exact(Vec2 a, Vec2 b, Vec2 c) {
    double bx[2], by[2], cx[2], cy[2];
    two_sum(b.x, -a.x, bx[0], bx[1]);
    two_sum(b.y, -a.y, by[0], by[1]);
    two_sum(c.x, -a.x, cx[0], cx[1]);
    two_sum(c.y, -a.y, cy[0], cy[1]);
    // note: 8 products of two-term differences, each split exactly by fma into 2 terms, summed
    // into a nonoverlapping expansion of increasing magnitude (Grow-Expansion).
    double expansion[16];
    int size = 0;
    const auto grow = [&](double value) {
        double q = value;
        for (int i = 0; i < size; ++i) {
            double s, e;
            two_sum(q, expansion[i], s, e);
            expansion[i] = e;
            q = s;
        }
        expansion[size++] = q;
    };
    for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
            const double p = bx[i] * cy[j];
            grow(p);
            grow(std::fma(bx[i], cy[j], -p));
            const double q = -(by[i] * cx[j]);
            grow(q);
            grow(std::fma(-by[i], cx[j], -q));
        }
    }
    for (int i = size - 1; i >= 0; --i) {
        if (expansion[i] != 0.0) {
            return expansion[i] > 0.0 ? 1 : -1;
        }
    }
    return 0;
}

/// Exact sign of the orientation of (a, b, c): +1 counter-clockwise (c left of a->b), -1
/// clockwise, 0 collinear. A floating-point filter (Shewchuk's ccwerrboundA) decides almost
/// always; otherwise exact expansion arithmetic. Finite, non-subnormal coordinates assumed.
inline int orientation(Vec2 a, Vec2 b, Vec2 c) {
    const double left = (b.x - a.x) * (c.y - a.y);
    const double right = (b.y - a.y) * (c.x - a.x);
    const double det = left - right;
    const double bound = 3.3306690738754716e-16 * (std::abs(left) + std::abs(right));
    if (det > bound) {
        return 1;
    }
    if (-det > bound) {
        return -1;
    }
    return orientation_exact(a, b, c);
}

/// A point of a hull and its signed offset from a line (cross product, not yet divided by the
/// line's length).
struct HullExtreme {
    std::uint32_t index = 0;
    double offset = 0.0;
};

/// One half of the path hull: the convex hull of the chain from the tag outward, by Melkman's
/// algorithm (A. A. Melkman, "On-line construction of the convex hull of a simple polyline",
/// IPL 25, 1987). The deque holds point indices; deque_[bot_] == deque_[top_] is the point added
/// last and deque_[bot_..top_) lists the hull counter-clockwise. Every change is recorded so
/// that `undo_after(k)` restores the hull of the chain from the tag up to point k.
///
/// Exact for simple chains (up to collinear hull vertices). For a self-intersecting chain
/// Melkman's algorithm may drop points, so queries can miss the true extreme; callers must not
/// rely on them for correctness then (simplify_contours verifies every accepted segment).
class HalfHull {
public:
    /// Sizes the buffers for chains of up to `max_points` points.
    void reserve(std::size_t max_points) {
        center_ = max_points + 1;
        deque_.assign(2 * max_points + 3, 0);
        history_.clear();
        history_.reserve(3 * max_points);
    }

    /// Starts the hull of the chain tag, next (next = tag + 1 or tag - 1).
    void start(std::span<const Vec2> points, std::uint32_t tag, std::uint32_t next) {
        points_ = points;
        increasing_ = next > tag;
        history_.clear();
        bot_ = center_ - 1;
        top_ = center_ + 1;
        deque_[center_] = tag;
        deque_[bot_] = next;
        deque_[top_] = next;
        history_.push_back({next, kPush});
    }

    /// Adds the next point of the chain (one step of Melkman's algorithm).
    void add(std::uint32_t index) {
        const Vec2 p = points_[index];
        if (top_ - bot_ == 2) {
            // note: all points so far are collinear; the hull is a segment [other, last].
            const Vec2 last = points_[deque_[top_]];
            const Vec2 other = points_[deque_[bot_ + 1]];
            if (orientation(other, last, p) == 0) {
                if (dot(last - other, p - last) > 0.0) {
                    pop_bot();
                    pop_top();
                    push(index);
                } else if (!(p == last)) {
                    // note: only a self-overlapping chain gets here; keep all three points.
                    pop_top();
                    push(index);
                }
                return;
            }
        }
        int top_side = orientation(at(top_ - 1), at(top_), p);
        int bot_side = orientation(at(bot_), at(bot_ + 1), p);
        if (top_side > 0 && bot_side > 0) {
            return;  // inside the hull
        }
        // note: popping at one end leaves the other end's edge unchanged while >= 2 remain.
        while (top_ - bot_ >= 2 && bot_side <= 0) {
            pop_bot();
            bot_side = orientation(at(bot_), at(bot_ + 1), p);
        }
        while (top_ - bot_ >= 2 && top_side <= 0) {
            pop_top();
            top_side = orientation(at(top_ - 1), at(top_), p);
        }
        push(index);
    }

    /// Restores the hull as it was right after point k was added (k between the tag's
    /// neighbour and the last added point), undoing all later changes.
    void undo_after(std::uint32_t k) {
        while (!history_.empty()) {
            const Change change = history_.back();
            if (change.kind == kPush && (increasing_ ? change.point <= k : change.point >= k)) {
                return;
            }
            history_.pop_back();
            switch (change.kind) {
                case kPush:
                    --top_;
                    ++bot_;
                    break;
                case kPopTop:
                    deque_[++top_] = change.point;
                    break;
                case kPopBot:
                    deque_[--bot_] = change.point;
                    break;
            }
        }
    }

    /// The hull vertices, counter-clockwise, starting at the point added last.
    std::span<const std::uint32_t> vertices() const {
        return {deque_.data() + bot_, static_cast<std::size_t>(top_ - bot_)};
    }

    /// The hull vertices with the largest and smallest signed offset cross(b - a, v - a) from
    /// the line through a and b (a != b), by binary search over the hull: O(log h).
    void extremes(Vec2 a, Vec2 b, HullExtreme& max, HullExtreme& min) const {
        const Vec2 d = b - a;
        const std::size_t m = static_cast<std::size_t>(top_ - bot_);
        const auto vertex = [&](std::size_t k) { return deque_[bot_ + k % m]; };
        // note: keys compare by offset, ties by position along the line: a symbolic rotation of
        // the normal, so that collinear hull vertices and edges parallel to the line give a
        // strictly bitonic cyclic sequence.
        const auto less = [&](std::uint32_t p, std::uint32_t q) {
            const Vec2 wp = points_[p] - a;
            const Vec2 wq = points_[q] - a;
            const double fp = cross(d, wp);
            const double fq = cross(d, wq);
            return fp != fq ? fp < fq : dot(d, wp) < dot(d, wq);
        };
        std::size_t kmax = 0;
        std::size_t kmin = 0;
        if (m <= 8) {
            for (std::size_t k = 1; k < m; ++k) {
                if (less(vertex(kmax), vertex(k))) {
                    kmax = k;
                }
                if (less(vertex(k), vertex(kmin))) {
                    kmin = k;
                }
            }
        } else {
            const std::uint32_t first = vertex(0);
            const auto up = [&](std::size_t k) { return less(vertex(k), vertex(k + 1)); };
            const bool rising = up(0);
            // The run starting at vertex 0 ends at one extreme: the first k whose edge leaves
            // the run, or that lies past the other extreme (back below/above vertex 0).
            std::size_t lo = 1;
            std::size_t hi = m;
            while (lo < hi) {
                const std::size_t mid = lo + (hi - lo) / 2;
                const bool in_run = rising ? up(mid) && !less(vertex(mid), first)
                                           : !up(mid) && !less(first, vertex(mid));
                if (in_run) {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            const std::size_t turn = lo;
            // The other extreme: the first edge after `turn` that turns back (else vertex 0).
            hi = m;
            while (lo < hi) {
                const std::size_t mid = lo + (hi - lo) / 2;
                if (up(mid) != rising) {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            (rising ? kmax : kmin) = turn;
            (rising ? kmin : kmax) = lo;
        }
        max.index = vertex(kmax);
        max.offset = cross(d, points_[max.index] - a);
        min.index = vertex(kmin);
        min.offset = cross(d, points_[min.index] - a);
    }

    /// The hull vertex farthest from a (first in deque order on ties), and its distance:
    /// O(h), for segments whose ends coincide (the farthest point of a set is a hull vertex).
    HullExtreme farthest_from(Vec2 a) const {
        HullExtreme best{deque_[bot_], -1.0};
        for (const std::uint32_t v : vertices()) {
            const double distance = norm(points_[v] - a);
            if (distance > best.offset) {
                best = {v, distance};
            }
        }
        return best;
    }

private:
    enum Kind : std::uint8_t { kPush, kPopTop, kPopBot };
    struct Change {
        std::uint32_t point;
        Kind kind;
    };

    Vec2 at(std::ptrdiff_t slot) const { return points_[deque_[slot]]; }
    void push(std::uint32_t index) {
        deque_[++top_] = index;
        deque_[--bot_] = index;
        history_.push_back({index, kPush});
    }
    void pop_top() { history_.push_back({deque_[top_--], kPopTop}); }
    void pop_bot() { history_.push_back({deque_[bot_++], kPopBot}); }

    std::span<const Vec2> points_;
    std::vector<std::uint32_t> deque_;
    std::vector<Change> history_;
    std::ptrdiff_t center_ = 0;
    std::ptrdiff_t bot_ = 0;
    std::ptrdiff_t top_ = 0;
    bool increasing_ = true;
};

/// The path hull of a chain points[first..last] (at least 3 points): the hulls of
/// [first, tag] and [tag, last] with the tag in the middle. Splitting at a point k keeps the
/// half containing the tag valid in O(undone changes); the other half must be rebuilt, which
/// costs each point O(log n) rebuilds over a whole Douglas-Peucker run.
class PathHull {
public:
    void reserve(std::size_t max_points) {
        left_.reserve(max_points);
        right_.reserve(max_points);
    }

    /// Builds the hull of points[first..last], first + 2 <= last: O(last - first).
    void build(std::span<const Vec2> points, std::uint32_t first, std::uint32_t last) {
        tag_ = first + (last - first) / 2;
        left_.start(points, tag_, tag_ - 1);
        for (std::uint32_t k = tag_ - 1; k-- > first;) {
            left_.add(k);
        }
        right_.start(points, tag_, tag_ + 1);
        for (std::uint32_t k = tag_ + 2; k <= last; ++k) {
            right_.add(k);
        }
    }

    std::uint32_t tag() const { return tag_; }

    /// Keeps the hull of [first, k] if k > tag, or of [k, last] if k < tag (k != tag).
    void split(std::uint32_t k) {
        if (k > tag_) {
            right_.undo_after(k);
        } else {
            left_.undo_after(k);
        }
    }

    /// The point of the chain farthest from the line through a and b (a != b), with its
    /// absolute offset |cross(b - a, p - a)|; ties prefer the smaller index.
    HullExtreme farthest_from_line(Vec2 a, Vec2 b) const {
        HullExtreme candidates[4];
        left_.extremes(a, b, candidates[0], candidates[1]);
        right_.extremes(a, b, candidates[2], candidates[3]);
        HullExtreme best{candidates[0].index, std::abs(candidates[0].offset)};
        for (const HullExtreme& c : candidates) {
            const double offset = std::abs(c.offset);
            if (offset > best.offset || (offset == best.offset && c.index < best.index)) {
                best = {c.index, offset};
            }
        }
        return best;
    }

    /// The point of the chain farthest from a, with its distance.
    HullExtreme farthest_from_point(Vec2 a) const {
        const HullExtreme l = left_.farthest_from(a);
        const HullExtreme r = right_.farthest_from(a);
        return r.offset > l.offset ? r : l;
    }

    const HalfHull& left() const { return left_; }
    const HalfHull& right() const { return right_; }

private:
    HalfHull left_;
    HalfHull right_;
    std::uint32_t tag_ = 0;
};

}  // namespace strata::detail

// Medial axes between neighbouring slices (Klein, Schilling, Strasser, section 4.2): the zero
// set of D_k + D_k+1 traced by marching squares on the half-pixel node grid, oriented like the
// contours, every point carrying its closest contour sites on both slices; contour runs without
// correspondence (section 5, Fig. 7) are reported for the triangulation.

#include "medial/medial_axis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>

#include "core/error.h"
#include "core/parallel.h"

namespace strata {

namespace {

const DistanceField* find_field(const SliceDistanceFields& fields, std::uint16_t label) {
    for (const DistanceField& f : fields.fields) {
        if (f.label == label) {
            return &f;
        }
    }
    return nullptr;
}

/// Simplified edge of `contour` holding original point `point` (edge e covers points
/// simplified[e] .. simplified[e+1]; the last edge wraps around).
std::uint32_t simplified_edge(const Contour& contour, std::uint32_t point) {
    const auto& s = contour.simplified;
    if (s.empty()) {
        return 0;
    }
    auto it = std::upper_bound(s.begin(), s.end(), point);
    if (it == s.begin()) {
        return static_cast<std::uint32_t>(s.size() - 1);  // before the first kept point: wraps
    }
    return static_cast<std::uint32_t>(it - s.begin() - 1);
}

/// The sum field over the common window of two fields of one label.
struct SumGrid {
    std::int64_t nx = 0;
    std::int64_t ny = 0;
    double origin_x = 0;  // px
    double origin_y = 0;
    std::int64_t offset_a_x = 0;  // node offsets into the two fields
    std::int64_t offset_a_y = 0;
    std::int64_t offset_b_x = 0;
    std::int64_t offset_b_y = 0;
    std::vector<float> sum;

    float at(std::int64_t i, std::int64_t j) const { return sum[j * nx + i]; }
    Vec2 position(double i, double j) const {
        return {origin_x + DistanceField::kCellPx * i, origin_y + DistanceField::kCellPx * j};
    }
};

SumGrid sum_fields(const DistanceField& a, const DistanceField& b) {
    auto nodes = [](double px) { return static_cast<std::int64_t>(std::llround(px * 2.0)); };
    const std::int64_t ax0 = nodes(a.origin_x);
    const std::int64_t ay0 = nodes(a.origin_y);
    const std::int64_t bx0 = nodes(b.origin_x);
    const std::int64_t by0 = nodes(b.origin_y);
    const std::int64_t x0 = std::max(ax0, bx0);
    const std::int64_t y0 = std::max(ay0, by0);
    const std::int64_t x1 = std::min(ax0 + a.nx, bx0 + b.nx);
    const std::int64_t y1 = std::min(ay0 + a.ny, by0 + b.ny);
    SumGrid g;
    if (x1 - x0 < 2 || y1 - y0 < 2) {
        return g;
    }
    g.nx = x1 - x0;
    g.ny = y1 - y0;
    g.origin_x = x0 * 0.5;
    g.origin_y = y0 * 0.5;
    g.offset_a_x = x0 - ax0;
    g.offset_a_y = y0 - ay0;
    g.offset_b_x = x0 - bx0;
    g.offset_b_y = y0 - by0;
    g.sum.resize(static_cast<std::size_t>(g.nx * g.ny));
    std::vector<float> rb(static_cast<std::size_t>(g.nx));
    const auto count = static_cast<std::uint32_t>(g.nx);
    for (std::int64_t j = 0; j < g.ny; ++j) {
        float* out = g.sum.data() + j * g.nx;
        a.distance_row(static_cast<std::uint32_t>(j + g.offset_a_y),
                       static_cast<std::uint32_t>(g.offset_a_x), count, out);
        b.distance_row(static_cast<std::uint32_t>(j + g.offset_b_y),
                       static_cast<std::uint32_t>(g.offset_b_x), count, rb.data());
        for (std::int64_t i = 0; i < g.nx; ++i) {
            out[i] += rb[static_cast<std::size_t>(i)];
        }
    }
    return g;
}

/// Arc-length positions of a contour's points (cumulative, closed length last).
std::vector<double> arc_lengths(const Contour& c) {
    std::vector<double> s(c.points.size() + 1, 0.0);
    for (std::size_t i = 0; i < c.points.size(); ++i) {
        s[i + 1] = s[i] + norm(c.points[(i + 1) % c.points.size()] - c.points[i]);
    }
    return s;
}

/// Marks the points of one slice's contours that medial points correspond to.
class Coverage {
public:
    Coverage(const SliceContourSet& set, const MedialOptions& options)
        : set_(set), options_(options), covered_(set.contours.size()), arcs_(set.contours.size()) {}

    void mark_site(const ContourSite& s) {
        auto& cov = ensure(s.contour);
        cov[s.point] = true;
        if (s.is_midpoint) {
            cov[(s.point + 1) % cov.size()] = true;
        }
    }

    /// Covers the contour between the sites of two consecutive medial points (the shorter way
    /// round) unless it is a jump: a skipped point farther than jump_px from their chord.
    void mark_step(const ContourSite& a, const ContourSite& b) {
        mark_site(a);
        mark_site(b);
        if (a.contour != b.contour) {
            return;
        }
        const Contour& contour = set_.contours[a.contour];
        const auto& arc = arcs_[a.contour];
        const double length = arc.back();
        auto where = [&](const ContourSite& s) {
            const double base = arc[s.point];
            return s.is_midpoint ? 0.5 * (base + arc[s.point + 1]) : base;
        };
        double forward = where(b) - where(a);
        if (forward < 0) {
            forward += length;
        }
        const bool go_forward = forward <= length - forward;
        const ContourSite& from = go_forward ? a : b;
        const ContourSite& to = go_forward ? b : a;
        if (from.point == to.point) {
            return;
        }
        const Vec2 p = site_position(set_, from);
        const Vec2 q = site_position(set_, to);
        const Vec2 pq = q - p;
        const double len2 = dot(pq, pq);
        auto& cov = covered_[a.contour];
        const std::size_t n = cov.size();
        for (std::size_t i = (from.point + 1) % n; i != to.point; i = (i + 1) % n) {
            const Vec2 x = contour.points[i];
            const double t = len2 > 0 ? std::clamp(dot(x - p, pq) / len2, 0.0, 1.0) : 0.0;
            if (norm(x - (p + t * pq)) > options_.jump_px) {
                return;  // a jump: leave the skipped points uncovered
            }
        }
        for (std::size_t i = (from.point + 1) % n; i != to.point; i = (i + 1) % n) {
            cov[i] = true;
        }
    }

    /// Runs of uncovered points, for the contours of `labels` (whole contours when never seen).
    void collect(bool on_upper,
                 const std::vector<std::uint16_t>& labels,
                 std::vector<UnmatchedRun>& out) const {
        for (std::uint32_t c = 0; c < set_.contours.size(); ++c) {
            const Contour& contour = set_.contours[c];
            if (!std::binary_search(labels.begin(), labels.end(), contour.label)) {
                continue;
            }
            const std::uint32_t n = static_cast<std::uint32_t>(contour.points.size());
            const auto& cov = covered_[c];
            if (cov.empty()) {
                out.push_back({on_upper, c, 0, n});
                continue;
            }
            // start scanning just after a covered point so runs do not wrap
            std::uint32_t start = 0;
            while (start < n && !cov[start]) {
                ++start;
            }
            if (start == n) {
                out.push_back({on_upper, c, 0, n});
                continue;
            }
            std::uint32_t run_first = 0;
            std::uint32_t run_count = 0;
            for (std::uint32_t step = 1; step <= n; ++step) {
                const std::uint32_t i = (start + step) % n;
                if (!cov[i]) {
                    if (run_count == 0) {
                        run_first = i;
                    }
                    ++run_count;
                } else if (run_count > 0) {
                    out.push_back({on_upper, c, run_first, run_count});
                    run_count = 0;
                }
            }
        }
    }

private:
    std::vector<bool>& ensure(std::uint32_t contour) {
        auto& cov = covered_.at(contour);
        if (cov.empty()) {
            cov.assign(set_.contours[contour].points.size(), false);
            arcs_[contour] = arc_lengths(set_.contours[contour]);
        }
        return cov;
    }

    const SliceContourSet& set_;
    const MedialOptions& options_;
    std::vector<std::vector<bool>> covered_;
    std::vector<std::vector<double>> arcs_;
};

/// A grid edge the boundary crosses and the next such edge along the boundary.
struct BoundaryLink {
    std::int64_t from = 0;
    std::int64_t to = 0;
};

/// Marching squares on {sum < 0}: for each grid edge the boundary crosses, the next such edge
/// along the boundary (inside on the left), sorted by `from` (one link per edge). Grid edge ids:
/// 2 * node + 0 for the edge to the right, 2 * node + 1 for the edge down.
/// note: only the crossed edges are stored, not an entry per grid edge (T32's 4096^2 slices:
/// 620 MB a slice pair)
std::vector<BoundaryLink> boundary_links(const SumGrid& g) {
    const std::int64_t nx = g.nx;
    const std::int64_t ny = g.ny;
    auto inside = [&](std::int64_t i, std::int64_t j) { return g.at(i, j) < 0.0f; };
    std::vector<BoundaryLink> next;
    for (std::int64_t j = 0; j + 1 < ny; ++j) {
        for (std::int64_t i = 0; i + 1 < nx; ++i) {
            // corners counter-clockwise in (x, y): c00, c10, c11, c01; edges e0..e3 between them
            const std::array<bool, 4> in = {inside(i, j), inside(i + 1, j), inside(i + 1, j + 1),
                                            inside(i, j + 1)};
            const int count = in[0] + in[1] + in[2] + in[3];
            if (count == 0 || count == 4) {
                continue;
            }
            const std::array<std::int64_t, 4> edge = {
                2 * (j * nx + i),          // e0: c00-c10
                2 * (j * nx + i + 1) + 1,  // e1: c10-c11
                2 * ((j + 1) * nx + i),    // e2: c11-c01 (the edge right of c01)
                2 * (j * nx + i) + 1,      // e3: c01-c00 (the edge below c00)
            };
            // crossings in counter-clockwise order: in->out starts a segment, out->in ends it
            std::array<int, 2> starts{};
            std::array<int, 2> ends{};
            int ns = 0;
            int ne = 0;
            for (int e = 0; e < 4; ++e) {
                const bool a = in[e];
                const bool b = in[(e + 1) % 4];
                if (a && !b) {
                    starts[ns++] = e;
                } else if (!a && b) {
                    ends[ne++] = e;
                }
            }
            auto next_end_after = [&](int s) {
                for (int step = 1; step <= 4; ++step) {
                    const int e = (s + step) % 4;
                    if ((e == ends[0]) || (ne == 2 && e == ends[1])) {
                        return e;
                    }
                }
                return ends[0];
            };
            if (ns == 1) {
                next.push_back({edge[starts[0]], edge[ends[0]]});
            } else {
                // saddle: join the inside corners when the cell centre is inside
                const float centre =
                    g.at(i, j) + g.at(i + 1, j) + g.at(i + 1, j + 1) + g.at(i, j + 1);
                for (int s = 0; s < 2; ++s) {
                    const int e_start = starts[s];
                    int e_end = 0;
                    if (centre < 0.0f) {
                        e_end = next_end_after(e_start);
                    } else {
                        // the previous out->in crossing going clockwise
                        for (int step = 1; step <= 4; ++step) {
                            const int e = (e_start + 4 - step) % 4;
                            if (e == ends[0] || e == ends[1]) {
                                e_end = e;
                                break;
                            }
                        }
                    }
                    next.push_back({edge[e_start], edge[e_end]});
                }
            }
        }
    }
    // note: a later link of the same edge replaced an earlier one in the per-edge table
    std::stable_sort(next.begin(), next.end(),
                     [](const BoundaryLink& a, const BoundaryLink& b) { return a.from < b.from; });
    std::size_t kept = 0;
    for (std::size_t n = 0; n < next.size(); ++n) {
        if (kept > 0 && next[kept - 1].from == next[n].from) {
            next[kept - 1] = next[n];
        } else {
            next[kept++] = next[n];
        }
    }
    next.resize(kept);
    return next;
}

/// Where the boundary crosses grid edge `id`.
Vec2 edge_crossing(const SumGrid& g, std::int64_t id) {
    const std::int64_t nx = g.nx;
    auto inside = [&](std::int64_t i, std::int64_t j) { return g.at(i, j) < 0.0f; };
    const std::int64_t node = id / 2;
    std::int64_t pi = node % nx;
    std::int64_t pj = node / nx;
    std::int64_t qi = (id % 2 == 0) ? pi + 1 : pi;
    std::int64_t qj = (id % 2 == 0) ? pj : pj + 1;
    // note: parametrised from the inside node so both cells compute the same point
    if (!inside(pi, pj)) {
        std::swap(pi, qi);
        std::swap(pj, qj);
    }
    const double sp = g.at(pi, pj);
    const double sq = g.at(qi, qj);
    const double t = sp / (sp - sq);
    return g.position(pi + t * (qi - pi), pj + t * (qj - pj));
}

/// The two grid nodes of edge `id`: (i0, j0, i1, j1).
std::array<std::int64_t, 4> edge_nodes(const SumGrid& g, std::int64_t id) {
    const std::int64_t nx = g.nx;
    const std::int64_t node = id / 2;
    const std::int64_t i = node % nx;
    const std::int64_t j = node / nx;
    return std::array<std::int64_t, 4>{i, j, (id % 2 == 0) ? i + 1 : i, (id % 2 == 0) ? j : j + 1};
}

/// The closer to `p` of the closest sites of field `f` at the nodes `n` (grid nodes, offset by
/// (ox, oy) in the field); its distance goes to `distance`.
ContourSite closest_site(const DistanceField& f,
                         const SliceContourSet& set,
                         std::int64_t ox,
                         std::int64_t oy,
                         const std::array<std::int64_t, 4>& n,
                         Vec2 p,
                         double& distance) {
    const std::uint32_t s0 = f.closest(static_cast<std::size_t>((n[1] + oy) * f.nx + n[0] + ox));
    const std::uint32_t s1 = f.closest(static_cast<std::size_t>((n[3] + oy) * f.nx + n[2] + ox));
    const double d0 = norm(p - site_position(set, f.sites[s0]));
    const double d1 = norm(p - site_position(set, f.sites[s1]));
    const bool second = d1 < d0 || (d1 == d0 && s1 < s0);
    distance = second ? d1 : d0;
    return f.sites[second ? s1 : s0];
}

/// Traces the boundary of {sum < 0} (marching squares, inside on the left) and attaches the
/// correspondences.
void trace_label(std::uint16_t label,
                 const SumGrid& g,
                 const DistanceField& fa,
                 const DistanceField& fb,
                 const SliceContourSet& lower,
                 const SliceContourSet& upper,
                 std::vector<MedialCurve>& curves) {
    if (g.nx < 2 || g.ny < 2) {
        return;
    }
    const std::vector<BoundaryLink> next = boundary_links(g);
    std::vector<bool> used(next.size(), false);
    auto link_of = [&](std::int64_t id) {
        const auto it =
            std::lower_bound(next.begin(), next.end(), id,
                             [](const BoundaryLink& l, std::int64_t e) { return l.from < e; });
        return it != next.end() && it->from == id ? std::size_t(it - next.begin()) : next.size();
    };
    for (std::size_t first = 0; first < next.size(); ++first) {
        if (used[first]) {
            continue;
        }
        MedialCurve curve;
        curve.label = label;
        const std::int64_t start = next[first].from;
        std::int64_t id = start;
        std::size_t link = first;
        do {
            used[link] = true;
            const Vec2 p = edge_crossing(g, id);
            if (curve.points.empty() || !(curve.points.back().position == p)) {
                MedialPoint m;
                m.position = p;
                const auto n = edge_nodes(g, id);
                m.lower =
                    closest_site(fa, lower, g.offset_a_x, g.offset_a_y, n, p, m.lower_distance_px);
                m.upper =
                    closest_site(fb, upper, g.offset_b_x, g.offset_b_y, n, p, m.upper_distance_px);
                m.lower_edge = simplified_edge(lower.contours[m.lower.contour], m.lower.point);
                m.upper_edge = simplified_edge(upper.contours[m.upper.contour], m.upper.point);
                curve.points.push_back(m);
            }
            id = next[link].to;
            link = link_of(id);
            if (link == next.size()) {
                throw Error(ErrorCode::Internal,
                            "medial curve of label " + std::to_string(label) + " is not closed");
            }
        } while (id != start);
        if (curve.points.size() > 1 &&
            curve.points.front().position == curve.points.back().position) {
            curve.points.pop_back();
        }
        if (!curve.points.empty()) {
            curves.push_back(std::move(curve));
        }
    }
}

/// The labels of `set` among `wanted` (increasing; empty: all).
std::vector<std::uint16_t> labels_of(const SliceContourSet& set,
                                     const std::vector<std::uint16_t>& wanted) {
    std::vector<std::uint16_t> labels;
    for (const SliceLabelRegions& r : set.labels) {
        if (wanted.empty() || std::binary_search(wanted.begin(), wanted.end(), r.label)) {
            labels.push_back(r.label);
        }
    }
    return labels;
}

}  // namespace

MedialAxis extract_medial_axis(const SliceContourSet& lower,
                               const SliceContourSet& upper,
                               const SliceDistanceFields& lower_fields,
                               const SliceDistanceFields& upper_fields,
                               std::uint32_t k,
                               const MedialOptions& options) {
    MedialAxis axis;
    axis.lower_slice = k;
    const std::vector<std::uint16_t> lower_labels = labels_of(lower, options.labels);
    const std::vector<std::uint16_t> upper_labels = labels_of(upper, options.labels);
    for (std::uint16_t label : lower_labels) {
        if (!std::binary_search(upper_labels.begin(), upper_labels.end(), label)) {
            continue;
        }
        const DistanceField* fa = find_field(lower_fields, label);
        const DistanceField* fb = find_field(upper_fields, label);
        if (fa == nullptr || fb == nullptr) {
            throw Error(ErrorCode::Internal,
                        "slices " + std::to_string(k) + "/" + std::to_string(k + 1) +
                            ": no distance field for label " + std::to_string(label));
        }
        trace_label(label, sum_fields(*fa, *fb), *fa, *fb, lower, upper, axis.curves);
    }
    Coverage lower_cov(lower, options);
    Coverage upper_cov(upper, options);
    for (const MedialCurve& curve : axis.curves) {
        const std::size_t n = curve.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const MedialPoint& a = curve.points[i];
            const MedialPoint& b = curve.points[(i + 1) % n];
            lower_cov.mark_step(a.lower, b.lower);
            upper_cov.mark_step(a.upper, b.upper);
        }
    }
    lower_cov.collect(false, lower_labels, axis.unmatched);
    upper_cov.collect(true, upper_labels, axis.unmatched);
    return axis;
}

std::vector<MedialAxis> extract_medial_axes(const SliceContours& contours,
                                            const std::vector<SliceDistanceFields>& fields,
                                            const MedialOptions& options) {
    if (fields.size() != contours.slices.size()) {
        throw Error(ErrorCode::Internal, "medial axes: " + std::to_string(fields.size()) +
                                             " distance field sets for " +
                                             std::to_string(contours.slices.size()) + " slices");
    }
    const std::size_t pairs = contours.slices.empty() ? 0 : contours.slices.size() - 1;
    std::vector<MedialAxis> axes(pairs);
    std::mutex progress_mutex;
    std::size_t done = 0;
    parallel_for(pairs, options.threads, [&](std::size_t k) {
        axes[k] = extract_medial_axis(contours.slices[k], contours.slices[k + 1], fields[k],
                                      fields[k + 1], static_cast<std::uint32_t>(k), options);
        if (options.progress) {
            std::lock_guard<std::mutex> lock(progress_mutex);
            options.progress("slice pairs", ++done, pairs);
        }
    });
    return axes;
}

void count_medial_axes(const std::vector<MedialAxis>& axes,
                       const SliceContours& contours,
                       std::vector<MedialCounts>& counts) {
    auto entry = [&counts](std::uint16_t label) -> MedialCounts& {
        const auto it =
            std::lower_bound(counts.begin(), counts.end(), label,
                             [](const MedialCounts& c, std::uint16_t l) { return c.label < l; });
        if (it != counts.end() && it->label == label) {
            return *it;
        }
        MedialCounts c;
        c.label = label;
        return *counts.insert(it, c);
    };
    for (const MedialAxis& axis : axes) {
        for (const MedialCurve& curve : axis.curves) {
            MedialCounts& c = entry(curve.label);
            ++c.curves;
            c.points += curve.points.size();
        }
        for (const UnmatchedRun& run : axis.unmatched) {
            const SliceContourSet& set =
                contours.slices.at(axis.lower_slice + (run.on_upper ? 1 : 0));
            MedialCounts& c = entry(set.contours.at(run.contour).label);
            ++c.unmatched_runs;
            c.unmatched_points += run.count;
        }
    }
}

}  // namespace strata

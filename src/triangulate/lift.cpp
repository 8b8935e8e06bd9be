// Triangulation, lifting: the height t of a point between slices k and k+1 (from the slices'
// distance fields and the simplified rings), Steiner points, and the level (z_k, between,
// z_k+1) of every corner of a surface face.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include "triangulate/detail/label_surface.h"

namespace strata::detail {

/// The root in [0, 1] of the cubic Hermite curve from a (at 0) to b (at 1), a and b of opposite
/// signs, with end slopes m0 and m1 limited so that the curve is monotone there (Fritsch and
/// Carlson): the root is unique and moves continuously with the data.
///
/// The answer is that of 40 bisection steps on [0, 1] (the middle of the interval of width 2^-40
/// where the computed curve changes sign), found with a few safeguarded Newton steps instead: the
/// Newton root r names the candidate interval [L, L + 2^-40], and the bisection's sign test is
/// evaluated at L, at L + 2^-40 and one interval further out on each side, where the computed
/// value must exceed twice a bound on its rounding error (the curve is monotone, so every point
/// the bisection could test farther out has the same sign). When any check fails (a flat curve
/// at the root, rounding at the interval's edge) the bisection itself runs. Same result, bit for
/// bit (HermiteRoot test: against a plain bisection on random and edge cases).
double hermite_root(double a, double b, double m0, double m1) {
    const double delta = b - a;
    if (m0 * delta <= 0.0) {
        m0 = 0.0;
    }
    if (m1 * delta <= 0.0) {
        m1 = 0.0;
    }
    const double alpha = m0 / delta;
    const double beta = m1 / delta;
    const double norm = alpha * alpha + beta * beta;
    if (norm > 9.0) {
        const double tau = 3.0 / std::sqrt(norm);
        m0 = tau * alpha * delta;
        m1 = tau * beta * delta;
    }
    auto value = [&](double t) {
        const double t2 = t * t;
        const double t3 = t2 * t;
        return (2 * t3 - 3 * t2 + 1) * a + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * b +
               (t3 - t2) * m1;
    };
    const bool rising = delta > 0.0;
    // the bisection's test: the root lies above t
    auto below = [&](double t) { return (value(t) < 0.0) == rising; };
    constexpr int kSteps = 40;
    const double width = std::ldexp(1.0, -kSteps);

    // Safeguarded Newton from the secant's root, in a bracket that only shrinks.
    double lo = 0.0;
    double hi = 1.0;
    double t = a / (a - b);
    bool converged = false;
    for (int i = 0; i < 16 && !converged; ++i) {
        const double f = value(t);
        if ((f < 0.0) == rising) {
            lo = t;
        } else {
            hi = t;
        }
        const double t2 = t * t;
        const double slope =
            (6 * t2 - 6 * t) * (a - b) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1;
        const double step = slope != 0.0 ? f / slope : 1.0;
        // Newton's error squares: after a step under 1e-8 the root is known to about 1e-15
        converged = std::abs(step) < 1e-8;
        t -= step;
        if (!converged && !(t > lo && t < hi)) {
            t = 0.5 * (lo + hi);
        }
    }
    if (converged && t >= 0.0 && t < 1.0) {
        double low = std::floor(t / width) * width;
        // r within rounding of an interval's edge: the sign test at that edge decides
        if (low > 0.0 && !below(low)) {
            low -= width;
        } else if (low + width < 1.0 && below(low + width)) {
            low += width;
        }
        const double high = low + width;
        // a bound on the rounding error of value(): each Hermite basis term is off by at most
        // about 20 eps of its factor's magnitude
        const double error = 64.0 * std::numeric_limits<double>::epsilon() *
                             (std::abs(a) + std::abs(b) + std::abs(m0) + std::abs(m1));
        auto clear = [&](double s, bool side) {
            const double f = value(s);
            return std::abs(f) > 2.0 * error && ((f < 0.0) == rising) == side;
        };
        const bool ok = (low == 0.0 || below(low)) && (high == 1.0 || !below(high)) &&
                        (low - width <= 0.0 || clear(low - width, true)) &&
                        (high + width >= 1.0 || clear(high + width, false));
        if (ok) {
            return low + 0.5 * width;
        }
    }

    lo = 0.0;
    hi = 1.0;
    for (int i = 0; i < kSteps; ++i) {
        const double mid = 0.5 * (lo + hi);
        if (below(mid)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

double sample_field(const DistanceField* f, Vec2 q) {
    if (f == nullptr) {
        return 1e9;
    }
    const double u = (q.x - f->origin_x) / DistanceField::kCellPx;
    const double v = (q.y - f->origin_y) / DistanceField::kCellPx;
    if (!(u >= 0.0 && v >= 0.0 && u <= f->nx - 1.0 && v <= f->ny - 1.0)) {
        return f->outside_window_px;
    }
    const auto i = std::min<std::uint32_t>(std::uint32_t(u), f->nx - 2);
    const auto j = std::min<std::uint32_t>(std::uint32_t(v), f->ny - 2);
    const double fu = u - i;
    const double fv = v - j;
    return (1 - fu) * (1 - fv) * f->at(i, j) + fu * (1 - fv) * f->at(i + 1, j) +
           (1 - fu) * fv * f->at(i, j + 1) + fu * fv * f->at(i + 1, j + 1);
}

bool closest_site(const DistanceField* f, Vec2 q, Vec2& site) {
    if (f == nullptr || f->nx == 0 || f->ny == 0) {
        return false;
    }
    const double cell = DistanceField::kCellPx;
    const auto i = std::uint32_t(
        std::clamp(std::nearbyint((q.x - f->origin_x) / cell), 0.0, double(f->nx - 1)));
    const auto j = std::uint32_t(
        std::clamp(std::nearbyint((q.y - f->origin_y) / cell), 0.0, double(f->ny - 1)));
    const std::array<std::int32_t, 2>& s = f->site_nodes[f->closest(f->node_index(i, j))];
    site = {f->origin_x + cell * s[0], f->origin_y + cell * s[1]};
    return true;
}

bool LabelSurface::end_slope(Vec2 q, std::uint32_t k, bool upper, double& slope) const {
    if (ends_slab_ != std::int64_t(k)) {
        for (int side = 0; side < 2; ++side) {
            const std::uint32_t slice = k + std::uint32_t(side);
            std::vector<EndRegion>& ends = ends_[std::size_t(side)];
            ends.clear();
            for (std::uint32_t r = 0; r < region_count_[slice]; ++r) {
                // ends on the far side of the slab, continues into it
                const bool ends_here = side == 0 ? !linked_down_[slice][r] && linked_up_[slice][r]
                                                 : !linked_up_[slice][r] && linked_down_[slice][r];
                double height = 0.0;
                const double s = ends_here ? dome_rim_slope(slice, r, side == 1, &height) : 0.0;
                if (s > 0.0) {
                    std::vector<Ring> rings;
                    double twice = 0.0;  // twice the signed area, and its first moments
                    Vec2 moment{0.0, 0.0};
                    for_each_region_ring(slice, r, [&](const Ring& ring) {
                        rings.push_back(ring);
                        for (std::size_t i = 0; i < ring.points.size(); ++i) {
                            const Vec2 a = to_vec(ring.points[i]);
                            const Vec2 b = to_vec(ring.points[(i + 1) % ring.points.size()]);
                            const double w = a.x * b.y - b.x * a.y;
                            twice += w;
                            moment = moment + w * (a + b);
                        }
                    });
                    const Vec2 centre =
                        twice != 0.0 ? (1.0 / (3.0 * twice)) * moment : Vec2{0.0, 0.0};
                    ends.push_back({SegmentGrid(rings), s, centre,
                                    options_.slice_spacing_px / (2.0 * height)});
                }
            }
        }
        ends_slab_ = k;
    }
    const std::vector<EndRegion>& ends = ends_[upper ? 1 : 0];
    if (ends.empty()) {
        return false;
    }
    const double nearest = slab_rings_[upper ? 1 : 0].distance(q);
    for (const EndRegion& end : ends) {
        if (end.rings.distance(q) <= nearest) {
            // An elongated region's dome draws in faster at its ends than at its sides: as a
            // paraboloid whose sections are the contour scaled about its centre, by the support
            // (p - centre) . n at the contour point p nearest q (n toward q) over 2 H.
            slope = end.slope;
            Vec2 site;
            if (closest_site(field(k + (upper ? 1 : 0)), q, site)) {
                const Vec2 n = q - site;
                const double length = std::sqrt(dot(n, n));
                if (length > 0.25) {
                    slope = std::max(slope, end.per_reach * dot(site - end.centre, n) / length);
                }
            }
            return true;
        }
    }
    return false;
}

double LabelSurface::height_t(const Point& p, std::uint32_t k, double* band) const {
    const Vec2 q = to_vec(p);
    const double a = sample_field(field(k), q);
    const double b = sample_field(field(k + 1), q);
    double t = 0.5;
    if (std::abs(a - b) > 1e-12) {
        t = a / (a - b);
    }
    if (options_.cubic_height && a * b < 0.0) {
        // The slices' signed distances as a function of z (one unit per slab): slopes at both
        // slices from the neighbouring slices (Catmull-Rom), else from a parabola through the
        // three known ones, else the secant.
        auto known = [&](std::int64_t slice, double& value) {
            if (slice < 0 || std::size_t(slice) >= fields_.size() || level_z_ != nullptr) {
                return false;
            }
            const DistanceField* f = field(std::uint32_t(slice));
            if (f == nullptr) {
                return false;
            }
            const double u = (q.x - f->origin_x) / DistanceField::kCellPx;
            const double v = (q.y - f->origin_y) / DistanceField::kCellPx;
            if (!(u >= 0.0 && v >= 0.0 && u <= f->nx - 1.0 && v <= f->ny - 1.0)) {
                return false;
            }
            value = sample_field(f, q);
            return true;
        };
        double c = 0.0;
        double e = 0.0;
        const bool has_c = known(std::int64_t(k) - 1, c);
        const bool has_e = known(std::int64_t(k) + 2, e);
        double m0 = b - a;
        double m1 = b - a;
        if (has_c) {
            m0 = 0.5 * (b - c);
        } else if (has_e) {
            m0 = 0.5 * (-3.0 * a + 4.0 * b - e);
        }
        if (has_e) {
            m1 = 0.5 * (e - a);
        } else if (has_c) {
            m1 = 0.5 * (3.0 * b - 4.0 * a + c);
        }
        // Where the region of the nearest contour ends at slice k (k+1), its dome says how fast
        // the object closes past the slice (a virtual slice k-1, k+2): the slope there is at
        // least the dome's, so the last slab bends toward the pole as the dome does.
        double end = 0.0;
        if (!has_c && end_slope(q, k, false, end)) {
            m0 = std::min(m0, -end);
        }
        if (!has_e && end_slope(q, k, true, end)) {
            m1 = std::max(m1, end);
        }
        t = hermite_root(a, b, m0, m1);
    }
    // The fields measure the distance to the original contours, while the surface meets the
    // simplified ones (up to the tolerance away): alone they folded the graph where the two
    // disagree, e.g. a point right beside slice k+1's simplified contour at t = 1/2, or inside
    // (outside) both slices by the fields and clamped to 0.05 or 0.95 between them. So half the
    // difference between the simplified rings' own distance ratio d_k / (d_k + d_k+1) and the
    // fields' ratio is added, and that ratio alone is taken where the fields put the point on
    // the same side of both slices.
    const double pa = slab_rings_[0].distance(q);
    const double pb = slab_rings_[1].distance(q);
    const double rings = pa + pb > 0.0 ? pa / (pa + pb) : 0.5;
    const double shift = a * b < 0.0 ? 0.5 * (rings - a / (a - b)) : 0.0;
    if (band != nullptr) {
        // The heights where the linear field (1 - t) a + t b is within its value at the fields'
        // own height (the rings' shift) plus the tolerance; where a and b barely differ, z says
        // little about the field: the whole slab.
        const double slope = std::abs(a - b);
        *band = std::abs(shift) + (slope > 1e-12 ? options_.relax.field_tolerance_px / slope : 1.0);
    }
    t = a * b < 0.0 ? t + shift : rings;
    const double interpolated = t;
    t = pocket_t(q, k, t);  // a cavity that closes here is domed (caps.cpp)
    if (band != nullptr && t != interpolated) {
        *band = 0.0;  // a dome's height is not the fields' to relax
    }
    return std::clamp(t, 0.05, 0.95);
}

void LabelSurface::make_steiner(VertexHandle v, std::uint32_t k) {
    v->info().steiner = std::int32_t(steiner_t_.size());
    double band = 0.0;
    const double t = height_t(v->point(), k, &band);
    steiner_t_.push_back(t);
    steiner_band_.push_back(band);
    steiner_id_.push_back(-1);
    steiner_xy_.push_back(to_vec(v->point()));
}

VertexHandle LabelSurface::insert_steiner(Cdt& cdt, const Point& p, std::uint32_t k) {
    VertexHandle v = cdt.insert(p);
    if (v->info().steiner < 0 && v->info().lower < 0 && v->info().upper < 0) {
        make_steiner(v, k);
    }
    return v;
}

void LabelSurface::insert_steiners(Cdt& cdt,
                                   const std::vector<Point>& points,
                                   std::uint32_t k,
                                   const std::map<EdgeKey, EdgeOwner>& owners,
                                   const char* what) {
    for (const Point& p : points) {
        insert_steiner(cdt, p, k);
    }
    const std::size_t unowned = flood_regions(cdt, k, owners);
    if (unowned != 0) {
        issue(k, std::string(what) + " split " + std::to_string(unowned) + " edges");
    }
}

/// Cost of each face of `wedge` with v at z_k ([0]) and at z_k+1 ([1]): the face's area times
/// the mean squared difference between its height and the interpolation height at four
/// interior points.
std::vector<std::array<double, 2>> LabelSurface::wedge_level_costs(
    const std::vector<FaceHandle>& wedge, VertexHandle v, std::uint32_t k) const {
    std::vector<std::array<double, 2>> cost(wedge.size());
    for (std::size_t j = 0; j < wedge.size(); ++j) {
        const FaceHandle w = wedge[j];
        const int vi = w->index(v);
        std::array<Vec2, 3> xy;
        std::array<double, 3> h{};
        for (int m = 0; m < 3; ++m) {
            const VertexHandle u = w->vertex(m);
            xy[std::size_t(m)] = to_vec(u->point());
            const VertexInfo& info = u->info();
            h[std::size_t(m)] = info.steiner >= 0 ? steiner_t_[std::size_t(info.steiner)]
                                : info.upper < 0  ? 0.0
                                : info.lower < 0  ? 1.0
                                                  : 0.5;  // another crossing: unknown
        }
        const double area = 0.5 * std::abs(cross(xy[1] - xy[0], xy[2] - xy[0]));
        // the centroid and the points (4, 1, 1) / 6 towards each corner, with t read there once
        // for both levels
        std::array<std::array<double, 3>, 4> samples{};
        std::array<double, 4> sample_t{};
        for (std::size_t sample = 0; sample < 4; ++sample) {
            std::array<double, 3>& b = samples[sample];
            b = {1.0 / 3, 1.0 / 3, 1.0 / 3};
            if (sample < 3) {
                b = {1.0 / 6, 1.0 / 6, 1.0 / 6};
                b[sample] = 4.0 / 6;
            }
            const Vec2 q = b[0] * xy[0] + b[1] * xy[1] + b[2] * xy[2];
            sample_t[sample] = height_t(to_point(q), k);
        }
        for (int level = 0; level < 2; ++level) {
            h[std::size_t(vi)] = level;
            double sum = 0.0;
            for (std::size_t sample = 0; sample < 4; ++sample) {
                const std::array<double, 3>& b = samples[sample];
                const double face_t = b[0] * h[0] + b[1] * h[1] + b[2] * h[2];
                const double diff = face_t - sample_t[sample];
                sum += diff * diff;
            }
            cost[j][std::size_t(level)] = area * sum / 4.0;
        }
    }
    return cost;
}

/// The inner edge of `wedge` (ordered from the low boundary edge) at which to split it:
/// among the edges to a Steiner point, the one of least total cost (wedge_level_costs);
/// wedge.size() when there is none.
std::size_t LabelSurface::best_wedge_split(const std::vector<FaceHandle>& wedge,
                                           VertexHandle v,
                                           std::uint32_t k) const {
    // wedge[0] touches the low boundary edge. Inner edge j lies between wedge[j] and
    // wedge[j + 1]; its far vertex is shared by both.
    std::vector<std::size_t> candidates;
    for (std::size_t j = 0; j + 1 < wedge.size(); ++j) {
        const FaceHandle a = wedge[j];
        const FaceHandle b = wedge[j + 1];
        for (int m = 0; m < 3; ++m) {
            const VertexHandle u = a->vertex(m);
            if (u != v && b->has_vertex(u) && u->info().steiner >= 0) {
                candidates.push_back(j);
                break;
            }
        }
    }
    std::size_t split = wedge.size();
    if (candidates.size() == 1) {
        split = candidates[0];
    } else if (!candidates.empty()) {
        const std::vector<std::array<double, 2>> cost = wedge_level_costs(wedge, v, k);
        // prefix sums: low cost of wedge[0..j], high cost of wedge[j+1..]
        std::vector<double> low(wedge.size() + 1, 0.0);
        std::vector<double> high(wedge.size() + 1, 0.0);
        for (std::size_t j = 0; j < wedge.size(); ++j) {
            low[j + 1] = low[j] + cost[j][0];
        }
        for (std::size_t j = wedge.size(); j-- > 0;) {
            high[j] = high[j + 1] + cost[j][1];
        }
        double best = std::numeric_limits<double>::infinity();
        for (const std::size_t j : candidates) {
            const double c = low[j + 1] + high[j + 1];
            if (c < best) {
                best = c;
                split = j;
            }
        }
    }
    return split;
}

/// Walks the faces of the surface around vertex i of f in both directions to the boundary
/// edges; equal classes give the level directly. A wedge between a low and a high edge (where
/// contours cross) is split at an edge to a Steiner point: faces on the low side use the
/// vertex at z_k, the rest at z_k+1 (the vertical triangle between them is added on output).
bool LabelSurface::resolve_corner(
    Cdt& cdt, FaceHandle f, int i, std::uint32_t k, std::vector<Point>& refine) {
    const VertexHandle v = f->vertex(i);
    if (v->info().steiner >= 0) {
        f->info().corner[std::size_t(i)] = kBetween;
        return true;
    }
    // Walk clockwise (across the edge (v, vertex(ccw))) to the first boundary edge, collecting
    // faces; then counter-clockwise.
    // Walks from f around v to the first boundary edge, collecting the faces passed; `found`
    // stays kUnset when the walk comes back to f. False on an infinite face (inconsistent
    // regions: the slab fails).
    auto walk = [&](bool clockwise, std::vector<FaceHandle>& passed, Level& found) {
        FaceHandle cur = f;
        int ci = i;
        for (;;) {
            const int e = clockwise ? cw(ci) : ccw(ci);  // edge (v, next vertex that way)
            if (is_boundary(cur, e, k)) {
                found = boundary_class(cur, e, k);
                return true;
            }
            cur = cur->neighbor(e);
            if (cdt.is_infinite(cur)) {
                return false;
            }
            if (cur == f) {
                return true;
            }
            ci = cur->index(v);
            passed.push_back(cur);
        }
    };
    // note: scratch kept per thread: this runs for every face corner of every slab (1.9 M
    // allocations on TotalSegmentator); resolve_corner does not call itself
    thread_local std::vector<FaceHandle> cw_faces;
    thread_local std::vector<FaceHandle> ccw_faces;
    thread_local std::vector<FaceHandle> wedge;
    cw_faces.assign(1, f);
    ccw_faces.clear();
    Level cw_class = kUnset;
    Level ccw_class = kUnset;
    if (!walk(true, cw_faces, cw_class)) {
        return false;
    }
    if (cw_class == kUnset) {
        // No boundary around v: a contour point inside the surface's domain (only where
        // unlinked contours lie inside it). Lift it like a Steiner point.
        make_steiner(v, k);
        f->info().corner[std::size_t(i)] = kBetween;
        return true;
    }
    if (!walk(false, ccw_faces, ccw_class)) {
        return false;
    }
    // Wedge in order from the clockwise boundary to the counter-clockwise one.
    wedge.assign(cw_faces.rbegin(), cw_faces.rend());
    wedge.insert(wedge.end(), ccw_faces.begin(), ccw_faces.end());
    if (cw_class == ccw_class) {
        for (FaceHandle w : wedge) {
            w->info().corner[std::size_t(w->index(v))] = cw_class;
        }
        return true;
    }
    // Mixed: split at an inner edge (v, u) with u a Steiner point. Of those, the one where the
    // wedge's faces best follow the interpolation height t = D_k / (D_k - D_k+1): faces before
    // it use v at z_k, faces after it v at z_k+1; each face is charged its area times the mean
    // squared difference between its height and t at four interior points. (The first such edge
    // from the low side, the old choice, fanned v at z_k+1 over the low half of long strips:
    // faces tilted backwards, a 1 px V-groove along the medial line.)
    const bool low_first = cw_class == kLow;
    if (!low_first) {
        std::reverse(wedge.begin(), wedge.end());
    }
    const std::size_t split = best_wedge_split(wedge, v, k);
    if (split == wedge.size()) {
        const FaceHandle mid = wedge[wedge.size() / 2];
        refine.push_back(CGAL::centroid(cdt.triangle(mid)));
        return false;
    }
    for (std::size_t j = 0; j < wedge.size(); ++j) {
        wedge[j]->info().corner[std::size_t(wedge[j]->index(v))] = j <= split ? kLow : kHigh;
    }
    return true;
}

}  // namespace strata::detail

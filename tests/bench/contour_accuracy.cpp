// In-plane accuracy of the contour stage against a phantom's analytic solids (issue 22: how much
// of the surface's error is in the slice planes, and how much placing simplified vertices off the
// half-pixel grid could remove).
//
//   contour_accuracy --phantom NAME [--slice-spacing D] [--tolerance T] [--sigma S] [--sag F]
//                    [--oracle-tolerance U] [--subdivide N] [--best]
//                    [--estimators [--window W] [--adaptive A] [--neighbours K]]
//
// Traces and simplifies every slice of the phantom's stack as `strata build` does
// (extract_contours; --tolerance T, default 0.5 px) and measures, in each slice plane z = k d px,
// the distance from the contours to the true surface: the solid's signed distance at points every
// 1/32 px along the contour, weighted by length (mean, bias, max, px; the 3D distance at in-plane
// points, as mesh_accuracy measures the surface there). Rows:
//   staircase   the original pixel-boundary contours; `beyond` counts their points farther than
//               T from the true surface (a bound from below of their in-plane distance);
//   simplified  the simplified contours (what the surface runs through in the slice planes);
//   iso         the simplified vertices moved along their normals (bisector of the two edges) to
//               the 0.5 iso-line of the mask smoothed by a Gaussian of sigma S px (default 1;
//               bilinear between pixel centres);
//   oracle      the vertices moved to the true section along their normals (the root of the
//               solid's signed distance in the plane nearest the vertex within +-1 px);
//   +sag        the same, each vertex then further out by F (default 0.25) times the sum of its
//               two chords' sagittas (the boundary's offset from the chord's midpoint along the
//               chord's normal, by the same estimate: iso-line or truth);
//   best        (--best) from oracle+sag, coordinate descent of each vertex over the 1/8 px grid
//               within 1/2 px of it, to the least in-plane error of its two edges against the
//               truth under the same guarantee: what placement alone can reach with these vertices;
//   iso best    (--best) the same against the iso-line (0.5 - smoothed mask) from iso+sag;
//   iso line    (--estimators) boundary estimates alone, one per original segment: its midpoint
//               moved along the normal of the 7 segments around it to the iso-line;
//   fit line    (--estimators) the same to a least-squares quadratic through the segment
//               midpoints within 2 W px along that tangent (Gaussian weight of sd W, default 3);
//               with --adaptive A, sd A / curvature (from a first fit of sd 3), in [1.5, W];
//   fit best    (--estimators) the simplified vertices moved by the coordinate descent of `best`
//               against the fit line (nearest of its segments) instead of the truth: a placement
//               from the mask alone.
//   fit3 line   (--neighbours K, K >= 2) the fit line's offsets along the same in-plane normal
//               line on slices k-K..k+K (its crossing with their fit lines, within 1 + |j| d px)
//               and a least-squares quadratic in z through them, taken at z = k d: the boundary
//               from 2K+1 independent quantisations of the same surface (K-1, ... down to 2 where
//               slices are missing or the line misses them; the slice's own fit line below);
//   fit3 best   the simplified vertices moved by the coordinate descent of `best` against it;
//   fit3 grid   the same descent over the contour's own points instead (each vertex to an original
//               point within 8 of it along the contour): what choosing among the half-pixel grid
//               positions of today's vertices can do.
// --subdivide N splits each simplified edge into N at original points (by index) first.
// Moves keep the slice-error guarantee: vertex by vertex (two passes) each goes the largest
// fraction k / 8 of its move that keeps every original point within T of its two edges, on a
// 1/16 px grid. The oracle rows use U (default T) instead: a large U shows what the guarantee
// costs.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iostream>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "contours/extract_contours.h"
#include "core/error.h"
#include "phantom/catalogue.h"
#include "phantom/solids.h"

namespace strata {
namespace {

struct Stats {
    double length = 0.0, sum_abs = 0.0, sum_signed = 0.0, max = 0.0;
    void add(double w, double d) {
        length += w;
        sum_abs += w * std::abs(d);
        sum_signed += w * d;
        max = std::max(max, std::abs(d));
    }
};

double truth(const Phantom& p, std::uint16_t label, Vec3 q) {
    double best = std::numeric_limits<double>::infinity();
    for (const PhantomObject& o : p.objects) {
        if (o.label == label && o.solid) {
            const double v = signed_distance(*o.solid, q);
            if (std::abs(v) < std::abs(best)) {
                best = v;
            }
        }
    }
    return best;
}

/// Original contour points farther than `tol` from the true surface.
std::size_t beyond(
    const Phantom& p, std::uint16_t label, double z, const std::vector<Vec2>& poly, double tol) {
    std::size_t count = 0;
    for (const Vec2& q : poly) {
        count += std::abs(truth(p, label, {q.x, q.y, z})) > tol ? 1 : 0;
    }
    return count;
}

void sample_polygon(
    const Phantom& p, std::uint16_t label, double z, const std::vector<Vec2>& poly, Stats& s) {
    const std::size_t n = poly.size();
    for (std::size_t e = 0; e < n; ++e) {
        const Vec2 a = poly[e];
        const Vec2 b = poly[(e + 1) % n];
        const double len = norm(b - a);
        const int m = std::max(1, static_cast<int>(std::ceil(len * 32)));
        for (int i = 0; i < m; ++i) {
            const double t = (i + 0.5) / m;
            const Vec2 q = a + t * (b - a);
            s.add(len / m, truth(p, label, {q.x, q.y, z}));
        }
    }
}

double sag_factor = 0.25;
int subdivide = 1;
bool optimise = false;
bool estimators = false;
double window = 3.0;
double adaptive = 0.0;
int neighbours = 0;
constexpr std::size_t kNoIndex = std::numeric_limits<std::size_t>::max();

double segment_distance(Vec2 p, Vec2 a, Vec2 b) {
    const Vec2 d = b - a;
    const Vec2 w = p - a;
    const double ll = dot(d, d);
    const double t = ll > 0 ? std::clamp(dot(w, d) / ll, 0.0, 1.0) : 0.0;
    return norm(w - t * d);
}

/// Largest distance of the original points of edge e (from vertex e to e+1) from the moved edge.
double edge_deviation(const Contour& c, const std::vector<Vec2>& at, std::size_t e) {
    const std::size_t m = c.simplified.size();
    const std::size_t n = c.points.size();
    const Vec2 a = at[e];
    const Vec2 b = at[(e + 1) % m];
    double worst = 0.0;
    for (std::size_t k = c.simplified[e];; k = (k + 1) % n) {
        worst = std::max(worst, segment_distance(c.points[k], a, b));
        if (k == c.simplified[(e + 1) % m]) {
            break;
        }
    }
    return worst;
}

bool placed_ok(const Contour& c, const std::vector<Vec2>& at, std::size_t e, double tol) {
    return edge_deviation(c, at, e) <= tol;
}

/// Moves vertex positions along `normal` toward `offset` (per vertex) as far as every original
/// point stays within `tol` of its edge: vertex by vertex, two passes, each vertex at the largest
/// fraction k / 8 of its offset that keeps its two edges within the tolerance (neighbours where
/// they are), on a 1/16 px grid as the quantize stage's.
std::vector<Vec2> moved(const Contour& c,
                        const std::vector<Vec2>& normal,
                        const std::vector<double>& offset,
                        double tol) {
    const std::size_t m = c.simplified.size();
    std::vector<Vec2> at(m);
    const auto place = [&](std::size_t v, double f) {
        const Vec2 q = c.points[c.simplified[v]] + (f * offset[v]) * normal[v];
        return Vec2{std::round(q.x * 16) / 16, std::round(q.y * 16) / 16};
    };
    for (std::size_t v = 0; v < m; ++v) {
        at[v] = c.points[c.simplified[v]];
    }
    for (int pass = 0; pass < 2; ++pass) {
        for (std::size_t v = 0; v < m; ++v) {
            const Vec2 keep = at[v];
            bool placed = false;
            for (int k = 8; k >= 1 && !placed; --k) {
                at[v] = place(v, k / 8.0);
                placed = edge_deviation(c, at, (v + m - 1) % m) <= tol &&
                         edge_deviation(c, at, v) <= tol;
            }
            if (!placed) {
                at[v] = keep;
            }
        }
    }
    return at;
}

/// Length-weighted |f| along [a, b] at 8 points per px (at least 4).
template <class F>
double edge_cost(Vec2 a, Vec2 b, F&& f) {
    const double len = norm(b - a);
    const int n = std::max(4, static_cast<int>(std::ceil(8 * len)));
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        sum += std::abs(f(a + ((i + 0.5) / n) * (b - a)));
    }
    return sum * len / n;
}

/// The same on the contour's own points: each simplified vertex in turn (but the first) moves
/// to the original point within `reach` of it along the contour (not past its neighbours) that
/// least costs its two edges against `f` while every original point stays within `tol` of
/// them; 3 passes. What choosing among today's vertex positions (pixel corners, edge midpoints)
/// can do without placing vertices off the half-pixel grid.
template <class F>
std::vector<Vec2> grid_positions(Contour c, F&& f, double tol, std::uint32_t reach) {
    const std::size_t m = c.simplified.size();
    const auto n = static_cast<std::uint32_t>(c.points.size());
    std::vector<Vec2> at(m);
    const auto sync = [&] {
        for (std::size_t v = 0; v < m; ++v) {
            at[v] = c.points[c.simplified[v]];
        }
    };
    sync();
    for (int pass = 0; pass < 3 && m >= 3; ++pass) {
        for (std::size_t v = 1; v < m; ++v) {
            const std::size_t u = v - 1, w = (v + 1) % m;
            const std::uint32_t here = c.simplified[v];
            const std::uint32_t lo = c.simplified[u] + 1;
            const std::uint32_t hi = w == 0 ? n - 1 : c.simplified[w] - 1;
            double cost = edge_cost(at[u], at[v], f) + edge_cost(at[v], at[w], f);
            std::uint32_t chosen = here;
            for (std::uint32_t i = here > lo + reach ? here - reach : lo;
                 i <= std::min(hi, here + reach); ++i) {
                c.simplified[v] = i;
                at[v] = c.points[i];
                const double candidate = edge_cost(at[u], at[v], f) + edge_cost(at[v], at[w], f);
                if (candidate < cost && placed_ok(c, at, u, tol) && placed_ok(c, at, v, tol)) {
                    cost = candidate;
                    chosen = i;
                }
            }
            c.simplified[v] = chosen;
            at[v] = c.points[chosen];
        }
    }
    return at;
}

/// Coordinate descent from `start`: each vertex in turn goes to the point of the 1/8 px grid
/// within 1/2 px of where it is that least costs its two edges (edge_cost of the true surface's
/// distance `f`) while every original point stays within `tol` of them; 3 passes.
template <class F>
std::vector<Vec2> best_positions(const Contour& c, std::vector<Vec2> at, F&& f, double tol) {
    const std::size_t m = at.size();
    for (int pass = 0; pass < 3; ++pass) {
        for (std::size_t v = 0; v < m; ++v) {
            const std::size_t u = (v + m - 1) % m, w = (v + 1) % m;
            const Vec2 here = at[v];
            double cost = edge_cost(at[u], here, f) + edge_cost(here, at[w], f);
            Vec2 chosen = here;
            for (int dy = -4; dy <= 4; ++dy) {
                for (int dx = -4; dx <= 4; ++dx) {
                    at[v] = Vec2{here.x + dx / 8.0, here.y + dy / 8.0};
                    const double candidate =
                        edge_cost(at[u], at[v], f) + edge_cost(at[v], at[w], f);
                    if (candidate < cost && placed_ok(c, at, u, tol) && placed_ok(c, at, v, tol)) {
                        cost = candidate;
                        chosen = at[v];
                    }
                }
            }
            at[v] = chosen;
        }
    }
    return at;
}

/// Dense boundary estimate of one traced contour: per original segment its midpoint, the outward
/// normal of the 7 segments around it, and the offset along it of a weighted least-squares
/// quadratic through the segment midpoints within 2 sd px along the tangent (Gaussian weight of
/// sd `window`; with `adaptive` > 0, sd adaptive / curvature from a first fit of sd 3, in
/// [1.5, window]).
struct FitLine {
    std::uint16_t label = 0;
    std::vector<Vec2> mid, normal;
    std::vector<double> offset;
    Vec2 at(std::size_t i) const { return mid[i] + offset[i] * normal[i]; }
};

FitLine fit_line_of(const Contour& c, double window_sd, double adaptive_factor) {
    const std::vector<Vec2>& pts = c.points;
    const std::size_t n = pts.size();
    FitLine f;
    f.label = c.label;
    f.mid.resize(n);
    f.normal.resize(n);
    f.offset.resize(n);
    std::vector<Vec2> tangent(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Vec2 a = pts[i], b = pts[(i + 1) % n];
        f.mid[i] = 0.5 * (a + b);
        tangent[i] = (1.0 / norm(b - a)) * (b - a);
    }
    for (std::size_t i = 0; i < n; ++i) {
        Vec2 t{0, 0};
        for (int o = -3; o <= 3; ++o) {
            t = t + tangent[(i + n + o) % n];
        }
        t = (1.0 / norm(t)) * t;
        const Vec2 nn{t.y, -t.x};
        f.normal[i] = nn;
        // weighted least-squares s = a + b t + c t^2; returns {a, c}
        const auto fit = [&](double sd) {
            double m00 = 0, m01 = 0, m02 = 0, m11 = 0, m12 = 0, m22 = 0;
            double r0 = 0, r1 = 0, r2 = 0;
            const int reach = static_cast<int>(std::ceil(4 * sd));
            for (int o = -reach; o <= reach; ++o) {
                const Vec2 q = f.mid[(i + n + o) % n] - f.mid[i];
                const double tt = dot(q, t), ss = dot(q, nn);
                if (std::abs(tt) > 2 * sd) {
                    continue;
                }
                const double w = std::exp(-0.5 * tt * tt / (sd * sd));
                const double t2 = tt * tt;
                m00 += w;
                m01 += w * tt;
                m02 += w * t2;
                m11 += w * t2;
                m12 += w * t2 * tt;
                m22 += w * t2 * t2;
                r0 += w * ss;
                r1 += w * ss * tt;
                r2 += w * ss * t2;
            }
            const double det = m00 * (m11 * m22 - m12 * m12) - m01 * (m01 * m22 - m12 * m02) +
                               m02 * (m01 * m12 - m11 * m02);
            if (!(std::abs(det) > 1e-12)) {
                return std::pair<double, double>{0.0, 0.0};
            }
            const double fa = (r0 * (m11 * m22 - m12 * m12) - m01 * (r1 * m22 - m12 * r2) +
                               m02 * (r1 * m12 - m11 * r2)) /
                              det;
            const double fc = (m00 * (m11 * r2 - r1 * m12) - m01 * (m01 * r2 - r1 * m02) +
                               r0 * (m01 * m12 - m11 * m02)) /
                              det;
            return std::pair<double, double>{fa, fc};
        };
        double sd = window_sd;
        if (adaptive_factor > 0) {
            const double curvature = std::abs(2.0 * fit(3.0).second);
            sd =
                std::clamp(curvature > 0 ? adaptive_factor / curvature : window_sd, 1.5, window_sd);
        }
        f.offset[i] = fit(sd).first;
    }
    return f;
}

/// Closed polylines bucketed by 1 px cells: signed distance (outside positive: right of a
/// counter-clockwise outer polyline) and crossings of a line.
class PolylineField {
public:
    void add(std::vector<Vec2> poly) {
        const std::size_t p = polys_.size();
        for (std::size_t i = 0; i < poly.size(); ++i) {
            const Vec2 a = poly[i], b = poly[(i + 1) % poly.size()];
            const int x0 = int(std::floor(std::min(a.x, b.x))),
                      x1 = int(std::floor(std::max(a.x, b.x)));
            const int y0 = int(std::floor(std::min(a.y, b.y))),
                      y1 = int(std::floor(std::max(a.y, b.y)));
            for (int y = y0; y <= y1; ++y) {
                for (int x = x0; x <= x1; ++x) {
                    cells_[{x, y}].push_back({p, i});
                }
            }
        }
        polys_.push_back(std::move(poly));
    }
    double signed_distance(Vec2 q) const {
        double best = std::numeric_limits<double>::infinity(), sign = 1.0;
        const int cx = int(std::floor(q.x)), cy = int(std::floor(q.y));
        for (int dy = -2; dy <= 2; ++dy) {
            for (int dx = -2; dx <= 2; ++dx) {
                const auto it = cells_.find({cx + dx, cy + dy});
                if (it == cells_.end()) {
                    continue;
                }
                for (const auto& [p, i] : it->second) {
                    const Vec2 a = polys_[p][i], b = polys_[p][(i + 1) % polys_[p].size()];
                    const double dist = segment_distance(q, a, b);
                    if (dist < best) {
                        best = dist;
                        sign = cross(b - a, q - a) <= 0 ? 1.0 : -1.0;
                    }
                }
            }
        }
        return std::isfinite(best) ? sign * best : 2.0;
    }
    /// The crossing of the line o + s n (|s| <= reach) with the polylines nearest s = 0, if any.
    bool crossing(Vec2 o, Vec2 n, double reach, double& s_out) const {
        bool found = false;
        std::map<std::pair<std::size_t, std::size_t>, bool> seen;
        for (double s = -reach; s <= reach + 0.25; s += 0.25) {
            const Vec2 q = o + s * n;
            const int cx = int(std::floor(q.x)), cy = int(std::floor(q.y));
            for (int dy = -1; dy <= 1; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                    const auto it = cells_.find({cx + dx, cy + dy});
                    if (it == cells_.end()) {
                        continue;
                    }
                    for (const auto& key : it->second) {
                        if (!seen.emplace(key, true).second) {
                            continue;
                        }
                        const auto& poly = polys_[key.first];
                        const Vec2 a = poly[key.second], b = poly[(key.second + 1) % poly.size()];
                        // o + s n = a + u (b - a)
                        const Vec2 e = b - a;
                        const double den = cross(n, e);
                        if (std::abs(den) < 1e-12) {
                            continue;
                        }
                        const Vec2 w = a - o;
                        const double ss = cross(w, e) / den, u = cross(w, n) / den;
                        if (u >= 0 && u < 1 && std::abs(ss) <= reach &&
                            (!found || std::abs(ss) < std::abs(s_out))) {
                            s_out = ss;
                            found = true;
                        }
                    }
                }
            }
        }
        return found;
    }

private:
    std::vector<std::vector<Vec2>> polys_;
    std::map<std::pair<int, int>, std::vector<std::pair<std::size_t, std::size_t>>> cells_;
};

int run(int argc, char** argv) {
    std::string name;
    double d = 0.0;
    double sigma = 1.0;
    double tolerance = 0.5;
    double free_tol = 0.5;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--phantom" && i + 1 < argc) {
            name = argv[++i];
        } else if (a == "--slice-spacing" && i + 1 < argc) {
            d = std::stod(argv[++i]);
        } else if (a == "--oracle-tolerance" && i + 1 < argc) {
            free_tol = std::stod(argv[++i]);
        } else if (a == "--neighbours" && i + 1 < argc) {
            neighbours = std::stoi(argv[++i]);
        } else if (a == "--estimators") {
            estimators = true;
        } else if (a == "--adaptive" && i + 1 < argc) {
            adaptive = std::stod(argv[++i]);
        } else if (a == "--window" && i + 1 < argc) {
            window = std::stod(argv[++i]);
        } else if (a == "--best") {
            optimise = true;
        } else if (a == "--subdivide" && i + 1 < argc) {
            subdivide = std::stoi(argv[++i]);
        } else if (a == "--sag" && i + 1 < argc) {
            sag_factor = std::stod(argv[++i]);
        } else if (a == "--tolerance" && i + 1 < argc) {
            tolerance = std::stod(argv[++i]);
        } else if (a == "--sigma" && i + 1 < argc) {
            sigma = std::stod(argv[++i]);
        } else {
            std::cerr
                << "usage: contour_accuracy --phantom NAME [--slice-spacing D] [--tolerance T]\n"
                   "  [--sigma S] [--sag F] [--oracle-tolerance U] [--subdivide N] [--best]\n"
                   "  [--estimators [--window W] [--adaptive A] [--neighbours K]]\n";
            return 2;
        }
    }
    PhantomOptions po;
    if (d > 0) {
        po.slice_spacing_px = d;
    }
    const Phantom p = make_phantom(name, po);
    const SliceStack& st = p.stack;
    ContourOptions co;
    co.tolerance_px = tolerance;
    const SliceContours sc = extract_contours(st, co);
    Stats stair, simp, iso, oracle, iso_sag, oracle_sag, optimised, iso_optimised, iso_line,
        fit_line, fit_optimised, fit3_line, fit3_optimised, fit3_grid;
    std::size_t fit3_points = 0, fit3_alone = 0;
    // --neighbours K: every slice's fit lines, for the estimate across slices k-K..k+K
    std::vector<std::vector<FitLine>> fits(neighbours > 0 ? sc.slices.size() : 0);
    std::vector<std::map<std::uint16_t, PolylineField>> fields(fits.size());
    for (std::size_t k = 0; k < fits.size(); ++k) {
        for (const Contour& c : sc.slices[k].contours) {
            fits[k].push_back(fit_line_of(c, window, adaptive));
            std::vector<Vec2> poly(c.points.size());
            for (std::size_t i = 0; i < poly.size(); ++i) {
                poly[i] = fits[k].back().at(i);
            }
            fields[k][c.label].add(std::move(poly));
        }
    }
    std::size_t vertices = 0, points = 0, far_points = 0;
    const int W = static_cast<int>(st.width), H = static_cast<int>(st.height);
    const int r = static_cast<int>(std::ceil(3 * sigma));
    std::vector<double> kernel(2 * r + 1);
    double ksum = 0;
    for (int i = -r; i <= r; ++i) {
        kernel[i + r] = std::exp(-0.5 * i * i / (sigma * sigma));
        ksum += kernel[i + r];
    }
    for (double& k : kernel) {
        k /= ksum;
    }
    for (std::uint32_t k = 0; k < sc.slices.size(); ++k) {
        const double z = k * p.slice_spacing_px;
        std::uint16_t blurred_label = 0;
        std::vector<double> tmp(std::size_t(W) * H), blur(std::size_t(W) * H);
        for (const Contour& traced : sc.slices[k].contours) {
            // --subdivide N: each simplified edge split into N by original points (by index)
            Contour c = traced;
            if (subdivide > 1) {
                const std::size_t n = c.points.size();
                const std::size_t m0 = traced.simplified.size();
                c.simplified.clear();
                for (std::size_t e = 0; e < m0; ++e) {
                    const std::size_t a = traced.simplified[e];
                    const std::size_t span = (traced.simplified[(e + 1) % m0] + n - a) % n;
                    std::size_t last = kNoIndex;
                    for (int j = 0; j < subdivide; ++j) {
                        const std::size_t step = span * j / subdivide;
                        if (step != last) {
                            c.simplified.push_back(static_cast<std::uint32_t>((a + step) % n));
                            last = step;
                        }
                    }
                }
            }
            if (c.label != blurred_label) {
                blurred_label = c.label;
                for (int j = 0; j < H; ++j) {
                    for (int i = 0; i < W; ++i) {
                        double s = 0;
                        for (int o = -r; o <= r; ++o) {
                            const int ii = i + o;
                            if (ii >= 0 && ii < W && st.at(ii, j, k) == c.label) {
                                s += kernel[o + r];
                            }
                        }
                        tmp[std::size_t(j) * W + i] = s;
                    }
                }
                for (int j = 0; j < H; ++j) {
                    for (int i = 0; i < W; ++i) {
                        double s = 0;
                        for (int o = -r; o <= r; ++o) {
                            const int jj = j + o;
                            if (jj >= 0 && jj < H) {
                                s += kernel[o + r] * tmp[std::size_t(jj) * W + i];
                            }
                        }
                        blur[std::size_t(j) * W + i] = s;
                    }
                }
            }
            const auto value = [&](Vec2 q) {
                // pixel centres at (i + 0.5, j + 0.5)
                const double x = q.x - 0.5, y = q.y - 0.5;
                const int i0 = static_cast<int>(std::floor(x)),
                          j0 = static_cast<int>(std::floor(y));
                const double fx = x - i0, fy = y - j0;
                const auto at = [&](int i, int j) {
                    return i < 0 || j < 0 || i >= W || j >= H ? 0.0 : blur[std::size_t(j) * W + i];
                };
                return (1 - fy) * ((1 - fx) * at(i0, j0) + fx * at(i0 + 1, j0)) +
                       fy * ((1 - fx) * at(i0, j0 + 1) + fx * at(i0 + 1, j0 + 1));
            };
            sample_polygon(p, c.label, z, c.points, stair);
            far_points += beyond(p, c.label, z, c.points, tolerance);
            points += c.points.size();
            const std::size_t m = c.simplified.size();
            std::vector<Vec2> at(m), normal(m);
            for (std::size_t v = 0; v < m; ++v) {
                at[v] = c.points[c.simplified[v]];
            }
            sample_polygon(p, c.label, z, at, simp);
            for (std::size_t v = 0; v < m; ++v) {
                const Vec2 a = at[(v + m - 1) % m], b = at[v], cc = at[(v + 1) % m];
                const Vec2 e1 = b - a, e2 = cc - b;
                // outward normal of a counter-clockwise outer contour: (dy, -dx); holes run
                // clockwise, so the same formula points into the hole (outward of the object)
                Vec2 nn =
                    (1.0 / norm(e1)) * Vec2{e1.y, -e1.x} + (1.0 / norm(e2)) * Vec2{e2.y, -e2.x};
                const double l = norm(nn);
                normal[v] = l > 1e-9 ? (1.0 / l) * nn : (1.0 / norm(e1)) * Vec2{e1.y, -e1.x};
            }
            // iso: root of value - 0.5 along the normal within +-0.75 px (outward: value falls)
            // the root of f nearest 0 in [-1, 1] (0 when none)
            const auto root = [&](auto f) {
                double best = 0.0;
                bool found = false;
                double prev_s = -1.0, prev = f(-1.0);
                for (int i = 1; i <= 64; ++i) {
                    const double s = -1.0 + i / 32.0;
                    const double cur = f(s);
                    if ((prev <= 0) != (cur <= 0)) {
                        double lo = prev_s, hi = s, flo = prev;
                        for (int it = 0; it < 30; ++it) {
                            const double mid = 0.5 * (lo + hi);
                            const double fm = f(mid);
                            if ((fm <= 0) == (flo <= 0)) {
                                lo = mid;
                                flo = fm;
                            } else {
                                hi = mid;
                            }
                        }
                        const double s0 = 0.5 * (lo + hi);
                        if (!found || std::abs(s0) < std::abs(best)) {
                            best = s0;
                            found = true;
                        }
                    }
                    prev_s = s;
                    prev = cur;
                }
                return best;
            };
            std::vector<double> off_iso(m, 0.0), off_true(m, 0.0);
            for (std::size_t v = 0; v < m; ++v) {
                off_iso[v] = root([&](double s) { return 0.5 - value(at[v] + s * normal[v]); });
                off_true[v] = root([&](double s) {
                    const Vec2 q = at[v] + s * normal[v];
                    return truth(p, c.label, {q.x, q.y, z});
                });
            }
            sample_polygon(p, c.label, z, moved(c, normal, off_iso, sc.tolerance_px), iso);
            sample_polygon(p, c.label, z, moved(c, normal, off_true, free_tol), oracle);
            // + sagitta: each vertex further out by a quarter of its two chords' sagittas (the
            // boundary's offset from the chord's midpoint along the chord's normal, by the same
            // estimate), which balances a circular arc's chords
            const auto sagged = [&](const std::vector<double>& off, auto boundary) {
                std::vector<Vec2> q(m);
                for (std::size_t v = 0; v < m; ++v) {
                    q[v] = at[v] + off[v] * normal[v];
                }
                std::vector<double> sag(m);
                for (std::size_t e = 0; e < m; ++e) {
                    const Vec2 a = q[e], b = q[(e + 1) % m];
                    const Vec2 dd = b - a;
                    const double l = norm(dd);
                    if (!(l > 0)) {
                        sag[e] = 0;
                        continue;
                    }
                    const Vec2 en = (1.0 / l) * Vec2{dd.y, -dd.x};
                    sag[e] = root([&](double t) { return boundary(0.5 * (a + b) + t * en); });
                }
                std::vector<double> out(off);
                for (std::size_t v = 0; v < m; ++v) {
                    out[v] += sag_factor * (sag[(v + m - 1) % m] + sag[v]);
                }
                return out;
            };
            const auto iso_f = [&](Vec2 q) { return 0.5 - value(q); };
            // a boundary estimate (closed polyline) and the simplified vertices optimised against
            // it (its signed distance), from where they are
            const auto measure_estimate = [&](const std::vector<Vec2>& line, Stats& on_line,
                                              Stats& placed) {
                sample_polygon(p, c.label, z, line, on_line);
                PolylineField field;
                field.add(line);
                if (&placed == &fit3_optimised) {
                    sample_polygon(p, c.label, z,
                                   grid_positions(
                                       c, [&](Vec2 q) { return field.signed_distance(q); },
                                       sc.tolerance_px, 8),
                                   fit3_grid);
                }
                sample_polygon(
                    p, c.label, z,
                    best_positions(
                        c, at, [&](Vec2 q) { return field.signed_distance(q); }, sc.tolerance_px),
                    placed);
            };
            if (estimators) {
                // Dense boundary estimates, one point per original segment midpoint: moved along
                // the normal of the 7 segments around it to the iso-line, or to the fit line.
                const FitLine f = fit_line_of(traced, window, adaptive);
                const std::size_t n = f.mid.size();
                std::vector<Vec2> on_iso(n), on_fit(n);
                for (std::size_t i = 0; i < n; ++i) {
                    on_iso[i] = f.mid[i] + root([&](double s0) {
                                               return iso_f(f.mid[i] + s0 * f.normal[i]);
                                           }) * f.normal[i];
                    on_fit[i] = f.at(i);
                }
                sample_polygon(p, c.label, z, on_iso, iso_line);
                measure_estimate(on_fit, fit_line, fit_optimised);
            }
            const auto true_f = [&](Vec2 q) { return truth(p, c.label, {q.x, q.y, z}); };
            sample_polygon(p, c.label, z, moved(c, normal, sagged(off_iso, iso_f), sc.tolerance_px),
                           iso_sag);
            const std::vector<Vec2> start = moved(c, normal, sagged(off_true, true_f), free_tol);
            sample_polygon(p, c.label, z, start, oracle_sag);
            if (optimise) {
                sample_polygon(p, c.label, z, best_positions(c, start, true_f, free_tol),
                               optimised);
                // the same against the smoothed mask's iso-line instead of the truth, from iso+sag
                const std::vector<Vec2> from_iso =
                    moved(c, normal, sagged(off_iso, iso_f), sc.tolerance_px);
                sample_polygon(p, c.label, z, best_positions(c, from_iso, iso_f, sc.tolerance_px),
                               iso_optimised);
            }
            if (neighbours > 0) {
                // the fit line's offset along each normal on slices k-K..k+K (the crossing of
                // the same in-plane line with their fit lines), and a least-squares quadratic in
                // z through them at z = k d: the boundary from 2K+1 independent quantisations
                const FitLine& own = fits[k][std::size_t(&traced - sc.slices[k].contours.data())];
                const std::size_t n = own.mid.size();
                std::vector<Vec2> on_fit3(n);
                for (std::size_t i = 0; i < n; ++i) {
                    double estimate = own.offset[i];
                    ++fit3_points;
                    for (int kk = neighbours; kk >= 2; --kk) {
                        double sum = 0.0, s2 = 0.0, s4 = 0.0, num = 0.0;
                        bool all = true;
                        std::vector<double> at_j(2 * kk + 1);
                        for (int j = -kk; j <= kk && all; ++j) {
                            const int slice = int(k) + j;
                            if (j == 0) {
                                at_j[kk] = own.offset[i];
                                continue;
                            }
                            double s0 = 0.0;
                            const auto it = slice >= 0 && slice < int(fields.size())
                                                ? fields[slice].find(c.label)
                                                : fields[0].end();
                            all = slice >= 0 && slice < int(fields.size()) &&
                                  it != fields[slice].end() &&
                                  it->second.crossing(own.mid[i], own.normal[i],
                                                      1.0 + std::abs(j) * p.slice_spacing_px, s0);
                            at_j[j + kk] = s0;
                        }
                        if (!all) {
                            continue;
                        }
                        for (int j = -kk; j <= kk; ++j) {
                            s2 += j * j;
                            s4 += double(j) * j * j * j;
                        }
                        const double nn = 2 * kk + 1, den = nn * s4 - s2 * s2;
                        for (int j = -kk; j <= kk; ++j) {
                            const double w = (s4 - s2 * j * j) / den;
                            num += w * at_j[j + kk];
                            sum += w;
                        }
                        estimate = num / sum;
                        break;
                    }
                    if (estimate == own.offset[i]) {
                        ++fit3_alone;
                    }
                    on_fit3[i] = own.mid[i] + estimate * own.normal[i];
                }
                measure_estimate(on_fit3, fit3_line, fit3_optimised);
            }
            vertices += m;
        }
    }
    const auto row = [](const char* what, const Stats& s) {
        std::printf("%-11s mean %.4f  bias %+.4f  max %.3f  (length %.0f px)\n", what,
                    s.sum_abs / s.length, s.sum_signed / s.length, s.max, s.length);
    };
    std::printf("%s d=%g sigma=%g\n", name.c_str(), p.slice_spacing_px, sigma);
    row("staircase", stair);
    row("simplified", simp);
    row("iso", iso);
    row("oracle", oracle);
    row("iso+sag", iso_sag);
    row("oracle+sag", oracle_sag);
    if (estimators) {
        row("iso line", iso_line);
        row("fit line", fit_line);
        row("fit best", fit_optimised);
    }
    if (neighbours > 0) {
        row("fit3 line", fit3_line);
        row("fit3 best", fit3_optimised);
        row("fit3 grid", fit3_grid);
        std::printf("fit3: %zu of %zu boundary points from their own slice alone\n", fit3_alone,
                    fit3_points);
    }
    if (optimise) {
        row("best", optimised);
        row("iso best", iso_optimised);
    }
    std::printf("simplified vertices %zu; staircase points %zu, beyond %g px of the truth %zu\n",
                vertices, points, tolerance, far_points);
    return 0;
}

}  // namespace
}  // namespace strata

int main(int argc, char** argv) {
    try {
        return strata::run(argc, argv);
    } catch (const std::exception& e) {
        std::cerr << "contour_accuracy: " << e.what() << "\n";
        return 1;
    }
}

// In-plane accuracy of the contour stage against a phantom's analytic solids (issue 22: how much
// of the surface's error is in the slice planes, and how much placing simplified vertices off the
// half-pixel grid could remove).
//
//   contour_accuracy --phantom NAME [--slice-spacing D] [--tolerance T] [--sigma S] [--sag F]
//                    [--oracle-tolerance U]
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
//               chord's normal, by the same estimate: iso-line or truth).
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
        } else if (a == "--subdivide" && i + 1 < argc) {
            subdivide = std::stoi(argv[++i]);
        } else if (a == "--sag" && i + 1 < argc) {
            sag_factor = std::stod(argv[++i]);
        } else if (a == "--tolerance" && i + 1 < argc) {
            tolerance = std::stod(argv[++i]);
        } else if (a == "--sigma" && i + 1 < argc) {
            sigma = std::stod(argv[++i]);
        } else {
            std::cerr << "usage: contour_accuracy --phantom NAME [--slice-spacing D] [--sigma S]\n";
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
    Stats stair, simp, iso, oracle, iso_sag, oracle_sag;
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
            const auto true_f = [&](Vec2 q) { return truth(p, c.label, {q.x, q.y, z}); };
            sample_polygon(p, c.label, z, moved(c, normal, sagged(off_iso, iso_f), sc.tolerance_px),
                           iso_sag);
            sample_polygon(p, c.label, z, moved(c, normal, sagged(off_true, true_f), free_tol),
                           oracle_sag);
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

// Analytic solids with signed distances for the test phantoms.
//
// - Ellipsoid distance: D. Eberly, "Distance from a Point to an Ellipse, an Ellipsoid, or a
//   Hyperellipsoid" (Geometric Tools, 2013, rev. 2020): the closest point solves a monotone
//   root problem in one variable, found by robust bisection to full double precision.
// - CSG bounds: J. C. Hart, "Sphere tracing: a geometric method for the antialiased ray tracing
//   of implicit surfaces" (The Visual Computer, 1996): min/max of distance bounds is a bound.
// - Twisted and polar primitives: bounds from the triangle inequality in polar coordinates
//   (derivations next to each function); their sign is exact.
//
// One file: every primitive is a pair of overloads (contains_prim, distance_prim) that the tree
// evaluation dispatches with one std::visit over Solid, next to the bounds and validation that
// walk the same tree; split by family, each family's overloads would need a header that only
// this file reads. The sections: helpers, ellipsoid distance, polar bound, primitives, tree
// evaluation, bounds, validation, rasterisation.
#include "phantom/solids.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>

#include "core/error.h"

namespace strata {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// Small helpers

double wrap_angle(double a) {
    // note: result in (-pi, pi]
    a = std::remainder(a, 2.0 * kPi);
    if (a <= -kPi) {
        a += 2.0 * kPi;
    }
    return a;
}

double mod_two_pi(double a) {
    double m = std::fmod(a, 2.0 * kPi);
    if (m < 0.0) {
        m += 2.0 * kPi;
    }
    if (m >= 2.0 * kPi) {
        m = 0.0;
    }
    return m;
}

double distance_to_segment(Vec2 p, Vec2 a, Vec2 b) {
    const Vec2 ab = b - a;
    const double len2 = dot(ab, ab);
    double t = len2 > 0.0 ? dot(p - a, ab) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return norm(p - (a + t * ab));
}

double distance_to_segment(Vec3 p, Vec3 a, Vec3 b) {
    const Vec3 ab = b - a;
    const double len2 = dot(ab, ab);
    double t = len2 > 0.0 ? dot(p - a, ab) / len2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return norm(p - (a + t * ab));
}

// Exact signed distance of a point to the intersection of two sets whose exact distances are
// a and b, when the sets are orthogonal extrusions (a capped prism): Quilez's formula.
double extrusion_distance(double a, double b) {
    const double ao = std::max(a, 0.0);
    const double bo = std::max(b, 0.0);
    return std::min(std::max(a, b), 0.0) + std::sqrt(ao * ao + bo * bo);
}

// ---------------------------------------------------------------------------------------------
// Eberly: distance from a point in the first quadrant/octant to an ellipse/ellipsoid with
// semi-axes sorted in decreasing order.

double robust_length(double a, double b) {
    const double m = std::max(std::abs(a), std::abs(b));
    if (m == 0.0) {
        return 0.0;
    }
    const double x = a / m;
    const double y = b / m;
    return m * std::sqrt(x * x + y * y);
}

double robust_length(double a, double b, double c) {
    const double m = std::max({std::abs(a), std::abs(b), std::abs(c)});
    if (m == 0.0) {
        return 0.0;
    }
    const double x = a / m;
    const double y = b / m;
    const double z = c / m;
    return m * std::sqrt(x * x + y * y + z * z);
}

constexpr int kMaxBisections =
    std::numeric_limits<double>::digits - std::numeric_limits<double>::min_exponent + 64;

// note: Eberly bisects on s, whose root approaches -1 when the point nears the principal plane
// of the smallest axis from inside; there s + 1 loses all relative precision (1e-16 absolute).
// We bisect on u = s + 1 instead, so x_last = y_last / u keeps full relative precision.
// (e_i / e_last)^2 - 1 is computed as (e_i - e_last)(e_i + e_last) / e_last^2.
/// Eberly's bisection on [u0, u1] for the root of g, which decreases in u: halves the interval
/// until it stops shrinking (full double precision) or g is exactly 0.
template <class G>
double bisect_root_u(double u0, double u1, G&& g) {
    double u = u0;
    for (int i = 0; i < kMaxBisections; ++i) {
        u = 0.5 * (u0 + u1);
        if (u == u0 || u == u1) {
            break;
        }
        const double value = g(u);
        if (value > 0.0) {
            u0 = u;
        } else if (value < 0.0) {
            u1 = u;
        } else {
            break;
        }
    }
    return u;
}

double ellipse_root_u(double d0, double n0, double z1, double g) {
    return bisect_root_u(z1, g < 0.0 ? 1.0 : robust_length(n0, z1), [&](double u) {
        const double ratio0 = n0 / (u + d0);
        const double ratio1 = z1 / u;
        return ratio0 * ratio0 + ratio1 * ratio1 - 1.0;
    });
}

// e0 >= e1 > 0, y0 >= 0, y1 >= 0.
double distance_point_ellipse(double e0, double e1, double y0, double y1) {
    if (y1 > 0.0) {
        if (y0 > 0.0) {
            const double z0 = y0 / e0;
            const double z1 = y1 / e1;
            const double g = z0 * z0 + z1 * z1 - 1.0;
            if (g == 0.0) {
                return 0.0;
            }
            const double r0 = (e0 / e1) * (e0 / e1);
            const double d0 = (e0 - e1) * (e0 + e1) / (e1 * e1);
            const double u = ellipse_root_u(d0, r0 * z0, z1, g);
            const double x0 = r0 * y0 / (u + d0);
            const double x1 = y1 / u;
            return std::hypot(x0 - y0, x1 - y1);
        }
        return std::abs(y1 - e1);
    }
    const double numer0 = e0 * y0;
    const double denom0 = e0 * e0 - e1 * e1;
    if (numer0 < denom0) {
        const double xde0 = numer0 / denom0;
        const double x0 = e0 * xde0;
        const double x1 = e1 * std::sqrt(std::max(0.0, 1.0 - xde0 * xde0));
        return std::hypot(x0 - y0, x1);
    }
    return std::abs(y0 - e0);
}

double ellipsoid_root_u(double d0, double d1, double n0, double n1, double z2, double g) {
    return bisect_root_u(z2, g < 0.0 ? 1.0 : robust_length(n0, n1, z2), [&](double u) {
        const double ratio0 = n0 / (u + d0);
        const double ratio1 = n1 / (u + d1);
        const double ratio2 = z2 / u;
        return ratio0 * ratio0 + ratio1 * ratio1 + ratio2 * ratio2 - 1.0;
    });
}

// e0 >= e1 >= e2 > 0, y0, y1, y2 >= 0.
double distance_point_ellipsoid(double e0, double e1, double e2, double y0, double y1, double y2) {
    if (y2 > 0.0) {
        if (y1 > 0.0) {
            if (y0 > 0.0) {
                const double z0 = y0 / e0;
                const double z1 = y1 / e1;
                const double z2 = y2 / e2;
                const double g = z0 * z0 + z1 * z1 + z2 * z2 - 1.0;
                if (g == 0.0) {
                    return 0.0;
                }
                const double r0 = (e0 / e2) * (e0 / e2);
                const double r1 = (e1 / e2) * (e1 / e2);
                const double d0 = (e0 - e2) * (e0 + e2) / (e2 * e2);
                const double d1 = (e1 - e2) * (e1 + e2) / (e2 * e2);
                const double u = ellipsoid_root_u(d0, d1, r0 * z0, r1 * z1, z2, g);
                const double x0 = r0 * y0 / (u + d0);
                const double x1 = r1 * y1 / (u + d1);
                const double x2 = y2 / u;
                return robust_length(x0 - y0, x1 - y1, x2 - y2);
            }
            return distance_point_ellipse(e1, e2, y1, y2);
        }
        if (y0 > 0.0) {
            return distance_point_ellipse(e0, e2, y0, y2);
        }
        return std::abs(y2 - e2);
    }
    const double denom0 = e0 * e0 - e2 * e2;
    const double denom1 = e1 * e1 - e2 * e2;
    const double numer0 = e0 * y0;
    const double numer1 = e1 * y1;
    if (numer0 < denom0 && numer1 < denom1) {
        const double xde0 = numer0 / denom0;
        const double xde1 = numer1 / denom1;
        const double discr = 1.0 - xde0 * xde0 - xde1 * xde1;
        if (discr > 0.0) {
            const double x0 = e0 * xde0;
            const double x1 = e1 * xde1;
            const double x2 = e2 * std::sqrt(discr);
            return robust_length(x0 - y0, x1 - y1, x2);
        }
    }
    return distance_point_ellipse(e0, e1, y0, y1);
}

// ---------------------------------------------------------------------------------------------
// Polar bound. For a shape {rho <= r(theta, z)} with |dr/dtheta| <= l_theta,
// |dr/dz| <= l_z and r_lo <= r <= r_hi: let q be the boundary point nearest to p, at distance
// D. If D < rho / 10, q's angle differs from p's by at most asin(D / rho) <= c D / rho with
// c = asin(0.1) / 0.1 (asin(x) / x grows with x), so
// |rho - r(theta, z)| <= |rho - rho_q| + l_theta |dtheta| + l_z |dz|
//                    <= D (sqrt(1 + l_z^2) + c l_theta / rho).
// If D >= rho / 10 the value capped at rho / 10 is below D. The radial bounds r_lo / r_hi give
// two more valid bounds; the maximum of valid bounds is valid.
double polar_bound(
    double rho, double r, double l_theta, double l_z, double r_lo, double r_hi, bool inside) {
    constexpr double kAsinSlope = 1.0016742116155979;  // asin(0.1) / 0.1, rounded up
    const double g = std::abs(rho - r);
    double f = 0.0;
    if (rho > 0.0) {
        f = std::min(g / (std::sqrt(1.0 + l_z * l_z) + kAsinSlope * l_theta / rho), 0.1 * rho);
    }
    if (inside) {
        return -std::max(f, r_lo - rho);
    }
    return std::max(f, rho - r_hi);
}

// A twist rotating every cross-section by omega per px of z moves a boundary point at radius
// <= r_max by <= r_max omega |dz| in-plane; so the exact in-plane distance s of the plane
// through p obeys s <= a + r_max omega b <= sqrt(1 + (r_max omega)^2) D (a, b: in-plane and z
// offsets to the nearest boundary point). Any in-plane bound divided by that factor is a bound.
double twist_factor(double r_max, double omega) {
    const double k = r_max * omega;
    return std::sqrt(1.0 + k * k);
}

// Intersection with the slab z_min <= z <= z_max (bound).
double clip_slab(double f, double z, double z_min, double z_max) {
    return std::max({f, z_min - z, z - z_max});
}

// ---------------------------------------------------------------------------------------------
// Primitives: membership and signed distance.

bool in_slab(double z, double z_min, double z_max) {
    return z >= z_min && z <= z_max;
}

Vec3 ellipsoid_local(const Ellipsoid& e, Vec3 p) {
    const Vec3 q = p - e.centre;
    Vec3 y;
    for (int c = 0; c < 3; ++c) {
        y[c] = e.rotation[0][c] * q.x + e.rotation[1][c] * q.y + e.rotation[2][c] * q.z;
    }
    return y;
}

bool contains_prim(const Ball& b, Vec3 p) {
    const Vec3 q = p - b.centre;
    return dot(q, q) <= b.radius * b.radius;
}
double distance_prim(const Ball& b, Vec3 p) {
    return norm(p - b.centre) - b.radius;
}

bool contains_prim(const Ellipsoid& e, Vec3 p) {
    const Vec3 y = ellipsoid_local(e, p);
    double s = 0.0;
    for (int c = 0; c < 3; ++c) {
        const double t = y[c] / e.semi_axes[c];
        s += t * t;
    }
    return s <= 1.0;
}
double distance_prim(const Ellipsoid& e, Vec3 p) {
    const Vec3 y = ellipsoid_local(e, p);
    int order[3] = {0, 1, 2};
    std::sort(order, order + 3, [&](int a, int b) { return e.semi_axes[a] > e.semi_axes[b]; });
    const double d = distance_point_ellipsoid(e.semi_axes[order[0]], e.semi_axes[order[1]],
                                              e.semi_axes[order[2]], std::abs(y[order[0]]),
                                              std::abs(y[order[1]]), std::abs(y[order[2]]));
    return contains_prim(e, p) ? -d : d;
}

bool contains_prim(const Box& b, Vec3 p) {
    for (int a = 0; a < 3; ++a) {
        if (p[a] < b.min[a] || p[a] > b.max[a] || (b.max_open[a] && p[a] == b.max[a])) {
            return false;
        }
    }
    return true;
}
double distance_prim(const Box& b, Vec3 p) {
    double outside2 = 0.0;
    double inside = -kInf;
    for (int a = 0; a < 3; ++a) {
        const double c = 0.5 * (b.min[a] + b.max[a]);
        const double h = 0.5 * (b.max[a] - b.min[a]);
        const double q = std::abs(p[a] - c) - h;
        outside2 += q > 0.0 ? q * q : 0.0;
        inside = std::max(inside, q);
    }
    return std::sqrt(outside2) + std::min(inside, 0.0);
}

bool is_straight(const Cylinder& c) {
    return c.slope.x == 0.0 && c.slope.y == 0.0;
}

Vec2 cylinder_axis_at(const Cylinder& c, double z) {
    return c.centre + z * c.slope;
}

bool contains_prim(const Cylinder& c, Vec3 p) {
    if (!in_slab(p.z, c.z_min, c.z_max)) {
        return false;
    }
    const Vec2 q = Vec2{p.x, p.y} - cylinder_axis_at(c, p.z);
    return dot(q, q) <= c.radius * c.radius;
}
double distance_prim(const Cylinder& c, Vec3 p) {
    if (is_straight(c)) {
        const double d_rho = norm(Vec2{p.x, p.y} - c.centre) - c.radius;
        const double d_z = std::abs(p.z - 0.5 * (c.z_min + c.z_max)) - 0.5 * (c.z_max - c.z_min);
        return extrusion_distance(d_rho, d_z);
    }
    // note: the infinite slanted cylinder is an elliptic cylinder along u = (slope, 1); its
    // cross-section normal to u is an ellipse with semi-axes r (normal to the slope in-plane)
    // and r / |(slope, 1)| (in the plane of u and z): exact there, a bound after the slab.
    const double s = std::sqrt(1.0 + dot(c.slope, c.slope));
    const Vec3 u{c.slope.x / s, c.slope.y / s, 1.0 / s};
    const double sl = norm(c.slope);
    const Vec3 e1{-c.slope.y / sl, c.slope.x / sl, 0.0};
    const Vec3 e2 = cross(u, e1);
    const Vec3 q = p - Vec3{c.centre.x, c.centre.y, 0.0};
    const double a = std::abs(dot(q, e1));
    const double b = std::abs(dot(q, e2));
    const double d = distance_point_ellipse(c.radius, c.radius / s, a, b);
    const Vec2 w = Vec2{p.x, p.y} - cylinder_axis_at(c, p.z);
    const double f = dot(w, w) <= c.radius * c.radius ? -d : d;
    return clip_slab(f, p.z, c.z_min, c.z_max);
}

bool contains_prim(const Capsule& c, Vec3 p) {
    return distance_to_segment(p, c.a, c.b) <= c.radius;
}
double distance_prim(const Capsule& c, Vec3 p) {
    return distance_to_segment(p, c.a, c.b) - c.radius;
}

double torus_tube_distance(const Torus& t, Vec3 p) {
    const Vec3 q = p - t.centre;
    const double h = dot(q, t.axis);
    const double rho = norm(q - h * t.axis);
    return std::hypot(rho - t.major_radius, h);
}
bool contains_prim(const Torus& t, Vec3 p) {
    return torus_tube_distance(t, p) <= t.minor_radius;
}
double distance_prim(const Torus& t, Vec3 p) {
    return torus_tube_distance(t, p) - t.minor_radius;
}

bool contains_prim(const HalfSpace& h, Vec3 p) {
    return dot(h.normal, p) <= h.offset;
}
double distance_prim(const HalfSpace& h, Vec3 p) {
    return dot(h.normal, p) - h.offset;
}

// T05 -----------------------------------------------------------------------------------------
double sector_gap_angle(const TwistedSector& s, double z) {
    return s.gap_angle_rad + s.twist_rad_per_px * z;
}
bool in_sector_plane(const TwistedSector& s, Vec3 p) {
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double r2 = dot(q, q);
    if (r2 <= s.inner_radius * s.inner_radius || r2 > s.outer_radius * s.outer_radius) {
        return false;
    }
    const double theta = std::atan2(q.y, q.x);
    return std::abs(wrap_angle(theta - sector_gap_angle(s, p.z))) >= s.gap_half_angle_rad;
}
bool contains_prim(const TwistedSector& s, Vec3 p) {
    return in_slab(p.z, s.z_min, s.z_max) && in_sector_plane(s, p);
}
double distance_prim(const TwistedSector& s, Vec3 p) {
    // Exact in-plane distance to the annular sector: arcs where the angle is in range, and
    // the two radial end edges at theta = gap +- half angle.
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double rho = norm(q);
    const double gap = sector_gap_angle(s, p.z);
    double d = kInf;
    if (rho > 0.0 && std::abs(wrap_angle(std::atan2(q.y, q.x) - gap)) >= s.gap_half_angle_rad) {
        d = std::min(std::abs(rho - s.inner_radius), std::abs(rho - s.outer_radius));
    }
    for (double sign : {-1.0, 1.0}) {
        const double a = gap + sign * s.gap_half_angle_rad;
        const Vec2 dir{std::cos(a), std::sin(a)};
        d = std::min(d, distance_to_segment(q, s.inner_radius * dir, s.outer_radius * dir));
    }
    const double f = (in_sector_plane(s, p) ? -d : d) /
                     twist_factor(s.outer_radius, std::abs(s.twist_rad_per_px));
    return clip_slab(f, p.z, s.z_min, s.z_max);
}

// T06 -----------------------------------------------------------------------------------------
struct SpiralPlane {
    double rho;
    double t0;  // (theta - start angle) mod 2 pi
};
SpiralPlane spiral_plane(const SpiralBand& s, Vec3 p) {
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double start = s.start_angle_rad + s.twist_rad_per_px * p.z;
    return {norm(q), mod_two_pi(std::atan2(q.y, q.x) - start)};
}
double spiral_radius(const SpiralBand& s, double t) {
    return s.start_radius + s.radius_per_rad * t;
}
bool in_spiral_plane(const SpiralBand& s, Vec3 p) {
    const SpiralPlane sp = spiral_plane(s, p);
    for (double t = sp.t0; t <= s.max_turn_rad; t += 2.0 * kPi) {
        if (std::abs(sp.rho - spiral_radius(s, t)) <= s.half_width) {
            return true;
        }
    }
    return false;
}
bool contains_prim(const SpiralBand& s, Vec3 p) {
    return in_slab(p.z, s.z_min, s.z_max) && in_spiral_plane(s, p);
}
double distance_prim(const SpiralBand& s, Vec3 p) {
    const SpiralPlane sp = spiral_plane(s, p);
    const double rho = sp.rho;
    const double a = s.start_radius;
    const double b = s.radius_per_rad;
    const double h = s.half_width;
    const double r_max = spiral_radius(s, s.max_turn_rad) + h;
    const bool inside = in_spiral_plane(s, p);
    // End edges: radial segments at t = 0 and t = max_turn.
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double start = s.start_angle_rad + s.twist_rad_per_px * p.z;
    double d_end = kInf;
    for (double t : {0.0, s.max_turn_rad}) {
        const Vec2 dir{std::cos(start + t), std::sin(start + t)};
        d_end = std::min(d_end, distance_to_segment(q, (spiral_radius(s, t) - h) * dir,
                                                    (spiral_radius(s, t) + h) * dir));
    }
    double f2 = 0.0;
    if (inside) {
        // The branch through p: A(p) = rho - r(t) has gradient <= sqrt(1 + b^2 / rho^2) and
        // every band point has rho >= a - h; so margin / that is below the distance to the
        // spiral edges, and the end edges are measured exactly.
        double margin = 0.0;
        for (double t = sp.t0; t <= s.max_turn_rad; t += 2.0 * kPi) {
            margin = std::max(margin, h - std::abs(rho - spiral_radius(s, t)));
        }
        const double lip = std::sqrt(1.0 + (b / (a - h)) * (b / (a - h)));
        f2 = -std::min(margin / lip, d_end);
    } else {
        // Outside: a band point q at distance D <= rho has a parameter t' with
        // |rho - r(t')| - h <= D and an angle within (pi / 2) D / rho of p's; so
        // M(t) = max(|rho - r(t)| - h, (2 rho / pi) |t - t_n|) <= D at t = t', where t_n is
        // p's own parameter on the nearest turn. M is convex piecewise linear: its minimum
        // over each turn's window lies at a breakpoint, a crossing or a window end.
        double best = kInf;
        const double k = 2.0 * rho / kPi;
        const double c = rho - a;  // A(t) = |c - b t| - h
        for (int n = -1; sp.t0 + 2.0 * kPi * (n - 1) <= s.max_turn_rad; ++n) {
            const double tn = sp.t0 + 2.0 * kPi * n;
            const double lo = std::max(tn - kPi, 0.0);
            const double hi = std::min(tn + kPi, s.max_turn_rad);
            if (lo > hi) {
                continue;
            }
            double candidates[8] = {
                lo,  hi, tn, c / b, (c - h + k * tn) / (k + b), (k * tn + c + h) / (k + b),
                0.0, 0.0};
            int count = 6;
            if (k != b) {
                candidates[count++] = (k * tn - (c - h)) / (k - b);
                candidates[count++] = (c + h - k * tn) / (b - k);
            }
            for (int m = 0; m < count; ++m) {
                const double t = std::clamp(candidates[m], lo, hi);
                best = std::min(best, std::max(std::abs(c - b * t) - h, k * std::abs(t - tn)));
            }
        }
        f2 = std::max({std::min(best, rho), rho - r_max, (a - h) - rho, 0.0});
    }
    const double f = f2 / twist_factor(r_max, std::abs(s.twist_rad_per_px));
    return clip_slab(f, p.z, s.z_min, s.z_max);
}

// T07 -----------------------------------------------------------------------------------------
double star_radius(const StarMorph& s, double theta) {
    const double half = kPi / s.points;
    double u = std::fmod(theta, 2.0 * half);
    if (u < 0.0) {
        u += 2.0 * half;
    }
    if (u > half) {
        u = 2.0 * half - u;
    }
    const double ro = s.outer_radius;
    const double ri = s.inner_radius;
    // Radial function of the line through (ro, 0) and (ri, half), in polar form.
    return ro * ri * std::sin(half) / (ro * std::sin(u) + ri * std::sin(half - u));
}
double morph_fraction(const StarMorph& s, double z) {
    return std::clamp((z - s.z_min) / (s.z_max - s.z_min), 0.0, 1.0);
}
double morph_radius(const StarMorph& s, double theta, double z) {
    const double t = morph_fraction(s, z);
    return (1.0 - t) * star_radius(s, theta) + t * s.circle_radius;
}
bool in_star_plane(const StarMorph& s, Vec3 p) {
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double rho = norm(q);
    return rho <= morph_radius(s, std::atan2(q.y, q.x), p.z);
}
bool contains_prim(const StarMorph& s, Vec3 p) {
    return in_slab(p.z, s.z_min, s.z_max) && in_star_plane(s, p);
}
struct Sample {
    bool inside = false;
    double distance = 0.0;  // signed bound
};

// Radial extent of a star-shaped primitive: r_lo <= boundary radius <= r_hi around centre.
struct RadialRange {
    Vec2 centre;
    double r_lo = 0.0;
    double r_hi = 0.0;
};

struct StarConstants {
    double l_theta, l_z, r_lo, r_hi;
};
StarConstants star_constants(const StarMorph& s) {
    const double half = kPi / s.points;
    const double ro = s.outer_radius;
    const double ri = s.inner_radius;
    const double sn = std::sin(half);
    const double cs = std::cos(half);
    // |r'| of a straight edge grows towards the end farther from the foot of the
    // perpendicular, so it is largest at a vertex.
    const double l_theta = 1.0001 * std::max(std::abs(ro * (ro - ri * cs) / (ri * sn)),
                                             std::abs(ri * (ro * cs - ri) / (ro * sn)));
    const double edge = std::hypot(ri * cs - ro, ri * sn);
    const double star_min = 0.9999 * std::min(ri, ro * ri * sn / edge);
    const double l_z =
        1.0001 * std::max(std::abs(s.circle_radius - ro), std::abs(s.circle_radius - star_min)) /
        (s.z_max - s.z_min);
    return {l_theta, l_z, std::min(star_min, s.circle_radius), std::max(ro, s.circle_radius)};
}
Sample sample_prim(const StarMorph& s, Vec3 p) {
    const StarConstants k = star_constants(s);
    const Vec2 q = Vec2{p.x, p.y} - s.centre;
    const double rho = norm(q);
    const double r = morph_radius(s, std::atan2(q.y, q.x), p.z);
    const bool in_plane = rho <= r;
    const double f = polar_bound(rho, r, k.l_theta, k.l_z, k.r_lo, k.r_hi, in_plane);
    return {in_plane && in_slab(p.z, s.z_min, s.z_max), clip_slab(f, p.z, s.z_min, s.z_max)};
}
double distance_prim(const StarMorph& s, Vec3 p) {
    return sample_prim(s, p).distance;
}
std::optional<RadialRange> radial_range(const StarMorph& s) {
    const StarConstants k = star_constants(s);
    return RadialRange{s.centre, k.r_lo, k.r_hi};
}

// T32 -----------------------------------------------------------------------------------------
double wave_radius(const RadialWave& w, double theta, double z) {
    double r = w.base_radius;
    for (const WaveTerm& t : w.terms) {
        r += t.amplitude * std::sin(t.frequency * theta + t.phase_rad + t.phase_rad_per_px * z);
    }
    return r;
}
double wave_amplitude(const RadialWave& w) {
    double a = 0.0;
    for (const WaveTerm& t : w.terms) {
        a += std::abs(t.amplitude);
    }
    return a;
}
bool contains_prim(const RadialWave& w, Vec3 p) {
    if (!in_slab(p.z, w.z_min, w.z_max)) {
        return false;
    }
    const Vec2 q = Vec2{p.x, p.y} - w.centre;
    return norm(q) <= wave_radius(w, std::atan2(q.y, q.x), p.z);
}
Sample sample_prim(const RadialWave& w, Vec3 p) {
    double l_theta = 0.0;
    double l_z = 0.0;
    for (const WaveTerm& t : w.terms) {
        l_theta += std::abs(t.amplitude * t.frequency);
        l_z += std::abs(t.amplitude * t.phase_rad_per_px);
    }
    const double amp = wave_amplitude(w);
    const Vec2 q = Vec2{p.x, p.y} - w.centre;
    const double rho = norm(q);
    const double r = wave_radius(w, std::atan2(q.y, q.x), p.z);
    const bool in_plane = rho <= r;
    const double f = polar_bound(rho, r, 1.0001 * l_theta, 1.0001 * l_z, w.base_radius - amp,
                                 w.base_radius + amp, in_plane);
    return {in_plane && in_slab(p.z, w.z_min, w.z_max), clip_slab(f, p.z, w.z_min, w.z_max)};
}
double distance_prim(const RadialWave& w, Vec3 p) {
    return sample_prim(w, p).distance;
}
std::optional<RadialRange> radial_range(const RadialWave& w) {
    const double amp = wave_amplitude(w);
    return RadialRange{w.centre, w.base_radius - amp, w.base_radius + amp};
}

// T36 -----------------------------------------------------------------------------------------
double gaussian_factor(double delta, double inv_two_sigma2) {
    return std::exp(-(delta * delta) * inv_two_sigma2);
}
double inv_two_sigma2(const GaussianBlob& b) {
    return 1.0 / (2.0 * b.sigma * b.sigma);
}

bool contains_prim(const GaussianLevelSet& g, Vec3 p) {
    return evaluate_gaussian_sum(g, p) >= g.level;
}
double distance_prim(const GaussianLevelSet& g, Vec3 p) {
    // |grad w exp(-r^2 / 2 s^2)| peaks at r = s with w / (s sqrt(e)).
    double lip = 0.0;
    for (const GaussianBlob& b : g.blobs) {
        lip += b.weight / (b.sigma * std::sqrt(std::numbers::e));
    }
    const double f = evaluate_gaussian_sum(g, p);
    const double d = (g.level - f) / (1.0001 * lip);
    if (f >= g.level) {
        return std::min(d, 0.0);
    }
    return std::max(d, 0.0);
}

bool contains_prim(const Csg&, Vec3) {
    return false;
}
double distance_prim(const Csg&, Vec3) {
    return kInf;
}

template <typename Prim>
Sample sample_prim(const Prim& prim, Vec3 p) {
    return {contains_prim(prim, p), distance_prim(prim, p)};
}
template <typename Prim>
std::optional<RadialRange> radial_range(const Prim&) {
    return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Tree evaluation

bool contains_node(const Solid& s, std::uint32_t node, Vec3 p) {
    const SolidNode& n = s.nodes[node];
    if (const Csg* c = std::get_if<Csg>(&n)) {
        switch (c->op) {
            case CsgOp::Union:
                for (std::uint32_t o : c->operands) {
                    if (contains_node(s, o, p)) {
                        return true;
                    }
                }
                return false;
            case CsgOp::Intersection:
                for (std::uint32_t o : c->operands) {
                    if (!contains_node(s, o, p)) {
                        return false;
                    }
                }
                return true;
            case CsgOp::Difference:
                if (!contains_node(s, c->operands[0], p)) {
                    return false;
                }
                for (std::size_t k = 1; k < c->operands.size(); ++k) {
                    if (contains_node(s, c->operands[k], p)) {
                        return false;
                    }
                }
                return true;
        }
        return false;
    }
    return std::visit([&](const auto& prim) { return contains_prim(prim, p); }, n);
}

double distance_node(const Solid& s, std::uint32_t node, Vec3 p) {
    const SolidNode& n = s.nodes[node];
    if (const Csg* c = std::get_if<Csg>(&n)) {
        double d = c->op == CsgOp::Union ? kInf : -kInf;
        for (std::size_t k = 0; k < c->operands.size(); ++k) {
            const double dk = distance_node(s, c->operands[k], p);
            switch (c->op) {
                case CsgOp::Union:
                    d = std::min(d, dk);
                    break;
                case CsgOp::Intersection:
                    d = std::max(d, dk);
                    break;
                case CsgOp::Difference:
                    d = std::max(d, k == 0 ? dk : -dk);
                    break;
            }
        }
        return d;
    }
    return std::visit([&](const auto& prim) { return distance_prim(prim, p); }, n);
}

// ---------------------------------------------------------------------------------------------
// Bounds

Bounds3 empty_bounds() {
    return {{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
}
Bounds3 infinite_bounds() {
    return {{-kInf, -kInf, -kInf}, {kInf, kInf, kInf}};
}
Bounds3 disc_prism(Vec2 c, double r, double z_min, double z_max) {
    return {{c.x - r, c.y - r, z_min}, {c.x + r, c.y + r, z_max}};
}

Bounds3 bounds_prim(const Ball& b) {
    const Vec3 r{b.radius, b.radius, b.radius};
    return {b.centre - r, b.centre + r};
}
Bounds3 bounds_prim(const Ellipsoid& e) {
    Vec3 h;
    for (int r = 0; r < 3; ++r) {
        double s = 0.0;
        for (int c = 0; c < 3; ++c) {
            const double v = e.rotation[r][c] * e.semi_axes[c];
            s += v * v;
        }
        h[r] = std::sqrt(s);
    }
    return {e.centre - h, e.centre + h};
}
Bounds3 bounds_prim(const Box& b) {
    return {b.min, b.max};
}
Bounds3 bounds_prim(const Cylinder& c) {
    const Vec2 a = cylinder_axis_at(c, c.z_min);
    const Vec2 b = cylinder_axis_at(c, c.z_max);
    return {{std::min(a.x, b.x) - c.radius, std::min(a.y, b.y) - c.radius, c.z_min},
            {std::max(a.x, b.x) + c.radius, std::max(a.y, b.y) + c.radius, c.z_max}};
}
Bounds3 bounds_prim(const Capsule& c) {
    Bounds3 b;
    for (int a = 0; a < 3; ++a) {
        b.min[a] = std::min(c.a[a], c.b[a]) - c.radius;
        b.max[a] = std::max(c.a[a], c.b[a]) + c.radius;
    }
    return b;
}
Bounds3 bounds_prim(const Torus& t) {
    Vec3 h;
    for (int a = 0; a < 3; ++a) {
        h[a] =
            t.major_radius * std::sqrt(std::max(0.0, 1.0 - t.axis[a] * t.axis[a])) + t.minor_radius;
    }
    return {t.centre - h, t.centre + h};
}
Bounds3 bounds_prim(const HalfSpace& h) {
    Bounds3 b = infinite_bounds();
    for (int a = 0; a < 3; ++a) {
        const int o1 = (a + 1) % 3;
        const int o2 = (a + 2) % 3;
        if (h.normal[o1] == 0.0 && h.normal[o2] == 0.0) {
            if (h.normal[a] > 0.0) {
                b.max[a] = h.offset / h.normal[a];
            } else {
                b.min[a] = h.offset / h.normal[a];
            }
        }
    }
    return b;
}
Bounds3 bounds_prim(const TwistedSector& s) {
    return disc_prism(s.centre, s.outer_radius, s.z_min, s.z_max);
}
Bounds3 bounds_prim(const SpiralBand& s) {
    return disc_prism(s.centre, spiral_radius(s, s.max_turn_rad) + s.half_width, s.z_min, s.z_max);
}
Bounds3 bounds_prim(const StarMorph& s) {
    return disc_prism(s.centre, std::max(s.outer_radius, s.circle_radius), s.z_min, s.z_max);
}
Bounds3 bounds_prim(const RadialWave& w) {
    return disc_prism(w.centre, w.base_radius + wave_amplitude(w), w.z_min, w.z_max);
}
Bounds3 bounds_prim(const GaussianLevelSet& g) {
    // f >= level needs some blob with weight * factor >= level / n.
    Bounds3 out = empty_bounds();
    const double n = static_cast<double>(g.blobs.size());
    for (const GaussianBlob& b : g.blobs) {
        const double ratio = n * b.weight / g.level;
        if (ratio < 1.0) {
            continue;
        }
        const double r = b.sigma * std::sqrt(2.0 * std::log(ratio)) * 1.0001 + 1e-9;
        for (int a = 0; a < 3; ++a) {
            out.min[a] = std::min(out.min[a], b.centre[a] - r);
            out.max[a] = std::max(out.max[a], b.centre[a] + r);
        }
    }
    return out;
}
Bounds3 bounds_prim(const Csg&) {
    return infinite_bounds();
}

std::vector<Bounds3> node_bounds(const Solid& s) {
    std::vector<Bounds3> out(s.nodes.size());
    for (std::size_t i = 0; i < s.nodes.size(); ++i) {
        if (const Csg* c = std::get_if<Csg>(&s.nodes[i])) {
            Bounds3 b = c->op == CsgOp::Intersection ? infinite_bounds() : empty_bounds();
            for (std::size_t k = 0; k < c->operands.size(); ++k) {
                const Bounds3& o = out[c->operands[k]];
                if (c->op == CsgOp::Difference) {
                    if (k == 0) {
                        b = o;
                    }
                    continue;
                }
                for (int a = 0; a < 3; ++a) {
                    if (c->op == CsgOp::Union) {
                        b.min[a] = std::min(b.min[a], o.min[a]);
                        b.max[a] = std::max(b.max[a], o.max[a]);
                    } else {
                        b.min[a] = std::max(b.min[a], o.min[a]);
                        b.max[a] = std::min(b.max[a], o.max[a]);
                    }
                }
            }
            out[i] = b;
        } else {
            out[i] = std::visit([](const auto& prim) { return bounds_prim(prim); }, s.nodes[i]);
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Validation

[[noreturn]] void invalid(const std::string& what, const std::string& why) {
    throw Error(ErrorCode::InvalidInput, "solid " + what + ": " + why);
}
void check_finite(const std::string& what, const std::string& field, double v) {
    if (!std::isfinite(v)) {
        invalid(what, field + " is not finite");
    }
}
void check_finite(const std::string& what, const std::string& field, Vec3 v) {
    for (int a = 0; a < 3; ++a) {
        check_finite(what, field, v[a]);
    }
}
void check_finite(const std::string& what, const std::string& field, Vec2 v) {
    check_finite(what, field, v.x);
    check_finite(what, field, v.y);
}
void check_positive(const std::string& what, const std::string& field, double v) {
    check_finite(what, field, v);
    if (v <= 0.0) {
        std::ostringstream s;
        s << field << " is " << v << ", expected > 0";
        invalid(what, s.str());
    }
}
void check_slab(const std::string& what, double z_min, double z_max) {
    check_finite(what, "z_min", z_min);
    check_finite(what, "z_max", z_max);
    if (z_max < z_min) {
        std::ostringstream s;
        s << "z range [" << z_min << ", " << z_max << "] is reversed";
        invalid(what, s.str());
    }
}
Vec3 unit_vector(const std::string& what, const std::string& field, Vec3 v) {
    check_finite(what, field, v);
    const double n = norm(v);
    if (!(n > 0.0)) {
        invalid(what, field + " is the zero vector");
    }
    return (1.0 / n) * v;
}

void validate(Ball& b) {
    check_finite("ball", "centre", b.centre);
    check_positive("ball", "radius", b.radius);
}
void validate(Ellipsoid& e) {
    check_finite("ellipsoid", "centre", e.centre);
    for (int a = 0; a < 3; ++a) {
        check_positive("ellipsoid", "semi_axes", e.semi_axes[a]);
    }
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            check_finite("ellipsoid", "rotation", e.rotation[r][c]);
        }
    }
    for (int c1 = 0; c1 < 3; ++c1) {
        for (int c2 = 0; c2 < 3; ++c2) {
            double d = 0.0;
            for (int r = 0; r < 3; ++r) {
                d += e.rotation[r][c1] * e.rotation[r][c2];
            }
            if (std::abs(d - (c1 == c2 ? 1.0 : 0.0)) > 1e-9) {
                invalid("ellipsoid", "rotation is not orthonormal");
            }
        }
    }
}
void validate(Box& b) {
    check_finite("box", "min", b.min);
    check_finite("box", "max", b.max);
    for (int a = 0; a < 3; ++a) {
        if (b.max[a] < b.min[a]) {
            invalid("box", std::string("max < min along ") + "xyz"[a]);
        }
    }
}
void validate(Cylinder& c) {
    check_finite("cylinder", "centre", c.centre);
    check_finite("cylinder", "slope", c.slope);
    check_positive("cylinder", "radius", c.radius);
    check_slab("cylinder", c.z_min, c.z_max);
}
void validate(Capsule& c) {
    check_finite("capsule", "a", c.a);
    check_finite("capsule", "b", c.b);
    check_positive("capsule", "radius", c.radius);
}
void validate(Torus& t) {
    check_finite("torus", "centre", t.centre);
    t.axis = unit_vector("torus", "axis", t.axis);
    check_positive("torus", "minor_radius", t.minor_radius);
    check_positive("torus", "major_radius", t.major_radius);
    if (t.major_radius <= t.minor_radius) {
        invalid("torus", "major_radius must exceed minor_radius");
    }
}
void validate(HalfSpace& h) {
    check_finite("half-space", "offset", h.offset);
    const double length = norm(h.normal);
    h.normal = unit_vector("half-space", "normal", h.normal);
    h.offset /= length;
}
void validate(TwistedSector& s) {
    check_finite("twisted sector", "centre", s.centre);
    check_positive("twisted sector", "inner_radius", s.inner_radius);
    check_positive("twisted sector", "outer_radius", s.outer_radius);
    if (s.outer_radius <= s.inner_radius) {
        invalid("twisted sector", "outer_radius must exceed inner_radius");
    }
    check_positive("twisted sector", "gap_half_angle_rad", s.gap_half_angle_rad);
    if (s.gap_half_angle_rad >= kPi) {
        invalid("twisted sector", "gap_half_angle_rad must be below pi");
    }
    check_finite("twisted sector", "gap_angle_rad", s.gap_angle_rad);
    check_finite("twisted sector", "twist_rad_per_px", s.twist_rad_per_px);
    check_slab("twisted sector", s.z_min, s.z_max);
}
void validate(SpiralBand& s) {
    check_finite("spiral band", "centre", s.centre);
    check_positive("spiral band", "half_width", s.half_width);
    check_positive("spiral band", "start_radius", s.start_radius);
    check_positive("spiral band", "radius_per_rad", s.radius_per_rad);
    check_positive("spiral band", "max_turn_rad", s.max_turn_rad);
    check_finite("spiral band", "start_angle_rad", s.start_angle_rad);
    check_finite("spiral band", "twist_rad_per_px", s.twist_rad_per_px);
    check_slab("spiral band", s.z_min, s.z_max);
    if (s.start_radius <= s.half_width) {
        invalid("spiral band", "start_radius must exceed half_width");
    }
    if (2.0 * s.half_width >= 2.0 * kPi * s.radius_per_rad) {
        invalid("spiral band", "turns overlap: 2 half_width must be below 2 pi radius_per_rad");
    }
}
void validate(StarMorph& s) {
    check_finite("star morph", "centre", s.centre);
    if (s.points < 2) {
        invalid("star morph", "points must be at least 2");
    }
    check_positive("star morph", "outer_radius", s.outer_radius);
    check_positive("star morph", "inner_radius", s.inner_radius);
    check_positive("star morph", "circle_radius", s.circle_radius);
    if (s.inner_radius > s.outer_radius) {
        invalid("star morph", "inner_radius must not exceed outer_radius");
    }
    check_slab("star morph", s.z_min, s.z_max);
    if (!(s.z_max > s.z_min)) {
        invalid("star morph", "z_max must exceed z_min");
    }
}
void validate(RadialWave& w) {
    check_finite("radial wave", "centre", w.centre);
    check_positive("radial wave", "base_radius", w.base_radius);
    for (const WaveTerm& t : w.terms) {
        check_finite("radial wave", "amplitude", t.amplitude);
        check_finite("radial wave", "frequency", t.frequency);
        check_finite("radial wave", "phase_rad", t.phase_rad);
        check_finite("radial wave", "phase_rad_per_px", t.phase_rad_per_px);
    }
    if (wave_amplitude(w) >= w.base_radius) {
        invalid("radial wave", "the radius can reach zero: sum of |amplitude| >= base_radius");
    }
    check_slab("radial wave", w.z_min, w.z_max);
}
void validate(GaussianLevelSet& g) {
    if (g.blobs.empty()) {
        invalid("gaussian level set", "no blobs");
    }
    for (const GaussianBlob& b : g.blobs) {
        check_finite("gaussian level set", "centre", b.centre);
        check_positive("gaussian level set", "sigma", b.sigma);
        check_positive("gaussian level set", "weight", b.weight);
    }
    check_positive("gaussian level set", "level", g.level);
}
void validate(Csg&) {
    invalid("csg", "use unite / intersect / subtract to build CSG nodes");
}

Solid combine(CsgOp op, std::vector<Solid> operands, const char* name) {
    if (operands.empty()) {
        invalid(name, "needs at least one operand");
    }
    Solid out;
    Csg csg{op, {}};
    for (Solid& o : operands) {
        if (o.nodes.empty()) {
            invalid(name, "operand is an empty solid");
        }
        const auto offset = static_cast<std::uint32_t>(out.nodes.size());
        for (SolidNode& n : o.nodes) {
            if (Csg* c = std::get_if<Csg>(&n)) {
                for (std::uint32_t& i : c->operands) {
                    i += offset;
                }
            }
            out.nodes.push_back(std::move(n));
        }
        csg.operands.push_back(static_cast<std::uint32_t>(out.nodes.size() - 1));
    }
    out.nodes.emplace_back(std::move(csg));
    return out;
}

// ---------------------------------------------------------------------------------------------
// Rasterisation

struct Window {
    std::int64_t i0 = 0, i1 = 0, j0 = 0, j1 = 0;  // [i0, i1) x [j0, j1)
    bool empty() const { return i0 >= i1 || j0 >= j1; }
    std::size_t width() const { return static_cast<std::size_t>(i1 - i0); }
    std::size_t size() const { return empty() ? 0 : width() * static_cast<std::size_t>(j1 - j0); }
};

Window intersect_window(const Window& w, const Bounds3& b, double z) {
    if (!(z >= b.min.z && z <= b.max.z)) {
        return {};
    }
    // Pixel i's centre i + 0.5 lies in [min, max] iff ceil(min - 0.5) <= i <= floor(max - 0.5).
    auto to_index = [](double v, std::int64_t lo, std::int64_t hi) {
        return static_cast<std::int64_t>(
            std::clamp(v, static_cast<double>(lo), static_cast<double>(hi)));
    };
    Window out;
    out.i0 = to_index(std::ceil(b.min.x - 0.5), w.i0, w.i1);
    out.i1 = to_index(std::floor(b.max.x - 0.5) + 1.0, w.i0, w.i1);
    out.j0 = to_index(std::ceil(b.min.y - 0.5), w.j0, w.j1);
    out.j1 = to_index(std::floor(b.max.y - 0.5) + 1.0, w.j0, w.j1);
    if (out.empty()) {
        return {};
    }
    return out;
}

// Copies (ORs) a sub-window mask into a window mask.
void or_into(const Window& dst_w,
             std::vector<std::uint8_t>& dst,
             const Window& src_w,
             const std::vector<std::uint8_t>& src) {
    for (std::int64_t j = src_w.j0; j < src_w.j1; ++j) {
        const std::uint8_t* s = src.data() + static_cast<std::size_t>(j - src_w.j0) * src_w.width();
        std::uint8_t* d = dst.data() + static_cast<std::size_t>(j - dst_w.j0) * dst_w.width() +
                          static_cast<std::size_t>(src_w.i0 - dst_w.i0);
        for (std::size_t i = 0; i < src_w.width(); ++i) {
            d[i] |= s[i];
        }
    }
}

// Gaussian level sets: separable factors per row, same arithmetic as evaluate_gaussian_sum.
void raster_gaussian(const GaussianLevelSet& g,
                     double z,
                     const Window& w,
                     const Window& out_w,
                     std::vector<std::uint8_t>& out) {
    const std::size_t n = g.blobs.size();
    const std::size_t cols = w.width();
    std::vector<double> gx(n * cols);
    std::vector<double> wz(n);
    std::vector<double> row(n);
    for (std::size_t b = 0; b < n; ++b) {
        const GaussianBlob& blob = g.blobs[b];
        const double inv = inv_two_sigma2(blob);
        wz[b] = blob.weight * gaussian_factor(z - blob.centre.z, inv);
        for (std::size_t c = 0; c < cols; ++c) {
            gx[b * cols + c] = gaussian_factor(
                static_cast<double>(w.i0 + std::int64_t(c)) + 0.5 - blob.centre.x, inv);
        }
    }
    for (std::int64_t j = w.j0; j < w.j1; ++j) {
        const double y = static_cast<double>(j) + 0.5;
        for (std::size_t b = 0; b < n; ++b) {
            row[b] = wz[b] * gaussian_factor(y - g.blobs[b].centre.y, inv_two_sigma2(g.blobs[b]));
        }
        std::uint8_t* d = out.data() + static_cast<std::size_t>(j - out_w.j0) * out_w.width() +
                          static_cast<std::size_t>(w.i0 - out_w.i0);
        for (std::size_t c = 0; c < cols; ++c) {
            double f = 0.0;
            for (std::size_t b = 0; b < n; ++b) {
                f += row[b] * gx[b * cols + c];
            }
            if (f >= g.level) {
                d[c] = 1;
            }
        }
    }
}

// Rasterises node into `out` (a mask of window out_w), setting 1 where inside; never clears.
void raster_node(const Solid& s,
                 const std::vector<Bounds3>& bounds,
                 std::uint32_t node,
                 double z,
                 const Window& out_w,
                 std::vector<std::uint8_t>& out) {
    const Window w = intersect_window(out_w, bounds[node], z);
    if (w.empty()) {
        return;
    }
    const SolidNode& n = s.nodes[node];
    if (const Csg* c = std::get_if<Csg>(&n)) {
        if (c->op == CsgOp::Union) {
            for (std::uint32_t o : c->operands) {
                raster_node(s, bounds, o, z, out_w, out);
            }
            return;
        }
        std::vector<std::uint8_t> acc(w.size(), 0);
        raster_node(s, bounds, c->operands[0], z, w, acc);
        for (std::size_t k = 1; k < c->operands.size(); ++k) {
            std::vector<std::uint8_t> other(w.size(), 0);
            raster_node(s, bounds, c->operands[k], z, w, other);
            for (std::size_t p = 0; p < acc.size(); ++p) {
                acc[p] =
                    c->op == CsgOp::Intersection ? (acc[p] & other[p]) : (acc[p] & (other[p] ^ 1));
            }
        }
        or_into(out_w, out, w, acc);
        return;
    }
    if (const GaussianLevelSet* g = std::get_if<GaussianLevelSet>(&n)) {
        raster_gaussian(*g, z, w, out_w, out);
        return;
    }
    // Walk each row; a pixel whose distance bound is f proves that every pixel centre closer
    // than |f| along the row has the same membership. Star-shaped primitives first settle the
    // chords of the rows inside r_lo and outside r_hi (1e-9 relative margins against rounding).
    const std::optional<RadialRange> radial =
        std::visit([](const auto& prim) { return radial_range(prim); }, n);
    const double r_in = radial ? radial->r_lo * (1.0 - 1e-9) : 0.0;
    const double r_out = radial ? radial->r_hi * (1.0 + 1e-9) : 0.0;
    for (std::int64_t j = w.j0; j < w.j1; ++j) {
        std::uint8_t* d = out.data() + static_cast<std::size_t>(j - out_w.j0) * out_w.width();
        const double y = static_cast<double>(j) + 0.5;
        // pixel i's centre offset from the radial centre: i + 0.5 - cx
        const double dy = radial ? y - radial->centre.y : 0.0;
        const double in_half2 = r_in * r_in - dy * dy;
        const double out_half2 = r_out * r_out - dy * dy;
        std::int64_t i = w.i0;
        while (i < w.i1) {
            const Vec3 p{static_cast<double>(i) + 0.5, y, z};
            if (radial) {
                const double dx = p.x - radial->centre.x;
                if (in_half2 > 0.0 && dx * dx < in_half2) {
                    // inside the inner disc up to the chord end: dx < a
                    const double a = std::sqrt(in_half2);
                    const double end = std::ceil(radial->centre.x + a - 0.5) - 1.0;
                    const std::int64_t last =
                        std::clamp(static_cast<std::int64_t>(std::min(end, 1e18)), i, w.i1 - 1);
                    std::fill_n(d + (i - out_w.i0), last - i + 1, std::uint8_t{1});
                    i = last + 1;
                    continue;
                }
                if (dx * dx > out_half2) {
                    if (dx > 0.0 || out_half2 <= 0.0) {
                        break;  // the rest of the row is outside r_hi
                    }
                    // skip to the first centre with dx >= -b
                    const double b = std::sqrt(out_half2);
                    const double first = std::ceil(radial->centre.x - b - 0.5);
                    i = std::max(i + 1, static_cast<std::int64_t>(std::min(first, 1e18)));
                    continue;
                }
            }
            const Sample sample =
                std::visit([&](const auto& prim) { return sample_prim(prim, p); }, n);
            const double f = std::abs(sample.distance);
            const double safe = f * (1.0 - 1e-9) - 1e-9;
            std::int64_t run = 1;
            if (safe > 1.0) {
                // note: all offsets m with m < safe, clamped to the window
                const double m = std::min(std::ceil(safe) - 1.0, static_cast<double>(w.i1 - i));
                run = 1 + static_cast<std::int64_t>(m);
            }
            run = std::min(run, w.i1 - i);
            if (sample.inside) {
                std::fill_n(d + (i - out_w.i0), run, std::uint8_t{1});
            }
            i += run;
        }
    }
}

}  // namespace

double evaluate_gaussian_sum(const GaussianLevelSet& set, Vec3 p) {
    double f = 0.0;
    for (const GaussianBlob& b : set.blobs) {
        const double inv = inv_two_sigma2(b);
        // note: ((w * gz) * gy) * gx, as the separable rasteriser computes it
        f += ((b.weight * gaussian_factor(p.z - b.centre.z, inv)) *
              gaussian_factor(p.y - b.centre.y, inv)) *
             gaussian_factor(p.x - b.centre.x, inv);
    }
    return f;
}

Solid make_solid(SolidNode primitive) {
    std::visit([](auto& prim) { validate(prim); }, primitive);
    Solid s;
    s.nodes.push_back(std::move(primitive));
    return s;
}

Solid unite(std::vector<Solid> operands) {
    return combine(CsgOp::Union, std::move(operands), "union");
}

Solid intersect(std::vector<Solid> operands) {
    return combine(CsgOp::Intersection, std::move(operands), "intersection");
}

Solid subtract(Solid minuend, Solid subtrahend) {
    std::vector<Solid> operands;
    operands.push_back(std::move(minuend));
    operands.push_back(std::move(subtrahend));
    return combine(CsgOp::Difference, std::move(operands), "difference");
}

bool contains(const Solid& solid, Vec3 p_px) {
    if (solid.nodes.empty()) {
        return false;
    }
    return contains_node(solid, static_cast<std::uint32_t>(solid.nodes.size() - 1), p_px);
}

double signed_distance(const Solid& solid, Vec3 p_px) {
    if (solid.nodes.empty()) {
        return kInf;
    }
    return distance_node(solid, static_cast<std::uint32_t>(solid.nodes.size() - 1), p_px);
}

bool has_exact_distance(const Solid& solid) {
    if (solid.nodes.empty()) {
        return false;
    }
    std::uint32_t node = static_cast<std::uint32_t>(solid.nodes.size() - 1);
    while (const Csg* c = std::get_if<Csg>(&solid.nodes[node])) {
        if (c->operands.size() != 1) {
            return false;
        }
        node = c->operands[0];
    }
    const SolidNode& n = solid.nodes[node];
    if (const Cylinder* c = std::get_if<Cylinder>(&n)) {
        return is_straight(*c);
    }
    return std::holds_alternative<Ball>(n) || std::holds_alternative<Ellipsoid>(n) ||
           std::holds_alternative<Box>(n) || std::holds_alternative<Capsule>(n) ||
           std::holds_alternative<Torus>(n) || std::holds_alternative<HalfSpace>(n);
}

Bounds3 bounding_box(const Solid& solid) {
    if (solid.nodes.empty()) {
        return empty_bounds();
    }
    return node_bounds(solid).back();
}

std::vector<std::uint8_t> rasterize_solid_slice(const Solid& solid,
                                                double z_px,
                                                std::uint32_t width,
                                                std::uint32_t height) {
    std::vector<std::uint8_t> mask(std::size_t(width) * height, 0);
    if (solid.nodes.empty() || width == 0 || height == 0) {
        return mask;
    }
    const std::vector<Bounds3> bounds = node_bounds(solid);
    const Window image{0, std::int64_t(width), 0, std::int64_t(height)};
    raster_node(solid, bounds, static_cast<std::uint32_t>(solid.nodes.size() - 1), z_px, image,
                mask);
    return mask;
}

}  // namespace strata

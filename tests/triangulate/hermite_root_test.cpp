// hermite_root (triangulate/lift.cpp), the height of a surface point between two slices where
// their distance fields change sign: its Newton shortcut must give exactly what 40 bisection
// steps on [0, 1] give, bit for bit, or the surfaces would change with it. The oracle here is
// that bisection written out from the specification, on random and edge cases.

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "triangulate/detail/label_surface.h"

namespace strata {
namespace {

/// The specification: slopes of the wrong sign set to 0, then scaled onto the circle of radius
/// 3 (in units of b - a) when outside it, and 40 halvings of [0, 1] by the sign of the curve.
double bisection_root(double a, double b, double m0, double m1) {
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
    double lo = 0.0;
    double hi = 1.0;
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        if ((value(mid) < 0.0) == (delta > 0.0)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

void expect_same(double a, double b, double m0, double m1) {
    const double fast = detail::hermite_root(a, b, m0, m1);
    const double oracle = bisection_root(a, b, m0, m1);
    ASSERT_EQ(fast, oracle) << "a " << a << " b " << b << " m0 " << m0 << " m1 " << m1;
}

TEST(HermiteRoot, EqualsTheBisectionOnRandomFields) {
    // distances in px as the fields give them (signed, bilinear samples), slopes from
    // neighbouring slices (Catmull-Rom or parabola) of any sign and size
    std::mt19937_64 rng(19);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::uniform_int_distribution<int> pick(0, 9);
    auto magnitude = [&] {
        switch (pick(rng)) {
            case 0:
                return std::ldexp(unit(rng), -int(unit(rng) * 40));  // near the slice
            case 1:
                return std::round(unit(rng) * 8.0) * 0.5 + 0.5;  // half-pixel grid
            default:
                return unit(rng) * 20.0;
        }
    };
    auto slope = [&](double a, double b) {
        switch (pick(rng)) {
            case 0:
                return 0.0;
            case 1:
                return b - a;  // the secant
            case 2:
                return -(b - a) * unit(rng);  // wrong sign: set to 0
            case 3:
                return (b - a) * 10.0 * unit(rng);  // beyond the monotone circle
            default:
                return (b - a) * 3.0 * unit(rng);
        }
    };
    for (int i = 0; i < 1000000; ++i) {
        double a = -magnitude();
        double b = magnitude();
        if (a == 0.0 || b == 0.0) {
            continue;
        }
        if (pick(rng) < 5) {
            std::swap(a, b);
            a = -a;
            b = -b;
        }
        const double m0 = slope(a, b);
        const double m1 = slope(a, b);
        expect_same(a, b, m0, m1);
    }
}

TEST(HermiteRoot, EqualsTheBisectionOnEdgeCases) {
    const std::vector<double> values{1e-300, 1e-17, 1e-13, 2e-12, 1e-9, 0.25, 0.5, 1.0, 3.0, 1e6};
    const std::vector<double> scales{0.0, 1e-9, 0.5, 1.0, 2.9999999, 3.0, 3.0000001, 1e9};
    for (const double ma : values) {
        for (const double mb : values) {
            for (const double s0 : scales) {
                for (const double s1 : scales) {
                    for (const double sign : {-1.0, 1.0}) {
                        const double a = -sign * ma;
                        const double b = sign * mb;
                        expect_same(a, b, s0 * (b - a), s1 * (b - a));
                        expect_same(a, b, -s0 * (b - a), s1 * (b - a));
                    }
                }
            }
        }
    }
    // roots exactly on a bisection point: the secant's root is a dyadic of level <= 40
    for (int level = 1; level <= 40; ++level) {
        const double t = std::ldexp(1.0, -level);
        expect_same(-t, 1.0 - t, 1.0, 1.0);
        expect_same(1.0 - t, -t, -1.0, -1.0);
        expect_same(-(1.0 - t), t, 1.0, 1.0);
    }
}

}  // namespace
}  // namespace strata

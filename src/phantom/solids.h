#pragma once

#include <array>
#include <cstdint>
#include <variant>
#include <vector>

#include "core/types.h"

namespace strata {

// Analytic solids for the test phantoms, in slice-space pixel units: x = column, y = row,
// z = slice position in px (slice k of spacing d lies at z = k * d; pixel (i, j) has its
// centre at (i + 0.5, j + 0.5)). Membership follows docs/test-catalogue.md: closed bounds unless a
// field says a bound is open. Signed distances are negative inside. The primitives marked
// "exact" below give the exact Euclidean distance to the boundary; the others and every CSG
// result give a *bound*: the sign is exact and |distance| never exceeds the true distance to
// the boundary (so a ball of that radius around the point lies entirely inside or outside).

/// Ball {|p - centre| <= radius}. Exact distance.
struct Ball {
    Vec3 centre;
    double radius = 1.0;  ///< px, > 0
};

/// Ellipsoid {sum_i (dot(p - centre, axis_i) / semi_axes[i])^2 <= 1}, where axis_i is column i
/// of `rotation`. Exact distance (Eberly's robust bisection for the closest-point root).
struct Ellipsoid {
    Vec3 centre;
    Vec3 semi_axes{1.0, 1.0, 1.0};  ///< px, > 0, along the local axes
    /// Orthonormal, row-major (rotation[r][c]); column c is local axis c in slice space. The
    /// catalogue's "R applied to the axis-aligned ellipsoid" is this matrix.
    std::array<std::array<double, 3>, 3> rotation{{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
};

/// Axis-aligned box: min[a] <= p[a] <= max[a], or p[a] < max[a] where max_open[a] (the
/// catalogue's half-open [a, b)). Exact distance (to the closed box).
struct Box {
    Vec3 min;
    Vec3 max{1.0, 1.0, 1.0};
    std::array<bool, 3> max_open{false, false, false};  ///< upper bound excluded, per axis
};

/// Finite circular cylinder along z, optionally slanted: on the plane z its cross-section is
/// the closed disc of `radius` around centre + z * slope, for z_min <= z <= z_max. Exact
/// distance when slope is zero (straight capped cylinder); a bound when slanted.
struct Cylinder {
    Vec2 centre;          ///< disc centre at z = 0, px
    double radius = 1.0;  ///< px, > 0
    double z_min = 0.0;   ///< px
    double z_max = 0.0;   ///< px, >= z_min (equal: a zero-thickness disc)
    Vec2 slope;           ///< centre shift per px of z (T29's shifted discs); {0, 0}: straight
};

/// Capsule: points within `radius` of the segment a-b. Exact distance.
struct Capsule {
    Vec3 a;
    Vec3 b;
    double radius = 1.0;  ///< px, > 0
};

/// Torus: points within `minor_radius` of the circle of `major_radius` around `centre` in the
/// plane normal to `axis`. Exact distance (major_radius > minor_radius).
struct Torus {
    Vec3 centre;
    Vec3 axis{0.0, 0.0, 1.0};   ///< any non-zero vector; normalised on construction
    double major_radius = 2.0;  ///< px, centre-line radius
    double minor_radius = 1.0;  ///< px, tube radius, 0 < minor < major
};

/// Half-space {p : dot(normal, p) <= offset}. Exact distance. Unbounded: use it inside an
/// intersection or difference. make_solid divides normal and offset by |normal|, so
/// {{-1, 0, 1.0 / 3}, -10} means -x + z / 3 <= -10.
struct HalfSpace {
    Vec3 normal{0.0, 0.0, 1.0};  ///< any non-zero vector
    double offset = 0.0;
};

/// T05: annulus inner_radius < r <= outer_radius around `centre` minus the open wedge
/// |theta - gap_angle(z)| < gap_half_angle, gap_angle(z) = gap_angle_rad + twist * z, for
/// z_min <= z <= z_max. Distance: a bound (exact in-plane distance divided by the twist's
/// Lipschitz factor).
struct TwistedSector {
    Vec2 centre;
    double inner_radius = 1.0;  ///< px, excluded
    double outer_radius = 2.0;  ///< px, included, > inner_radius
    double gap_half_angle_rad = 0.5;
    double gap_angle_rad = 0.0;     ///< wedge direction at z = 0, from +x towards +y
    double twist_rad_per_px = 0.0;  ///< wedge rotation per px of z
    double z_min = 0.0;
    double z_max = 0.0;
};

/// T06: a band along the Archimedean spiral r(t) = start_radius + radius_per_rad * t,
/// t in [0, max_turn_rad], measured radially: (r, theta) is inside iff |r - r(t)| <= half_width
/// for some such t with t == theta - start_angle(z) (mod 2 pi), start_angle(z) =
/// start_angle_rad + twist * z, for z_min <= z <= z_max. Distance: a bound.
struct SpiralBand {
    Vec2 centre;
    double start_radius = 8.0;     ///< px, > half_width
    double radius_per_rad = 1.0;   ///< px per radian of t, > 0
    double max_turn_rad = 6.0;     ///< radians of t, > 0
    double half_width = 1.0;       ///< px; turns must not touch: 2 half_width < 2 pi radius_per_rad
    double start_angle_rad = 0.0;  ///< angle of t = 0 at z = 0
    double twist_rad_per_px = 0.0;
    double z_min = 0.0;
    double z_max = 0.0;
};

/// T07: {r <= (1 - s) star(theta) + s circle_radius}, s = (z - z_min) / (z_max - z_min), for
/// z_min <= z <= z_max. star() is the radial function of a regular star polygon with `points`
/// outer vertices at angles 2 pi m / points (radius outer_radius) and inner vertices half-way
/// (radius inner_radius), joined by straight edges. Distance: a bound.
struct StarMorph {
    Vec2 centre;
    int points = 5;
    double outer_radius = 2.0;   ///< px
    double inner_radius = 1.0;   ///< px, 0 < inner <= outer
    double circle_radius = 1.0;  ///< px
    double z_min = 0.0;
    double z_max = 1.0;  ///< > z_min
};

/// One term amplitude * sin(frequency * theta + phase + phase_per_px * z) of a RadialWave.
struct WaveTerm {
    double amplitude = 0.0;  ///< px
    double frequency = 0.0;  ///< per radian of theta (an integer keeps r continuous)
    double phase_rad = 0.0;
    double phase_rad_per_px = 0.0;  ///< phase change per px of z
};

/// T32: {r <= base_radius + sum of terms} around `centre`, for z_min <= z <= z_max. The
/// radius must stay positive (base_radius > sum of |amplitude|). Distance: a bound.
struct RadialWave {
    Vec2 centre;
    double base_radius = 1.0;
    std::vector<WaveTerm> terms;
    double z_min = 0.0;
    double z_max = 0.0;
};

/// One Gaussian weight * exp(-|p - centre|^2 / (2 sigma^2)) of a GaussianLevelSet.
struct GaussianBlob {
    Vec3 centre;
    double sigma = 1.0;   ///< px, > 0
    double weight = 1.0;  ///< > 0
};

/// T36: {p : sum of blobs at p >= level}. Distance: a bound (level - f over the sum's
/// Lipschitz constant).
struct GaussianLevelSet {
    std::vector<GaussianBlob> blobs;  ///< at least one
    double level = 0.5;               ///< > 0
};

/// The sum of the blobs at p, each term evaluated as ((weight * gz) * gy) * gx with
/// g_a = exp(-(delta_a * delta_a) / (2 sigma^2)), in blob order: contains() and the
/// rasteriser use exactly this arithmetic.
double evaluate_gaussian_sum(const GaussianLevelSet& set, Vec3 p_px);

/// How a CSG node combines its operands.
enum class CsgOp {
    Union,         ///< in any operand
    Intersection,  ///< in every operand
    Difference,    ///< in the first operand and in none of the others
};

/// A CSG node; operands are indices of earlier nodes of the same Solid.
struct Csg {
    CsgOp op = CsgOp::Union;
    std::vector<std::uint32_t> operands;
};

/// One node of a Solid: a primitive or a CSG combination.
using SolidNode = std::variant<Ball,
                               Ellipsoid,
                               Box,
                               Cylinder,
                               Capsule,
                               Torus,
                               HalfSpace,
                               TwistedSector,
                               SpiralBand,
                               StarMorph,
                               RadialWave,
                               GaussianLevelSet,
                               Csg>;

/// An analytic solid: a tree of nodes stored in post-order (operands precede the node that
/// uses them); the root is nodes.back(). Build it with make_solid / unite / intersect /
/// subtract, which validate and keep that invariant.
struct Solid {
    std::vector<SolidNode> nodes;
};

/// Axis-aligned bounds in px; may be infinite along axes a half-space leaves open.
struct Bounds3 {
    Vec3 min;
    Vec3 max;
};

/// A solid of one primitive. Validates the parameters (finite, positive radii, orthonormal
/// rotation, non-zero axis and normal, ...) and normalises axis / normal vectors.
/// \throw Error{InvalidInput} naming the primitive and the bad field; also for a Csg node.
Solid make_solid(SolidNode primitive);

/// Union of the operands (at least one). \throw Error{InvalidInput} when empty.
Solid unite(std::vector<Solid> operands);

/// Intersection of the operands (at least one). \throw Error{InvalidInput} when empty.
Solid intersect(std::vector<Solid> operands);

/// Points of `minuend` not in `subtrahend`. Where the subtrahend's bound is closed, the
/// difference's is open (cylinder r <= 25 removed leaves 25 < r).
Solid subtract(Solid minuend, Solid subtrahend);

/// True iff p (px) belongs to the solid (the catalogue's membership rule).
bool contains(const Solid& solid, Vec3 p_px);

/// Signed distance in px from p to the solid's boundary, negative inside. Exact where
/// has_exact_distance(solid); otherwise a bound with the exact sign and |value| <= the true
/// distance. For CSG: union min, intersection max, difference max(a, -b).
double signed_distance(const Solid& solid, Vec3 p_px);

/// True iff signed_distance is the exact Euclidean distance: the root is one of Ball,
/// Ellipsoid, Box, straight Cylinder, Capsule, Torus, HalfSpace (or a CSG node with a single
/// such operand). Every other CSG result is a bound (e.g. inside a union of two overlapping
/// balls, min(d1, d2) underestimates the depth).
bool has_exact_distance(const Solid& solid);

/// Conservative axis-aligned bounds of the solid (px). Infinite along unbounded axes.
Bounds3 bounding_box(const Solid& solid);

/// Rasterises the plane z = z_px into a width x height mask (row-major, mask[j * width + i]):
/// 1 iff the centre (i + 0.5, j + 0.5, z_px) of pixel (i, j) is inside the solid. Equals
/// contains() at every pixel centre; it is evaluated only where needed: per operand bounding
/// box, skipping runs of a row that the distance bound proves uniform, settling the chords
/// inside / outside the radial range of star-shaped primitives at once, and separably for
/// Gaussian level sets (T32's 4096 x 4096 slice takes ~0.1 s).
std::vector<std::uint8_t> rasterize_solid_slice(const Solid& solid,
                                                double z_px,
                                                std::uint32_t width,
                                                std::uint32_t height);

}  // namespace strata

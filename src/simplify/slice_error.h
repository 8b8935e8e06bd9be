#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

#include "contours/slice_contours.h"
#include "core/types.h"
#include "distance/distance_field.h"

namespace strata {

/// Bounds of the sections that are mesh edges or vertices lying in a slice plane, by vertex ids:
/// simplification meets the same contour edges in many candidate triangles, so each is read once.
/// Valid for one mesh (ids), one `known_px` and one `cutoff_px`: a bound above the cutoff is only
/// known to exceed it.
class SectionCache {
public:
    explicit SectionCache(double known_px,
                          double cutoff_px = std::numeric_limits<double>::infinity())
        : known_px_(known_px), cutoff_px_(cutoff_px) {}
    double known_px() const { return known_px_; }
    double cutoff_px() const { return cutoff_px_; }

private:
    friend class SliceErrorMeter;
    double known_px_ = 0.0;
    double cutoff_px_ = std::numeric_limits<double>::infinity();
    std::unordered_map<std::uint64_t, double> bounds_;  ///< key: smaller id << 32 | larger id
};

/// A straight piece of one label's contour on one slice, in slice space (z = k d), standing for
/// the original contour points near it: each of them lies within `deviation_px` of the segment
/// ab. Pieces are the contour stage's simplified edges (with their measured deviation), or parts
/// of them.
struct ContourPiece {
    Vec3 a;
    Vec3 b;
    double deviation_px = 0.0;
    /// The original points it stands for, when known: points[first], ..., points[first + edges]
    /// (indices modulo the size: contours are closed), a first and b last. Null: a and b only.
    const std::vector<Vec2>* points = nullptr;
    std::uint32_t first = 0;
    std::uint32_t edges = 0;

    /// The original edges it stands for, each a piece of deviation 0 (itself without `points`).
    std::vector<ContourPiece> original_edges() const;
};

/// Bound (px, a hair above the exact value) on the distance from p to the triangle (3D).
double point_triangle_distance_px(const Vec3& p, const std::array<Vec3, 3>& triangle);

/// Bound (px) on the distance from every original contour point that `piece` stands for to the
/// triangle `triangle` (3D, slice space): deviation + the larger of the ends' distances (the
/// distance to a triangle is convex along a segment, so the ends bound the whole piece); where
/// that exceeds `good_enough` and the piece knows its original points, the largest of their
/// distances instead, if smaller (convexity again: the original polyline is bounded by its
/// points). With `cutoff`: once the bound is known to reach it, a value >= cutoff is returned
/// early.
double piece_distance_px(const ContourPiece& piece,
                         const std::array<Vec3, 3>& triangle,
                         double cutoff = std::numeric_limits<double>::infinity(),
                         double good_enough = -std::numeric_limits<double>::infinity());

/// Measures how far triangles of one label's surface stray from that label's original contours
/// (paper section 7.1), in slice space: x, y in px on the contour grid, z = k * d for slice k.
///
/// The error of a triangle is the largest, over the input slice planes z = k d it meets, of:
/// - the distance from its intersection with the plane (a segment, an edge or a point) to the
///   original contour of slice k, read along the segment from slice k's distance field;
/// - for a triangle lying in the plane (a planar cap): the largest distance of its points from
///   the inside region of slice k (points inside count 0).
/// Every value is an upper bound, never an estimate: a piece of segment is charged
/// max(|a - s|, |b - s|) for a contour site s (a point on the original contour) taken from the
/// field's closest-site map, which bounds the distance of every point of the piece from the
/// contour. Pieces are as long as the disc of radius `known_px` around their site allows (the
/// skipping of section 7.2, generalised: with the error already reached, whole stretches are
/// covered at once), else 0.25 px. Points outside the field's window use the sites of the nearest
/// window nodes, which still bound them. Planes where the label has no field give infinity.
/// Thread-safe (const methods only read).
class SliceErrorMeter {
public:
    /// `fields`: the distance stage's output (one entry per slice); `contours`: the contour stage's
    /// (site positions); `slice_spacing_px`: d. The meter keeps pointers into `fields`.
    SliceErrorMeter(const SliceContours& contours,
                    const std::vector<SliceDistanceFields>& fields,
                    std::uint16_t label,
                    double slice_spacing_px);

    /// max(known_px, error bound of the triangle) in px; see the class comment. Stretches that
    /// cannot exceed `known_px` are skipped, so a good `known_px` (the error already reached by
    /// the caller) makes this fast.
    double triangle_error_px(const std::array<Vec3, 3>& triangle, double known_px = 0.0) const;

    /// The same for a triangle of a mesh (vertex ids `ids`), with max(cache.known_px(), ...):
    /// sections that are edges or vertices of the mesh are read through `cache`. Once the bound
    /// is known to exceed cache.cutoff_px(), a value above it (not the bound) is returned early.
    double triangle_error_px(const std::array<Vec3, 3>& triangle,
                             const std::array<std::uint32_t, 3>& ids,
                             SectionCache& cache) const;

    /// max(known_px, error bound of the segment pq lying in the plane of slice k): its distance
    /// from the contour of slice k. Once that is known to exceed `cutoff`, a value above it (not
    /// the bound) is returned early.
    double segment_error_px(std::uint32_t k,
                            Vec2 p,
                            Vec2 q,
                            double known_px = 0.0,
                            double cutoff = std::numeric_limits<double>::infinity()) const;

    /// Error bound (px) of triangle abc lying in the plane of slice k: distance to its inside.
    double cap_error_px(std::uint32_t k, const std::array<Vec2, 3>& triangle) const;

    /// The label's contours as pieces (one per simplified edge, every slice): the data a surface
    /// must stay close to in the converse direction (contour to surface, see piece_distance_px).
    const std::vector<ContourPiece>& contour_pieces() const { return pieces_; }

    double slice_spacing_px() const { return spacing_; }
    std::uint32_t slice_count() const { return static_cast<std::uint32_t>(slices_.size()); }

private:
    struct Slice {
        const DistanceField* field = nullptr;  ///< null: label absent on this slice
        std::vector<Vec2> sites;               ///< position of every site of `field`
    };
    double triangle_error(const std::array<Vec3, 3>& triangle,
                          const std::array<std::uint32_t, 3>* ids,
                          SectionCache* cache,
                          double known_px,
                          double cutoff) const;

    std::vector<Slice> slices_;
    std::vector<ContourPiece> pieces_;
    double spacing_ = 1.0;
};

}  // namespace strata

// Internals of the triangulation stage (triangulate/surface.h), shared by its files: the planar
// constrained Delaunay triangulation a slab is built on, the contour rings, and LabelSurface,
// which builds one label's closed surface in these phases:
//   rings.cpp          contour rings with the neighbouring slices' crossing points, their
//                      triangulation, the region every face lies in;
//   overlap_check.cpp  whether the contours of a slab overlap as the pixels do;
//   lift.cpp           the height t of a point between the slices, Steiner points, the level of
//                      each face corner;
//   slab.cpp           one slab: medial, curvature and refinement points, then its triangles;
//   caps.cpp           end caps: planar, domed, or a region alone on its slice;
//   split_slabs.cpp    the stack with the pixels' AND layer inserted in slabs that still mismatch;
//   surface.cpp        build() runs the phases; the public entry points (triangulate_label).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include "triangulate/surface.h"

namespace strata::detail {

using Kernel = CGAL::Exact_predicates_exact_constructions_kernel;
using Point = Kernel::Point_2;
using Segment = Kernel::Segment_2;

/// What a planar vertex stands for in 3D: a point of slice k's contour ring (`lower`), of slice
/// k+1's (`upper`), both where the contours meet, or a Steiner point between the slices.
struct VertexInfo {
    std::int32_t lower = -1;    ///< global vertex id at z_k
    std::int32_t upper = -1;    ///< global vertex id at z_k+1
    std::int32_t steiner = -1;  ///< index into the slab's Steiner list
};

enum Level : std::int8_t { kUnset = -1, kLow = 0, kHigh = 1, kBetween = 2 };

struct FaceInfo {
    std::int32_t lower_region = -1;  ///< region of slice k containing the face, -1 none
    std::int32_t upper_region = -1;
    std::uint32_t lower_background = 0;  ///< background component of slice k (region -1 only)
    std::uint32_t upper_background = 0;
    bool seen = false;
    std::array<Level, 3> corner{kUnset, kUnset, kUnset};
};

using Vb = CGAL::Triangulation_vertex_base_with_info_2<VertexInfo, Kernel>;
using Fbi = CGAL::Triangulation_face_base_with_info_2<FaceInfo, Kernel>;
using Fb = CGAL::Constrained_triangulation_face_base_2<Kernel, Fbi>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_intersections_tag>;
using VertexHandle = Cdt::Vertex_handle;
using FaceHandle = Cdt::Face_handle;

inline int ccw(int i) {
    return Cdt::ccw(i);
}
inline int cw(int i) {
    return Cdt::cw(i);
}

/// The contour points of one contour as used by every triangle touching its slice: the
/// simplified vertices plus every point where a contour of a neighbouring slice crosses, touches
/// or overlaps one of its edges, in contour order.
struct Ring {
    std::vector<Point> points;
    std::vector<std::uint32_t> ids;  ///< global vertex ids (z = k d)
};

/// Key of a constrained edge: its two vertices, in a fixed order.
using EdgeKey = std::pair<const void*, const void*>;
inline EdgeKey edge_key(VertexHandle a, VertexHandle b) {
    const void* pa = &*a;
    const void* pb = &*b;
    return pa < pb ? EdgeKey{pa, pb} : EdgeKey{pb, pa};
}

/// Which contour (local index on its slice) an edge belongs to, per side of the slab.
struct EdgeOwner {
    std::int32_t lower = -1;
    std::int32_t upper = -1;
};

inline Point to_point(Vec2 p) {
    return Point(p.x, p.y);
}

inline Vec2 to_vec(const Point& p) {
    return {CGAL::to_double(p.x()), CGAL::to_double(p.y())};
}

/// Calls f(e, a, b) for each simplified edge e of `c`, from a to b (the last edge wraps to the
/// first simplified vertex).
template <class F>
void for_each_simplified_edge(const Contour& c, F&& f) {
    const std::size_t n = c.simplified.size();
    for (std::uint32_t e = 0; e < n; ++e) {
        f(e, c.points[c.simplified[e]], c.points[c.simplified[(e + 1) % n]]);
    }
}

/// The bounding box of segment a-b for CGAL's box intersection, carrying `info`.
template <class Box>
Box segment_box(Vec2 a, Vec2 b, const typename Box::Info& info) {
    double lo[2] = {std::min(a.x, b.x), std::min(a.y, b.y)};
    double hi[2] = {std::max(a.x, b.x), std::max(a.y, b.y)};
    return Box(lo, hi, info);
}

/// The edges of one slice's contour rings, bucketed on a square grid, for nearest-edge queries.
class SegmentGrid {
public:
    SegmentGrid() = default;
    explicit SegmentGrid(const std::vector<Ring>& rings) {
        for (const Ring& ring : rings) {
            const std::size_t n = ring.points.size();
            for (std::size_t i = 0; i < n; ++i) {
                segments_.push_back({to_vec(ring.points[i]), to_vec(ring.points[(i + 1) % n])});
            }
        }
        if (segments_.empty()) {
            return;
        }
        lo_ = hi_ = segments_.front()[0];
        for (const auto& s : segments_) {
            for (const Vec2 p : s) {
                lo_ = {std::min(lo_.x, p.x), std::min(lo_.y, p.y)};
                hi_ = {std::max(hi_.x, p.x), std::max(hi_.y, p.y)};
            }
        }
        nx_ = std::int64_t((hi_.x - lo_.x) / kCell) + 1;
        ny_ = std::int64_t((hi_.y - lo_.y) / kCell) + 1;
        // each cell's segments in increasing order, as one array (counted, then filled)
        start_.assign(std::size_t(nx_ * ny_) + 1, 0);
        auto for_cells = [&](const std::array<Vec2, 2>& s, auto&& fn) {
            const auto [i0, j0] = cell(Vec2{std::min(s[0].x, s[1].x), std::min(s[0].y, s[1].y)});
            const auto [i1, j1] = cell(Vec2{std::max(s[0].x, s[1].x), std::max(s[0].y, s[1].y)});
            for (std::int64_t j = j0; j <= j1; ++j) {
                for (std::int64_t c = i0; c <= i1; ++c) {
                    fn(std::size_t(j * nx_ + c));
                }
            }
        };
        for (const auto& s : segments_) {
            for_cells(s, [&](std::size_t c) { ++start_[c + 1]; });
        }
        for (std::size_t c = 1; c < start_.size(); ++c) {
            start_[c] += start_[c - 1];
        }
        cell_segments_.resize(start_.back());
        std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
        for (std::uint32_t i = 0; i < segments_.size(); ++i) {
            for_cells(segments_[i], [&](std::size_t c) { cell_segments_[fill[c]++] = i; });
        }
    }

    /// Distance (px) from q to the nearest edge; infinity without edges.
    double distance(Vec2 q) const {
        double best = std::numeric_limits<double>::infinity();
        if (segments_.empty()) {
            return best;
        }
        // q's projection onto the grid's box lies in cell (ci, cj); the cells of ring r + 1
        // around it are at least r cells away from q.
        const auto [ci, cj] = cell(q);
        for (std::int64_t r = 0;; ++r) {
            if (std::sqrt(best) <= (r - 1) * kCell || (r > nx_ && r > ny_)) {
                break;
            }
            for (std::int64_t j = cj - r; j <= cj + r; ++j) {
                if (j < 0 || j >= ny_) {
                    continue;
                }
                const bool edge_row = j == cj - r || j == cj + r;
                for (std::int64_t i = ci - r; i <= ci + r;
                     i += edge_row ? 1 : 2 * std::max<std::int64_t>(r, 1)) {
                    if (i < 0 || i >= nx_) {
                        continue;
                    }
                    const std::size_t c = std::size_t(j * nx_ + i);
                    for (std::uint32_t s = start_[c]; s < start_[c + 1]; ++s) {
                        best = std::min(best, squared_distance(q, segments_[cell_segments_[s]]));
                    }
                }
            }
        }
        return std::sqrt(best);
    }

private:
    static constexpr double kCell = 2.0;  // px
    std::pair<std::int64_t, std::int64_t> cell(Vec2 p) const {
        const auto i = std::int64_t(std::floor((std::clamp(p.x, lo_.x, hi_.x) - lo_.x) / kCell));
        const auto j = std::int64_t(std::floor((std::clamp(p.y, lo_.y, hi_.y) - lo_.y) / kCell));
        return {std::min(i, nx_ - 1), std::min(j, ny_ - 1)};
    }
    static double squared_distance(Vec2 q, const std::array<Vec2, 2>& s) {
        const Vec2 ab = s[1] - s[0];
        const double length2 = dot(ab, ab);
        const double u = length2 > 0.0 ? std::clamp(dot(q - s[0], ab) / length2, 0.0, 1.0) : 0.0;
        const Vec2 c = s[0] + u * ab;
        return dot(q - c, q - c);
    }
    std::vector<std::array<Vec2, 2>> segments_;
    std::vector<std::uint32_t> start_;          ///< cell c's segments: [start_[c], start_[c + 1])
    std::vector<std::uint32_t> cell_segments_;  ///< segment indices, cell after cell
    Vec2 lo_{};
    Vec2 hi_{};
    std::int64_t nx_ = 0;
    std::int64_t ny_ = 0;
};

/// SlabChecks' content: per slice, per local contour, the ring's points; per slab, whether it
/// mismatched (-1: not checked).
struct SlabCheckMemo {
    std::vector<std::vector<std::vector<Point>>> rings;
    std::vector<std::int8_t> mismatched;
    /// One hit of find_crossings: edges a (slice k) and b (slice k+1), each (slice, local
    /// contour, edge), the points it adds to both, and the overlap segment (overlap true).
    struct Crossing {
        std::array<std::uint32_t, 3> a;
        std::array<std::uint32_t, 3> b;
        std::vector<Point> points;
        bool overlap = false;
        Segment segment;
    };
    /// Per slab: find_crossings' hits in order, found on the simplified contours `simplified`
    /// holds for its two slices (per slice, per local contour); known: found at all.
    std::vector<std::vector<Crossing>> crossings;
    std::vector<bool> crossings_known;
    std::vector<std::vector<std::vector<std::uint32_t>>> simplified;
};

/// Background links of one slab, each (slice k components, slice k+1 components), sorted.
using BackgroundLinks =
    std::vector<std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>>>;

class LabelSurface {
public:
    LabelSurface(const SliceContours& contours,
                 const std::vector<SliceDistanceFields>& fields,
                 const std::vector<MedialAxis>& medial_axes,
                 const TriangulateOptions& options,
                 std::uint16_t label,
                 const std::vector<double>* level_z = nullptr,
                 TriangulateMode mode = TriangulateMode::kSurface,
                 SlabChecks* checks = nullptr)
        : contours_(contours),
          fields_(fields),
          medial_axes_(medial_axes),
          options_(options),
          label_(label),
          level_z_(level_z),
          mode_(mode),
          checks_(checks) {}

    LabelTriangulation build();

private:
    // --- set-up --------------------------------------------------------------------------------
    void collect_contours();
    void collect_links();
    void find_crossings(std::uint32_t k);
    void build_rings();

    // --- per slab ------------------------------------------------------------------------------
    /// Every slab with links, in slab order: on options_.threads threads, each slab built by a
    /// copy of this set-up, its new vertices and triangles appended in slab order (surface.cpp).
    void triangulate_slabs();
    /// Builds (or checks, by mode_) the slabs `slabs`, in this order (triangulate_slabs).
    void run_slabs(const std::vector<std::uint32_t>& slabs);
    void triangulate_slab(std::uint32_t k);
    /// Whether p lies inside a face of the surface's domain of slab k (not on an edge).
    bool in_surface_at(const Cdt& cdt, const Point& p, std::uint32_t k) const;
    std::vector<Point> medial_points(const Cdt& cdt, std::uint32_t k) const;
    /// Where the cubic height bends away from the straight faces between a medial point and
    /// the contours, a vertex half way to each contour's closest point follows it.
    void insert_curvature_points(Cdt& cdt,
                                 std::uint32_t k,
                                 const std::map<EdgeKey, EdgeOwner>& owners,
                                 const std::vector<Point>& medial);
    bool refine_slab(Cdt& cdt, std::uint32_t k, const std::map<EdgeKey, EdgeOwner>& owners);
    bool emit_faces(Cdt& cdt,
                    std::uint32_t k,
                    std::map<const void*, std::array<std::uint32_t, 3>>& emitted);
    /// Vertical triangles where a wedge switches from z_k to z_k+1, and vertical walls where
    /// both contours run along the same edge with the inside on the same side.
    bool emit_vertical_faces(Cdt& cdt,
                             std::uint32_t k,
                             const std::map<const void*, std::array<std::uint32_t, 3>>& emitted);
    /// Inserts the contour rings of `slice` (only those of region `only_region` when it is not
    /// negative) as vertices and constraints, recording which contour owns each edge.
    void insert_rings(Cdt& cdt,
                      std::uint32_t slice,
                      bool upper,
                      std::map<EdgeKey, EdgeOwner>& owners,
                      std::int64_t only_region = -1);
    /// Labels every face with the region of slice k and of slice k+1 it lies in. Returns the
    /// number of constrained edges no contour owns: contour edges that crossed or were split by
    /// an inserted point (0 unless something went wrong).
    std::size_t flood_regions(Cdt& cdt,
                              std::uint32_t k,
                              const std::map<EdgeKey, EdgeOwner>& owners);
    /// Inserts Steiner points in slab k, floods the regions again and reports the edges they
    /// split (`what` names the points in the report).
    void insert_steiners(Cdt& cdt,
                         const std::vector<Point>& points,
                         std::uint32_t k,
                         const std::map<EdgeKey, EdgeOwner>& owners,
                         const char* what);
    void check_overlap_topology(Cdt& cdt, std::uint32_t k);
    bool vertical_at(const Cdt& cdt,
                     VertexHandle v,
                     std::uint32_t k,
                     std::vector<FaceHandle>& around) const;
    bool in_lower(const FaceInfo& f, std::uint32_t k) const;
    bool in_upper(const FaceInfo& f, std::uint32_t k) const;
    bool in_surface(FaceHandle f, std::uint32_t k) const;
    Level boundary_class(FaceHandle f, int i, std::uint32_t k) const;
    bool is_boundary(FaceHandle f, int i, std::uint32_t k) const;
    /// Fills the corner levels of the wedge of `f` around its vertex `i`; returns false when the
    /// wedge needs a Steiner point first (then `refine` receives one).
    bool resolve_corner(Cdt& cdt, FaceHandle f, int i, std::uint32_t k, std::vector<Point>& refine);
    std::vector<std::array<double, 2>> wedge_level_costs(const std::vector<FaceHandle>& wedge,
                                                         VertexHandle v,
                                                         std::uint32_t k) const;
    std::size_t best_wedge_split(const std::vector<FaceHandle>& wedge,
                                 VertexHandle v,
                                 std::uint32_t k) const;
    /// The height t in [0.05, 0.95] of p between slices k and k+1; `band` (if given) gets how
    /// far from t (in t) p may move while the slices' linear field there stays within its
    /// value at t plus options_.relax.field_tolerance_px (relax_fold_heights).
    double height_t(const Point& p, std::uint32_t k, double* band = nullptr) const;
    VertexHandle insert_steiner(Cdt& cdt, const Point& p, std::uint32_t k);
    /// Gives vertex v a height between the slices (from the distance fields).
    void make_steiner(VertexHandle v, std::uint32_t k);

    // --- caps ----------------------------------------------------------------------------------
    void cap_region(std::uint32_t k, std::uint32_t region, bool top, bool bottom);
    /// Adds the dome's vertices to the cap triangulation of a region that ends at slice k.
    bool dome_cap(Cdt& cdt,
                  const std::map<EdgeKey, EdgeOwner>& owners,
                  std::uint32_t k,
                  std::uint32_t region,
                  bool top);
    /// The ring points of a region that ends at the stack's end, moved where its extension by
    /// d/2 reaches (caps.cpp); empty: vertical walls.
    std::map<std::uint32_t, Vec2> end_lean(const Cdt& cdt,
                                           std::uint32_t k,
                                           std::uint32_t region,
                                           bool top) const;
    /// Takes back the leans of stack-end wall vertices (toward upright, at most to it) where a
    /// leaned triangle meets another triangle beyond the end planes or folds over 90 degrees
    /// against a neighbour (caps.cpp).
    void settle_end_leans();
    /// Raises a dome's vertices by the volume its flat triangles leave out (caps.cpp).
    template <class Dome>
    void unbias_dome(const Cdt& cdt,
                     std::uint32_t region,
                     double z,
                     double sign,
                     double height,
                     const Dome& dome);
    /// Signed area (px^2) of region `region` of `slice`: its outer contours less its holes.
    double region_area(std::uint32_t slice, std::uint32_t region) const;
    double cap_height(std::uint32_t k, std::uint32_t region, bool top) const;
    /// How fast the dome closing region `region` of slice k (above when `top`) draws in at its
    /// rim, in px of signed distance per slab; 0 where no dome closes it (caps.cpp). `height_px`
    /// (if given) gets the dome's height H.
    double dome_rim_slope(std::uint32_t k,
                          std::uint32_t region,
                          bool top,
                          double* height_px = nullptr) const;
    /// Of slab k's slices (upper: k+1), the slope of the dome that closes the region whose
    /// contour is nearest q, when that region ends there (lift.cpp); false otherwise.
    bool end_slope(Vec2 q, std::uint32_t k, bool upper, double& slope) const;
    /// A dome's height (px) from its paraboloid's (cap_height; infinity: half a slab), at most
    /// options.cap_reach d: for end caps and for cavities that close (find_pockets).
    double dome_height(double height) const;
    /// A cavity (background component inside the label, bounded by one hole contour) that
    /// closes inside a slab: the hole of slice k with no background partner on slice k+1
    /// (`upper` false), or the hole of slice k+1 with none on slice k.
    struct Pocket {
        std::vector<Vec2> ring;                ///< the hole contour's ring
        Vec2 lo, hi;                           ///< its bounding box
        const DistanceField* field = nullptr;  ///< its slice's field (positive in the hole)
        double dmax = 0.0;                     ///< the field's largest value in the hole, px
        double height = 0.0;                   ///< the dome's height, in slabs (t units)
        bool upper = false;                    ///< a hole of slice k+1 closing downward
    };
    std::vector<Pocket> find_pockets(std::uint32_t k) const;
    /// The height t over a cavity that closes in slab k: the larger of t and the dome that
    /// continues the cavity (its end is domed like an end cap), else t.
    double pocket_t(Vec2 q, std::uint32_t k, double t) const;
    /// Area (px^2) inside the hole contours of background component `component` of `slice`.
    double background_area(std::uint32_t slice, std::uint32_t component) const;

    std::uint32_t add_vertex(Vec2 p, double z) {
        surface_.mesh.positions.push_back({p.x, p.y, z});
        return std::uint32_t(surface_.mesh.positions.size() - 1);
    }
    double slice_z(std::uint32_t k) const {
        return level_z_ != nullptr ? (*level_z_)[k] : options_.slice_spacing_px * k;
    }
    std::uint32_t owner_region(std::uint32_t slice, std::uint32_t local) const {
        const std::vector<Contour>& all = contours_.slices[slice].contours;
        const Contour& c = all[label_contours_[slice][local]];
        return c.is_hole ? all[std::size_t(c.parent)].region : c.region;
    }
    /// Calls f(ring) for each contour ring of `slice` that bounds region `region` (its outer
    /// contour and its holes).
    template <class F>
    void for_each_region_ring(std::uint32_t slice, std::uint32_t region, F&& f) const {
        for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
            if (owner_region(slice, local) == region) {
                f(rings_[slice][local]);
            }
        }
    }
    /// The background component on the outer side of an outer contour, inside a hole contour.
    std::uint32_t background_beside(std::uint32_t slice, std::uint32_t local) const {
        const std::vector<Contour>& all = contours_.slices[slice].contours;
        const Contour& c = all[label_contours_[slice][local]];
        if (c.is_hole) {
            return c.region;
        }
        return c.parent >= 0 ? all[std::size_t(c.parent)].region : 0;
    }
    const DistanceField* field(std::uint32_t slice) const {
        for (const DistanceField& f : fields_[slice].fields) {
            if (f.label == label_) {
                return &f;
            }
        }
        return nullptr;
    }
    void issue(std::uint32_t k, std::string what) {
        surface_.issues.push_back({k, std::move(what)});
    }

    const SliceContours& contours_;
    const std::vector<SliceDistanceFields>& fields_;
    const std::vector<MedialAxis>& medial_axes_;
    const TriangulateOptions& options_;
    std::uint16_t label_;
    /// z of each level when levels are not the slices (split slabs), else null: z = k d.
    const std::vector<double>* level_z_;
    TriangulateMode mode_;
    /// The slabs' rings and mismatches of the label's previous build (SlabChecks), or null.
    SlabChecks* checks_;
    /// Per slice: its simplified contours are those checks_ holds (its slabs' crossings too).
    std::vector<bool> same_simplified_;
    /// Set once any slab mismatched (kSurfaceIfMatched: the other slabs stop after their check).
    std::atomic<bool>* mismatch_seen_ = nullptr;

    ObjectSurface surface_;
    /// Per slice: indices (into the slice's contour list) of this label's contours.
    std::vector<std::vector<std::uint32_t>> label_contours_;
    /// Per slice: number of foreground regions of this label.
    std::vector<std::uint32_t> region_count_;
    /// Per slice, per region: linked to a region of the next / previous slice.
    std::vector<std::vector<bool>> linked_up_;
    std::vector<std::vector<bool>> linked_down_;
    /// Per slab: number of overlap pieces between (lower region, upper region).
    std::vector<std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t>> link_pieces_;
    /// Per slab: background links, each (slice k components, slice k+1 components), sorted.
    std::vector<BackgroundLinks> background_links_;
    /// Per slice, per local contour, per simplified edge: extra points on it.
    std::vector<std::vector<std::vector<std::vector<Point>>>> splits_;
    /// Per slice, per local contour.
    std::vector<std::vector<Ring>> rings_;
    /// Steiner points of the slab being built: height parameter t and global id (-1: unused).
    std::vector<double> steiner_t_;
    std::vector<double> steiner_band_;  ///< height_t's band per Steiner point
    std::vector<std::int32_t> steiner_id_;
    std::vector<Vec2> steiner_xy_;
    /// The contour rings of the slab being built's two slices (height_t).
    std::array<SegmentGrid, 2> slab_rings_;
    std::vector<std::uint32_t> mismatched_slabs_;
    /// The closing cavities of slab `pockets_slab_` (pocket_t), found on first use.
    mutable std::int64_t pockets_slab_ = -1;
    mutable std::vector<Pocket> pockets_;
    /// The regions of slab `ends_slab_`'s slices that end there (lower: ending below slice k,
    /// upper: above slice k+1) and are domed: their rings and dome_rim_slope (end_slope).
    struct EndRegion {
        SegmentGrid rings;
        double slope = 0.0;      ///< at least this, d Dmax / (2 H)
        Vec2 centre;             ///< the region's centroid
        double per_reach = 0.0;  ///< d / (2 H): times the support (p - centre) . n
    };
    mutable std::int64_t ends_slab_ = -1;
    mutable std::array<std::vector<EndRegion>, 2> ends_;
    /// A stack-end wall vertex that leans (cap_region): its upright and its leaned position.
    struct Lean {
        std::uint32_t id = 0;
        Vec2 upright;
        Vec2 leaned;
    };
    std::vector<Lean> leans_;
    /// Every slab's Steiner vertices with their slab's planes (relax_fold_heights).
    std::vector<FreeHeightVertex> free_heights_;

    /// Collinear overlaps of a slice k edge and a slice k+1 edge (slice, local contour, edge):
    /// every point on one edge inside the overlap must be on the other too.
    struct Overlap {
        Segment segment;
        std::array<std::uint32_t, 3> lower;
        std::array<std::uint32_t, 3> upper;
    };
    std::vector<Overlap> overlaps_;
    void share_overlap_points();  ///< constrained edges split by the triangulation (a bug)
};

/// The root in [0, 1] of the monotone cubic Hermite curve from a (at t = 0) to b (at t = 1), a and
/// b of opposite signs, end slopes m0, m1 (per unit t; limited by Fritsch and Carlson's rule): the
/// middle of the interval of width 2^-40 where the computed curve changes sign.
double hermite_root(double a, double b, double m0, double m1);

/// The signed distance of slice field `f` at q (bilinear between nodes; negative inside; 1e9
/// without a field, outside_window_px outside its window).
double sample_field(const DistanceField* f, Vec2 q);

/// The closest contour site of field `f` to q (that of the node nearest q); false without a
/// field.
bool closest_site(const DistanceField* f, Vec2 q, Vec2& site);

/// The stack with a level inserted in the middle of every split slab: the contours of the pixel
/// AND of the two slices (the reference volume's middle layer), saddles widened, with its own
/// distance field and links by pixel overlap to both slices.
struct Levels {
    SliceContours contours;
    std::vector<SliceDistanceFields> fields;
    std::vector<MedialAxis> medial_axes;
    std::vector<double> z;
    std::vector<std::uint32_t> slice_of;  ///< per level: the slice it is, or lies above
};

/// The stack with a level inserted in the middle of every slab marked in `split` (see Levels),
/// for one label; `d` is the slice spacing (px).
Levels split_slabs(const SliceStack& stack,
                   const SliceContours& contours,
                   const std::vector<SliceDistanceFields>& fields,
                   const std::vector<MedialAxis>& medial_axes,
                   std::uint16_t label,
                   const std::vector<bool>& split,
                   double d);

}  // namespace strata::detail

#include "triangulate/surface.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdlib>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <string>
#include <utility>

#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include "contours/extract_contours.h"
#include "contours/simplify_contours.h"
#include "core/parallel.h"

namespace strata {
namespace {

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

/// Union-find over 0..n-1 (path halving).
class DisjointSets {
public:
    explicit DisjointSets(std::size_t n) : parent_(n) {
        std::iota(parent_.begin(), parent_.end(), std::size_t(0));
    }
    std::size_t find(std::size_t x) {
        while (parent_[x] != x) {
            x = parent_[x] = parent_[parent_[x]];
        }
        return x;
    }
    void join(std::size_t a, std::size_t b) { parent_[find(a)] = find(b); }

private:
    std::vector<std::size_t> parent_;
};

/// The contour points of one contour as used by every triangle touching its slice: the
/// simplified vertices plus every point where a contour of a neighbouring slice crosses, touches
/// or overlaps one of its edges, in contour order.
struct Ring {
    std::vector<Point> points;
    std::vector<std::uint32_t> ids;  ///< global vertex ids (z = k d)
};

/// Key of a constrained edge: its two vertices, in a fixed order.
using EdgeKey = std::pair<const void*, const void*>;
EdgeKey edge_key(VertexHandle a, VertexHandle b) {
    const void* pa = &*a;
    const void* pb = &*b;
    return pa < pb ? EdgeKey{pa, pb} : EdgeKey{pb, pa};
}

/// Which contour (local index on its slice) an edge belongs to, per side of the slab.
struct EdgeOwner {
    std::int32_t lower = -1;
    std::int32_t upper = -1;
};

Point to_point(Vec2 p) {
    return Point(p.x, p.y);
}

Vec2 to_vec(const Point& p) {
    return {CGAL::to_double(p.x()), CGAL::to_double(p.y())};
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
        cells_.assign(std::size_t(nx_ * ny_), {});
        for (std::uint32_t i = 0; i < segments_.size(); ++i) {
            const auto& s = segments_[i];
            const auto [i0, j0] = cell(Vec2{std::min(s[0].x, s[1].x), std::min(s[0].y, s[1].y)});
            const auto [i1, j1] = cell(Vec2{std::max(s[0].x, s[1].x), std::max(s[0].y, s[1].y)});
            for (std::int64_t j = j0; j <= j1; ++j) {
                for (std::int64_t c = i0; c <= i1; ++c) {
                    cells_[std::size_t(j * nx_ + c)].push_back(i);
                }
            }
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
                    for (const std::uint32_t s : cells_[std::size_t(j * nx_ + i)]) {
                        best = std::min(best, squared_distance(q, segments_[s]));
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
    std::vector<std::vector<std::uint32_t>> cells_;
    Vec2 lo_{};
    Vec2 hi_{};
    std::int64_t nx_ = 0;
    std::int64_t ny_ = 0;
};

class LabelSurface {
public:
    LabelSurface(const SliceContours& contours,
                 const std::vector<SliceDistanceFields>& fields,
                 const std::vector<MedialAxis>& medial_axes,
                 const TriangulateOptions& options,
                 std::uint16_t label,
                 const std::vector<double>* level_z = nullptr)
        : contours_(contours),
          fields_(fields),
          medial_axes_(medial_axes),
          options_(options),
          label_(label),
          level_z_(level_z) {}

    ObjectSurface build();

private:
    // --- set-up --------------------------------------------------------------------------------
    void collect_contours();
    void collect_links();
    void find_crossings(std::uint32_t k);
    void build_rings();

    // --- per slab ------------------------------------------------------------------------------
    void triangulate_slab(std::uint32_t k);
    /// Inserts the contour rings of `slice` (only those of region `only_region` when it is not
    /// negative) as vertices and constraints, recording which contour owns each edge.
    void insert_rings(Cdt& cdt,
                      std::uint32_t slice,
                      bool upper,
                      std::map<EdgeKey, EdgeOwner>& owners,
                      std::int64_t only_region = -1);
    void flood_regions(Cdt& cdt, std::uint32_t k, const std::map<EdgeKey, EdgeOwner>& owners);
    /// Inserts Steiner points in slab k, floods the regions again and reports the edges they
    /// split (`what` names the points in the report).
    void insert_steiners(Cdt& cdt,
                         const std::vector<Point>& points,
                         std::uint32_t k,
                         const std::map<EdgeKey, EdgeOwner>& owners,
                         const char* what);
    void check_overlap_topology(Cdt& cdt, std::uint32_t k);
    bool in_lower(const FaceInfo& f, std::uint32_t k) const;
    bool in_upper(const FaceInfo& f, std::uint32_t k) const;
    bool in_surface(FaceHandle f, std::uint32_t k) const;
    Level boundary_class(FaceHandle f, int i, std::uint32_t k) const;
    bool is_boundary(FaceHandle f, int i, std::uint32_t k) const;
    /// Fills the corner levels of the wedge of `f` around its vertex `i`; returns false when the
    /// wedge needs a Steiner point first (then `refine` receives one).
    bool resolve_corner(Cdt& cdt, FaceHandle f, int i, std::uint32_t k, std::vector<Point>& refine);
    double height_t(const Point& p, std::uint32_t k) const;
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
    /// Signed area (px^2) of region `region` of `slice`: its outer contours less its holes.
    double region_area(std::uint32_t slice, std::uint32_t region) const;
    double cap_height(std::uint32_t k, std::uint32_t region, bool top) const;

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
    std::vector<std::vector<std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>>>>
        background_links_;
    /// Per slice, per local contour, per simplified edge: extra points on it.
    std::vector<std::vector<std::vector<std::vector<Point>>>> splits_;
    /// Per slice, per local contour.
    std::vector<std::vector<Ring>> rings_;
    /// Steiner points of the slab being built: height parameter t and global id (-1: unused).
    std::vector<double> steiner_t_;
    std::vector<std::int32_t> steiner_id_;
    std::vector<Vec2> steiner_xy_;
    /// The contour rings of the slab being built's two slices (height_t).
    std::array<SegmentGrid, 2> slab_rings_;
    std::size_t unowned_edges_ = 0;
    std::vector<std::uint32_t> mismatched_slabs_;

public:
    /// Slabs whose simplified contours overlapped unlike the pixels (filled by build()).
    const std::vector<std::uint32_t>& mismatched_slabs() const { return mismatched_slabs_; }

private:
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

void LabelSurface::collect_contours() {
    const std::size_t slices = contours_.slices.size();
    label_contours_.assign(slices, {});
    region_count_.assign(slices, 0);
    for (std::size_t k = 0; k < slices; ++k) {
        const SliceContourSet& set = contours_.slices[k];
        for (std::uint32_t c = 0; c < set.contours.size(); ++c) {
            if (set.contours[c].label == label_) {
                label_contours_[k].push_back(c);
            }
        }
        for (const SliceLabelRegions& regions : set.labels) {
            if (regions.label == label_) {
                region_count_[k] = regions.foreground_count;
            }
        }
    }
}

void LabelSurface::collect_links() {
    const std::size_t slices = contours_.slices.size();
    linked_up_.assign(slices, {});
    linked_down_.assign(slices, {});
    for (std::size_t k = 0; k < slices; ++k) {
        linked_up_[k].assign(region_count_[k], false);
        linked_down_[k].assign(region_count_[k], false);
    }
    link_pieces_.assign(slices, {});
    background_links_.assign(slices, {});
    for (const RegionLink& link : contours_.links) {
        if (link.label == label_ && link.is_background) {
            auto lower = link.lower_regions;
            auto upper = link.upper_regions;
            std::sort(lower.begin(), lower.end());
            std::sort(upper.begin(), upper.end());
            background_links_[link.lower_slice].emplace_back(lower, upper);
        }
    }
    for (auto& links : background_links_) {
        std::sort(links.begin(), links.end());
    }
    for (const RegionLink& link : contours_.links) {
        if (link.label != label_ || link.is_background || link.lower_regions.empty() ||
            link.upper_regions.empty()) {
            continue;
        }
        const std::uint32_t k = link.lower_slice;
        const std::uint32_t a = link.lower_regions.front();
        const std::uint32_t b = link.upper_regions.front();
        linked_up_[k][a] = true;
        linked_down_[k + 1][b] = true;
        ++link_pieces_[k][{a, b}];
    }
}

/// Exact crossings, touches and overlaps between the contours of slices k and k+1: every such
/// point is added to the edges it lies on, so both slabs and caps share it.
void LabelSurface::find_crossings(std::uint32_t k) {
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::array<std::uint32_t, 3>>;
    std::array<std::vector<Box>, 2> boxes;
    std::array<std::vector<Segment>, 2> segments;
    for (int side = 0; side < 2; ++side) {
        const std::uint32_t slice = k + side;
        const std::vector<Contour>& all = contours_.slices[slice].contours;
        for (std::uint32_t local = 0; local < label_contours_[slice].size(); ++local) {
            const Contour& c = all[label_contours_[slice][local]];
            const std::size_t n = c.simplified.size();
            for (std::uint32_t e = 0; e < n; ++e) {
                const Vec2 a = c.points[c.simplified[e]];
                const Vec2 b = c.points[c.simplified[(e + 1) % n]];
                double lo[2] = {std::min(a.x, b.x), std::min(a.y, b.y)};
                double hi[2] = {std::max(a.x, b.x), std::max(a.y, b.y)};
                boxes[side].emplace_back(
                    lo, hi,
                    std::array<std::uint32_t, 3>{local, e, std::uint32_t(segments[side].size())});
                segments[side].push_back(Segment(to_point(a), to_point(b)));
            }
        }
    }
    if (boxes[0].empty() || boxes[1].empty()) {
        return;
    }
    std::vector<std::pair<std::array<std::uint32_t, 3>, std::array<std::uint32_t, 3>>> pairs;
    CGAL::box_intersection_d(
        boxes[0].begin(), boxes[0].end(), boxes[1].begin(), boxes[1].end(),
        [&](const Box& a, const Box& b) { pairs.emplace_back(a.info(), b.info()); },
        std::ptrdiff_t(10), CGAL::Box_intersection_d::CLOSED);
    std::sort(pairs.begin(), pairs.end());  // deterministic order
    for (const auto& [a, b] : pairs) {
        const Segment& sa = segments[0][a[2]];
        const Segment& sb = segments[1][b[2]];
        const auto hit = CGAL::intersection(sa, sb);
        if (!hit) {
            continue;
        }
        std::vector<Point> points;
        if (const Point* p = boost::get<Point>(&*hit)) {
            points.push_back(*p);
        } else if (const Segment* s = boost::get<Segment>(&*hit)) {
            points.push_back(s->source());
            points.push_back(s->target());
            overlaps_.push_back({*s, {k, a[0], a[1]}, {k + 1, b[0], b[1]}});
        }
        for (const Point& p : points) {
            splits_[k][a[0]][a[1]].push_back(p);
            splits_[k + 1][b[0]][b[1]].push_back(p);
        }
    }
}

/// Points on overlapping collinear edges of neighbouring slices are shared both ways, to a fixed
/// point (an edge may overlap edges of both neighbouring slices).
void LabelSurface::share_overlap_points() {
    auto list = [&](const std::array<std::uint32_t, 3>& e) -> std::vector<Point>& {
        return splits_[e[0]][e[1]][e[2]];
    };
    auto endpoints = [&](const std::array<std::uint32_t, 3>& e) {
        const Contour& c = contours_.slices[e[0]].contours[label_contours_[e[0]][e[1]]];
        const std::size_t n = c.simplified.size();
        return std::array<Point, 2>{to_point(c.points[c.simplified[e[2]]]),
                                    to_point(c.points[c.simplified[(e[2] + 1) % n]])};
    };
    // Worklist: an overlap is looked at again only when one of its edges gained a point.
    std::map<std::array<std::uint32_t, 3>, std::vector<std::size_t>> by_edge;
    for (std::size_t i = 0; i < overlaps_.size(); ++i) {
        by_edge[overlaps_[i].lower].push_back(i);
        by_edge[overlaps_[i].upper].push_back(i);
    }
    std::deque<std::size_t> work(overlaps_.size());
    std::iota(work.begin(), work.end(), std::size_t(0));
    std::vector<bool> queued(overlaps_.size(), true);
    while (!work.empty()) {
        const Overlap& o = overlaps_[work.front()];
        queued[work.front()] = false;
        work.pop_front();
        for (int dir = 0; dir < 2; ++dir) {
            const auto& from = dir == 0 ? o.lower : o.upper;
            const auto& to = dir == 0 ? o.upper : o.lower;
            const std::vector<Point>& source = list(from);  // another slice: not `target`
            std::vector<Point>& target = list(to);
            bool grew = false;
            auto share = [&](const Point& p) {
                if (o.segment.has_on(p) &&
                    std::find(target.begin(), target.end(), p) == target.end()) {
                    target.push_back(p);
                    grew = true;
                }
            };
            for (const Point& p : source) {
                share(p);
            }
            for (const Point& p : endpoints(from)) {
                share(p);
            }
            if (grew) {
                for (const std::size_t j : by_edge[to]) {
                    if (!queued[j]) {
                        queued[j] = true;
                        work.push_back(j);
                    }
                }
            }
        }
    }
}

void LabelSurface::build_rings() {
    const std::size_t slices = contours_.slices.size();
    rings_.assign(slices, {});
    for (std::uint32_t k = 0; k < slices; ++k) {
        const std::vector<Contour>& all = contours_.slices[k].contours;
        for (std::uint32_t local = 0; local < label_contours_[k].size(); ++local) {
            const Contour& c = all[label_contours_[k][local]];
            Ring ring;
            const std::size_t n = c.simplified.size();
            for (std::uint32_t e = 0; e < n; ++e) {
                const Point a = to_point(c.points[c.simplified[e]]);
                const Point b = to_point(c.points[c.simplified[(e + 1) % n]]);
                ring.points.push_back(a);
                std::vector<Point>& extra = splits_[k][local][e];
                std::sort(extra.begin(), extra.end(), [&](const Point& p, const Point& q) {
                    return CGAL::compare_distance_to_point(a, p, q) == CGAL::SMALLER;
                });
                for (const Point& p : extra) {
                    if (p != a && p != b && p != ring.points.back()) {
                        ring.points.push_back(p);
                    }
                }
            }
            for (const Point& p : ring.points) {
                ring.ids.push_back(add_vertex(to_vec(p), slice_z(k)));
            }
            rings_[k].push_back(std::move(ring));
        }
    }
}

void LabelSurface::insert_rings(Cdt& cdt,
                                std::uint32_t slice,
                                bool upper,
                                std::map<EdgeKey, EdgeOwner>& owners,
                                std::int64_t only_region) {
    for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
        if (only_region >= 0 && owner_region(slice, local) != only_region) {
            continue;
        }
        const Ring& ring = rings_[slice][local];
        std::vector<VertexHandle> handles;
        handles.reserve(ring.points.size());
        for (std::size_t i = 0; i < ring.points.size(); ++i) {
            VertexHandle v = cdt.insert(ring.points[i]);
            (upper ? v->info().upper : v->info().lower) = std::int32_t(ring.ids[i]);
            handles.push_back(v);
        }
        for (std::size_t i = 0; i < handles.size(); ++i) {
            VertexHandle a = handles[i];
            VertexHandle b = handles[(i + 1) % handles.size()];
            cdt.insert_constraint(a, b);
            EdgeOwner& owner = owners[edge_key(a, b)];
            (upper ? owner.upper : owner.lower) = std::int32_t(local);
        }
    }
}

/// Labels every face with the region of slice k and of slice k+1 it lies in, by walking from the
/// infinite face and toggling the region across each contour edge.
void LabelSurface::insert_steiners(Cdt& cdt,
                                   const std::vector<Point>& points,
                                   std::uint32_t k,
                                   const std::map<EdgeKey, EdgeOwner>& owners,
                                   const char* what) {
    for (const Point& p : points) {
        insert_steiner(cdt, p, k);
    }
    flood_regions(cdt, k, owners);
    if (unowned_edges_ != 0) {
        issue(k, std::string(what) + " split " + std::to_string(unowned_edges_) + " edges");
        unowned_edges_ = 0;
    }
}

void LabelSurface::flood_regions(Cdt& cdt,
                                 std::uint32_t k,
                                 const std::map<EdgeKey, EdgeOwner>& owners) {
    for (FaceHandle f : cdt.all_face_handles()) {
        f->info() = FaceInfo{};
    }
    std::deque<FaceHandle> queue;
    FaceHandle start = cdt.infinite_face();
    start->info().seen = true;
    queue.push_back(start);
    while (!queue.empty()) {
        const FaceHandle f = queue.front();
        queue.pop_front();
        for (int i = 0; i < 3; ++i) {
            const FaceHandle n = f->neighbor(i);
            if (n->info().seen) {
                continue;
            }
            FaceInfo state;
            state.lower_region = f->info().lower_region;
            state.upper_region = f->info().upper_region;
            state.lower_background = f->info().lower_background;
            state.upper_background = f->info().upper_background;
            if (cdt.is_constrained({f, i})) {
                const auto it = owners.find(edge_key(f->vertex(ccw(i)), f->vertex(cw(i))));
                if (it == owners.end()) {
                    ++unowned_edges_;
                }
                if (it != owners.end()) {
                    if (it->second.lower >= 0) {
                        const auto c = std::uint32_t(it->second.lower);
                        const auto r = std::int32_t(owner_region(k, c));
                        state.lower_region = state.lower_region == r ? -1 : r;
                        state.lower_background = background_beside(k, c);
                    }
                    if (it->second.upper >= 0) {
                        const auto c = std::uint32_t(it->second.upper);
                        const auto r = std::int32_t(owner_region(k + 1, c));
                        state.upper_region = state.upper_region == r ? -1 : r;
                        state.upper_background = background_beside(k + 1, c);
                    }
                }
            }
            state.seen = true;
            n->info() = state;
            queue.push_back(n);
        }
    }
}

/// The surface joins regions a (slice k) and b (slice k+1) once per connected piece of their
/// polygons' overlap; the reference joins them once per piece of their pixels' overlap. Reports
/// slabs where the two disagree.
void LabelSurface::check_overlap_topology(Cdt& cdt, std::uint32_t k) {
    std::map<const void*, std::size_t> index;
    std::vector<FaceHandle> faces;
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (f->info().lower_region >= 0 && f->info().upper_region >= 0) {
            index.emplace(&*f, faces.size());
            faces.push_back(f);
        }
    }
    DisjointSets sets(faces.size());
    for (std::size_t i = 0; i < faces.size(); ++i) {
        for (int j = 0; j < 3; ++j) {
            const FaceHandle n = faces[i]->neighbor(j);
            const auto it = index.find(&*n);
            if (it != index.end() && n->info().lower_region == faces[i]->info().lower_region &&
                n->info().upper_region == faces[i]->info().upper_region) {
                sets.join(i, it->second);
            }
        }
    }
    // Overlap pieces that touch at a contour point also join when the surface does not pass
    // through the vertical segment above it (no crossing wedge, no wall there): the solid is
    // connected around that segment, as the pixels are across a diagonal.
    for (VertexHandle v : cdt.finite_vertex_handles()) {
        if (v->info().lower < 0 || v->info().upper < 0) {
            continue;
        }
        std::vector<FaceHandle> around;
        Cdt::Face_circulator fc = cdt.incident_faces(v);
        const Cdt::Face_circulator done = fc;
        do {
            around.push_back(fc);
        } while (++fc != done);
        const std::size_t n = around.size();
        bool vertical = false;
        // Boundary edge between around[j] and around[j + 1], or kUnset when not a boundary.
        std::vector<Level> edge_class(n, kUnset);
        std::vector<Level> edge_class_next(n, kUnset);
        for (std::size_t j = 0; j < n; ++j) {
            const FaceHandle f = around[j];
            const FaceHandle g = around[(j + 1) % n];
            if (cdt.is_infinite(f) || cdt.is_infinite(g)) {
                continue;
            }
            const int e = f->index(g);
            const bool f_both = in_lower(f->info(), k) && in_upper(f->info(), k);
            const bool g_both = in_lower(g->info(), k) && in_upper(g->info(), k);
            const bool f_none = !in_lower(f->info(), k) && !in_upper(f->info(), k);
            const bool g_none = !in_lower(g->info(), k) && !in_upper(g->info(), k);
            if ((f_both && g_none) || (f_none && g_both)) {
                vertical = true;  // a wall
            }
            if (is_boundary(f, e, k)) {
                edge_class[j] = in_surface(f, k) ? boundary_class(f, e, k) : kUnset;
                edge_class_next[j] = in_surface(g, k) ? boundary_class(g, g->index(f), k) : kUnset;
            }
        }
        // A run of surface faces between two boundary edges with different classes crosses.
        for (std::size_t j = 0; j < n && !vertical; ++j) {
            if (edge_class_next[j] == kUnset) {
                continue;  // no surface run starts after edge j
            }
            const Level start = edge_class_next[j];
            for (std::size_t m = 1; m <= n; ++m) {
                const std::size_t e = (j + m) % n;
                if (edge_class[e] != kUnset ||
                    is_boundary(around[e], around[e]->index(around[(e + 1) % n]), k)) {
                    vertical = edge_class[e] != start;
                    break;
                }
            }
        }
        if (vertical) {
            continue;
        }
        std::size_t first = faces.size();
        for (const FaceHandle f : around) {
            const auto it = index.find(&*f);
            if (it == index.end()) {
                continue;
            }
            if (first == faces.size()) {
                first = it->second;
            } else if (faces[first]->info().lower_region == f->info().lower_region &&
                       faces[first]->info().upper_region == f->info().upper_region) {
                sets.join(first, it->second);
            }
        }
    }
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> pieces;
    std::vector<bool> counted(faces.size(), false);
    for (std::size_t i = 0; i < faces.size(); ++i) {
        const std::size_t root = sets.find(i);
        if (!counted[root]) {
            counted[root] = true;
            ++pieces[{std::uint32_t(faces[i]->info().lower_region),
                      std::uint32_t(faces[i]->info().upper_region)}];
        }
    }
    // Background: the pieces of the complement of the overlap (4-connected: across edges only)
    // that touch a hole of either slice, each with the background components it touches.
    std::map<const void*, std::size_t> bg_index;
    std::vector<FaceHandle> bg_faces;
    for (FaceHandle f : cdt.all_face_handles()) {
        if (f->info().lower_region < 0 || f->info().upper_region < 0) {
            bg_index.emplace(&*f, bg_faces.size());
            bg_faces.push_back(f);
        }
    }
    DisjointSets bg_sets(bg_faces.size());
    for (std::size_t i = 0; i < bg_faces.size(); ++i) {
        for (int j = 0; j < 3; ++j) {
            const auto it = bg_index.find(&*bg_faces[i]->neighbor(j));
            if (it != bg_index.end()) {
                bg_sets.join(i, it->second);
            }
        }
    }
    std::map<std::size_t, std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>>> touch;
    for (std::size_t i = 0; i < bg_faces.size(); ++i) {
        auto& [lower, upper] = touch[bg_sets.find(i)];
        const FaceInfo& info = bg_faces[i]->info();
        if (info.lower_region < 0) {
            lower.push_back(info.lower_background);
        }
        if (info.upper_region < 0) {
            upper.push_back(info.upper_background);
        }
    }
    std::vector<std::pair<std::vector<std::uint32_t>, std::vector<std::uint32_t>>> polygon_bg;
    for (auto& [root, touched] : touch) {
        for (auto* v : {&touched.first, &touched.second}) {
            std::sort(v->begin(), v->end());
            v->erase(std::unique(v->begin(), v->end()), v->end());
        }
        const bool hole = std::any_of(touched.first.begin(), touched.first.end(),
                                      [](std::uint32_t b) { return b != 0; }) ||
                          std::any_of(touched.second.begin(), touched.second.end(),
                                      [](std::uint32_t b) { return b != 0; });
        if (hole) {
            polygon_bg.push_back(touched);
        }
    }
    std::sort(polygon_bg.begin(), polygon_bg.end());
    if (polygon_bg != background_links_[k]) {
        ++surface_.topology_mismatches;
        mismatched_slabs_.push_back(k);
        issue(k, "contours overlap unlike the pixels: " + std::to_string(polygon_bg.size()) +
                     " background connection(s) through holes, pixels " +
                     std::to_string(background_links_[k].size()));
        return;
    }
    if (pieces != link_pieces_[k]) {
        std::size_t differ = 0;
        std::string example;
        auto note = [&](std::pair<std::uint32_t, std::uint32_t> pair, std::uint32_t polygons,
                        std::uint32_t pixels) {
            if (differ++ == 0) {
                example = ", e.g. regions " + std::to_string(pair.first) + " and " +
                          std::to_string(pair.second) + ": " + std::to_string(polygons) +
                          " polygon overlap(s), " + std::to_string(pixels) + " pixel overlap(s)";
            }
        };
        for (const auto& [pair, count] : pieces) {
            const auto it = link_pieces_[k].find(pair);
            const std::uint32_t pixels = it == link_pieces_[k].end() ? 0 : it->second;
            if (pixels != count) {
                note(pair, count, pixels);
            }
        }
        for (const auto& [pair, count] : link_pieces_[k]) {
            if (pieces.find(pair) == pieces.end()) {
                note(pair, 0, count);
            }
        }
        ++surface_.topology_mismatches;
        mismatched_slabs_.push_back(k);
        issue(k, "contours overlap unlike the pixels for " + std::to_string(differ) +
                     " region pair(s)" + example);
    }
}

bool LabelSurface::in_lower(const FaceInfo& f, std::uint32_t k) const {
    return f.lower_region >= 0 && linked_up_[k][std::size_t(f.lower_region)];
}

bool LabelSurface::in_upper(const FaceInfo& f, std::uint32_t k) const {
    return f.upper_region >= 0 && linked_down_[k + 1][std::size_t(f.upper_region)];
}

bool LabelSurface::in_surface(FaceHandle f, std::uint32_t k) const {
    return in_lower(f->info(), k) != in_upper(f->info(), k);
}

bool LabelSurface::is_boundary(FaceHandle f, int i, std::uint32_t k) const {
    const FaceHandle n = f->neighbor(i);
    return in_lower(f->info(), k) != in_lower(n->info(), k) ||
           in_upper(f->info(), k) != in_upper(n->info(), k);
}

/// Level of the boundary edge opposite vertex i of the surface face f: on slice k's contour
/// (low), on slice k+1's (high); where both contours run along the edge, the face's own side.
Level LabelSurface::boundary_class(FaceHandle f, int i, std::uint32_t k) const {
    const FaceHandle n = f->neighbor(i);
    const bool lower_changes = in_lower(f->info(), k) != in_lower(n->info(), k);
    const bool upper_changes = in_upper(f->info(), k) != in_upper(n->info(), k);
    if (lower_changes && upper_changes) {
        return in_lower(f->info(), k) ? kLow : kHigh;
    }
    return lower_changes ? kLow : kHigh;
}

/// The signed distance of slice field `f` at q (bilinear between nodes; negative inside; 1e9
/// without a field, outside_window_px outside its window).
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

/// The closest contour site of field `f` to q (that of the node nearest q); false without a
/// field.
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

/// The root in [0, 1] of the cubic Hermite curve from a (at 0) to b (at 1), a and b of opposite
/// signs, with end slopes m0 and m1 limited so that the curve is monotone there (Fritsch and
/// Carlson): the root is unique and moves continuously with the data.
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
    double lo = 0.0;
    double hi = 1.0;
    const bool rising = delta > 0.0;
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        if ((value(mid) < 0.0) == rising) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return 0.5 * (lo + hi);
}

double LabelSurface::height_t(const Point& p, std::uint32_t k) const {
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
    t = a * b < 0.0 ? t + 0.5 * (rings - a / (a - b)) : rings;
    return std::clamp(t, 0.05, 0.95);
}

void LabelSurface::make_steiner(VertexHandle v, std::uint32_t k) {
    v->info().steiner = std::int32_t(steiner_t_.size());
    steiner_t_.push_back(height_t(v->point(), k));
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
    std::vector<FaceHandle> cw_faces{f};
    std::vector<FaceHandle> ccw_faces;
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
    std::vector<FaceHandle> wedge(cw_faces.rbegin(), cw_faces.rend());
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
        // Cost of each face with v low and with v high.
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
            for (int level = 0; level < 2; ++level) {
                h[std::size_t(vi)] = level;
                double sum = 0.0;
                for (int sample = 0; sample < 4; ++sample) {
                    // the centroid and the points (4, 1, 1) / 6 towards each corner
                    std::array<double, 3> b{1.0 / 3, 1.0 / 3, 1.0 / 3};
                    if (sample < 3) {
                        b = {1.0 / 6, 1.0 / 6, 1.0 / 6};
                        b[std::size_t(sample)] = 4.0 / 6;
                    }
                    const Vec2 q = b[0] * xy[0] + b[1] * xy[1] + b[2] * xy[2];
                    const double face_t = b[0] * h[0] + b[1] * h[1] + b[2] * h[2];
                    const double diff = face_t - height_t(to_point(q), k);
                    sum += diff * diff;
                }
                cost[j][std::size_t(level)] = area * sum / 4.0;
            }
        }
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

/// Which points of a medial curve become Steiner points: those of its Douglas-Peucker
/// simplification (options.medial_tolerance_px), plus one at least every medial_max_step_px of
/// arc length, none closer than medial_step_px of arc length to the previous kept one.
std::vector<bool> thin_medial_curve(const MedialCurve& curve, const TriangulateOptions& options) {
    const std::size_t n = curve.points.size();
    std::vector<bool> corner(n, options.medial_tolerance_px <= 0.0);
    if (n > 0) {
        corner[0] = true;
        corner[n - 1] = true;
    }
    std::vector<std::pair<std::size_t, std::size_t>> stack;
    if (n > 2 && options.medial_tolerance_px > 0.0) {
        stack.emplace_back(0, n - 1);
    }
    while (!stack.empty()) {
        const auto [a, b] = stack.back();
        stack.pop_back();
        const Vec2 pa = curve.points[a].position;
        const Vec2 dir = curve.points[b].position - pa;
        const double length = norm(dir);
        double worst = -1.0;
        std::size_t at = a;
        for (std::size_t i = a + 1; i < b; ++i) {
            const Vec2 q = curve.points[i].position - pa;
            const double d = length > 0.0 ? std::abs(cross(dir, q)) / length : norm(q);
            if (d > worst) {
                worst = d;
                at = i;
            }
        }
        if (worst > options.medial_tolerance_px) {
            corner[at] = true;
            if (at - a > 1) {
                stack.emplace_back(a, at);
            }
            if (b - at > 1) {
                stack.emplace_back(at, b);
            }
        }
    }
    std::vector<bool> keep(n, false);
    double since = options.medial_step_px;  // arc length since the last kept point
    for (std::size_t i = 0; i < n; ++i) {
        if (i > 0) {
            since += norm(curve.points[i].position - curve.points[i - 1].position);
        }
        if (since >= options.medial_step_px && (corner[i] || since >= options.medial_max_step_px)) {
            keep[i] = true;
            since = 0.0;
        }
    }
    return keep;
}

void LabelSurface::triangulate_slab(std::uint32_t k) {
    slab_rings_ = {SegmentGrid(rings_[k]), SegmentGrid(rings_[k + 1])};
    Cdt cdt;
    std::map<EdgeKey, EdgeOwner> owners;
    insert_rings(cdt, k, false, owners);
    insert_rings(cdt, k + 1, true, owners);
    flood_regions(cdt, k, owners);
    if (unowned_edges_ != 0) {
        ++surface_.failed_slabs;
        issue(k, std::to_string(unowned_edges_) + " contour edges cross unexpectedly");
        unowned_edges_ = 0;
    }
    check_overlap_topology(cdt, k);

    steiner_t_.clear();
    steiner_id_.clear();
    steiner_xy_.clear();

    // The medial axis: the paper's correspondence curve, at t = 1/2 between the slices.
    std::vector<Point> medial;
    if (k < medial_axes_.size()) {
        for (const MedialCurve& curve : medial_axes_[k].curves) {
            if (curve.label != label_) {
                continue;
            }
            const std::vector<bool> keep = thin_medial_curve(curve, options_);
            for (std::size_t i = 0; i < curve.points.size(); ++i) {
                if (!keep[i]) {
                    continue;
                }
                const Point p = to_point(curve.points[i].position);
                Cdt::Locate_type type;
                int li = 0;
                const FaceHandle f = cdt.locate(p, type, li);
                if (type == Cdt::FACE && in_surface(f, k)) {
                    medial.push_back(p);
                }
            }
        }
    }
    if (!medial.empty()) {
        insert_steiners(cdt, medial, k, owners, "medial points");
    }
    // Where the cubic height bends away from the straight faces between a medial point and the
    // contours, a vertex half way to each contour's closest point follows it.
    if (options_.cubic_height && options_.curvature_tolerance_px > 0.0 && level_z_ == nullptr) {
        const double d = slice_z(k + 1) - slice_z(k);
        std::vector<Point> bends;
        for (const Point& p : medial) {
            const Vec2 m = to_vec(p);
            const double tm = height_t(p, k);
            for (std::uint32_t side = 0; side < 2; ++side) {
                Vec2 site{};
                if (!closest_site(field(k + side), m, site)) {
                    continue;
                }
                const Point q = to_point({0.5 * (m.x + site.x), 0.5 * (m.y + site.y)});
                const double straight = side == 0 ? 0.5 * tm : 0.5 * (tm + 1.0);
                if (std::abs(height_t(q, k) - straight) * d < options_.curvature_tolerance_px) {
                    continue;
                }
                Cdt::Locate_type type;
                int li = 0;
                const FaceHandle f = cdt.locate(q, type, li);
                if (type == Cdt::FACE && in_surface(f, k)) {
                    bends.push_back(q);
                }
            }
        }
        std::sort(bends.begin(), bends.end());
        bends.erase(std::unique(bends.begin(), bends.end()), bends.end());
        if (!bends.empty()) {
            insert_steiners(cdt, bends, k, owners, "curvature points");
        }
    }

    // Refine until every surface face has its levels and no inner edge lies in a slice plane.
    bool valid = false;
    for (unsigned round = 0; round <= options_.refine_rounds; ++round) {
        std::vector<Point> refine;
        std::vector<FaceHandle> faces;
        for (FaceHandle f : cdt.finite_face_handles()) {
            f->info().corner = {kUnset, kUnset, kUnset};
            if (in_surface(f, k)) {
                faces.push_back(f);
            }
        }
        bool complete = true;
        for (FaceHandle f : faces) {
            for (int i = 0; i < 3; ++i) {
                if (f->info().corner[std::size_t(i)] == kUnset &&
                    !resolve_corner(cdt, f, i, k, refine)) {
                    complete = false;
                }
            }
        }
        if (complete) {
            for (FaceHandle f : faces) {
                const std::array<Level, 3>& c = f->info().corner;
                if (c[0] != kBetween && c[0] == c[1] && c[1] == c[2]) {
                    refine.push_back(CGAL::centroid(cdt.triangle(f)));
                    continue;
                }
                for (int i = 0; i < 3; ++i) {
                    const Level a = c[std::size_t(ccw(i))];
                    const Level b = c[std::size_t(cw(i))];
                    // Both faces of the edge may ask (sorted and made unique below); no
                    // ordering by address, which would make the output depend on the heap.
                    if (a != kBetween && a == b && !is_boundary(f, i, k) &&
                        !cdt.is_constrained({f, i})) {
                        refine.push_back(
                            CGAL::midpoint(f->vertex(ccw(i))->point(), f->vertex(cw(i))->point()));
                    }
                }
            }
        }
        if (refine.empty() && complete) {
            valid = true;
            break;
        }
        if (round == options_.refine_rounds) {
            break;
        }
        std::sort(refine.begin(), refine.end());
        refine.erase(std::unique(refine.begin(), refine.end()), refine.end());
        insert_steiners(cdt, refine, k, owners, "refinement");
    }
    if (!valid) {
        ++surface_.failed_slabs;
        issue(k, "refinement did not converge in " + std::to_string(options_.refine_rounds) +
                     " rounds");
    }

    // Output.
    const double z0 = slice_z(k);
    const double d = slice_z(k + 1) - z0;
    auto corner_id = [&](FaceHandle f, int i) -> std::int32_t {
        const VertexHandle v = f->vertex(i);
        switch (f->info().corner[std::size_t(i)]) {
            case kLow:
                return v->info().lower;
            case kHigh:
                return v->info().upper;
            case kBetween: {
                const auto s = std::size_t(v->info().steiner);
                if (steiner_id_[s] < 0) {
                    steiner_id_[s] =
                        std::int32_t(add_vertex(steiner_xy_[s], z0 + steiner_t_[s] * d));
                    ++surface_.steiner_points;
                }
                return steiner_id_[s];
            }
            default:
                return -1;
        }
    };
    std::vector<std::array<std::uint32_t, 3>>& out = surface_.mesh.triangles;
    bool missing = false;
    std::map<const void*, std::array<std::uint32_t, 3>> emitted;
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (!in_surface(f, k)) {
            continue;
        }
        std::array<std::int32_t, 3> ids{corner_id(f, 0), corner_id(f, 1), corner_id(f, 2)};
        if (ids[0] < 0 || ids[1] < 0 || ids[2] < 0) {
            missing = true;
            continue;
        }
        std::array<std::uint32_t, 3> t{std::uint32_t(ids[0]), std::uint32_t(ids[1]),
                                       std::uint32_t(ids[2])};
        if (!in_lower(f->info(), k)) {
            std::swap(t[1], t[2]);  // below the graph is outside: face down
        }
        out.push_back(t);
        emitted.emplace(&*f, t);
    }
    // Vertical triangles where a wedge switches from z_k to z_k+1, and vertical walls where
    // both contours run along the same edge with the inside on the same side.
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (in_surface(f, k)) {
            for (int i = 0; i < 3; ++i) {
                // Inner edge opposite i, between corner levels low (here) and high (neighbour).
                const FaceHandle n = f->neighbor(i);
                if (is_boundary(f, i, k) || !in_surface(n, k)) {
                    continue;
                }
                for (int side = 0; side < 2; ++side) {
                    const int vi = side == 0 ? ccw(i) : cw(i);
                    const VertexHandle v = f->vertex(vi);
                    const VertexHandle u = f->vertex(side == 0 ? cw(i) : ccw(i));
                    if (f->info().corner[std::size_t(vi)] != kLow ||
                        n->info().corner[std::size_t(n->index(v))] != kHigh ||
                        u->info().steiner < 0) {
                        continue;
                    }
                    const auto it = emitted.find(&*f);
                    if (it == emitted.end()) {
                        continue;
                    }
                    if (v->info().lower < 0 || v->info().upper < 0 ||
                        steiner_id_[std::size_t(u->info().steiner)] < 0) {
                        missing = true;
                        continue;
                    }
                    const auto lo = std::uint32_t(v->info().lower);
                    const auto hi = std::uint32_t(v->info().upper);
                    const auto us = std::uint32_t(steiner_id_[std::size_t(u->info().steiner)]);
                    const std::array<std::uint32_t, 3>& t = it->second;
                    bool forward = false;  // does t contain the directed edge lo -> us?
                    for (int m = 0; m < 3; ++m) {
                        if (t[std::size_t(m)] == lo && t[std::size_t((m + 1) % 3)] == us) {
                            forward = true;
                        }
                    }
                    if (forward) {
                        out.push_back({us, lo, hi});
                    } else {
                        out.push_back({lo, us, hi});
                    }
                }
            }
        }
        const bool inside_both = in_lower(f->info(), k) && in_upper(f->info(), k);
        if (!inside_both) {
            continue;
        }
        for (int i = 0; i < 3; ++i) {
            const FaceHandle n = f->neighbor(i);
            if (in_lower(n->info(), k) || in_upper(n->info(), k)) {
                continue;
            }
            // f lies left of p -> q; the wall faces right, outward.
            const VertexHandle p = f->vertex(ccw(i));
            const VertexHandle q = f->vertex(cw(i));
            if (p->info().lower < 0 || p->info().upper < 0 || q->info().lower < 0 ||
                q->info().upper < 0) {
                missing = true;
                continue;
            }
            const auto pl = std::uint32_t(p->info().lower);
            const auto ph = std::uint32_t(p->info().upper);
            const auto ql = std::uint32_t(q->info().lower);
            const auto qh = std::uint32_t(q->info().upper);
            out.push_back({pl, ql, qh});
            out.push_back({pl, qh, ph});
        }
    }
    if (missing && valid) {
        ++surface_.failed_slabs;
        issue(k, "a surface vertex has no position on the slice it lies on");
    }
    ++surface_.slabs;
}

/// Closes region `region` of slice k by planar caps: on top (normal +z) when it has no partner
/// above, below when none below; alone on its slice it becomes a slab of thickness d/2.
void LabelSurface::cap_region(std::uint32_t k, std::uint32_t region, bool top, bool bottom) {
    Cdt cdt;
    std::map<EdgeKey, EdgeOwner> owners;
    insert_rings(cdt, k, false, owners, region);
    flood_regions(cdt, k, owners);  // inside the region: lower_region >= 0
    std::vector<std::array<std::uint32_t, 3>>& out = surface_.mesh.triangles;
    const bool slab = top && bottom;
    // At the ends of the stack the object may go on out of it: its last slice stands for its
    // whole cell, as a voxel does, and the region is extended by d/2 (walls and a planar cap).
    // note: unless it visibly closes within the cap's reach (then a dome, as inside the stack).
    const bool stack_end =
        !slab && level_z_ == nullptr && options_.cap_reach > 0.0 &&
        ((top && k + 1 == contours_.slices.size()) || (bottom && k == 0)) &&
        !(cap_height(k, region, top) < options_.cap_reach * options_.slice_spacing_px);
    const bool walls = slab || stack_end;
    if (!walls && !dome_cap(cdt, owners, k, region, top)) {
        // no dome (too small, or its refinement did not converge): planar
        cdt.clear();
        owners.clear();
        insert_rings(cdt, k, false, owners, region);
        flood_regions(cdt, k, owners);
    }
    std::map<std::uint32_t, std::array<std::uint32_t, 2>> lifted;  // ring id -> (below, above)
    auto lift = [&](std::uint32_t id) {
        auto it = lifted.find(id);
        if (it == lifted.end()) {
            const Vec3 p = surface_.mesh.positions[id];
            const double d = options_.slice_spacing_px;
            const double down = slab ? d / 4.0 : bottom ? d / 2.0 : 0.0;
            const double up = slab ? d / 4.0 : top ? d / 2.0 : 0.0;
            const std::uint32_t below = down > 0.0 ? add_vertex({p.x, p.y}, p.z - down) : id;
            const std::uint32_t above = up > 0.0 ? add_vertex({p.x, p.y}, p.z + up) : id;
            it = lifted.emplace(id, std::array<std::uint32_t, 2>{below, above}).first;
        }
        return it->second;
    };
    for (FaceHandle f : cdt.finite_face_handles()) {
        if (f->info().lower_region < 0) {
            continue;
        }
        std::array<std::uint32_t, 3> t{};
        bool on_contour = true;
        for (int i = 0; i < 3; ++i) {
            const VertexInfo& info = f->vertex(i)->info();
            // dome vertices carry their global id in `steiner`
            const std::int32_t id = info.lower >= 0 ? info.lower : info.steiner;
            on_contour = on_contour && id >= 0;
            t[std::size_t(i)] = std::uint32_t(id);
        }
        if (!on_contour) {
            ++surface_.failed_slabs;
            issue(k, "a cap vertex is not on the contour");
            continue;
        }
        if (walls) {
            if (top) {
                out.push_back({lift(t[0])[1], lift(t[1])[1], lift(t[2])[1]});
            }
            if (bottom) {
                out.push_back({lift(t[0])[0], lift(t[2])[0], lift(t[1])[0]});
            }
        } else if (top) {
            out.push_back(t);
        } else {
            out.push_back({t[0], t[2], t[1]});
        }
    }
    if (walls) {
        // Walls: contours keep the region on their left, so outward is to the right.
        for (std::uint32_t local = 0; local < rings_[k].size(); ++local) {
            if (owner_region(k, local) != region) {
                continue;
            }
            const Ring& ring = rings_[k][local];
            for (std::size_t i = 0; i < ring.ids.size(); ++i) {
                const auto p = lift(ring.ids[i]);
                const auto q = lift(ring.ids[(i + 1) % ring.ids.size()]);
                out.push_back({p[0], q[0], q[1]});
                out.push_back({p[0], q[1], p[1]});
            }
        }
    }
    if (slab) {
        surface_.caps += 2;
    } else {
        surface_.caps += 1;
    }
}

double LabelSurface::region_area(std::uint32_t slice, std::uint32_t region) const {
    double area = 0.0;  // outer contours count positive, holes negative
    for (std::uint32_t local = 0; local < rings_[slice].size(); ++local) {
        if (owner_region(slice, local) != region) {
            continue;
        }
        const Ring& ring = rings_[slice][local];
        for (std::size_t i = 0; i < ring.points.size(); ++i) {
            const Vec2 a = to_vec(ring.points[i]);
            const Vec2 b = to_vec(ring.points[(i + 1) % ring.points.size()]);
            area += 0.5 * (a.x * b.y - b.x * a.y);
        }
    }
    return area;
}

/// How far the object goes on past slice k where region `region` ends (above when `top`): a
/// paraboloid cut by planes d apart has H = d A / (A' - A), A the region's area and A' its
/// partners' on the other side (each shared between its partners here by area). Infinity
/// where the areas do not shrink.
double LabelSurface::cap_height(std::uint32_t k, std::uint32_t region, bool top) const {
    const double d = options_.slice_spacing_px;
    const double area = region_area(k, region);
    // The partners on the other side, and the share of each that leads to this region.
    double partner_area = 0.0;
    const std::uint32_t slab = top ? k - 1 : k;
    const std::uint32_t other = top ? k - 1 : k + 1;
    for (const auto& [pair, count] : link_pieces_[slab]) {
        const std::uint32_t here = top ? pair.second : pair.first;
        const std::uint32_t there = top ? pair.first : pair.second;
        if (here != region) {
            continue;
        }
        double siblings = 0.0;  // every region of slice k this partner leads to
        for (const auto& [pair2, count2] : link_pieces_[slab]) {
            if ((top ? pair2.first : pair2.second) == there) {
                siblings += region_area(k, top ? pair2.second : pair2.first);
            }
        }
        partner_area += region_area(other, there) * (siblings > 0.0 ? area / siblings : 1.0);
    }
    if (partner_area > area && area > 0.0) {
        return d * area / (partner_area - area);
    }
    return std::numeric_limits<double>::infinity();
}

/// Region `region` of slice k ends there (no partner above when `top`, else below). The object
/// goes on past the slice plane by some height in [0, d) that the slices do not show; the cap is
/// domed by the paraboloid that continues the slab it closes: over a point at distance D inside
/// the contour its height is H (1 - (1 - D / Dmax)^2), Dmax the region's largest D. H follows
/// from the shrinking areas A (this region) and A' (its partners on the other side, shared
/// between their partners here by area): a paraboloid cut by planes d apart has
/// H = d A / (A' - A). H is at most options.cap_reach d (half a slab where the areas do not
/// shrink). Adds Steiner vertices on a grid inside the region (vertex info `steiner`: their
/// global id); the contour keeps z_k, so the section at the slice plane is still the contour.
/// Returns false, with the triangulation to be built again, where no dome is made (a region
/// too small or too flat for one, or chords that would not go).
bool LabelSurface::dome_cap(Cdt& cdt,
                            const std::map<EdgeKey, EdgeOwner>& owners,
                            std::uint32_t k,
                            std::uint32_t region,
                            bool top) {
    const double d = options_.slice_spacing_px;
    const DistanceField* f = field(k);
    if (level_z_ != nullptr || options_.cap_reach <= 0.0 || f == nullptr) {
        return false;
    }
    double height = cap_height(k, region, top);
    if (!std::isfinite(height)) {
        height = 0.5 * d;  // the areas do not shrink: half a slab on average
    }
    height = std::min(height, options_.cap_reach * d);

    // Dmax: the deepest field node inside this region.
    double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
    for (std::uint32_t local = 0; local < rings_[k].size(); ++local) {
        if (owner_region(k, local) != region) {
            continue;
        }
        for (const Point& p : rings_[k][local].points) {
            const Vec2 q = to_vec(p);
            x0 = std::min(x0, q.x);
            y0 = std::min(y0, q.y);
            x1 = std::max(x1, q.x);
            y1 = std::max(y1, q.y);
        }
    }
    auto inside = [&](Vec2 q) {
        Cdt::Locate_type type;
        int li = 0;
        const FaceHandle face = cdt.locate(to_point(q), type, li);
        if (type == Cdt::VERTEX || type == Cdt::OUTSIDE_CONVEX_HULL ||
            type == Cdt::OUTSIDE_AFFINE_HULL || cdt.is_infinite(face) ||
            face->info().lower_region != std::int32_t(region)) {
            return false;
        }
        return !(type == Cdt::EDGE && cdt.is_constrained({face, li}));
    };
    const double cell = DistanceField::kCellPx;
    const auto i0 =
        std::uint32_t(std::clamp(std::floor((x0 - f->origin_x) / cell), 0.0, double(f->nx - 1)));
    const auto i1 =
        std::uint32_t(std::clamp(std::ceil((x1 - f->origin_x) / cell), 0.0, double(f->nx - 1)));
    const auto j0 =
        std::uint32_t(std::clamp(std::floor((y0 - f->origin_y) / cell), 0.0, double(f->ny - 1)));
    const auto j1 =
        std::uint32_t(std::clamp(std::ceil((y1 - f->origin_y) / cell), 0.0, double(f->ny - 1)));
    std::vector<std::pair<float, std::uint32_t>> deep;  // (-D, node) inside the label
    for (std::uint32_t j = j0; j <= j1; ++j) {
        for (std::uint32_t i = i0; i <= i1; ++i) {
            const float v = f->at(i, j);
            if (v < 0.0f) {
                deep.emplace_back(v, j * f->nx + i);
            }
        }
    }
    std::sort(deep.begin(), deep.end());
    double dmax = 0.0;
    for (std::size_t n = 0; n < deep.size() && n < 256; ++n) {
        const std::uint32_t node = deep[n].second;
        if (inside(f->node_position(node % f->nx, node / f->nx))) {
            dmax = -double(deep[n].first);
            break;
        }
    }
    if (!(dmax > 1.0) || !(height > 0.0)) {
        return false;
    }
    // Grid points: spacing a third of Dmax (1 to 8 px), at least 1 px inside. Heights are at
    // least one quantization step of z (d / 16) so that no vertex snaps into the plane.
    const double step = std::clamp(dmax / 3.0, 1.0, 8.0);
    const double z = slice_z(k);
    const double sign = top ? 1.0 : -1.0;
    const double lowest = d / 16.0;
    if (height < 2.0 * lowest) {
        return false;
    }
    auto dome_height = [&](Vec2 q) {
        const double depth = std::max(-sample_field(f, q), 0.0);
        const double u = 1.0 - std::min(depth / dmax, 1.0);
        return std::max(height * (1.0 - u * u), lowest);
    };
    std::vector<Vec2> points;
    for (double y = std::floor(y0 / step) * step + 0.5 * step; y < y1; y += step) {
        for (double x = std::floor(x0 / step) * step + 0.5 * step; x < x1; x += step) {
            const Vec2 q{x, y};
            if (-sample_field(f, q) >= 1.0 && inside(q)) {
                points.push_back(q);
            }
        }
    }
    if (points.empty()) {
        return false;
    }
    auto add = [&](const Point& p) {
        const VertexHandle v = cdt.insert(p);
        if (v->info().lower < 0 && v->info().steiner < 0) {
            const Vec2 q = to_vec(p);
            v->info().steiner = std::int32_t(add_vertex(q, z + sign * dome_height(q)));
        }
    };
    // note: the points were checked on the rings' triangulation (faces labelled), not between
    // insertions; Steiner points never split a constrained edge.
    for (const Vec2& q : points) {
        add(to_point(q));
    }
    // No inner edge may join two contour vertices: it would lie in the slice plane, inside the
    // region, and become part of the section there. Split such chords at their midpoints.
    for (int round = 0; round < 16; ++round) {
        flood_regions(cdt, k, owners);
        std::vector<Point> chords;
        for (FaceHandle face : cdt.finite_face_handles()) {
            if (face->info().lower_region != std::int32_t(region)) {
                continue;
            }
            for (int i = 0; i < 3; ++i) {
                const VertexHandle a = face->vertex(ccw(i));
                const VertexHandle b = face->vertex(cw(i));
                if (!cdt.is_constrained({face, i}) && a->info().steiner < 0 &&
                    b->info().steiner < 0) {
                    chords.push_back(CGAL::midpoint(a->point(), b->point()));
                }
            }
        }
        if (chords.empty()) {
            return true;
        }
        std::sort(chords.begin(), chords.end());
        chords.erase(std::unique(chords.begin(), chords.end()), chords.end());
        for (const Point& p : chords) {
            add(p);
        }
    }
    return false;
}

ObjectSurface LabelSurface::build() {
    surface_.label = label_;
    collect_contours();
    collect_links();
    const std::size_t slices = contours_.slices.size();
    splits_.assign(slices, {});
    for (std::size_t k = 0; k < slices; ++k) {
        const std::vector<Contour>& all = contours_.slices[k].contours;
        for (std::uint32_t c : label_contours_[k]) {
            splits_[k].emplace_back(all[c].simplified.size());
        }
    }
    for (std::uint32_t k = 0; k + 1 < slices; ++k) {
        if (!label_contours_[k].empty() && !label_contours_[k + 1].empty()) {
            find_crossings(k);
        }
    }
    share_overlap_points();
    build_rings();
    splits_.clear();
    for (std::uint32_t k = 0; k + 1 < slices; ++k) {
        if (!link_pieces_[k].empty()) {
            triangulate_slab(k);
        }
    }
    for (std::uint32_t k = 0; k < slices; ++k) {
        for (std::uint32_t r = 0; r < region_count_[k]; ++r) {
            const bool top = !linked_up_[k][r];
            const bool bottom = !linked_down_[k][r];
            if (top || bottom) {
                cap_region(k, r, top, bottom);
            }
        }
    }
    // Drop ring vertices no triangle uses (contours of single-slice slabs).
    TriMesh& mesh = surface_.mesh;
    std::vector<std::int64_t> remap(mesh.positions.size(), -1);
    for (const auto& t : mesh.triangles) {
        for (std::uint32_t v : t) {
            remap[v] = 0;
        }
    }
    std::vector<Vec3> kept;
    for (std::size_t v = 0; v < remap.size(); ++v) {
        if (remap[v] == 0) {
            remap[v] = std::int64_t(kept.size());
            kept.push_back(mesh.positions[v]);
        }
    }
    mesh.positions = std::move(kept);
    for (auto& t : mesh.triangles) {
        for (std::uint32_t& v : t) {
            v = std::uint32_t(remap[v]);
        }
    }
    std::stable_sort(
        surface_.issues.begin(), surface_.issues.end(),
        [](const SlabIssue& a, const SlabIssue& b) { return a.lower_slice < b.lower_slice; });
    return std::move(surface_);
}

/// Builds one label's surface. Where simplified contours overlap in another pattern than the
/// pixels (the surface would get the wrong topology), the label's contours on both slices of
/// that slab are simplified again with vertices at pixel corners only (where they had
/// edge-midpoint vertices), then only their edges near the other slice's contours go back to the
/// original points, then all of them (exactly the pixel boundary, so the error bound holds
/// trivially); the label is built again each time, a few times at most.
/// Where contours meet at a saddle corner v the tracer cuts the corner on one side (foreground
/// 8-connected). Moves that cut to distance r of v and cuts the opposite corner by the same
/// amount, so the region covers a small diamond around v: it overlaps whichever of the two
/// diagonal pixels a neighbouring slice has, and the overlap stays connected through v.
void widen_saddles(SliceContourSet& set, double r) {
    std::vector<Vec2> corners;
    for (Contour& c : set.contours) {
        const std::size_t n = c.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            Vec2& a = c.points[i];
            Vec2& b = c.points[(i + 1) % n];
            if (std::abs(std::abs(a.x - b.x) - 0.5) > 1e-12 ||
                std::abs(std::abs(a.y - b.y) - 0.5) > 1e-12) {
                continue;
            }
            const Vec2 v{std::floor(a.x) == a.x ? a.x : b.x, std::floor(a.y) == a.y ? a.y : b.y};
            corners.push_back(v);
            a = v + (r / 0.5) * (a - v);
            b = v + (r / 0.5) * (b - v);
        }
    }
    for (Contour& c : set.contours) {
        std::vector<Vec2> out;
        const std::size_t n = c.points.size();
        for (std::size_t i = 0; i < n; ++i) {
            const Vec2 p = c.points[i];
            if (std::find(corners.begin(), corners.end(), p) == corners.end()) {
                out.push_back(p);
                continue;
            }
            for (const Vec2 q : {c.points[(i + n - 1) % n], c.points[(i + 1) % n]}) {
                const Vec2 d = q - p;
                out.push_back(p + (r / std::sqrt(dot(d, d))) * d);
            }
        }
        c.points = std::move(out);
        c.simplified.resize(c.points.size());
        std::iota(c.simplified.begin(), c.simplified.end(), 0u);
        c.edge_deviation_px.assign(c.points.size(), 0.0);
    }
}

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

Levels split_slabs(const SliceStack& stack,
                   const SliceContours& contours,
                   const std::vector<SliceDistanceFields>& fields,
                   const std::vector<MedialAxis>& medial_axes,
                   std::uint16_t label,
                   const std::vector<bool>& split,
                   double d) {
    Levels levels;
    levels.contours.width = contours.width;
    levels.contours.height = contours.height;
    levels.contours.tolerance_px = contours.tolerance_px;
    auto label_fields = [&](const SliceDistanceFields& all) {
        SliceDistanceFields out;
        for (const DistanceField& f : all.fields) {
            if (f.label == label) {
                out.fields.push_back(f);
            }
        }
        return out;
    };
    std::vector<std::uint32_t> level_of(contours.slices.size());
    for (std::uint32_t k = 0; k < contours.slices.size(); ++k) {
        level_of[k] = std::uint32_t(levels.contours.slices.size());
        levels.contours.slices.push_back(contours.slices[k]);
        levels.fields.push_back(label_fields(fields[k]));
        levels.z.push_back(k * d);
        levels.slice_of.push_back(k);
        if (k + 1 >= contours.slices.size()) {
            break;
        }
        if (!split[k]) {
            MedialAxis axis;
            for (const MedialCurve& curve : medial_axes[k].curves) {
                if (curve.label == label) {
                    axis.curves.push_back(curve);
                }
            }
            levels.medial_axes.push_back(std::move(axis));
            continue;
        }
        // slice k, AND, slice k+1 of this label as a three-slice stack.
        SliceStack mini;
        mini.width = stack.width;
        mini.height = stack.height;
        mini.depth = 3;
        mini.labels.assign(mini.slice_size() * 3, 0);
        const auto lower = stack.slice(k);
        const auto upper = stack.slice(k + 1);
        for (std::size_t i = 0; i < mini.slice_size(); ++i) {
            const bool a = lower[i] == label;
            const bool b = upper[i] == label;
            mini.labels[i] = a ? label : 0;
            mini.labels[mini.slice_size() + i] = a && b ? label : 0;
            mini.labels[2 * mini.slice_size() + i] = b ? label : 0;
        }
        mini.label_table.push_back({label, "label", {}});
        const std::vector<std::uint16_t> only{label};
        const SliceContourSet set0 = trace_slice_contours(mini, 0, only);
        SliceContourSet mid = trace_slice_contours(mini, 1, only);
        const SliceContourSet set2 = trace_slice_contours(mini, 2, only);
        std::vector<RegionLink> down = link_slices(mini, 0, set0, mid, only);
        std::vector<RegionLink> up = link_slices(mini, 1, mid, set2, only);
        SliceDistanceFields mid_fields;
        if (!mid.contours.empty()) {
            mid_fields.fields.push_back(compute_distance_field(mini, mid, 1, label, {}));
        }
        widen_saddles(mid, 0.25);
        const auto m = std::uint32_t(levels.contours.slices.size());
        for (RegionLink& link : down) {
            link.lower_slice = m - 1;
            levels.contours.links.push_back(std::move(link));
        }
        for (RegionLink& link : up) {
            link.lower_slice = m;
            levels.contours.links.push_back(std::move(link));
        }
        levels.contours.slices.push_back(std::move(mid));
        levels.fields.push_back(std::move(mid_fields));
        levels.z.push_back((k + 0.5) * d);
        levels.slice_of.push_back(k);
        levels.medial_axes.emplace_back();
        levels.medial_axes.emplace_back();
    }
    for (const RegionLink& link : contours.links) {
        if (link.label == label && !split[link.lower_slice]) {
            RegionLink moved = link;
            moved.lower_slice = level_of[link.lower_slice];
            levels.contours.links.push_back(std::move(moved));
        }
    }
    std::stable_sort(
        levels.contours.links.begin(), levels.contours.links.end(),
        [](const RegionLink& a, const RegionLink& b) { return a.lower_slice < b.lower_slice; });
    return levels;
}

/// The largest deviation of `label`'s simplified contours from their original points, px.
double contour_deviation_px(const SliceContours& contours, std::uint16_t label) {
    double deviation = 0.0;
    for (const SliceContourSet& set : contours.slices) {
        for (const Contour& contour : set.contours) {
            if (contour.label == label) {
                for (const double d : contour.edge_deviation_px) {
                    deviation = std::max(deviation, d);
                }
            }
        }
    }
    return deviation;
}

/// Whether the simplified contours of `label` on one slice are simple and pairwise disjoint
/// (exact predicates), as the triangulation needs them.
bool contours_clean(const SliceContourSet& set, std::uint16_t label) {
    // Predicates only, on double coordinates: the exact-predicates kernel decides them exactly
    // without the lazy exact constructions (whose filter, inlined here, gcc 12 under the
    // sanitizers reports as maybe-uninitialized).
    using PredicateKernel = CGAL::Exact_predicates_inexact_constructions_kernel;
    using EdgeSegment = PredicateKernel::Segment_2;
    using EdgePoint = PredicateKernel::Point_2;
    using Box = CGAL::Box_intersection_d::Box_with_info_d<double, 2, std::array<std::uint32_t, 2>>;
    std::vector<Box> boxes;
    std::vector<std::vector<EdgeSegment>> segments;
    for (const Contour& c : set.contours) {
        if (c.label != label) {
            continue;
        }
        const auto contour = std::uint32_t(segments.size());
        segments.emplace_back();
        const std::size_t n = c.simplified.size();
        for (std::uint32_t e = 0; e < n; ++e) {
            const Vec2 a = c.points[c.simplified[e]];
            const Vec2 b = c.points[c.simplified[(e + 1) % n]];
            double lo[2] = {std::min(a.x, b.x), std::min(a.y, b.y)};
            double hi[2] = {std::max(a.x, b.x), std::max(a.y, b.y)};
            boxes.emplace_back(lo, hi, std::array<std::uint32_t, 2>{contour, e});
            segments.back().push_back(EdgeSegment(EdgePoint(a.x, a.y), EdgePoint(b.x, b.y)));
        }
    }
    bool clean = true;
    CGAL::box_self_intersection_d(
        boxes.begin(), boxes.end(),
        [&](const Box& p, const Box& q) {
            const auto [cp, ep] = p.info();
            const auto [cq, eq] = q.info();
            const EdgeSegment& a = segments[cp][ep];
            const EdgeSegment& b = segments[cq][eq];
            const std::size_t n = segments[cp].size();
            if (cp == cq && (ep + 1) % n == eq) {
                // consecutive: they share a.target() == b.source() and nothing else
                clean = clean && !a.has_on(b.target()) && !b.has_on(a.source());
            } else if (cp == cq && (eq + 1) % n == ep) {
                clean = clean && !b.has_on(a.target()) && !a.has_on(b.source());
            } else if (CGAL::do_intersect(a, b)) {
                clean = false;
            }
        },
        std::ptrdiff_t(10), CGAL::Box_intersection_d::CLOSED);
    return clean;
}

ObjectSurface build_label_surface(const SliceStack& stack,
                                  const SliceContours& contours,
                                  const std::vector<SliceDistanceFields>& fields,
                                  const std::vector<MedialAxis>& medial_axes,
                                  const TriangulateOptions& options,
                                  std::uint16_t label) {
    LabelSurface first(contours, fields, medial_axes, options, label);
    ObjectSurface surface = first.build();
    if (first.mismatched_slabs().empty()) {
        surface.contour_deviation_px = contour_deviation_px(contours, label);
        return surface;
    }
    SliceContours exact = contours;
    std::vector<bool> at_corners(contours.slices.size(), false);
    std::vector<bool> partly(contours.slices.size(), false);
    std::vector<bool> unsimplified(contours.slices.size(), false);
    SimplifyOptions corners;
    corners.tolerance_px = contours.tolerance_px;
    corners.edge_midpoints = false;
    const double radius = unsimplify_radius_px(contours.tolerance_px);
    std::vector<std::uint32_t> mismatched = first.mismatched_slabs();
    // Each slice of a mismatched slab goes one step further per attempt: vertices at pixel
    // corners, then original points near the neighbouring slices' contours only (a whole
    // original slice left a row of staircase notches between smooth neighbours), then all of
    // them original. Steps that change nothing are skipped.
    for (int attempt = 0; attempt < 4 && !mismatched.empty(); ++attempt) {
        for (std::uint32_t k : mismatched) {
            for (std::uint32_t slice : {k, k + 1}) {
                if (unsimplified[slice]) {
                    continue;
                }
                SliceContourSet& set = exact.slices[slice];
                if (!at_corners[slice]) {
                    at_corners[slice] = true;
                    if (resimplify_label(set, label, corners)) {
                        continue;
                    }
                }
                if (!partly[slice]) {
                    partly[slice] = true;
                    const SliceContourSet before = set;
                    if (unsimplify_near_neighbours(set, label, fields, slice, radius)) {
                        if (contours_clean(set, label)) {
                            continue;
                        }
                        set = before;
                    }
                }
                unsimplified[slice] = true;
                for (Contour& c : set.contours) {
                    if (c.label == label) {
                        c.simplified.resize(c.points.size());
                        std::iota(c.simplified.begin(), c.simplified.end(), 0u);
                        c.edge_deviation_px.assign(c.points.size(), 0.0);
                    }
                }
            }
        }
        LabelSurface again(exact, fields, medial_axes, options, label);
        surface = again.build();
        mismatched = again.mismatched_slabs();
    }
    if (!mismatched.empty()) {
        // Last resort: split each remaining slab at the pixels' AND layer (the reference
        // volume's own middle layer), so the surface meets it as R does.
        std::vector<bool> split(contours.slices.size(), false);
        for (std::uint32_t k : mismatched) {
            split[k] = true;
        }
        const Levels levels =
            split_slabs(stack, exact, fields, medial_axes, label, split, options.slice_spacing_px);
        LabelSurface third(levels.contours, levels.fields, levels.medial_axes, options, label,
                           &levels.z);
        surface = third.build();
        for (SlabIssue& issue : surface.issues) {
            issue.lower_slice = levels.slice_of[issue.lower_slice];
        }
        surface.split_slabs = std::uint32_t(mismatched.size());
        surface.contour_deviation_px = contour_deviation_px(levels.contours, label);
    } else {
        surface.contour_deviation_px = contour_deviation_px(exact, label);
    }
    surface.unsimplified_slices =
        std::uint32_t(std::count(unsimplified.begin(), unsimplified.end(), true));
    for (std::uint32_t k = 0; k < unsimplified.size(); ++k) {
        if (unsimplified[k]) {
            surface.unsimplified.push_back(k);
            continue;
        }
        if (at_corners[k]) {
            surface.at_corners.push_back(k);
        }
        if (partly[k]) {
            surface.partly_unsimplified.push_back(k);
        }
    }
    return surface;
}

}  // namespace

double unsimplify_radius_px(double tolerance_px) {
    return 2.0 * tolerance_px + 0.5;
}

bool unsimplify_near_neighbours(SliceContourSet& set,
                                std::uint16_t label,
                                const std::vector<SliceDistanceFields>& fields,
                                std::uint32_t slice,
                                double radius_px) {
    std::vector<const DistanceField*> others;
    for (const std::int64_t s : {std::int64_t(slice) - 1, std::int64_t(slice) + 1}) {
        if (s < 0 || s >= std::int64_t(fields.size())) {
            continue;
        }
        for (const DistanceField& f : fields[std::size_t(s)].fields) {
            if (f.label == label) {
                others.push_back(&f);
            }
        }
    }
    auto near = [&](Vec2 p) {
        for (const DistanceField* f : others) {
            const double u = std::round((p.x - f->origin_x) / DistanceField::kCellPx);
            const double v = std::round((p.y - f->origin_y) / DistanceField::kCellPx);
            if (!(u >= 0.0 && v >= 0.0 && u <= f->nx - 1.0 && v <= f->ny - 1.0)) {
                if (f->outside_window_px <= radius_px) {
                    return true;
                }
                continue;
            }
            if (std::abs(f->at(std::uint32_t(u), std::uint32_t(v))) <= radius_px) {
                return true;
            }
        }
        return false;
    };
    bool changed = false;
    for (Contour& c : set.contours) {
        if (c.label != label) {
            continue;
        }
        const std::size_t n = c.points.size();
        const std::size_t m = c.simplified.size();
        std::vector<bool> keep(n, false);
        std::vector<double> deviation(n, 0.0);  // of the edge starting at each kept point
        bool grew = false;
        for (std::size_t e = 0; e < m; ++e) {
            const std::uint32_t a = c.simplified[e];
            const std::uint32_t b = c.simplified[(e + 1) % m];
            keep[a] = true;
            deviation[a] = c.edge_deviation_px[e];
            const std::size_t span = (b + n - a) % n;
            if (span <= 1) {
                continue;
            }
            bool expand = false;
            for (std::size_t s = 0; s <= span && !expand; ++s) {
                expand = near(c.points[(a + s) % n]);
            }
            if (expand) {
                for (std::size_t s = 0; s < span; ++s) {
                    keep[(a + s) % n] = true;
                    deviation[(a + s) % n] = 0.0;
                }
                grew = true;
            }
        }
        if (!grew) {
            continue;
        }
        changed = true;
        c.simplified.clear();
        c.edge_deviation_px.clear();
        for (std::uint32_t i = 0; i < n; ++i) {
            if (keep[i]) {
                c.simplified.push_back(i);
                c.edge_deviation_px.push_back(deviation[i]);
            }
        }
    }
    return changed;
}

std::vector<ObjectSurface> triangulate_surfaces(const SliceStack& stack,
                                                const SliceContours& contours,
                                                const std::vector<SliceDistanceFields>& fields,
                                                const std::vector<MedialAxis>& medial_axes,
                                                const TriangulateOptions& options) {
    const std::vector<std::uint16_t> labels =
        options.labels.empty() ? contour_labels(contours) : options.labels;
    std::vector<ObjectSurface> surfaces(labels.size());
    std::atomic<std::size_t> done{0};
    std::mutex progress_mutex;
    parallel_for(labels.size(), options.threads, [&](std::size_t i) {
        surfaces[i] = build_label_surface(stack, contours, fields, medial_axes, options, labels[i]);
        if (options.progress) {
            const std::lock_guard lock(progress_mutex);
            options.progress("objects", ++done, labels.size());
        }
    });
    return surfaces;
}

}  // namespace strata

// Exact self-intersection test of a triangle soup.
//
// Follows CGAL Polygon Mesh Processing's `self_intersections` (CGAL 5.5,
// Polygon_mesh_processing/self_intersections.h, after Lutz Kettner): axis-aligned boxes around
// every triangle, candidate pairs from `box_self_intersection_d` (Zomorodian & Edelsbrunner,
// "Fast software for box intersections", 2002), then exact predicates on each pair, where a
// pair sharing an edge or a vertex intersects only if it overlaps beyond it. CGAL 5.5 runs this
// on face graphs only, which cannot hold non-manifold soups; its soup version arrived later, so
// the same per-pair rules are applied here to the soup directly, with shared vertices found by
// exact coordinate equality.
#include "mesh/self_intersection.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <numeric>
#include <string>
#include <tuple>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>
#include <CGAL/intersections.h>

#include "core/error.h"

namespace strata {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_3;
using Point2 = Kernel::Point_2;
using Segment = Kernel::Segment_3;
using Triangle = Kernel::Triangle_3;
using Box = CGAL::Box_intersection_d::
    Box_with_info_d<double, 3, std::uint32_t, CGAL::Box_intersection_d::ID_FROM_BOX_ADDRESS>;

/// Thrown by the box callback to stop the search once enough pairs were found.
struct StopSearch {};

bool is_finite(const Vec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// CGAL's do_faces_intersect: triangles h and g (corner points and vertex ids, both
/// non-degenerate) intersect beyond the vertices and edges they share (equal ids).
bool faces_intersect(const std::array<const Point*, 3>& hp3,
                     const std::array<std::uint32_t, 3>& h,
                     const std::array<const Point*, 3>& gp3,
                     const std::array<std::uint32_t, 3>& g) {
    int shared = 0;
    int hi = -1, gj = -1;  // a shared corner (1 shared) or the unshared corner (2 shared)
    std::array<bool, 3> h_shared{}, g_shared{};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            if (h[i] == g[j]) {
                ++shared;
                h_shared[i] = g_shared[j] = true;
                hi = i;
                gj = j;
            }
        }
    }
    auto hp = [&](int k) -> const Point& { return *hp3[k % 3]; };
    auto gp = [&](int k) -> const Point& { return *gp3[k % 3]; };

    if (shared == 3) {
        return true;  // the same triangle twice
    }
    if (shared == 2) {
        // Overlap only if coplanar with the unshared corners on the same side of the edge.
        const int h_free = !h_shared[0] ? 0 : (!h_shared[1] ? 1 : 2);
        const int g_free = !g_shared[0] ? 0 : (!g_shared[1] ? 1 : 2);
        const Point& p = hp(h_free + 1);
        const Point& q = hp(h_free + 2);
        const Point& r = hp(h_free);
        const Point& s = gp(g_free);
        if (p.z() == q.z() && p.z() == r.z() && p.z() == s.z()) {
            // note: four points of one plane z = c (planar caps, whose pairs the 3D filters cannot
            // decide: exact coplanarity falls through to exact arithmetic); r and s lie on the
            // same side of pq in that plane iff they do in its xy projection.
            const Point2 p2(p.x(), p.y());
            const Point2 q2(q.x(), q.y());
            return CGAL::orientation(p2, q2, Point2(s.x(), s.y())) ==
                   CGAL::orientation(p2, q2, Point2(r.x(), r.y()));
        }
        return CGAL::coplanar(p, q, r, s) &&
               CGAL::coplanar_orientation(p, q, r, s) == CGAL::POSITIVE;
    }
    const Triangle th(hp(0), hp(1), hp(2));
    const Triangle tg(gp(0), gp(1), gp(2));
    if (shared == 1) {
        // Overlap beyond the shared corner only if an opposite side meets the other triangle.
        return CGAL::do_intersect(th, Segment(gp(gj + 1), gp(gj + 2))) ||
               CGAL::do_intersect(tg, Segment(hp(hi + 1), hp(hi + 2)));
    }
    return CGAL::do_intersect(th, tg);
}

/// The soup ready for testing: canonical vertex ids (one per distinct finite position) and a
/// box per testable triangle.
class Soup {
public:
    explicit Soup(const TriMesh& mesh) : mesh_(mesh) {
        const std::size_t n = mesh.positions.size();
        // Canonical id of a vertex: the smallest index with exactly the same finite position.
        canonical_.resize(n);
        std::iota(canonical_.begin(), canonical_.end(), std::uint32_t{0});
        std::vector<std::uint32_t> order;
        order.reserve(n);
        for (std::size_t v = 0; v < n; ++v) {
            if (is_finite(mesh.positions[v])) {
                order.push_back(static_cast<std::uint32_t>(v));
            }
        }
        auto key = [&](std::uint32_t v) {
            const Vec3& p = mesh.positions[v];
            return std::tuple(p.x, p.y, p.z, v);
        };
        std::sort(order.begin(), order.end(),
                  [&](std::uint32_t a, std::uint32_t b) { return key(a) < key(b); });
        for (std::size_t i = 1; i < order.size(); ++i) {
            if (mesh.positions[order[i]] == mesh.positions[order[i - 1]]) {
                canonical_[order[i]] = canonical_[order[i - 1]];
            }
        }

        points_.reserve(n);
        for (const Vec3& p : mesh.positions) {
            points_.emplace_back(p.x, p.y, p.z);
        }

        boxes_.reserve(mesh.triangles.size());
        for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
            const auto& tri = mesh.triangles[t];
            const bool testable =
                tri[0] < n && tri[1] < n && tri[2] < n && is_finite(mesh.positions[tri[0]]) &&
                is_finite(mesh.positions[tri[1]]) && is_finite(mesh.positions[tri[2]]) &&
                !CGAL::collinear(points_[tri[0]], points_[tri[1]], points_[tri[2]]);
            if (testable) {
                boxes_.emplace_back(
                    points_[tri[0]].bbox() + points_[tri[1]].bbox() + points_[tri[2]].bbox(),
                    static_cast<std::uint32_t>(t));
            } else {
                degenerate_.push_back(static_cast<std::uint32_t>(t));
            }
        }
    }

    const std::vector<std::uint32_t>& degenerate() const { return degenerate_; }

    /// Calls `report(t, u)` for every intersecting pair of testable triangles.
    template <class Report>
    void for_each_intersection(Report&& report) const {
        std::vector<const Box*> pointers;
        pointers.reserve(boxes_.size());
        for (const Box& box : boxes_) {
            pointers.push_back(&box);
        }
        // note: the cutoff is CGAL PMP's; below it, box subsets are compared pairwise.
        constexpr std::ptrdiff_t kCutoff = 2000;
        CGAL::box_self_intersection_d<CGAL::Sequential_tag>(
            pointers.begin(), pointers.end(),
            [&](const Box* a, const Box* b) {
                if (intersect(a->info(), b->info())) {
                    report(std::min(a->info(), b->info()), std::max(a->info(), b->info()));
                }
            },
            kCutoff);
    }

private:
    /// CGAL's do_faces_intersect on soup triangles (both non-degenerate).
    bool intersect(std::uint32_t t, std::uint32_t u) const {
        const auto& ht = mesh_.triangles[t];
        const auto& gt = mesh_.triangles[u];
        std::array<std::uint32_t, 3> h{}, g{};
        for (int k = 0; k < 3; ++k) {
            h[k] = canonical_[ht[k]];
            g[k] = canonical_[gt[k]];
        }
        return faces_intersect({&points_[ht[0]], &points_[ht[1]], &points_[ht[2]]}, h,
                               {&points_[gt[0]], &points_[gt[1]], &points_[gt[2]]}, g);
    }

    const TriMesh& mesh_;
    std::vector<std::uint32_t> canonical_;
    std::vector<Point> points_;
    std::vector<Box> boxes_;
    std::vector<std::uint32_t> degenerate_;
};

}  // namespace

SelfIntersections find_self_intersections(const TriMesh& mesh, std::size_t max_pairs) {
    SelfIntersections result;
    try {
        const Soup soup(mesh);
        result.degenerate_triangles = soup.degenerate();
        try {
            soup.for_each_intersection([&](std::uint32_t t, std::uint32_t u) {
                result.pairs.emplace_back(t, u);
                if (max_pairs != 0 && result.pairs.size() >= max_pairs) {
                    throw StopSearch{};
                }
            });
        } catch (const StopSearch&) {
            result.truncated = true;
        }
    } catch (const std::exception& e) {
        throw Error(ErrorCode::Internal, std::string("CGAL: self-intersection test of ") +
                                             std::to_string(mesh.triangles.size()) +
                                             " triangles: " + e.what());
    }
    std::sort(result.pairs.begin(), result.pairs.end());
    return result;
}

bool triangle_is_degenerate(const std::array<Vec3, 3>& t) {
    return CGAL::collinear(Point(t[0].x, t[0].y, t[0].z), Point(t[1].x, t[1].y, t[1].z),
                           Point(t[2].x, t[2].y, t[2].z));
}

bool triangles_intersect(const std::array<Vec3, 3>& a,
                         const std::array<std::uint32_t, 3>& a_ids,
                         const std::array<Vec3, 3>& b,
                         const std::array<std::uint32_t, 3>& b_ids) {
    std::array<Point, 3> pa, pb;
    for (int i = 0; i < 3; ++i) {
        pa[i] = Point(a[i].x, a[i].y, a[i].z);
        pb[i] = Point(b[i].x, b[i].y, b[i].z);
    }
    if (CGAL::collinear(pa[0], pa[1], pa[2]) || CGAL::collinear(pb[0], pb[1], pb[2])) {
        return true;
    }
    return faces_intersect({&pa[0], &pa[1], &pa[2]}, a_ids, {&pb[0], &pb[1], &pb[2]}, b_ids);
}

bool has_self_intersections(const TriMesh& mesh) {
    try {
        const Soup soup(mesh);
        if (!soup.degenerate().empty()) {
            return true;
        }
        try {
            soup.for_each_intersection([](std::uint32_t, std::uint32_t) { throw StopSearch{}; });
        } catch (const StopSearch&) {
            return true;
        }
    } catch (const std::exception& e) {
        throw Error(ErrorCode::Internal, std::string("CGAL: self-intersection test of ") +
                                             std::to_string(mesh.triangles.size()) +
                                             " triangles: " + e.what());
    }
    return false;
}

}  // namespace strata

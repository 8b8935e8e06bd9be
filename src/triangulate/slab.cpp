// Triangulation, one slab: the medial axis (t = 1/2), curvature points and refinement inserted
// as Steiner points until every surface face has its corner levels, then the slab's triangles,
// vertical triangles where contours cross and walls where they coincide.
#include <algorithm>
#include <cstddef>

#include "triangulate/detail/label_surface.h"

namespace strata::detail {

namespace {

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

}  // namespace

void LabelSurface::triangulate_slab(std::uint32_t k) {
    slab_rings_ = {SegmentGrid(rings_[k]), SegmentGrid(rings_[k + 1])};
    Cdt cdt;
    std::map<EdgeKey, EdgeOwner> owners;
    insert_rings(cdt, k, false, owners);
    insert_rings(cdt, k + 1, true, owners);
    const std::size_t unowned = flood_regions(cdt, k, owners);
    if (unowned != 0) {
        ++surface_.failed_slabs;
        issue(k, std::to_string(unowned) + " contour edges cross unexpectedly");
    }
    check_overlap_topology(cdt, k);
    if (!mismatched_slabs_.empty() && mismatch_seen_ != nullptr) {
        mismatch_seen_->store(true, std::memory_order_relaxed);
    }
    // note: a surface with a mismatched slab is not kept (TriangulateMode): its other slabs
    // need only their check
    if (mode_ == TriangulateMode::kMismatchesOnly ||
        (mode_ == TriangulateMode::kSurfaceIfMatched && mismatch_seen_ != nullptr &&
         mismatch_seen_->load(std::memory_order_relaxed))) {
        return;
    }

    steiner_t_.clear();
    steiner_band_.clear();
    steiner_id_.clear();
    steiner_xy_.clear();

    const std::vector<Point> medial = medial_points(cdt, k);
    if (!medial.empty()) {
        insert_steiners(cdt, medial, k, owners, "medial points");
    }
    insert_curvature_points(cdt, k, owners, medial);
    const bool valid = refine_slab(cdt, k, owners);
    std::map<const void*, std::array<std::uint32_t, 3>> emitted;
    const bool missing_face = emit_faces(cdt, k, emitted);
    const bool missing_vertical = emit_vertical_faces(cdt, k, emitted);
    if ((missing_face || missing_vertical) && valid) {
        ++surface_.failed_slabs;
        issue(k, "a surface vertex has no position on the slice it lies on");
    }
    ++surface_.slabs;
}

bool LabelSurface::in_surface_at(const Cdt& cdt, const Point& p, std::uint32_t k) const {
    Cdt::Locate_type type;
    int li = 0;
    const FaceHandle f = cdt.locate(p, type, li);
    return type == Cdt::FACE && in_surface(f, k);
}

/// The medial axis: the paper's correspondence curve, at t = 1/2 between the slices (the
/// thinned points of slab k's curves of this label that lie inside the surface's domain).
std::vector<Point> LabelSurface::medial_points(const Cdt& cdt, std::uint32_t k) const {
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
                if (in_surface_at(cdt, p, k)) {
                    medial.push_back(p);
                }
            }
        }
    }
    return medial;
}

void LabelSurface::insert_curvature_points(Cdt& cdt,
                                           std::uint32_t k,
                                           const std::map<EdgeKey, EdgeOwner>& owners,
                                           const std::vector<Point>& medial) {
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
                if (in_surface_at(cdt, q, k)) {
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
}

/// Refines until every surface face has its levels and no inner edge lies in a slice plane;
/// returns false (reported) when that did not happen in options.refine_rounds rounds.
bool LabelSurface::refine_slab(Cdt& cdt,
                               std::uint32_t k,
                               const std::map<EdgeKey, EdgeOwner>& owners) {
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
    return valid;
}

/// The slab's triangles over its surface faces, each corner at its level; `emitted` receives
/// each face's triangle. Returns whether a corner had no vertex.
bool LabelSurface::emit_faces(Cdt& cdt,
                              std::uint32_t k,
                              std::map<const void*, std::array<std::uint32_t, 3>>& emitted) {
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
                    const double z = z0 + steiner_t_[s] * d;
                    const double band = steiner_band_[s] * d;
                    free_heights_.push_back(
                        {std::uint32_t(steiner_id_[s]), z0, z0 + d, z - band, z + band});
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
    return missing;
}

/// Returns whether a vertex was missing.
bool LabelSurface::emit_vertical_faces(
    Cdt& cdt, std::uint32_t k, const std::map<const void*, std::array<std::uint32_t, 3>>& emitted) {
    std::vector<std::array<std::uint32_t, 3>>& out = surface_.mesh.triangles;
    bool missing = false;
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
    return missing;
}

}  // namespace strata::detail

#include "triangulate/surface.h"

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <mutex>
#include <numeric>
#include <string>
#include <utility>

#include <CGAL/Box_intersection_d/Box_with_info_d.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/box_intersection_d.h>

#include "contours/extract_contours.h"
#include "contours/simplify_contours.h"
#include "core/parallel.h"
#include "triangulate/detail/label_surface.h"

namespace strata {

namespace detail {

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

}  // namespace detail

namespace {

using detail::LabelSurface;
using detail::Levels;
using detail::split_slabs;

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

/// Builds one label's surface. Where simplified contours overlap in another pattern than the
/// pixels (the surface would get the wrong topology), the label's contours on both slices of
/// that slab are simplified again with vertices at pixel corners only (where they had
/// edge-midpoint vertices), then only their edges near the other slice's contours go back to the
/// original points, then all of them (exactly the pixel boundary, so the error bound holds
/// trivially); the label is built again each time, a few times at most.
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

#include "triangulate/surface.h"

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <iterator>
#include <memory>
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
#include "triangulate/relax_heights.h"

namespace strata {

SlabChecks::SlabChecks() = default;
SlabChecks::~SlabChecks() = default;

namespace detail {

LabelTriangulation LabelSurface::build() {
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
    // the simplified contours of each slice as checks_ holds them, and as they are now
    auto simplified = [&](std::size_t k) {
        std::vector<std::vector<std::uint32_t>> own;
        for (std::uint32_t c : label_contours_[k]) {
            own.push_back(contours_.slices[k].contours[c].simplified);
        }
        return own;
    };
    if (checks_ != nullptr) {
        if (!checks_->memo_) {
            checks_->memo_ = std::make_unique<SlabCheckMemo>();
        }
        SlabCheckMemo& memo = *checks_->memo_;
        memo.crossings.resize(slices);
        memo.crossings_known.resize(slices, false);
        memo.simplified.resize(slices);
        memo.mismatched.resize(slices, -1);
        memo.rings.resize(slices);
        same_simplified_.assign(slices, false);
        for (std::size_t k = 0; k < slices; ++k) {
            std::vector<std::vector<std::uint32_t>> now = simplified(k);
            same_simplified_[k] = memo.simplified[k] == now;
            memo.simplified[k] = std::move(now);
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
    std::atomic<bool> mismatch_seen{false};
    mismatch_seen_ = &mismatch_seen;
    triangulate_slabs();
    mismatch_seen_ = nullptr;
    if (mode_ == TriangulateMode::kMismatchesOnly ||
        (mode_ == TriangulateMode::kSurfaceIfMatched && !mismatched_slabs_.empty())) {
        return {std::move(surface_), std::move(mismatched_slabs_)};
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
    settle_end_leans();
    // Steiner heights unfolded, only in a surface the repair policy keeps (pipeline/repair.cpp):
    // without mismatches, or split at the AND layer.
    if (mismatched_slabs_.empty() || level_z_ != nullptr) {
        relax_fold_heights(surface_.mesh, free_heights_, options_.relax);
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
    return {std::move(surface_), std::move(mismatched_slabs_)};
}

void LabelSurface::triangulate_slabs() {
    std::vector<std::uint32_t> slabs;
    for (std::uint32_t k = 0; k + 1 < contours_.slices.size(); ++k) {
        if (!link_pieces_[k].empty()) {
            slabs.push_back(k);
        }
    }
    // note: a ring point's coordinates as doubles tighten once its exact value is known (a
    // crossing computed lazily); known from here on, the two slabs of a slice read the same
    // doubles whichever of them runs first. A point whose interval is one double already (a
    // contour vertex) has nothing to tighten: its exact value, which costs, is left alone.
    for (const std::vector<Ring>& slice : rings_) {
        for (const Ring& ring : slice) {
            for (const Point& p : ring.points) {
                const auto& approx = p.approx();
                if (approx.x().inf() != approx.x().sup() || approx.y().inf() != approx.y().sup()) {
                    CGAL::exact(p);
                }
            }
        }
    }
    const std::size_t before = mismatched_slabs_.size();
    // the slabs checked, and the mismatched ones of those checked before (checks_)
    std::vector<std::uint32_t> known;
    std::vector<std::uint32_t> checked = slabs;
    // note: build() made checks_'s memo and sized it
    if (checks_ != nullptr) {
        const SlabCheckMemo& memo = *checks_->memo_;
        if (mode_ == TriangulateMode::kMismatchesOnly) {
            std::vector<bool> same(rings_.size());
            for (std::size_t s = 0; s < rings_.size(); ++s) {
                same[s] = memo.rings[s].size() == rings_[s].size();
                for (std::size_t c = 0; same[s] && c < rings_[s].size(); ++c) {
                    same[s] = memo.rings[s][c] == rings_[s][c].points;
                }
            }
            checked.clear();
            for (const std::uint32_t k : slabs) {
                if (memo.mismatched[k] >= 0 && same[k] && same[k + 1]) {
                    if (memo.mismatched[k] == 1) {
                        known.push_back(k);
                    }
                } else {
                    checked.push_back(k);
                }
            }
        }
    }
    run_slabs(checked);
    if (checks_ != nullptr) {
        SlabCheckMemo& memo = *checks_->memo_;
        for (const std::uint32_t k : checked) {
            memo.mismatched[k] =
                std::binary_search(mismatched_slabs_.begin() + before, mismatched_slabs_.end(), k);
        }
        for (std::size_t s = 0; s < rings_.size(); ++s) {
            memo.rings[s].resize(rings_[s].size());
            for (std::size_t c = 0; c < rings_[s].size(); ++c) {
                memo.rings[s][c] = rings_[s][c].points;
            }
        }
        if (!known.empty()) {
            mismatched_slabs_.insert(mismatched_slabs_.end(), known.begin(), known.end());
            std::sort(mismatched_slabs_.begin() + before, mismatched_slabs_.end());
        }
    }
}

void LabelSurface::run_slabs(const std::vector<std::uint32_t>& slabs) {
    if (resolve_thread_count(options_.threads) <= 1 || slabs.size() < 2) {
        for (const std::uint32_t k : slabs) {
            triangulate_slab(k);
        }
        return;
    }
    // Each slab is built by a copy of this set-up (one per thread, reused) into a part: its new
    // vertices numbered from `base` on, its triangles, issues and Steiner heights. The parts are
    // appended in slab order, their new vertices renumbered as the serial loop numbers them.
    struct SlabPart {
        std::vector<Vec3> positions;
        std::vector<std::array<std::uint32_t, 3>> triangles;
        std::vector<SlabIssue> issues;
        std::vector<std::uint32_t> mismatched;
        std::vector<FreeHeightVertex> free_heights;
        std::uint32_t slabs = 0;
        std::uint32_t failed = 0;
        std::uint32_t steiner = 0;
        std::uint32_t mismatches = 0;
    };
    const auto base = std::uint32_t(surface_.mesh.positions.size());
    std::vector<SlabPart> parts(slabs.size());
    std::mutex idle_mutex;
    std::vector<std::unique_ptr<LabelSurface>> idle;
    parallel_for(slabs.size(), options_.threads, [&](std::size_t i) {
        std::unique_ptr<LabelSurface> worker;
        {
            const std::lock_guard<std::mutex> lock(idle_mutex);
            if (!idle.empty()) {
                worker = std::move(idle.back());
                idle.pop_back();
            }
        }
        if (!worker) {
            worker = std::make_unique<LabelSurface>(*this);
        }
        ObjectSurface& s = worker->surface_;
        s.mesh.positions.resize(base);
        s.mesh.triangles.clear();
        s.issues.clear();
        s.slabs = s.failed_slabs = s.steiner_points = s.topology_mismatches = 0;
        worker->mismatched_slabs_.clear();
        worker->free_heights_.clear();
        worker->triangulate_slab(slabs[i]);
        SlabPart& part = parts[i];
        part.positions.assign(s.mesh.positions.begin() + base, s.mesh.positions.end());
        part.triangles = std::move(s.mesh.triangles);
        part.issues = std::move(s.issues);
        part.mismatched = std::move(worker->mismatched_slabs_);
        part.free_heights = std::move(worker->free_heights_);
        part.slabs = s.slabs;
        part.failed = s.failed_slabs;
        part.steiner = s.steiner_points;
        part.mismatches = s.topology_mismatches;
        const std::lock_guard<std::mutex> lock(idle_mutex);
        idle.push_back(std::move(worker));
    });
    idle.clear();
    TriMesh& mesh = surface_.mesh;
    for (SlabPart& part : parts) {
        const auto shift = std::uint32_t(mesh.positions.size()) - base;
        mesh.positions.insert(mesh.positions.end(), part.positions.begin(), part.positions.end());
        for (std::array<std::uint32_t, 3> t : part.triangles) {
            for (std::uint32_t& v : t) {
                v += v >= base ? shift : 0;
            }
            mesh.triangles.push_back(t);
        }
        for (FreeHeightVertex& f : part.free_heights) {
            f.id += shift;
            free_heights_.push_back(f);
        }
        std::move(part.issues.begin(), part.issues.end(), std::back_inserter(surface_.issues));
        mismatched_slabs_.insert(mismatched_slabs_.end(), part.mismatched.begin(),
                                 part.mismatched.end());
        surface_.slabs += part.slabs;
        surface_.failed_slabs += part.failed;
        surface_.steiner_points += part.steiner;
        surface_.topology_mismatches += part.mismatches;
    }
}

}  // namespace detail

namespace {

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

}  // namespace

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
        detail::for_each_simplified_edge(c, [&](std::uint32_t e, Vec2 a, Vec2 b) {
            boxes.push_back(detail::segment_box<Box>(a, b, {contour, e}));
            segments.back().push_back(EdgeSegment(EdgePoint(a.x, a.y), EdgePoint(b.x, b.y)));
        });
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

LabelTriangulation triangulate_label(const SliceContours& contours,
                                     const std::vector<SliceDistanceFields>& fields,
                                     const std::vector<MedialAxis>& medial_axes,
                                     const TriangulateOptions& options,
                                     std::uint16_t label,
                                     TriangulateMode mode,
                                     SlabChecks* checks) {
    LabelTriangulation result =
        detail::LabelSurface(contours, fields, medial_axes, options, label, nullptr, mode, checks)
            .build();
    result.surface.contour_deviation_px = contour_deviation_px(contours, label);
    return result;
}

LabelTriangulation triangulate_label_split(const SliceStack& stack,
                                           const SliceContours& contours,
                                           const std::vector<SliceDistanceFields>& fields,
                                           const std::vector<MedialAxis>& medial_axes,
                                           const TriangulateOptions& options,
                                           std::uint16_t label,
                                           const std::vector<bool>& split) {
    const detail::Levels levels = detail::split_slabs(stack, contours, fields, medial_axes, label,
                                                      split, options.slice_spacing_px);
    LabelTriangulation result = detail::LabelSurface(levels.contours, levels.fields,
                                                     levels.medial_axes, options, label, &levels.z)
                                    .build();
    for (SlabIssue& issue : result.surface.issues) {
        issue.lower_slice = levels.slice_of[issue.lower_slice];
    }
    for (std::uint32_t& k : result.mismatched_slabs) {
        k = levels.slice_of[k];
    }
    result.surface.contour_deviation_px = contour_deviation_px(levels.contours, label);
    return result;
}

}  // namespace strata

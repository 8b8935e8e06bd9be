// The repair policy (repair.h): every step the pipeline takes where a stage cannot give its
// guarantee, in the order it is tried. The stages report what they could not do (the
// triangulation its mismatched slabs, the quantize stage a surface that does not snap); what is
// done about it is decided here alone.
#include "pipeline/repair.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <mutex>
#include <numeric>
#include <optional>
#include <utility>

#include "contours/simplify_contours.h"
#include "core/parallel.h"
#include "mesh/self_intersection.h"
#include "quantize/snap_to_grid.h"

namespace strata {

namespace {

/// What the steps on one slice of a mismatched slab need to know.
struct SliceRepairContext {
    std::uint16_t label = 0;
    const std::vector<SliceDistanceFields>& fields;
    SimplifyOptions corners;  ///< the contours' tolerance, vertices at pixel corners only
    double radius_px = 0.0;   ///< of kOriginalNearNeighbours
};

/// A step on one slice of a mismatched slab: changes the label's contours in `set` and returns
/// true, or returns false with `set` as it was (the step cannot help there: the next is tried).
using SliceRepair = bool (*)(SliceContourSet& set,
                             std::uint32_t slice,
                             const SliceRepairContext& context);

bool corner_vertices(SliceContourSet& set, std::uint32_t, const SliceRepairContext& context) {
    return resimplify_label(set, context.label, context.corners);
}

bool original_near_neighbours(SliceContourSet& set,
                              std::uint32_t slice,
                              const SliceRepairContext& context) {
    const SliceContourSet before = set;
    if (unsimplify_near_neighbours(set, context.label, context.fields, slice, context.radius_px)) {
        if (contours_clean(set, context.label)) {
            return true;
        }
        set = before;
    }
    return false;
}

bool original_contours(SliceContourSet& set, std::uint32_t, const SliceRepairContext& context) {
    for (Contour& c : set.contours) {
        if (c.label == context.label) {
            c.simplified.resize(c.points.size());
            std::iota(c.simplified.begin(), c.simplified.end(), 0u);
            c.edge_deviation_px.assign(c.points.size(), 0.0);
        }
    }
    return true;
}

/// kCornerVertices .. kOriginalContours, in the order of kRepairPolicy: each slice of a
/// mismatched slab goes one step further per attempt (a whole original slice left a row of
/// staircase notches between smooth neighbours, so it comes last); steps that change nothing
/// are skipped.
constexpr std::array<std::pair<RepairStep, SliceRepair>, 3> kSliceRepairs{{
    {RepairStep::kCornerVertices, &corner_vertices},
    {RepairStep::kOriginalNearNeighbours, &original_near_neighbours},
    {RepairStep::kOriginalContours, &original_contours},
}};
static_assert(kSliceRepairs[0].first == kRepairPolicy[0].step &&
              kSliceRepairs[1].first == kRepairPolicy[1].step &&
              kSliceRepairs[2].first == kRepairPolicy[2].step);

/// The contours, regions and links of `label` alone, contour indices renumbered (what the
/// repairs change and the triangulation of `label` reads, without the other labels' contours).
SliceContours label_contours(const SliceContours& contours, std::uint16_t label) {
    SliceContours own;
    own.width = contours.width;
    own.height = contours.height;
    own.tolerance_px = contours.tolerance_px;
    own.slices.resize(contours.slices.size());
    std::vector<std::int32_t> index;
    for (std::size_t k = 0; k < contours.slices.size(); ++k) {
        const SliceContourSet& set = contours.slices[k];
        SliceContourSet& out = own.slices[k];
        index.assign(set.contours.size(), -1);
        for (std::size_t c = 0; c < set.contours.size(); ++c) {
            if (set.contours[c].label == label) {
                index[c] = std::int32_t(out.contours.size());
                out.contours.push_back(set.contours[c]);
            }
        }
        auto renumber = [&](std::int32_t& c) {
            if (c >= 0) {
                c = index[std::size_t(c)];
            }
        };
        for (Contour& c : out.contours) {
            renumber(c.parent);
        }
        for (const SliceLabelRegions& regions : set.labels) {
            if (regions.label == label) {
                out.labels.push_back(regions);
                for (std::int32_t& c : out.labels.back().outer_contour) {
                    renumber(c);
                }
                for (std::int32_t& c : out.labels.back().hole_contour) {
                    renumber(c);
                }
            }
        }
    }
    for (const RegionLink& link : contours.links) {
        if (link.label == label) {
            own.links.push_back(link);
        }
    }
    return own;
}

/// Attempts of the slice steps on a label, at most (its slabs are checked again after each).
constexpr int kSliceRepairAttempts = 4;

/// One label's surface with the repairs of its mismatched slabs (kCornerVertices ..
/// kSplitAtAndLayer), recorded in `record`.
ObjectSurface triangulate_label_with_repairs(const SliceStack& stack,
                                             const SliceContours& contours,
                                             const std::vector<SliceDistanceFields>& fields,
                                             const std::vector<MedialAxis>& medial_axes,
                                             const TriangulateOptions& options,
                                             std::uint16_t label,
                                             RepairRecord& record) {
    record.label = label;
    // note: a surface with a mismatched slab is replaced, so only the last build (no mismatch
    // left) or the split one is finished; the others stop once a slab mismatches, and the
    // attempts' builds check the slabs' contours only (TriangulateMode)
    // note: each attempt checks again only the slabs whose rings changed (SlabChecks)
    SlabChecks checks;
    LabelTriangulation built = triangulate_label(contours, fields, medial_axes, options, label,
                                                 TriangulateMode::kSurfaceIfMatched, &checks);
    if (built.mismatched_slabs.empty()) {
        return std::move(built.surface);
    }
    std::vector<std::uint32_t> mismatched = std::move(built.mismatched_slabs);
    SliceContours repaired = label_contours(contours, label);
    SliceRepairContext context{label, fields, {}, unsimplify_radius_px(contours.tolerance_px)};
    context.corners.tolerance_px = contours.tolerance_px;
    context.corners.edge_midpoints = false;
    // Per slice: the slice steps tried so far (the next one to try).
    std::vector<std::size_t> tried(contours.slices.size(), 0);
    for (int attempt = 0; attempt < kSliceRepairAttempts && !mismatched.empty(); ++attempt) {
        for (const std::uint32_t k : mismatched) {
            for (const std::uint32_t slice : {k, k + 1}) {
                while (tried[slice] < kSliceRepairs.size()) {
                    const SliceRepair step = kSliceRepairs[tried[slice]++].second;
                    if (step(repaired.slices[slice], slice, context)) {
                        break;
                    }
                }
            }
        }
        mismatched = triangulate_label(repaired, fields, medial_axes, options, label,
                                       TriangulateMode::kMismatchesOnly, &checks)
                         .mismatched_slabs;
    }
    ObjectSurface surface;
    if (!mismatched.empty()) {
        std::vector<bool> split(contours.slices.size(), false);
        for (const std::uint32_t k : mismatched) {
            split[k] = true;
        }
        surface =
            triangulate_label_split(stack, repaired, fields, medial_axes, options, label, split)
                .surface;
        record.split_slabs = std::uint32_t(mismatched.size());
    } else {
        surface = triangulate_label(repaired, fields, medial_axes, options, label).surface;
    }
    for (std::uint32_t k = 0; k < tried.size(); ++k) {
        if (tried[k] > 2) {
            record.original_slices.push_back(k);
            continue;
        }
        if (tried[k] > 0) {
            record.corner_slices.push_back(k);
        }
        if (tried[k] > 1) {
            record.near_neighbour_slices.push_back(k);
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

RepairedSurfaces triangulate_with_repairs(const SliceStack& stack,
                                          const SliceContours& contours,
                                          const std::vector<SliceDistanceFields>& fields,
                                          const std::vector<MedialAxis>& medial_axes,
                                          const TriangulateOptions& options,
                                          const std::vector<std::uint16_t>& labels,
                                          unsigned threads,
                                          const ProgressFn& progress) {
    RepairedSurfaces result;
    result.surfaces.resize(labels.size());
    result.repairs.resize(labels.size());
    std::atomic<std::size_t> done{0};
    std::mutex progress_mutex;
    parallel_for(labels.size(), threads, [&](std::size_t i) {
        result.surfaces[i] = triangulate_label_with_repairs(stack, contours, fields, medial_axes,
                                                            options, labels[i], result.repairs[i]);
        if (progress) {
            const std::lock_guard lock(progress_mutex);
            progress("objects", ++done, labels.size());
        }
    });
    return result;
}

std::string quantize_with_repairs(const SliceStack& stack,
                                  double slice_spacing_px,
                                  const QuantizeOptions& options,
                                  bool verify,
                                  ObjectSurface& surface) {
    // note: the reference depends on the label alone: read once however many attempts
    std::optional<ReferenceTopology> reference;
    auto verify_once = [&](const SliceStack& in, ObjectSurface& s) {
        if (!reference) {
            reference = reference_topology(in, s.label);
        }
        verify_surface(*reference, s);
    };
    if (!options.enabled || surface.mesh.positions.empty()) {
        if (verify) {
            verify_once(stack, surface);
        }
        return {};
    }
    // note: files store the grid frame (grid_frame_positions), where snapped vertices are exact;
    // slice space (z = k d in doubles) can be a hair off it, so a vertex landing exactly on a
    // neighbour's edge, or a slab triangle snapped flat, shows only there. Empty: clean.
    auto grid_frame_problem = [&](const TriMesh& mesh, double grid_step) -> std::string {
        TriMesh grid = mesh;
        grid.positions = grid_frame_positions(mesh.positions, slice_spacing_px, grid_step);
        const SelfIntersections hits = find_self_intersections(grid, 1);
        if (!hits.pairs.empty()) {
            return "intersects itself in the stored grid frame";
        }
        if (!hits.degenerate_triangles.empty()) {
            return "has a degenerate triangle in the stored grid frame";
        }
        return {};
    };
    const TriMesh original = surface.mesh;
    std::string why;
    bool original_checked = false;
    double step = options.step;
    for (unsigned attempt = 0; attempt <= options.max_halvings; ++attempt, step /= 2.0) {
        GridSnap snap;
        if (!snap_to_grid(original, slice_spacing_px, step, snap, why)) {
            continue;
        }
        surface.mesh = std::move(snap.mesh);
        surface.grid_step = step;
        surface.grid_shift_px = snap.max_plane_shift_px;
        if (!verify) {
            // note: snapping may push nearly touching sheets through each other; without the
            // full verification, check that much (exact)
            if (has_self_intersections(surface.mesh)) {
                why = "the surface snapped to the grid of step " + std::to_string(step) +
                      " intersects itself";
                continue;
            }
            const std::string grid_problem = grid_frame_problem(surface.mesh, step);
            if (grid_problem.empty()) {
                return {};
            }
            why = "the surface snapped to the grid of step " + std::to_string(step) + " " +
                  grid_problem;
            continue;
        }
        verify_once(stack, surface);
        if (surface.verification.ok()) {
            const std::string grid_problem = grid_frame_problem(surface.mesh, step);
            if (grid_problem.empty()) {
                return {};
            }
            surface.verification.self_intersection_free = false;
            surface.verification.problem = "the surface " + grid_problem;
        }
        why = "the surface snapped to the grid of step " + std::to_string(step) +
              " failed verification: " + surface.verification.problem;
        if (!original_checked) {
            // note: a surface that fails unsnapped too keeps the triangulation's problem; snapping
            // finer cannot help then.
            ObjectSurface unsnapped = surface;
            unsnapped.mesh = original;
            verify_once(stack, unsnapped);
            original_checked = true;
            if (!unsnapped.verification.ok()) {
                surface = std::move(unsnapped);
                surface.grid_step = 0.0;
                surface.grid_shift_px = 0.0;
                return {};
            }
        }
    }
    surface.mesh = original;
    surface.grid_step = 0.0;
    surface.grid_shift_px = 0.0;
    if (verify) {
        verify_once(stack, surface);
    }
    return "kept unsnapped (no progressive export): " + why;
}

void rebuild_at_corners(const SliceStack& stack,
                        const RebuildOptions& options,
                        const std::vector<std::size_t>& redo,
                        Reconstruction& result,
                        std::vector<std::string>& unsnapped,
                        Report& report) {
    if (redo.empty()) {
        return;
    }
    std::vector<std::uint16_t> labels;
    SimplifyOptions corners;
    corners.tolerance_px = options.tolerance_px;
    corners.edge_midpoints = false;
    for (const std::size_t i : redo) {
        for (SliceContourSet& set : result.contours.slices) {
            resimplify_label(set, result.surfaces[i].label, corners);
        }
        labels.push_back(result.surfaces[i].label);
    }
    result.medial_axes = extract_medial_axes(result.contours, result.fields, options.medial);
    RepairedSurfaces rebuilt =
        triangulate_with_repairs(stack, result.contours, result.fields, result.medial_axes,
                                 options.triangulate, labels, options.threads, nullptr);
    for (std::size_t j = 0; j < redo.size(); ++j) {
        const std::size_t i = redo[j];
        const std::string first_try = unsnapped[i];
        result.surfaces[i] = std::move(rebuilt.surfaces[j]);
        result.repairs[i] = std::move(rebuilt.repairs[j]);
        result.repairs[i].rebuilt_at_corners = true;
        unsnapped[i] = quantize_with_repairs(stack, result.slice_spacing_px, options.quantize,
                                             options.verify, result.surfaces[i]);
        // note: the warning says how the retry ended (the quantize warning says so again when
        // it failed too)
        const std::string why = first_try.substr(first_try.find(": ") + 2);
        report.warn("contours", "label " + std::to_string(result.surfaces[i].label),
                    "could not be snapped to a grid with edge-midpoint contours (" + why +
                        "); built again with contour vertices at pixel corners only: " +
                        (unsnapped[i].empty() ? "snapped to the grid of step " +
                                                    std::to_string(result.surfaces[i].grid_step) +
                                                    " px, in the progressive model"
                                              : "still " + unsnapped[i]));
    }
}

}  // namespace strata

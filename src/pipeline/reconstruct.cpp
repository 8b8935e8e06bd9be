#include "pipeline/reconstruct.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <iterator>
#include <mutex>
#include <numeric>
#include <string_view>
#include <tuple>
#include <utility>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "core/cpu_time.h"
#include "core/parallel.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/repair.h"
#include "triangulate/reference_topology.h"

namespace strata {

namespace {

class StageClock {
public:
    explicit StageClock(std::vector<StageTiming>& timings) : timings_(timings) {}
    /// Adds the time since the last mark to `stage` (a stage run once per batch of labels sums).
    void done(std::string stage) {
        const auto now = std::chrono::steady_clock::now();
        const double seconds = std::chrono::duration<double>(now - last_).count();
        last_ = now;
        const double cpu_now = process_cpu_seconds();
        const double cpu_seconds = cpu_now - last_cpu_;
        last_cpu_ = cpu_now;
        for (StageTiming& t : timings_) {
            if (t.stage == stage) {
                t.seconds += seconds;
                t.cpu_seconds += cpu_seconds;
                return;
            }
        }
        timings_.push_back({std::move(stage), seconds, cpu_seconds});
    }

private:
    std::vector<StageTiming>& timings_;
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
    double last_cpu_ = process_cpu_seconds();
};

}  // namespace

double slice_spacing_px(const SliceStack& stack) {
    const Vec3 spacing = stack.spacing_mm();
    return spacing.z / spacing.x;
}

Vec3 slice_to_world(const SliceStack& stack, double slice_spacing_px, Vec3 p) {
    return stack.index_to_world.apply({p.x - 0.5, p.y - 0.5, p.z / slice_spacing_px});
}

double error_mm_per_px(const SliceStack& stack) {
    const Vec3 spacing = stack.spacing_mm();
    return std::max(spacing.x, spacing.y);
}

SliceFrame slice_frame(const SliceStack& stack, double slice_spacing_px) {
    SliceFrame frame;
    const Vec3 origin = slice_to_world(stack, slice_spacing_px, {0, 0, 0});
    frame.origin = {origin.x, origin.y, origin.z};
    const std::array<Vec3, 3> units{Vec3{1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}};
    for (int c = 0; c < 3; ++c) {
        const Vec3 column = slice_to_world(stack, slice_spacing_px, units[c]) - origin;
        for (int r = 0; r < 3; ++r) {
            frame.linear[3 * r + c] = column[r];
        }
    }
    frame.slice_spacing_px = slice_spacing_px;
    frame.error_mm_per_px = error_mm_per_px(stack);
    return frame;
}

TriMesh surface_to_world(const SliceStack& stack, double slice_spacing_px, const TriMesh& mesh) {
    TriMesh world = mesh;
    for (Vec3& p : world.positions) {
        p = slice_to_world(stack, slice_spacing_px, p);
    }
    if (stack.index_to_world.determinant() < 0.0) {
        for (auto& t : world.triangles) {
            std::swap(t[1], t[2]);
        }
    }
    return world;
}

void verify_surface(const SliceStack& stack, ObjectSurface& surface) {
    verify_surface(reference_topology(stack, surface.label), surface);
}

void verify_surface(const ReferenceTopology& reference, ObjectSurface& surface) {
    ObjectSurface::Verification& v = surface.verification;
    v = {};
    v.done = true;
    const MeshReport report = check_mesh(surface.mesh);
    v.closed_manifold = is_closed_manifold(report);
    v.outward = report.signed_volume > 0.0;
    v.reference = describe(reference);
    std::vector<int> expected;
    for (const ReferenceSurface& s : reference.surfaces) {
        expected.push_back(s.genus);
    }
    std::vector<int> genus;
    for (const MeshComponent& c : report.components) {
        genus.push_back(c.genus.value_or(-1));
    }
    std::sort(expected.begin(), expected.end());
    std::sort(genus.begin(), genus.end());
    v.topology_as_reference = v.closed_manifold && genus == expected;
    v.self_intersection_free = v.closed_manifold && !has_self_intersections(surface.mesh);
    if (!v.closed_manifold) {
        v.problem = report.problems.empty() ? "not a closed manifold" : report.problems.front();
    } else if (!v.outward) {
        v.problem = "the surface faces inwards";
    } else if (!v.self_intersection_free) {
        v.problem = "the surface intersects itself";
    } else if (!v.topology_as_reference) {
        v.problem =
            std::to_string(genus.size()) + " surface(s) where the reference has " + v.reference;
    }
}

namespace {

/// Frees the distance fields of `label` on every slice (they stay in place, empty).
/// note: other threads read other labels' fields meanwhile; the label member stays as it was.
void release_fields(std::vector<SliceDistanceFields>& fields, std::uint16_t label) {
    for (SliceDistanceFields& slice : fields) {
        for (DistanceField& field : slice.fields) {
            if (field.label == label) {
                field.node_offsets = {};
                field.block_bases = {};
                field.wide_values = {};
                field.sites = {};
                field.site_nodes = {};
                field.nx = field.ny = 0;
            }
        }
    }
}

/// Adds the medial axes of one batch of labels to those of the batches before it: curves are
/// merged by label (each label's in one batch, in their order), unmatched runs are sorted
/// again, so the result is what one pass over all labels gives.
void merge_medial_axes(std::vector<MedialAxis>& into, std::vector<MedialAxis>&& batch) {
    if (into.empty()) {
        into = std::move(batch);
        return;
    }
    for (std::size_t k = 0; k < into.size(); ++k) {
        MedialAxis& axis = into[k];
        const auto before = static_cast<std::ptrdiff_t>(axis.curves.size());
        std::move(batch[k].curves.begin(), batch[k].curves.end(), std::back_inserter(axis.curves));
        std::inplace_merge(
            axis.curves.begin(), axis.curves.begin() + before, axis.curves.end(),
            [](const MedialCurve& a, const MedialCurve& b) { return a.label < b.label; });
        std::move(batch[k].unmatched.begin(), batch[k].unmatched.end(),
                  std::back_inserter(axis.unmatched));
        std::sort(axis.unmatched.begin(), axis.unmatched.end(),
                  [](const UnmatchedRun& a, const UnmatchedRun& b) {
                      return std::tie(a.on_upper, a.contour, a.first) <
                             std::tie(b.on_upper, b.contour, b.first);
                  });
    }
}

/// What the batches of labels share: the per-label messages, in label order, and the progress
/// counters.
struct LabelRun {
    std::vector<std::uint16_t> labels;
    std::vector<std::string> unsnapped;
    std::vector<std::vector<Warning>> retried;  // the corner rebuilds' warnings, per label
    std::vector<std::string> kept;
    std::size_t checked = 0;
    std::size_t simplified = 0;
    std::mutex progress_mutex;
};

/// One batch of labels and what the stages after the contours make of it.
struct LabelBatch {
    std::vector<std::size_t> index;  ///< each label's place in LabelRun::labels, increasing
    std::vector<std::uint16_t> labels;
    const LabelBoxes* boxes = nullptr;  ///< of all labels, shared by the batches
    ProgressFn progress;
    MedialOptions medial_options;
    TriangulateOptions triangulate_options;
    std::vector<SliceDistanceFields> fields;
    std::vector<MedialAxis> axes;
    std::vector<ObjectSurface> surfaces;
    std::vector<RepairRecord> repairs;
    std::vector<MultiresMesh> models;
};

ContourOptions contour_options_of(const ReconstructOptions& options) {
    ContourOptions contour_options = options.contours;
    contour_options.threads = options.threads;
    if (!contour_options.progress) {
        contour_options.progress = options.progress;
    }
    return contour_options;
}

/// The places in `labels` by decreasing number of contour points (ties in label order): the
/// batches take the largest labels together, so that no batch waits for one large label while
/// the other threads have nothing left to do.
std::vector<std::size_t> largest_first(const SliceContours& contours,
                                       const std::vector<std::uint16_t>& labels) {
    const std::vector<std::int32_t> index = index_of_labels(labels);
    std::vector<std::size_t> points(labels.size(), 0);
    for (const SliceContourSet& set : contours.slices) {
        for (const Contour& c : set.contours) {
            if (index[c.label] >= 0) {
                points[std::size_t(index[c.label])] += c.points.size();
            }
        }
    }
    std::vector<std::size_t> order(labels.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return points[a] > points[b]; });
    return order;
}

/// The labels at `order[first]` on, at most `batch_size`, in label order, with their progress
/// reports prefixed by the batch's range when it is not all labels.
LabelBatch start_batch(const ReconstructOptions& options,
                       const std::vector<std::uint16_t>& labels,
                       const std::vector<std::size_t>& order,
                       std::size_t first,
                       std::size_t batch_size) {
    LabelBatch batch;
    batch.index.assign(
        order.begin() + static_cast<std::ptrdiff_t>(first),
        order.begin() + static_cast<std::ptrdiff_t>(std::min(first + batch_size, order.size())));
    std::sort(batch.index.begin(), batch.index.end());
    for (const std::size_t i : batch.index) {
        batch.labels.push_back(labels[i]);
    }
    std::string prefix;
    if (batch.labels.size() < labels.size()) {
        prefix = "labels " + std::to_string(first + 1) + "-" +
                 std::to_string(first + batch.labels.size()) + " of " +
                 std::to_string(labels.size()) + ": ";
    }
    if (options.progress) {
        batch.progress = [&options, prefix](std::string_view what, std::size_t done,
                                            std::size_t total) {
            options.progress(prefix + std::string(what), done, total);
        };
    }
    return batch;
}

/// Distance fields, medial axes and surfaces of the batch's labels.
void triangulate_batch(const SliceStack& stack,
                       const ReconstructOptions& options,
                       const Reconstruction& result,
                       StageClock& clock,
                       LabelBatch& batch) {
    DistanceOptions distance_options = options.distance;
    distance_options.threads = options.threads;
    distance_options.labels = batch.labels;
    distance_options.boxes = batch.boxes;
    if (!distance_options.progress) {
        distance_options.progress = batch.progress;
    }
    batch.fields = compute_distance_fields(stack, result.contours, distance_options);
    clock.done("distance");

    batch.medial_options = options.medial;
    batch.medial_options.threads = options.threads;
    batch.medial_options.labels = batch.labels;
    if (!batch.medial_options.progress) {
        batch.medial_options.progress = batch.progress;
    }
    batch.axes = extract_medial_axes(result.contours, batch.fields, batch.medial_options);
    clock.done("medial");

    batch.triangulate_options = options.triangulate;
    batch.triangulate_options.slice_spacing_px = result.slice_spacing_px;
    batch.triangulate_options.threads = options.threads;
    batch.triangulate_options.grid_step = options.quantize.enabled ? options.quantize.step : 0.0;
    batch.triangulate_options.grid_halvings = options.quantize.max_halvings;
    RepairedSurfaces repaired = triangulate_with_repairs(
        stack, result.contours, batch.fields, batch.axes, batch.triangulate_options, batch.labels,
        options.threads, batch.progress);
    batch.surfaces = std::move(repaired.surfaces);
    batch.repairs = std::move(repaired.repairs);
    clock.done("triangulate");
}

/// Contour vertices at pixel-edge midpoints can leave two surface vertices closer than the
/// finest grid; such a label (in `redo`) is built again from contours simplified at pixel
/// corners.
void rebuild_batch_at_corners(const SliceStack& stack,
                              const ReconstructOptions& options,
                              const ContourOptions& contour_options,
                              const std::vector<std::size_t>& redo,
                              Reconstruction& result,
                              LabelRun& run,
                              LabelBatch& batch) {
    // note: the rebuild reads and updates the contours, this batch's fields, axes
    // and surfaces; its warnings wait to be reported in label order
    Reconstruction part;
    part.contours = std::move(result.contours);
    part.fields = std::move(batch.fields);
    part.medial_axes = std::move(batch.axes);
    part.surfaces = std::move(batch.surfaces);
    part.repairs = std::move(batch.repairs);
    part.slice_spacing_px = result.slice_spacing_px;
    std::vector<std::string> part_unsnapped;
    for (const std::size_t i : batch.index) {
        part_unsnapped.push_back(run.unsnapped[i]);
    }
    Report part_report;
    rebuild_at_corners(
        stack,
        {contour_options.tolerance_px, batch.medial_options, batch.triangulate_options,
         options.quantize, options.verify, options.threads},
        redo, part, part_unsnapped, part_report);
    result.contours = std::move(part.contours);
    batch.fields = std::move(part.fields);
    batch.axes = std::move(part.medial_axes);
    batch.surfaces = std::move(part.surfaces);
    batch.repairs = std::move(part.repairs);
    for (std::size_t i = 0; i < batch.index.size(); ++i) {
        run.unsnapped[batch.index[i]] = std::move(part_unsnapped[i]);
    }
    // note: one warning per rebuilt label, in `redo` order
    for (std::size_t j = 0; j < part_report.warnings.size(); ++j) {
        const std::size_t i = batch.index[redo[std::min(j, redo.size() - 1)]];
        run.retried[i].push_back(std::move(part_report.warnings[j]));
    }
}

/// Quantizes and/or verifies the batch's surfaces, rebuilding at pixel corners those that
/// stayed unsnapped.
void verify_batch(const SliceStack& stack,
                  const ReconstructOptions& options,
                  const ContourOptions& contour_options,
                  const char* verify_stage,
                  Reconstruction& result,
                  LabelRun& run,
                  LabelBatch& batch) {
    const std::string stage = std::string(verify_stage) + " labels";
    std::vector<ObjectSurface>& surfaces = batch.surfaces;
    parallel_for(surfaces.size(), options.threads, [&](std::size_t i) {
        run.unsnapped[batch.index[i]] = quantize_with_repairs(
            stack, result.slice_spacing_px, options.quantize, options.verify, surfaces[i]);
        if (options.progress) {
            const std::lock_guard<std::mutex> lock(run.progress_mutex);
            options.progress(stage, ++run.checked, run.labels.size());
        }
    });
    std::vector<std::size_t> redo;
    for (std::size_t i = 0; i < surfaces.size(); ++i) {
        if (options.quantize.enabled && contour_options.edge_midpoints &&
            surfaces[i].grid_step == 0.0 && !run.unsnapped[batch.index[i]].empty()) {
            redo.push_back(i);
        }
    }
    if (!redo.empty()) {
        rebuild_batch_at_corners(stack, options, contour_options, redo, result, run, batch);
    }
}

/// The multiresolution model of each of the batch's surfaces; frees each label's distance
/// fields once its model is built unless they are kept.
void simplify_batch(const ReconstructOptions& options,
                    const Reconstruction& result,
                    LabelRun& run,
                    LabelBatch& batch) {
    const std::vector<ObjectSurface>& surfaces = batch.surfaces;
    std::vector<MultiresMesh>& models = batch.models;
    models.resize(surfaces.size());
    // note: the largest surfaces start first; each also spreads its groups over the
    // threads.
    std::vector<std::size_t> order(surfaces.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return surfaces[a].mesh.triangles.size() > surfaces[b].mesh.triangles.size();
    });
    parallel_for(order.size(), options.threads, [&](std::size_t n) {
        const std::size_t i = order[n];
        const ObjectSurface& surface = surfaces[i];
        const SliceErrorMeter meter(result.contours, batch.fields, surface.label,
                                    result.slice_spacing_px);
        MultiresOptions label_options = options.multires;
        label_options.progress = nullptr;
        label_options.threads = options.threads;
        label_options.grid_step = surface.grid_step;
        if (surface.verification.done && !surface.verification.ok()) {
            label_options.max_levels = 0;  // note: collapses assume a closed manifold
            run.kept[batch.index[i]] = "surface failed verification; kept at full resolution only";
        }
        models[i] = build_multires_mesh(surface.mesh, meter,
                                        surface.contour_deviation_px + surface.grid_shift_px,
                                        label_options);
        models[i].grid_step = surface.grid_step;
        if (!options.keep_fields) {
            release_fields(batch.fields, surface.label);
        }
        if (options.progress) {
            const std::lock_guard<std::mutex> lock(run.progress_mutex);
            options.progress("simplify labels", ++run.simplified, run.labels.size());
        }
    });
}

/// Moves the batch's results to their labels' places among all `labels` labels' results.
void append_batch(Reconstruction& result, std::size_t labels, LabelBatch& batch) {
    result.surfaces.resize(labels);
    result.repairs.resize(labels);
    for (std::size_t i = 0; i < batch.index.size(); ++i) {
        result.surfaces[batch.index[i]] = std::move(batch.surfaces[i]);
        result.repairs[batch.index[i]] = std::move(batch.repairs[i]);
    }
    if (!batch.models.empty()) {
        result.models.resize(labels);
        for (std::size_t i = 0; i < batch.index.size(); ++i) {
            result.models[batch.index[i]] = std::move(batch.models[i]);
        }
    }
    merge_medial_axes(result.medial_axes, std::move(batch.axes));
    if (result.fields.empty()) {
        // note: one batch when the fields are kept; else they are released, only the
        // slices' empty sets stay
        result.fields = std::move(batch.fields);
    }
}

/// Warnings in stage order, as one pass over all labels gives them.
void report_warnings(const SliceStack& stack,
                     const ReconstructOptions& options,
                     const Reconstruction& result,
                     LabelRun& run,
                     Report& report) {
    for (std::vector<Warning>& warnings : run.retried) {
        for (Warning& w : warnings) {
            report.warn(std::move(w.stage), std::move(w.where), std::move(w.message));
        }
    }
    for (std::size_t i = 0; i < run.labels.size(); ++i) {
        if (!run.unsnapped[i].empty()) {
            report.warn("quantize", "label " + std::to_string(run.labels[i]), run.unsnapped[i]);
        }
    }
    if (options.verify) {
        for (const ObjectSurface& surface : result.surfaces) {
            if (!surface.verification.ok()) {
                report.warn("verify", "label " + std::to_string(surface.label),
                            surface.verification.problem);
            }
        }
    }
    for (std::size_t i = 0; i < run.kept.size(); ++i) {
        if (!run.kept[i].empty()) {
            report.warn("simplify", "label " + std::to_string(run.labels[i]), run.kept[i]);
        }
    }
    for (const ObjectSurface& surface : result.surfaces) {
        for (const SlabIssue& issue : surface.issues) {
            report.warn("triangulate",
                        "label " + std::to_string(surface.label) + ", slices " +
                            std::to_string(issue.lower_slice) + "-" +
                            std::to_string(issue.lower_slice + 1),
                        issue.what);
        }
    }
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        if (result.contours.slices[k].contours.empty() && k > 0 && k + 1 < stack.depth &&
            !result.contours.slices[k - 1].contours.empty() &&
            !result.contours.slices[k + 1].contours.empty()) {
            report.warn("contours", "slice " + std::to_string(k),
                        "empty slice inside the stack: objects are split there");
        }
    }
}

}  // namespace

Reconstruction reconstruct(const SliceStack& stack,
                           const ReconstructOptions& options,
                           Report& report) {
    Reconstruction result;
    StageClock clock(result.timings);
    const ContourOptions contour_options = contour_options_of(options);
    result.contours = extract_contours(stack, contour_options);
    clock.done("contours");
    result.slice_spacing_px = slice_spacing_px(stack);

    // The labels go through the stages after the contours in batches of options.batch_labels
    // (all at once when the fields are kept): a batch's distance fields and medial axes are
    // freed before the next batch starts, so they take the memory of one batch, not of all
    // labels. Every stage works on each label alone: the output is the same for any batch size.
    LabelRun run;
    run.labels = contour_labels(result.contours);
    const std::size_t batch_size = options.keep_fields || options.batch_labels == 0
                                       ? std::max<std::size_t>(run.labels.size(), 1)
                                       : options.batch_labels;
    const char* verify_stage = options.quantize.enabled ? "quantize+verify" : "verify";
    run.unsnapped.resize(run.labels.size());
    run.retried.resize(run.labels.size());
    run.kept.resize(run.labels.size());
    // note: one scan of the stack for the label boxes, not one per batch
    const LabelBoxes boxes = compute_label_boxes(stack, result.contours, options.threads);
    const std::vector<std::size_t> order = largest_first(result.contours, run.labels);
    for (std::size_t first = 0; first < run.labels.size(); first += batch_size) {
        LabelBatch batch = start_batch(options, run.labels, order, first, batch_size);
        batch.boxes = &boxes;
        triangulate_batch(stack, options, result, clock, batch);
        if (options.quantize.enabled || options.verify) {
            verify_batch(stack, options, contour_options, verify_stage, result, run, batch);
            clock.done(verify_stage);
        }
        if (options.simplify) {
            simplify_batch(options, result, run, batch);
            clock.done("simplify");
        }
        count_medial_axes(batch.axes, result.contours, result.medial_counts);
        if (!options.keep_medial_axes) {
            batch.axes = {};
        }
        append_batch(result, run.labels.size(), batch);
#if defined(__GLIBC__)
        // note: the batch's fields and scratch were freed in the arenas of the threads that
        // used them; return those pages, or every thread's arena keeps its own high-water mark
        // (FreeSurfer at 2 threads: 100 MB more than at 1)
        malloc_trim(0);
#endif
    }
    if (result.fields.empty()) {
        result.fields.resize(stack.depth);
    }
    if (options.keep_medial_axes && result.medial_axes.empty() && stack.depth > 1) {
        result.medial_axes = extract_medial_axes(result.contours, result.fields, options.medial);
    }
    report_warnings(stack, options, result, run, report);
    return result;
}

}  // namespace strata

#include "pipeline/reconstruct.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <mutex>
#include <numeric>
#include <utility>

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
    void done(std::string stage) {
        const auto now = std::chrono::steady_clock::now();
        timings_.push_back({std::move(stage), std::chrono::duration<double>(now - last_).count()});
        last_ = now;
    }

private:
    std::vector<StageTiming>& timings_;
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
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
                field.node_sites = {};
                field.sites = {};
                field.site_nodes = {};
                field.nx = field.ny = 0;
            }
        }
    }
}

}  // namespace

Reconstruction reconstruct(const SliceStack& stack,
                           const ReconstructOptions& options,
                           Report& report) {
    Reconstruction result;
    StageClock clock(result.timings);
    ContourOptions contour_options = options.contours;
    contour_options.threads = options.threads;
    if (!contour_options.progress) {
        contour_options.progress = options.progress;
    }
    result.contours = extract_contours(stack, contour_options);
    clock.done("contours");

    DistanceOptions distance_options = options.distance;
    distance_options.threads = options.threads;
    if (!distance_options.progress) {
        distance_options.progress = options.progress;
    }
    result.fields = compute_distance_fields(stack, result.contours, distance_options);
    clock.done("distance");

    MedialOptions medial_options = options.medial;
    medial_options.threads = options.threads;
    if (!medial_options.progress) {
        medial_options.progress = options.progress;
    }
    result.medial_axes = extract_medial_axes(result.contours, result.fields, medial_options);
    clock.done("medial");

    TriangulateOptions triangulate_options = options.triangulate;
    triangulate_options.threads = options.threads;
    triangulate_options.slice_spacing_px = result.slice_spacing_px = slice_spacing_px(stack);
    if (!triangulate_options.progress) {
        triangulate_options.progress = options.progress;
    }
    result.surfaces = triangulate_with_repairs(stack, result.contours, result.fields,
                                               result.medial_axes, triangulate_options);
    clock.done("triangulate");
    if (options.quantize.enabled || options.verify) {
        std::vector<std::string> unsnapped(result.surfaces.size());
        std::size_t checked = 0;
        std::mutex checked_mutex;
        const char* stage = options.quantize.enabled ? "quantize+verify labels" : "verify labels";
        parallel_for(result.surfaces.size(), options.threads, [&](std::size_t i) {
            unsnapped[i] = quantize_with_repairs(stack, result.slice_spacing_px, options.quantize,
                                                 options.verify, result.surfaces[i]);
            if (options.progress) {
                const std::lock_guard<std::mutex> lock(checked_mutex);
                options.progress(stage, ++checked, result.surfaces.size());
            }
        });
        // Contour vertices at pixel-edge midpoints can leave two surface vertices closer than
        // the finest grid; such a label is built again from contours simplified at pixel corners.
        std::vector<std::size_t> redo;
        for (std::size_t i = 0; i < unsnapped.size(); ++i) {
            if (options.quantize.enabled && contour_options.edge_midpoints &&
                result.surfaces[i].grid_step == 0.0 && !unsnapped[i].empty()) {
                redo.push_back(i);
            }
        }
        rebuild_at_corners(stack,
                           {contour_options.tolerance_px, medial_options, triangulate_options,
                            options.quantize, options.verify},
                           redo, result, unsnapped, report);
        clock.done(options.quantize.enabled ? "quantize+verify" : "verify");
        for (std::size_t i = 0; i < unsnapped.size(); ++i) {
            if (!unsnapped[i].empty()) {
                report.warn("quantize", "label " + std::to_string(result.surfaces[i].label),
                            unsnapped[i]);
            }
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
    if (options.simplify) {
        result.models.resize(result.surfaces.size());
        MultiresOptions multires = options.multires;
        std::vector<std::string> kept(result.surfaces.size());
        std::size_t done = 0;
        std::mutex progress_mutex;
        // note: the largest surfaces start first; each also spreads its groups over the threads.
        std::vector<std::size_t> order(result.surfaces.size());
        std::iota(order.begin(), order.end(), std::size_t{0});
        std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
            return result.surfaces[a].mesh.triangles.size() >
                   result.surfaces[b].mesh.triangles.size();
        });
        parallel_for(order.size(), options.threads, [&](std::size_t n) {
            const std::size_t i = order[n];
            const ObjectSurface& surface = result.surfaces[i];
            const SliceErrorMeter meter(result.contours, result.fields, surface.label,
                                        result.slice_spacing_px);
            MultiresOptions label_options = multires;
            label_options.progress = nullptr;
            label_options.threads = options.threads;
            label_options.grid_step = surface.grid_step;
            if (surface.verification.done && !surface.verification.ok()) {
                label_options.max_levels = 0;  // note: collapses assume a closed manifold
                kept[i] = "surface failed verification; kept at full resolution only";
            }
            result.models[i] = build_multires_mesh(
                surface.mesh, meter, surface.contour_deviation_px + surface.grid_shift_px,
                label_options);
            result.models[i].grid_step = surface.grid_step;
            if (!options.keep_fields) {
                release_fields(result.fields, surface.label);
            }
            if (options.progress) {
                const std::lock_guard<std::mutex> lock(progress_mutex);
                options.progress("simplify labels", ++done, result.surfaces.size());
            }
        });
        clock.done("simplify");
        for (std::size_t i = 0; i < kept.size(); ++i) {
            if (!kept[i].empty()) {
                report.warn("simplify", "label " + std::to_string(result.surfaces[i].label),
                            kept[i]);
            }
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
    return result;
}

}  // namespace strata

// `strata extract` and `strata info`: a cut of every object within a bound, and what an input or
// a progressive file holds; their reports are cli/file_summaries.h.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli/build_summary.h"
#include "cli/command_support.h"
#include "cli/commands.h"
#include "cli/file_summaries.h"
#include "cli/output_folder.h"
#include "contours/contour_stats.h"
#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/report.h"
#include "core/version.h"
#include "debug/draw_contours.h"
#include "debug/draw_medial.h"
#include "exporters/detail/meshopt_scene.h"
#include "exporters/lod_gltf.h"
#include "exporters/progressive_gltf.h"
#include "exporters/read_progressive_gltf.h"
#include "exporters/scene_gltf.h"
#include "input/label_map_check.h"
#include "input/planar_contours.h"
#include "input/read_slice_stack.h"
#include "input/write_nifti.h"
#include "input/write_slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/mesh_io.h"
#include "mesh/shading_normals.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "pipeline/reconstruct_contours.h"

namespace strata::cli {

namespace {

/// sRGB encoding of a linear channel (IEC 61966-2-1), clamped to [0, 1].
double linear_to_srgb(double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}

/// The end of `strata extract`: writes the cut objects (a glTF scene, or one mesh file with a
/// label per triangle) and reports them (`summary`, whose output and warnings it fills in).
int write_extracted(const ExtractOptions& options,
                    const std::vector<SceneObject>& scene,
                    ExtractSummary summary,
                    const SceneInfo& info,
                    const Report& report) {
    TriMesh merged;
    for (const SceneObject& object : scene) {
        const std::uint32_t offset = static_cast<std::uint32_t>(merged.positions.size());
        merged.positions.insert(merged.positions.end(), object.mesh.positions.begin(),
                                object.mesh.positions.end());
        for (const auto& t : object.mesh.triangles) {
            merged.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
            merged.labels.push_back(object.label);
        }
    }
    if (merged.triangles.empty()) {
        throw Error(ErrorCode::InvalidInput, "extract: the input has no objects to extract");
    }
    if (is_gltf_path(options.output.string())) {
        write_scene_gltf(options.output, scene, info);
    } else {
        write_mesh(merged, options.output);
    }
    summary.output = options.output.string();
    summary.warnings = report.warnings;
    if (options.output_options.json) {
        std::cout << extract_json(summary).dump(2) << '\n';
    } else if (!options.output_options.quiet) {
        print_extract(std::cout, summary);
    }
    if (!options.output_options.quiet) {
        print_warnings(std::cerr, report.warnings);
    }
    return 0;
}

/// True when `a` and `b` are equal but for the case of ASCII letters.
bool same_text_ignoring_case(const std::string& a, const std::string& b) {
    return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](unsigned char x, unsigned char y) {
        return std::tolower(x) == std::tolower(y);
    });
}

/// `strata extract FILE.glb`: one cut of every object of a progressive file (or of those
/// `--labels` selects).
int extract_from_file(const ExtractOptions& options, const ErrorBound& bound) {
    if (bound.in_pixels) {
        throw Error(ErrorCode::InvalidInput,
                    "--max-error " + options.max_error +
                        ": a progressive file states its errors in millimetres; give the bound "
                        "in mm (e.g. 0.5mm)");
    }
    const ProgressiveFile file = read_progressive_gltf(options.input);
    const double max_error_m = bound.value / 1000.0;
    // --labels: each selector a label value ("6") or an object name (case-insensitive), as for
    // label stacks; one that matches no object is an error naming the available ones.
    std::vector<bool> wanted(file.objects.size(), options.labels.empty());
    for (const std::string& selector : options.labels) {
        bool found = false;
        for (std::size_t i = 0; i < file.objects.size(); ++i) {
            const ProgressiveFileObject& object = file.objects[i];
            if ((object.label >= 0 && std::to_string(object.label) == selector) ||
                same_text_ignoring_case(object.name, selector)) {
                wanted[i] = true;
                found = true;
            }
        }
        if (!found) {
            std::string available;
            for (const ProgressiveFileObject& object : file.objects) {
                available += (available.empty() ? "" : ", ") + std::to_string(object.label) + " (" +
                             object.name + ")";
            }
            throw Error(ErrorCode::InvalidInput,
                        "--labels: '" + selector + "' matches no object of " + options.input +
                            "; available: " + (available.empty() ? "none" : available));
        }
    }
    std::vector<SceneObject> scene;
    ExtractSummary summary;
    summary.max_error_mm = bound.value;
    Report report;
    for (std::size_t i = 0; i < file.objects.size(); ++i) {
        if (!wanted[i]) {
            continue;
        }
        const ProgressiveFileObject& object = file.objects[i];
        const MultiresCut cut = select_cut_by_error(object.model, max_error_m);
        SceneObject out;
        out.name = object.name;
        out.label = static_cast<std::uint16_t>(std::clamp<std::int64_t>(object.label, 0, 65535));
        out.srgb = {linear_to_srgb(object.base_color[0]), linear_to_srgb(object.base_color[1]),
                    linear_to_srgb(object.base_color[2])};
        out.mesh = file_cut_to_patient(object, cut);
        const MeshReport check = check_mesh(out.mesh);
        std::size_t full = 0;
        for (const MultiresCluster& c : object.model.clusters) {
            full += c.level == 0 ? c.triangles.size() : 0;
        }
        summary.objects.push_back({object.label, object.name, out.mesh.triangles.size(), full,
                                   cut.error_px * 1000.0, std::nullopt, is_closed_manifold(check)});
        if (cut.error_px > max_error_m) {
            report.warn("extract", object.name,
                        "the full-resolution surface already has an error of " +
                            std::to_string(cut.error_px * 1000.0) +
                            " mm, more than the bound asked for");
        }
        scene.push_back(std::move(out));
    }
    SceneInfo info;
    info.source = options.input;
    info.generator = kGenerator;
    return write_extracted(options, scene, std::move(summary), info, report);
}

/// `strata info FILE.glb`: what a progressive file holds, per object and level.
int info_of_file(const InfoOptions& options) {
    const ProgressiveFile file = read_progressive_gltf(options.input);
    FileInfo info{options.input, file.generator, file.total_bytes, {}};
    for (const ProgressiveFileObject& object : file.objects) {
        FileObjectInfo o{object.name,
                         object.label,
                         object.model.positions.size(),
                         object.model.groups.size(),
                         object.base_bytes,
                         {}};
        for (std::uint32_t level = 0; level < level_count(object.model); ++level) {
            const MultiresCut cut = select_cut_at_level(object.model, level);
            std::size_t triangles = 0;
            for (const std::uint32_t c : cut.clusters) {
                triangles += object.model.clusters[c].triangles.size();
            }
            o.levels.push_back({level, triangles, cut.clusters.size(), cut.error_px * 1000.0,
                                cut.fine_error_px * 1000.0,
                                level < object.level_bytes.size() ? object.level_bytes[level] : 0});
        }
        info.objects.push_back(std::move(o));
    }
    if (options.output.json) {
        std::cout << file_info_json(info).dump(2) << '\n';
    } else if (!options.output.quiet) {
        print_file_info(std::cout, info);
    }
    return 0;
}

/// `strata info` of planar contours (RTSTRUCT, contour JSON): every structure as read and cleaned.
int info_of_contours(const InfoOptions& options) {
    Report report;
    const PlanarContours contours = clean_planar_contours(read_raw_contours(options.input, ""),
                                                          ContourCleaningOptions{}, report);
    ContoursInfo info = summarize_contours(contours);
    info.warnings = report.warnings;
    if (options.output.json) {
        std::cout << contours_info_json(info).dump(2) << '\n';
        return 0;
    }
    if (options.output.quiet) {
        return 0;
    }
    print_contours_info(std::cout, info);
    print_warnings(std::cerr, report.warnings);
    return 0;
}

}  // namespace

int run_info(const InfoOptions& options) {
    if (is_gltf_path(options.input)) {
        return info_of_file(options);
    }
    if (is_planar_contour_file(options.input)) {
        return info_of_contours(options);
    }
    Report report;
    ReadOptions read;
    read.spacing_mm = options.spacing_mm;
    read.color_table = options.color_table;
    read.allowed_data_file = options.allow_data_file;
    TerminalProgress progress(options.output.quiet || options.output.json);
    read.progress = progress.callback();
    const SliceStack stack = read_slice_stack(options.input, read, report);
    progress.finish();
    if (options.output.json) {
        Json j = input_json(summarize_input(stack));
        j["warnings"] = warnings_json(report.warnings);
        std::cout << j.dump(2) << '\n';
    } else if (!options.output.quiet) {
        print_input(std::cout, summarize_input(stack));
        print_warnings(std::cerr, report.warnings);
    }
    return 0;
}

int run_extract(const ExtractOptions& options) {
    Report report;
    TerminalProgress progress(options.output_options.quiet || options.output_options.json);
    std::string extension = options.output.extension().string();
    std::transform(extension.begin(), extension.end(), extension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    const bool to_gltf = extension == ".glb" || extension == ".gltf";
    if (!to_gltf && extension != ".ply" && extension != ".obj" && extension != ".stl") {
        throw Error(ErrorCode::InvalidInput, "extract: output '" + options.output.string() +
                                                 "' has no known extension; expected .ply, "
                                                 ".obj, .stl, .glb or .gltf");
    }
    const ErrorBound bound = parse_error_bound(options.max_error);
    {
        // note: checked before any work, not after the whole pipeline ran
        std::error_code ec;
        const auto type = std::filesystem::status(options.output, ec).type();
        if (type != std::filesystem::file_type::not_found &&
            type != std::filesystem::file_type::regular) {
            throw Error(ErrorCode::InvalidInput,
                        "extract: -o " + options.output.string() +
                            " exists and is not a regular file (a folder?), expected a file name");
        }
    }
    if (is_gltf_path(options.input)) {
        return extract_from_file(options, bound);
    }
    const SliceStack stack = load_stack(options.input, options.phantom, options.spacing_mm,
                                        options.color_table, options.labels, progress, report,
                                        options.allow_data_file, options.force_label_map);
    ReconstructOptions reconstruct_options;
    reconstruct_options.contours.tolerance_px = options.tolerance_px;
    reconstruct_options.threads = options.threads;
    reconstruct_options.progress = progress.callback();
    const Reconstruction result = reconstruct(stack, reconstruct_options, report);
    progress.finish();

    const double mm_per_px = error_mm_per_px(stack);
    const double max_error_px = bound.in_pixels ? bound.value : bound.value / mm_per_px;
    std::vector<SceneObject> scene;
    ExtractSummary summary;
    summary.max_error_mm = max_error_px * mm_per_px;
    for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
        const MultiresMesh& model = result.models[i];
        const MultiresCut cut = select_cut_by_error(model, max_error_px);
        SceneObject object = scene_object(stack, result.surfaces[i].label);
        object.mesh = surface_to_world(stack, result.slice_spacing_px, cut_mesh(model, cut));
        const MeshReport check = check_mesh(object.mesh);
        summary.objects.push_back({object.label, object.name, object.mesh.triangles.size(),
                                   result.surfaces[i].mesh.triangles.size(),
                                   cut.error_px * mm_per_px, cut.error_px,
                                   is_closed_manifold(check)});
        if (cut.error_px > max_error_px) {
            report.warn("extract", object.name,
                        "the full-resolution surface already has an error of " +
                            std::to_string(cut.error_px * mm_per_px) +
                            " mm, more than the bound asked for");
        }
        scene.push_back(std::move(object));
    }
    SceneInfo info;
    info.source = stack.source;
    const Vec3 spacing = stack.spacing_mm();
    info.spacing_mm = {spacing.x, spacing.y, spacing.z};
    info.generator = kGenerator;
    return write_extracted(options, scene, std::move(summary), info, report);
}

}  // namespace strata::cli

#include "cli/commands.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <nlohmann/json.hpp>

#include "cli/build_summary.h"
#include "cli/command_support.h"
#include "cli/output_folder.h"
#include "contours/contour_stats.h"
#include "core/atomic_write.h"
#include "core/cpu_time.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/parallel.h"
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

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

Vec3 parse_spacing(const std::string& text) {
    Vec3 v;
    std::istringstream in(text);
    std::string part;
    int n = 0;
    while (std::getline(in, part, ',')) {
        if (n == 3) {
            n = 4;
            break;
        }
        std::size_t used = 0;
        double value = 0;
        try {
            value = std::stod(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used == 0 || used != part.size()) {
            throw Error(ErrorCode::InvalidInput, "--spacing: '" + part +
                                                     "' is not a number; expected X,Y,Z in mm, "
                                                     "e.g. 0.7,0.7,5");
        }
        v[n++] = value;
    }
    if (n != 3) {
        throw Error(ErrorCode::InvalidInput,
                    "--spacing: '" + text + "' expected three values X,Y,Z in mm, e.g. 0.7,0.7,5");
    }
    check_spacing(v, "--spacing");
    return v;
}

/// A file name stem from a structure name: lower case letters, digits and '_'.
std::string file_stem(const std::string& name) {
    std::string stem;
    for (const char c : name) {
        const auto u = static_cast<unsigned char>(c);
        stem += std::isalnum(u) ? char(std::tolower(u)) : '_';
    }
    return stem.empty() ? std::string("object") : stem;
}

SliceStack load_stack(const std::string& input,
                      const std::string& phantom,
                      const std::optional<Vec3>& spacing_mm,
                      const std::filesystem::path& color_table,
                      const std::vector<std::string>& labels,
                      TerminalProgress& progress,
                      Report& report,
                      const std::filesystem::path& allowed_data_file,
                      bool force_label_map) {
    SliceStack stack;
    if (input.empty()) {
        stack = make_phantom(phantom).stack;
        if (spacing_mm) {
            override_spacing(stack, *spacing_mm);
        }
    } else {
        const std::string lower = [&] {
            std::string l = input;
            std::transform(l.begin(), l.end(), l.begin(),
                           [](unsigned char c) { return char(std::tolower(c)); });
            return l;
        }();
        if (lower.ends_with(".glb") || lower.ends_with(".gltf")) {
            throw Error(ErrorCode::InvalidInput,
                        input +
                            ": a glTF file is an output of strata, not a label stack; give the "
                            "label stack (`strata info` and `strata extract` read glTF files)");
        }
        ReadOptions read;
        read.spacing_mm = spacing_mm;
        read.color_table = color_table;
        read.allowed_data_file = allowed_data_file;
        read.progress = progress.callback();
        stack = read_slice_stack(input, read, report);
    }
    progress.finish();
    if (!labels.empty()) {
        select_labels(stack, labels);
    } else if (!input.empty() && !force_label_map) {
        // note: before any work; a greyscale picture would otherwise build hundreds of speckles
        check_is_label_map(stack);
    }
    return stack;
}

/// Name and colour of a label from the stack's table (a generated name when absent).
SceneObject scene_object(const SliceStack& stack, std::uint16_t value) {
    const auto label = std::find_if(stack.label_table.begin(), stack.label_table.end(),
                                    [&](const LabelInfo& l) { return l.value == value; });
    SceneObject object;
    object.label = value;
    object.name = label != stack.label_table.end() ? label->name : "label " + std::to_string(value);
    if (label != stack.label_table.end()) {
        object.srgb = {label->color[0] / 255.0, label->color[1] / 255.0, label->color[2] / 255.0};
    }
    return object;
}

/// True for a .glb / .gltf path (strata's progressive files as input).
bool is_gltf_path(const std::string& input) {
    const std::string ext = lowercase_extension(input);
    return ext == ".glb" || ext == ".gltf";
}

namespace {

/// `stem`, or `stem_LABEL`, or `stem_LABEL_2`, ...: the first not in `taken` (two objects never
/// share a mesh file, whatever their names: "a" with value 12 beside an object named "a_12").
std::string unique_stem(const std::string& stem,
                        std::uint16_t label,
                        const std::vector<std::string>& taken) {
    const auto is_taken = [&](const std::string& s) {
        return std::find(taken.begin(), taken.end(), s) != taken.end();
    };
    if (!is_taken(stem)) {
        return stem;
    }
    const std::string with_label = stem + "_" + std::to_string(label);
    std::string candidate = with_label;
    for (int n = 2; is_taken(candidate); ++n) {
        candidate = with_label + "_" + std::to_string(n);
    }
    return candidate;
}

}  // namespace

ErrorBound parse_error_bound(const std::string& text) {
    ErrorBound bound;
    std::string number = text;
    if (text.size() > 2 && text.ends_with("mm")) {
        number = text.substr(0, text.size() - 2);
    } else if (text.size() > 2 && text.ends_with("px")) {
        number = text.substr(0, text.size() - 2);
        bound.in_pixels = true;
    }
    std::size_t used = 0;
    try {
        bound.value = std::stod(number, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != number.size() || !std::isfinite(bound.value) || bound.value < 0.0) {
        throw Error(ErrorCode::InvalidInput,
                    "--max-error: '" + text +
                        "' is not an error bound; expected a non-negative number with mm or px, "
                        "e.g. 0.5mm or 2px");
    }
    return bound;
}

namespace {

/// `--lod-levels`: error bounds ("0.5mm,2mm,8mm", px allowed) or a count ("3"); none when empty.
struct LodRequest {
    bool wanted = false;
    std::vector<ErrorBound> bounds;
    unsigned count = 0;
};

LodRequest parse_lod_levels(const std::string& text) {
    LodRequest request;
    if (text.empty()) {
        return request;
    }
    request.wanted = true;
    const auto bad = [&](const std::string& why) {
        return Error(ErrorCode::InvalidInput,
                     "--lod-levels: '" + text + "' " + why +
                         "; expected increasing error bounds with mm or px (e.g. 0.5mm,2mm,8mm) "
                         "or a number of levels from 1 to 32 (e.g. 3)");
    };
    if (text.find_first_not_of("0123456789") == std::string::npos) {
        const unsigned long count = text.size() > 3 ? 0 : std::stoul(text);
        if (count < 1 || count > 32) {
            throw bad("is not a level count");
        }
        request.count = static_cast<unsigned>(count);
        return request;
    }
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) {
        try {
            request.bounds.push_back(parse_error_bound(item));
        } catch (const Error&) {
            throw bad("has a bound '" + item + "' that is not a number with mm or px");
        }
    }
    if (request.bounds.empty() || text.back() == ',') {
        throw bad("has an empty bound");
    }
    for (std::size_t i = 1; i < request.bounds.size(); ++i) {
        const ErrorBound& a = request.bounds[i - 1];
        const ErrorBound& b = request.bounds[i];
        if (a.in_pixels == b.in_pixels && !(b.value > a.value)) {
            throw bad("is not increasing");  // before the reconstruction; mixed units: after it
        }
    }
    return request;
}

/// Writes OUTPUT/lods.glb for `request`; returns its summary.
LodSummary write_lods(const BuildOptions& options,
                      const LodRequest& request,
                      const std::vector<ProgressiveObject>& progressive,
                      const SliceFrame& frame,
                      const SceneInfo& info,
                      const StagedOutputFolder& out) {
    LodOptions lod;
    lod.level_count = request.count;
    for (const ErrorBound& b : request.bounds) {
        lod.error_mm.push_back(b.in_pixels ? b.value * frame.error_mm_per_px : b.value);
    }
    for (std::size_t i = 1; i < lod.error_mm.size(); ++i) {
        if (!(lod.error_mm[i] > lod.error_mm[i - 1])) {
            throw Error(ErrorCode::InvalidInput,
                        "--lod-levels: '" + options.lod_levels + "': bound " +
                            std::to_string(i + 1) +
                            " is not larger than the one before; expected increasing bounds");
        }
    }
    lod.compression =
        options.lod_compression == "meshopt" ? LodCompression::Meshopt : LodCompression::Draco;
    std::vector<LodObject> objects;
    for (const ProgressiveObject& p : progressive) {
        objects.push_back({p.name, p.label, p.srgb, p.model});
    }
    LodSummary summary;
    summary.file = options.output_dir / "lods.glb";
    summary.compression = options.lod_compression;
    const LodStats stats = write_lod_gltf(out.staged(summary.file), objects, frame, info, lod);
    summary.total_bytes = stats.total_bytes;
    for (std::size_t o = 0; o < objects.size(); ++o) {
        summary.objects.push_back({objects[o].name, objects[o].label, stats.objects[o]});
    }
    return summary;
}

/// The input of `strata build` and the reconstruction of it.
struct BuildInput {
    SliceStack stack;
    Reconstruction result;
    double input_seconds = 0.0;      ///< reading and cleaning the input (wall)
    double input_cpu_seconds = 0.0;  ///< the same, process CPU time
};

/// Reads the input (a label stack, planar contours or the built-in phantom) and runs the
/// pipeline on it.
BuildInput read_and_reconstruct(const BuildOptions& options,
                                TerminalProgress& progress,
                                Report& report) {
    const auto start = Clock::now();
    const double cpu_start = process_cpu_seconds();
    ReconstructOptions reconstruct_options;
    reconstruct_options.contours.tolerance_px = options.tolerance_px;
    reconstruct_options.threads = options.threads;
    reconstruct_options.multires.cluster_triangles = options.cluster_triangles;
    reconstruct_options.batch_labels = options.batch_labels;
    if (options.grid_step > 0.0) {
        // note: exactly this grid; a surface that does not snap to it fails the build
        reconstruct_options.quantize.step = options.grid_step;
        reconstruct_options.quantize.max_halvings = 0;
    }
    reconstruct_options.progress = progress.callback();
    reconstruct_options.keep_fields = !options.debug_dir.empty();  // note: debug pictures read them
    reconstruct_options.keep_medial_axes = reconstruct_options.keep_fields;
    BuildInput in;
    if (!options.input.empty() && is_planar_contour_file(options.input)) {
        // Planar contours (RTSTRUCT, contour JSON): one reconstruction per structure, gathered
        // in the contours' common frame.
        PlanarContours contours =
            clean_planar_contours(read_raw_contours(options.input, options.reference_ct),
                                  ContourCleaningOptions{}, report);
        if (!options.labels.empty()) {
            select_contour_objects(contours, options.labels);
        }
        ContourGridOptions grid;
        grid.pitch_mm = options.contour_pitch_mm;
        ContourFrame frame = contour_frame(contours, grid, report);
        in.input_seconds = seconds_since(start);
        in.input_cpu_seconds = process_cpu_seconds() - cpu_start;
        in.result = reconstruct_contours(contours, frame, grid, reconstruct_options, report);
        in.stack = std::move(frame.stack);
    } else {
        if (!options.reference_ct.empty() || options.contour_pitch_mm > 0.0) {
            throw Error(ErrorCode::InvalidInput,
                        "--reference-ct and --contour-pitch apply to planar contour input "
                        "(DICOM RTSTRUCT or contour JSON), not to '" +
                            options.input + "'");
        }
        in.stack = load_stack(options.input, options.phantom, options.spacing_mm,
                              options.color_table, options.labels, progress, report,
                              options.allow_data_file, options.force_label_map);
        in.input_seconds = seconds_since(start);
        in.input_cpu_seconds = process_cpu_seconds() - cpu_start;
        in.result = reconstruct(in.stack, reconstruct_options, report);
    }
    progress.finish();
    return in;
}

/// --debug-dir: the contours of every slice and the medial axis of every slice pair as PNGs.
void write_debug_pictures(const std::filesystem::path& debug_dir,
                          const SliceStack& stack,
                          const Reconstruction& result,
                          const StagedOutputFolder& out) {
    if (debug_dir.empty() || stack.depth == 0) {
        return;
    }
    const DebugView view = debug_view(stack);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        char name[48];
        std::snprintf(name, sizeof(name), "contours_%04u.png", k);
        write_rgb_png(draw_slice_contours(stack, result.contours, k, view),
                      out.staged(debug_dir / name));
    }
    for (std::uint32_t k = 0; k + 1 < stack.depth; ++k) {
        char name[48];
        std::snprintf(name, sizeof(name), "medial_%04u_%04u.png", k, k + 1);
        write_rgb_png(
            draw_medial_axis(result.contours.slices[k], result.contours.slices[k + 1],
                             result.fields[k], result.fields[k + 1], result.medial_axes[k], view),
            out.staged(debug_dir / name));
    }
}

/// What the files of `stack` say they were made by and from.
SceneInfo scene_info(const SliceStack& stack) {
    SceneInfo info;
    info.source = stack.source;
    const Vec3 spacing = stack.spacing_mm();
    info.spacing_mm = {spacing.x, spacing.y, spacing.z};
    info.generator = kGenerator;
    return info;
}

/// Per surface: its mesh in patient LPS mm written to OUTPUT/meshes/, and its summary (checked
/// in mm, with the levels of its model). Returns the scene objects, one per surface; the
/// slice-space surfaces' meshes are freed as their world meshes are made (nothing after the
/// export reads them).
std::vector<SceneObject> write_surface_meshes(const BuildOptions& options,
                                              const SliceStack& stack,
                                              Reconstruction& result,
                                              const StagedOutputFolder& out,
                                              BuildSummary& summary,
                                              Report& report) {
    const std::size_t n = result.surfaces.size();
    std::vector<SceneObject> scene(n);
    std::vector<std::string> stems;
    std::vector<std::filesystem::path> mesh_files;
    for (std::size_t i = 0; i < n; ++i) {
        scene[i] = scene_object(stack, result.surfaces[i].label);
        stems.push_back(unique_stem(file_stem(scene[i].name), scene[i].label, stems));
        mesh_files.push_back(options.output_dir / "meshes" /
                             (stems.back() + "." + options.mesh_format));
    }
    // note: each object's world mesh, checks, normals and file depend on it alone: the objects
    // go over the threads, the summaries and warnings follow in object order
    std::vector<MeshReport> checks(n);
    parallel_for(n, options.threads, [&](std::size_t i) {
        SceneObject& object = scene[i];
        object.mesh = surface_to_world(stack, result.slice_spacing_px, result.surfaces[i].mesh);
        result.surfaces[i].mesh = {};
        checks[i] = check_mesh(object.mesh);
        if (!object.mesh.triangles.empty()) {
            // note: the normals stay for scene.glb, which would compute the same again
            object.normals = shading_normals(object.mesh);
            write_mesh(object.mesh, out.staged(mesh_files[i]),
                       options.mesh_format == "stl" ? std::vector<Vec3>{} : object.normals);
        }
    });
    const double mm_per_px = error_mm_per_px(stack);
    for (std::size_t i = 0; i < n; ++i) {
        const ObjectSurface& surface = result.surfaces[i];
        const SceneObject& object = scene[i];
        const MeshReport& check = checks[i];
        SurfaceSummary s = summarize_surface(surface, result.repairs[i], check, mesh_files[i]);
        if (i < result.models.size()) {
            s.levels = summarize_levels(result.models[i], mm_per_px);
            s.groups = result.models[i].groups.size();
        }
        if (!s.closed_manifold) {
            report.warn("triangulate", object.name,
                        "the surface is not a closed manifold: " + check.problems.front());
        }
        summary.surfaces.push_back(std::move(s));
    }
    return scene;
}

}  // namespace

int run_build(const BuildOptions& options) {
    // note: the output folder is checked and locked before any work; every output goes into
    // its staging folder, which replaces it at the end (all or nothing)
    StagedOutputFolder out(options.output_dir);
    const LodRequest lod_request = parse_lod_levels(options.lod_levels);
    Report report;
    TerminalProgress progress(options.output.quiet || options.output.json);
    BuildInput in = read_and_reconstruct(options, progress, report);
    const SliceStack& stack = in.stack;
    Reconstruction& result = in.result;
    write_debug_pictures(options.debug_dir, stack, result, out);

    BuildSummary summary;
    summary.input = summarize_input(stack);
    summary.tolerance_px = result.contours.tolerance_px;
    summary.contour_stats = contour_stats(result.contours);
    summary.objects = summarize_objects(stack, result, summary.contour_stats);
    summary.slice_spacing_px = result.slice_spacing_px;
    summary.output_dir = options.output_dir;
    // note: the export reads the surfaces and models only: the contours, fields and medial
    // axes go now (the peak memory of a build is in its export)
    result.contours.slices = {};
    result.contours.links = {};
    result.fields = {};
    result.medial_axes = {};

    // Surfaces: one mesh file per object, the full-resolution scene as a plain glTF, and the
    // progressive scene. Each holds only what it writes: the world meshes go once scene.glb is
    // written, before the progressive scene's encodings are made.
    const auto export_start = Clock::now();
    const double export_cpu_start = process_cpu_seconds();
    std::vector<SceneObject> scene =
        write_surface_meshes(options, stack, result, out, summary, report);
    const SceneInfo info = scene_info(stack);
    const std::filesystem::path scene_file = options.output_dir / "scene.glb";
    std::vector<bool> has_triangles(scene.size());
    for (std::size_t i = 0; i < scene.size(); ++i) {
        has_triangles[i] = !scene[i].mesh.triangles.empty();
    }
    const bool any_triangles =
        std::find(has_triangles.begin(), has_triangles.end(), true) != has_triangles.end();
    if (any_triangles) {
        if (options.scene_meshopt) {
            detail::write_meshopt_scene(out.staged(scene_file), scene,
                                        info);  // EXT_meshopt_compression
        } else {
            SceneGltfOptions scene_options;
            scene_options.draco = !options.scene_uncompressed;
            scene_options.threads = options.threads;
            write_scene_gltf(out.staged(scene_file), scene, info, scene_options);
        }
        summary.scene = scene_file;
    }
    for (SceneObject& object : scene) {
        object.mesh = {};
        object.normals = {};
    }
#if defined(__GLIBC__)
    malloc_trim(0);  // note: return the freed pages before the progressive scene's encodings
#endif
    // The progressive scene: every object whose surface lies on a grid (all but those the
    // quantize stage had to leave unsnapped, which the report names).
    std::vector<ProgressiveObject> progressive;
    for (std::size_t i = 0; i < result.models.size() && i < scene.size(); ++i) {
        if (!has_triangles[i]) {
            continue;
        }
        if (!(result.models[i].grid_step > 0.0)) {
            // note: every object of the input is in every output, or the build fails; the
            // quantize stage's warning says why
            std::string why;
            for (const Warning& w : report.warnings) {
                if (w.stage == "quantize" && w.where == "label " + std::to_string(scene[i].label)) {
                    why = " (" + w.message + ")";
                }
            }
            throw Error(ErrorCode::Internal, "export: " + scene[i].name + " (label " +
                                                 std::to_string(scene[i].label) +
                                                 "): its surface is not on a grid" + why +
                                                 ", so it cannot be in model." +
                                                 options.model_format + "; no outputs written");
        }
        ProgressiveObject object;
        object.name = scene[i].name;
        object.label = scene[i].label;
        object.srgb = scene[i].srgb;
        object.volume_ml = summary.surfaces[i].volume_ml;
        object.model = &result.models[i];
        progressive.push_back(object);
    }
    const SliceFrame frame = slice_frame(stack, result.slice_spacing_px);
    if (!progressive.empty()) {
        ModelSummary model;
        model.file = options.output_dir / ("model." + options.model_format);
        model.objects = progressive.size();
        ProgressiveOptions export_options;
        export_options.threads = options.threads;
        model.stats = write_progressive_gltf(out.staged(model.file), progressive, frame, info,
                                             export_options);
        summary.model = model;
    }
    if (lod_request.wanted && !progressive.empty()) {
        summary.lods = write_lods(options, lod_request, progressive, frame, info, out);
    }
    const double export_seconds = seconds_since(export_start);
    const double export_cpu_seconds = process_cpu_seconds() - export_cpu_start;

    summary.timings.push_back({"input", in.input_seconds, in.input_cpu_seconds});
    for (const StageTiming& t : result.timings) {
        summary.timings.push_back({t.stage, t.seconds, t.cpu_seconds});
    }
    summary.timings.push_back({"export", export_seconds, export_cpu_seconds});
    summary.warnings = report.warnings;
    summary.summary_file = options.output_dir / kSummaryFileName;
    const std::string summary_text = build_summary_json(summary);
    write_file_atomically(out.staged(summary.summary_file), summary_text);
    out.commit();

    if (options.output.json) {
        std::cout << summary_text;
    } else if (!options.output.quiet) {
        print_build_report(std::cout, summary);
    }
    if (!options.output.quiet) {
        print_warnings(std::cerr, report.warnings);
    }
    return 0;
}

int run_phantom(const PhantomCommandOptions& options) {
    if (options.list) {
        for (const std::string& name : phantom_names()) {
            std::cout << name << '\n';
        }
        for (const std::string& name : benchmark_phantom_names()) {
            std::cout << name << '\n';
        }
        return 0;
    }
    PhantomOptions phantom_options;
    phantom_options.pixel_mm = options.pixel_mm;
    phantom_options.slice_spacing_px = options.slice_spacing_px;
    const Phantom phantom = make_phantom(options.name, phantom_options);
    std::string written;
    if (options.format == "nifti") {
        std::filesystem::path file = options.output;
        const std::string name = file.filename().string();
        const bool has_ext = name.ends_with(".nii") || name.ends_with(".nii.gz");
        if (!has_ext) {
            file /= phantom.name + ".nii.gz";
        }
        write_nifti(phantom.stack, file);
        written = file.string();
    } else {
        write_png_stack(phantom.stack, options.output);
        written =
            (options.output / "slices").string() + " + " + (options.output / "meta.json").string();
    }
    if (options.output_options.json) {
        Json j;
        j["phantom"] = phantom.name;
        j["description"] = phantom.description;
        j["written"] = written;
        j["stack"] = input_json(summarize_input(phantom.stack));
        std::cout << j.dump(2) << '\n';
    } else if (!options.output_options.quiet) {
        std::cout << phantom.name << ": " << phantom.description << '\n';
        print_input(std::cout, summarize_input(phantom.stack));
        std::cout << "wrote " << written << '\n';
    }
    return 0;
}

}  // namespace strata::cli

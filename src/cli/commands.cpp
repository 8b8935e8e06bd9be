#include "cli/commands.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli/output_folder.h"
#include "contours/contour_stats.h"
#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/report.h"
#include "debug/draw_contours.h"
#include "debug/draw_medial.h"
#include "exporters/detail/meshopt_scene.h"
#include "exporters/lod_gltf.h"
#include "exporters/progressive_gltf.h"
#include "exporters/read_progressive_gltf.h"
#include "exporters/scene_gltf.h"
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

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

/// Progress on a terminal: one line on stderr rewritten in place, at most ~10 times a second.
class TerminalProgress {
public:
    explicit TerminalProgress(bool quiet) : enabled_(!quiet && ::isatty(STDERR_FILENO) != 0) {}
    ~TerminalProgress() { finish(); }

    ProgressFn callback() {
        if (!enabled_) {
            return {};
        }
        return [this](std::string_view what, std::size_t done, std::size_t total) {
            const auto now = Clock::now();
            if (done < total && now - last_ < std::chrono::milliseconds(100)) {
                return;
            }
            last_ = now;
            std::fprintf(stderr, "\rstrata: %.*s %zu/%zu", static_cast<int>(what.size()),
                         what.data(), done, total);
            std::fflush(stderr);
            open_ = true;
        };
    }
    void finish() {
        if (open_) {
            std::fputc('\n', stderr);
            open_ = false;
        }
    }

private:
    bool enabled_;
    bool open_ = false;
    Clock::time_point last_{};
};

struct LabelStats {
    std::uint64_t voxels = 0;
    std::uint32_t first_slice = 0;
    std::uint32_t last_slice = 0;
    std::uint32_t slices = 0;
};

std::vector<LabelStats> label_stats(const SliceStack& stack) {
    std::vector<int> index(65536, -1);
    for (std::size_t i = 0; i < stack.label_table.size(); ++i) {
        index[stack.label_table[i].value] = static_cast<int>(i);
    }
    std::vector<LabelStats> stats(stack.label_table.size());
    std::vector<std::uint32_t> last_seen(stats.size(), UINT32_MAX);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        for (std::uint16_t v : stack.slice(k)) {
            const int l = index[v];
            if (l < 0) {
                continue;
            }
            LabelStats& s = stats[l];
            if (s.voxels == 0) {
                s.first_slice = k;
            }
            ++s.voxels;
            if (last_seen[l] != k) {
                last_seen[l] = k;
                s.last_slice = k;
                ++s.slices;
            }
        }
    }
    return stats;
}

Json stack_json(const SliceStack& stack) {
    Json j;
    j["source"] = stack.source;
    j["source_frame"] = stack.source_frame;
    j["dims"] = {stack.width, stack.height, stack.depth};
    const Vec3 spacing = stack.spacing_mm();
    j["spacing_mm"] = {spacing.x, spacing.y, spacing.z};
    Json affine = Json::array();
    for (int r = 0; r < 3; ++r) {
        const auto& row = stack.index_to_world.linear[r];
        affine.push_back({row[0], row[1], row[2], stack.index_to_world.translation[r]});
    }
    affine.push_back({0, 0, 0, 1});
    j["index_to_world_lps_mm"] = affine;
    const double voxel_ml = spacing.x * spacing.y * spacing.z / 1000.0;
    const std::vector<LabelStats> stats = label_stats(stack);
    Json labels = Json::array();
    for (std::size_t i = 0; i < stack.label_table.size(); ++i) {
        const LabelInfo& l = stack.label_table[i];
        Json e;
        e["value"] = l.value;
        e["name"] = l.name;
        e["color_srgb"] = {l.color[0], l.color[1], l.color[2]};
        e["voxels"] = stats[i].voxels;
        e["slices"] = stats[i].slices;
        e["first_slice"] = stats[i].first_slice;
        e["last_slice"] = stats[i].last_slice;
        e["volume_ml"] = static_cast<double>(stats[i].voxels) * voxel_ml;
        labels.push_back(e);
    }
    j["labels"] = labels;
    return j;
}

Json warnings_json(const Report& report) {
    Json w = Json::array();
    for (const Warning& warning : report.warnings) {
        w.push_back(
            {{"stage", warning.stage}, {"where", warning.where}, {"message", warning.message}});
    }
    return w;
}

std::string format_vec(Vec3 v) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%g x %g x %g", v.x, v.y, v.z);
    return buf;
}

void print_stack(std::ostream& out, const SliceStack& stack) {
    out << "input:   " << stack.source << " (frame " << stack.source_frame << ")\n";
    out << "dims:    " << stack.width << " x " << stack.height << " x " << stack.depth << '\n';
    out << "spacing: " << format_vec(stack.spacing_mm()) << " mm\n";
    out << "affine (voxel index -> LPS mm):\n";
    for (int r = 0; r < 3; ++r) {
        char buf[160];
        const auto& row = stack.index_to_world.linear[r];
        std::snprintf(buf, sizeof(buf), "  [%10.5g %10.5g %10.5g | %10.5g]\n", row[0], row[1],
                      row[2], stack.index_to_world.translation[r]);
        out << buf;
    }
    const std::vector<LabelStats> stats = label_stats(stack);
    const Vec3 spacing = stack.spacing_mm();
    const double voxel_ml = spacing.x * spacing.y * spacing.z / 1000.0;
    out << "labels:  " << stack.label_table.size() << '\n';
    for (std::size_t i = 0; i < stack.label_table.size(); ++i) {
        const LabelInfo& l = stack.label_table[i];
        char buf[256];
        std::snprintf(buf, sizeof(buf),
                      "  %5u  %-32s  #%02x%02x%02x  %9llu voxels  slices %u-%u  %.2f mL\n",
                      unsigned(l.value), l.name.c_str(), l.color[0], l.color[1], l.color[2],
                      static_cast<unsigned long long>(stats[i].voxels), stats[i].first_slice,
                      stats[i].last_slice, static_cast<double>(stats[i].voxels) * voxel_ml);
        out << buf;
    }
}

void print_warnings(std::ostream& out, const Report& report) {
    for (const Warning& w : report.warnings) {
        out << "strata: warning: " << w.stage << ": " << w.where << ": " << w.message << '\n';
    }
}

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

/// The stack a command works on: the input file or folder, else the named phantom; spacing
/// override and label selection applied.
SliceStack load_stack(const std::string& input,
                      const std::string& phantom,
                      const std::optional<Vec3>& spacing_mm,
                      const std::filesystem::path& color_table,
                      const std::vector<std::string>& labels,
                      TerminalProgress& progress,
                      Report& report,
                      const std::filesystem::path& allowed_data_file = {}) {
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

/// sRGB encoding of a linear channel (IEC 61966-2-1), clamped to [0, 1].
double linear_to_srgb(double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c <= 0.0031308 ? 12.92 * c : 1.055 * std::pow(c, 1.0 / 2.4) - 0.055;
}

/// The end of `strata extract`: writes the cut objects (a glTF scene, or one mesh file with a
/// label per triangle) and reports them (`objects`: one JSON entry per object).
int write_extracted(const ExtractOptions& options,
                    const std::vector<SceneObject>& scene,
                    const Json& objects,
                    const SceneInfo& info,
                    double max_error_mm,
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
    const Json summary = {{"output", options.output.string()},
                          {"max_error_mm", max_error_mm},
                          {"objects", objects},
                          {"warnings", warnings_json(report)}};
    if (options.output_options.json) {
        std::cout << summary.dump(2) << '\n';
    } else if (!options.output_options.quiet) {
        for (const Json& o : objects) {
            char buf[256];
            std::snprintf(
                buf, sizeof(buf), "  %5lld  %-24s %8zu triangles (of %zu), error <= %.3g mm\n",
                static_cast<long long>(o["label"].get<std::int64_t>()),
                o["name"].get<std::string>().c_str(), o["triangles"].get<std::size_t>(),
                o["full_resolution_triangles"].get<std::size_t>(), o["error_mm"].get<double>());
            std::cout << buf;
        }
        std::cout << "wrote " << options.output.string() << '\n';
    }
    if (!options.output_options.quiet) {
        print_warnings(std::cerr, report);
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
    Json objects = Json::array();
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
        objects.push_back({{"label", object.label},
                           {"name", object.name},
                           {"triangles", out.mesh.triangles.size()},
                           {"full_resolution_triangles", full},
                           {"error_mm", cut.error_px * 1000.0},
                           {"closed_manifold", is_closed_manifold(check)}});
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
    info.generator = "strata 0.1.0";
    return write_extracted(options, scene, objects, info, bound.value, report);
}

/// `strata info FILE.glb`: what a progressive file holds, per object and level.
int info_of_file(const InfoOptions& options) {
    const ProgressiveFile file = read_progressive_gltf(options.input);
    Json objects = Json::array();
    for (const ProgressiveFileObject& object : file.objects) {
        Json levels = Json::array();
        for (std::uint32_t level = 0; level < level_count(object.model); ++level) {
            const MultiresCut cut = select_cut_at_level(object.model, level);
            std::size_t triangles = 0;
            for (const std::uint32_t c : cut.clusters) {
                triangles += object.model.clusters[c].triangles.size();
            }
            levels.push_back({{"level", level},
                              {"triangles", triangles},
                              {"clusters", cut.clusters.size()},
                              {"error_mm", cut.error_px * 1000.0},
                              {"chunk_bytes",
                               level < object.level_bytes.size() ? object.level_bytes[level] : 0}});
        }
        objects.push_back({{"name", object.name},
                           {"label", object.label},
                           {"vertices", object.model.positions.size()},
                           {"groups", object.model.groups.size()},
                           {"base_bytes", object.base_bytes},
                           {"levels", levels}});
    }
    Json j = {{"file", options.input},
              {"generator", file.generator},
              {"total_bytes", file.total_bytes},
              {"objects", objects}};
    if (options.output.json) {
        std::cout << j.dump(2) << '\n';
        return 0;
    }
    if (options.output.quiet) {
        return 0;
    }
    std::cout << options.input << ": progressive glTF, " << file.total_bytes << " bytes, "
              << file.objects.size() << " object(s), generator '" << file.generator << "'\n";
    for (const Json& o : objects) {
        std::cout << "  " << o["name"].get<std::string>() << " (label " << o["label"] << "): base "
                  << o["base_bytes"] << " bytes, " << o["groups"] << " splits\n";
        std::cout << "    level  triangles  clusters  error mm  chunk bytes\n";
        for (const Json& level : o["levels"]) {
            char buf[160];
            std::snprintf(buf, sizeof(buf), "    %5u  %9zu  %8zu  %8.3f  %11zu\n",
                          level["level"].get<unsigned>(), level["triangles"].get<std::size_t>(),
                          level["clusters"].get<std::size_t>(), level["error_mm"].get<double>(),
                          level["chunk_bytes"].get<std::size_t>());
            std::cout << buf;
        }
    }
    return 0;
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
Json write_lods(const BuildOptions& options,
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
    const std::filesystem::path file = options.output_dir / "lods.glb";
    const LodStats stats = write_lod_gltf(out.staged(file), objects, frame, info, lod);
    Json j = {{"file", file.string()},
              {"compression", options.lod_compression},
              {"total_bytes", stats.total_bytes}};
    Json list = Json::array();
    for (std::size_t o = 0; o < objects.size(); ++o) {
        Json levels = Json::array();
        for (const LodLevelStats& l : stats.objects[o]) {
            levels.push_back({{"error_mm", l.error_mm},
                              {"triangles", l.triangles},
                              {"vertices", l.vertices},
                              {"bytes", l.bytes},
                              {"model_level", l.model_level}});
        }
        list.push_back(
            {{"name", objects[o].name}, {"label", objects[o].label}, {"levels", levels}});
    }
    j["objects"] = list;
    return j;
}

}  // namespace

int run_build(const BuildOptions& options) {
    const auto start = Clock::now();
    // note: the output folder is checked and locked before any work; every output goes into
    // its staging folder, which replaces it at the end (all or nothing)
    StagedOutputFolder out(options.output_dir);
    const LodRequest lod_request = parse_lod_levels(options.lod_levels);
    Report report;
    TerminalProgress progress(options.output.quiet || options.output.json);
    ReconstructOptions reconstruct_options;
    reconstruct_options.contours.tolerance_px = options.tolerance_px;
    reconstruct_options.threads = options.threads;
    reconstruct_options.multires.cluster_triangles = options.cluster_triangles;
    reconstruct_options.progress = progress.callback();
    SliceStack stack;
    Reconstruction result;
    double input_seconds = 0.0;
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
        input_seconds = seconds_since(start);
        result = reconstruct_contours(contours, frame, grid, reconstruct_options, report);
        stack = std::move(frame.stack);
    } else {
        if (!options.reference_ct.empty() || options.contour_pitch_mm > 0.0) {
            throw Error(ErrorCode::InvalidInput,
                        "--reference-ct and --contour-pitch apply to planar contour input "
                        "(DICOM RTSTRUCT or contour JSON), not to '" +
                            options.input + "'");
        }
        stack = load_stack(options.input, options.phantom, options.spacing_mm, options.color_table,
                           options.labels, progress, report, options.allow_data_file);
        input_seconds = seconds_since(start);
        result = reconstruct(stack, reconstruct_options, report);
    }
    progress.finish();

    if (!options.debug_dir.empty() && stack.depth > 0) {
        const DebugView view = debug_view(stack);
        for (std::uint32_t k = 0; k < stack.depth; ++k) {
            char name[48];
            std::snprintf(name, sizeof(name), "contours_%04u.png", k);
            write_rgb_png(draw_slice_contours(stack, result.contours, k, view),
                          out.staged(options.debug_dir / name));
        }
        for (std::uint32_t k = 0; k + 1 < stack.depth; ++k) {
            char name[48];
            std::snprintf(name, sizeof(name), "medial_%04u_%04u.png", k, k + 1);
            write_rgb_png(draw_medial_axis(result.contours.slices[k], result.contours.slices[k + 1],
                                           result.fields[k], result.fields[k + 1],
                                           result.medial_axes[k], view),
                          out.staged(options.debug_dir / name));
        }
    }

    // Surfaces: one mesh file per object, the progressive scene, and the full-resolution scene
    // as a plain glTF.
    const auto export_start = Clock::now();
    std::vector<SceneObject> scene;
    std::vector<Json> surface_json;
    std::vector<std::string> stems;
    const double mm_per_px = error_mm_per_px(stack);
    for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
        const ObjectSurface& surface = result.surfaces[i];
        SceneObject object = scene_object(stack, surface.label);
        object.mesh = surface_to_world(stack, result.slice_spacing_px, surface.mesh);
        const MeshReport check = check_mesh(object.mesh);
        const std::string stem = unique_stem(file_stem(object.name), surface.label, stems);
        stems.push_back(stem);
        const std::filesystem::path mesh_file =
            options.output_dir / "meshes" / (stem + "." + options.mesh_format);
        if (!object.mesh.triangles.empty()) {
            write_mesh(
                object.mesh, out.staged(mesh_file),
                options.mesh_format == "stl" ? std::vector<Vec3>{} : shading_normals(object.mesh));
        }
        Json genus = Json::array();
        for (const int g : component_genera(check)) {
            genus.push_back(g);
        }
        Json j = {{"label", surface.label},
                  {"file", mesh_file.string()},
                  {"vertices", object.mesh.positions.size()},
                  {"triangles", object.mesh.triangles.size()},
                  {"components", check.components.size()},
                  {"genus", genus},
                  {"closed_manifold", is_closed_manifold(check)},
                  {"volume_ml", check.signed_volume / 1000.0},
                  {"slabs", surface.slabs},
                  {"caps", surface.caps},
                  {"steiner_points", surface.steiner_points},
                  {"fallback_corner_slices", surface.at_corners.size()},
                  {"fallback_unsimplified_slices", surface.unsimplified_slices},
                  {"fallback_split_slabs", surface.split_slabs},
                  {"verified", surface.verification.ok()},
                  {"topology_mismatches", surface.topology_mismatches},
                  {"failed_slabs", surface.failed_slabs}};
        if (i < result.models.size()) {
            const MultiresMesh& model = result.models[i];
            Json levels = Json::array();
            for (std::uint32_t level = 0; level < level_count(model); ++level) {
                const MultiresCut cut = select_cut_at_level(model, level);
                std::size_t triangles = 0;
                for (const std::uint32_t c : cut.clusters) {
                    triangles += model.clusters[c].triangles.size();
                }
                levels.push_back({{"level", level},
                                  {"triangles", triangles},
                                  {"clusters", cut.clusters.size()},
                                  {"error_px", cut.error_px},
                                  {"error_mm", cut.error_px * mm_per_px}});
            }
            j["levels"] = levels;
            j["groups"] = model.groups.size();
        }
        if (!is_closed_manifold(check)) {
            j["problems"] = check.problems;
            report.warn("triangulate", object.name,
                        "the surface is not a closed manifold: " + check.problems.front());
        }
        surface_json.push_back(j);
        scene.push_back(std::move(object));
    }
    // The progressive scene: every object whose surface lies on a grid (all but those the
    // quantize stage had to leave unsnapped, which the report names).
    std::vector<ProgressiveObject> progressive;
    for (std::size_t i = 0; i < result.models.size() && i < scene.size(); ++i) {
        if (scene[i].mesh.triangles.empty()) {
            continue;
        }
        if (!(result.models[i].grid_step > 0.0)) {
            // note: every object of the input is in every output, or the build fails
            throw Error(ErrorCode::Internal,
                        "export: " + scene[i].name + " (label " + std::to_string(scene[i].label) +
                            "): its surface is not on a grid, so it cannot be in model." +
                            options.model_format + "; no outputs written");
        }
        ProgressiveObject object;
        object.name = scene[i].name;
        object.label = scene[i].label;
        object.srgb = scene[i].srgb;
        object.volume_ml = surface_json[i]["volume_ml"].get<double>();
        object.model = &result.models[i];
        progressive.push_back(object);
    }
    const std::filesystem::path model_file = options.output_dir / ("model." + options.model_format);
    ProgressiveStats model_stats;
    if (!progressive.empty()) {
        SceneInfo info;
        info.source = stack.source;
        const Vec3 spacing = stack.spacing_mm();
        info.spacing_mm = {spacing.x, spacing.y, spacing.z};
        info.generator = "strata 0.1.0";
        ProgressiveOptions export_options;
        export_options.threads = options.threads;
        model_stats = write_progressive_gltf(out.staged(model_file), progressive,
                                             slice_frame(stack, result.slice_spacing_px), info,
                                             export_options);
    }
    Json lods_json;
    if (lod_request.wanted && !progressive.empty()) {
        SceneInfo info;
        info.source = stack.source;
        const Vec3 spacing = stack.spacing_mm();
        info.spacing_mm = {spacing.x, spacing.y, spacing.z};
        info.generator = "strata 0.1.0";
        lods_json = write_lods(options, lod_request, progressive,
                               slice_frame(stack, result.slice_spacing_px), info, out);
    }
    const double export_seconds = seconds_since(export_start);

    const std::filesystem::path scene_file = options.output_dir / "scene.glb";
    const bool any_triangles = std::any_of(
        scene.begin(), scene.end(), [](const SceneObject& o) { return !o.mesh.triangles.empty(); });
    if (any_triangles) {
        SceneInfo info;
        info.source = stack.source;
        const Vec3 spacing = stack.spacing_mm();
        info.spacing_mm = {spacing.x, spacing.y, spacing.z};
        info.generator = "strata 0.1.0";
        if (options.scene_meshopt) {
            detail::write_meshopt_scene(out.staged(scene_file), scene,
                                        info);  // EXT_meshopt_compression
        } else {
            SceneGltfOptions scene_options;
            scene_options.draco = !options.scene_uncompressed;
            write_scene_gltf(out.staged(scene_file), scene, info, scene_options);
        }
    }

    Json summary;
    summary["strata_version"] = "0.1.0";
    summary["input"] = stack_json(stack);
    const std::vector<LabelContourStats> stats = contour_stats(result.contours);
    Json objects = Json::array();
    for (const LabelInfo& label : stack.label_table) {
        Json o;
        o["label"] = label.value;
        o["name"] = label.name;
        const auto it = std::find_if(stats.begin(), stats.end(), [&](const LabelContourStats& s) {
            return s.label == label.value;
        });
        const LabelContourStats s = it != stats.end() ? *it : LabelContourStats{};
        o["contours"] = {{"contours", s.contours},
                         {"holes", s.holes},
                         {"slices", s.slices},
                         {"max_nesting_depth", s.max_depth},
                         {"points_original", s.points_original},
                         {"points_simplified", s.points_simplified},
                         {"max_deviation_px", s.max_deviation_px},
                         {"tolerance_px", result.contours.tolerance_px},
                         {"links", s.links},
                         {"hole_links", s.hole_links}};
        std::uint64_t curves = 0;
        std::uint64_t medial_points = 0;
        std::uint64_t unmatched_runs = 0;
        std::uint64_t unmatched_points = 0;
        for (const MedialAxis& axis : result.medial_axes) {
            for (const MedialCurve& curve : axis.curves) {
                if (curve.label == label.value) {
                    ++curves;
                    medial_points += curve.points.size();
                }
            }
            for (const UnmatchedRun& run : axis.unmatched) {
                const auto& set = result.contours.slices[axis.lower_slice + (run.on_upper ? 1 : 0)];
                if (set.contours[run.contour].label == label.value) {
                    ++unmatched_runs;
                    unmatched_points += run.count;
                }
            }
        }
        o["medial"] = {{"curves", curves},
                       {"points", medial_points},
                       {"unmatched_runs", unmatched_runs},
                       {"unmatched_points", unmatched_points}};
        for (const Json& surface : surface_json) {
            if (surface["label"] == label.value) {
                o["surface"] = surface;
            }
        }
        objects.push_back(o);
    }
    summary["objects"] = objects;
    if (any_triangles) {
        summary["scene"] = scene_file.string();
    }
    if (!progressive.empty()) {
        summary["model"] = {{"file", model_file.string()},
                            {"objects", progressive.size()},
                            {"total_bytes", model_stats.total_bytes},
                            {"base_bytes", model_stats.base_bytes},
                            {"chunk_bytes", model_stats.chunk_bytes},
                            {"chunks", model_stats.chunks}};
    }
    if (!lods_json.is_null()) {
        summary["lods"] = lods_json;
    }
    summary["output_dir"] = options.output_dir.string();
    Json timings = {{"input", input_seconds}};
    for (const StageTiming& t : result.timings) {
        timings[t.stage] = t.seconds;
    }
    timings["export"] = export_seconds;
    summary["timings_s"] = timings;
    summary["warnings"] = warnings_json(report);
    const std::filesystem::path summary_file = options.output_dir / "summary.json";
    write_file_atomically(out.staged(summary_file), summary.dump(2) + "\n");
    out.commit();

    if (options.output.json) {
        std::cout << summary.dump(2) << '\n';
    } else if (!options.output.quiet) {
        print_stack(std::cout, stack);
        std::cout << "contours (tolerance " << result.contours.tolerance_px << " px):\n";
        for (const LabelContourStats& s : stats) {
            char buf[256];
            std::snprintf(buf, sizeof(buf),
                          "  %5u  %6u contours (%u holes) on %u slices, %llu -> %llu points, "
                          "max deviation %.3f px\n",
                          unsigned(s.label), s.contours, s.holes, s.slices,
                          static_cast<unsigned long long>(s.points_original),
                          static_cast<unsigned long long>(s.points_simplified), s.max_deviation_px);
            std::cout << buf;
        }
        std::cout << "surfaces (slice spacing " << result.slice_spacing_px << " px):\n";
        for (const Json& j : surface_json) {
            char buf[320];
            std::snprintf(
                buf, sizeof(buf),
                "  %5u  %8zu triangles, %zu component(s), %s, %.2f mL, %u fallback "
                "slice(s), %u mismatch(es) -> %s\n",
                unsigned(j["label"].get<int>()), j["triangles"].get<std::size_t>(),
                j["components"].get<std::size_t>(),
                j["closed_manifold"].get<bool>() ? "closed manifold" : "NOT CLOSED",
                j["volume_ml"].get<double>(), j["fallback_unsimplified_slices"].get<unsigned>(),
                j["topology_mismatches"].get<unsigned>(), j["file"].get<std::string>().c_str());
            std::cout << buf;
            if (j.contains("levels")) {
                std::cout << "         levels (triangles, error mm):";
                for (const Json& level : j["levels"]) {
                    std::snprintf(buf, sizeof(buf), " %zu %.3g",
                                  level["triangles"].get<std::size_t>(),
                                  level["error_mm"].get<double>());
                    std::cout << (level["level"] == 0 ? "" : " ->") << buf;
                }
                std::cout << '\n';
            }
        }
        if (!progressive.empty()) {
            char buf[256];
            std::snprintf(buf, sizeof(buf),
                          "model: %s (%zu bytes: base %zu, %zu refinement chunks %zu)\n",
                          model_file.string().c_str(), model_stats.total_bytes,
                          model_stats.base_bytes, model_stats.chunks, model_stats.chunk_bytes);
            std::cout << buf;
        }
        if (any_triangles) {
            std::cout << "scene: " << scene_file.string() << '\n';
        }
        if (!lods_json.is_null()) {
            std::cout << "lods: " << lods_json["file"].get<std::string>() << " ("
                      << lods_json["total_bytes"] << " bytes, " << options.lod_compression << ")\n";
        }
        std::cout << "timings: input " << input_seconds << " s";
        for (const StageTiming& t : result.timings) {
            std::cout << ", " << t.stage << ' ' << t.seconds << " s";
        }
        std::cout << "\nwrote " << summary_file.string() << '\n';
    }
    if (!options.output.quiet) {
        print_warnings(std::cerr, report);
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
    const SliceStack stack =
        load_stack(options.input, options.phantom, options.spacing_mm, options.color_table,
                   options.labels, progress, report, options.allow_data_file);
    ReconstructOptions reconstruct_options;
    reconstruct_options.contours.tolerance_px = options.tolerance_px;
    reconstruct_options.threads = options.threads;
    reconstruct_options.progress = progress.callback();
    const Reconstruction result = reconstruct(stack, reconstruct_options, report);
    progress.finish();

    const double mm_per_px = error_mm_per_px(stack);
    const double max_error_px = bound.in_pixels ? bound.value : bound.value / mm_per_px;
    std::vector<SceneObject> scene;
    Json objects = Json::array();
    for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
        const MultiresMesh& model = result.models[i];
        const MultiresCut cut = select_cut_by_error(model, max_error_px);
        SceneObject object = scene_object(stack, result.surfaces[i].label);
        object.mesh = surface_to_world(stack, result.slice_spacing_px, cut_mesh(model, cut));
        const MeshReport check = check_mesh(object.mesh);
        objects.push_back({{"label", object.label},
                           {"name", object.name},
                           {"triangles", object.mesh.triangles.size()},
                           {"full_resolution_triangles", result.surfaces[i].mesh.triangles.size()},
                           {"error_mm", cut.error_px * mm_per_px},
                           {"error_px", cut.error_px},
                           {"closed_manifold", is_closed_manifold(check)}});
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
    info.generator = "strata 0.1.0";
    return write_extracted(options, scene, objects, info, max_error_px * mm_per_px, report);
}

int run_phantom(const PhantomCommandOptions& options) {
    if (options.list) {
        for (const std::string& name : phantom_names()) {
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
        j["stack"] = stack_json(phantom.stack);
        std::cout << j.dump(2) << '\n';
    } else if (!options.output_options.quiet) {
        std::cout << phantom.name << ": " << phantom.description << '\n';
        print_stack(std::cout, phantom.stack);
        std::cout << "wrote " << written << '\n';
    }
    return 0;
}

namespace {

/// `strata info` of planar contours (RTSTRUCT, contour JSON): every structure as read and cleaned.
int info_of_contours(const InfoOptions& options) {
    Report report;
    const PlanarContours contours = clean_planar_contours(read_raw_contours(options.input, ""),
                                                          ContourCleaningOptions{}, report);
    Json objects = Json::array();
    for (const ContourObject& o : contours.objects) {
        std::size_t count = 0;
        for (const ContourPlane& plane : o.planes) {
            count += plane.contours.size();
        }
        Json j = {{"number", o.number},
                  {"name", o.name},
                  {"interpreted_type", o.interpreted_type},
                  {"color_srgb", {o.color[0], o.color[1], o.color[2]}},
                  {"planes", o.planes.size()},
                  {"contours", count},
                  {"markers", o.markers.size()}};
        if (!o.planes.empty()) {
            j["plane_range_mm"] = {o.planes.front().w, o.planes.back().w};
        }
        objects.push_back(j);
    }
    Json j = {{"source", contours.source},
              {"frame", contours.frame},
              {"plane_normal", {contours.normal.x, contours.normal.y, contours.normal.z}},
              {"structures", objects},
              {"warnings", warnings_json(report)}};
    if (contours.reference) {
        const PlaneGrid& g = *contours.reference;
        j["reference_grid"] = {
            {"columns", g.columns}, {"rows", g.rows}, {"pixel_mm", {g.pixel_mm[0], g.pixel_mm[1]}}};
    }
    if (options.output.json) {
        std::cout << j.dump(2) << '\n';
        return 0;
    }
    if (options.output.quiet) {
        return 0;
    }
    std::cout << "input:   " << contours.source << " (planar contours, frame " << contours.frame
              << ")\n";
    std::cout << "normal:  " << format_vec(contours.normal) << '\n';
    if (contours.reference) {
        std::cout << "grid:    " << contours.reference->columns << " x " << contours.reference->rows
                  << ", " << contours.reference->pixel_mm[0] << " x "
                  << contours.reference->pixel_mm[1] << " mm pixels (reference CT)\n";
    }
    std::cout << "structures: " << contours.objects.size() << '\n';
    for (const Json& o : objects) {
        char buf[256];
        std::snprintf(
            buf, sizeof(buf), "  %5d  %-28s  #%02x%02x%02x  %-10s %4zu planes  %5zu contours",
            o["number"].get<int>(), o["name"].get<std::string>().c_str(),
            o["color_srgb"][0].get<int>(), o["color_srgb"][1].get<int>(),
            o["color_srgb"][2].get<int>(), o["interpreted_type"].get<std::string>().c_str(),
            o["planes"].get<std::size_t>(), o["contours"].get<std::size_t>());
        std::cout << buf;
        if (o.contains("plane_range_mm")) {
            std::snprintf(buf, sizeof(buf), "  %.2f..%.2f mm", o["plane_range_mm"][0].get<double>(),
                          o["plane_range_mm"][1].get<double>());
            std::cout << buf;
        }
        if (o["markers"].get<std::size_t>() > 0) {
            std::cout << "  " << o["markers"].get<std::size_t>() << " markers";
        }
        std::cout << '\n';
    }
    print_warnings(std::cerr, report);
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
        Json j = stack_json(stack);
        j["warnings"] = warnings_json(report);
        std::cout << j.dump(2) << '\n';
    } else if (!options.output.quiet) {
        print_stack(std::cout, stack);
        print_warnings(std::cerr, report);
    }
    return 0;
}

}  // namespace strata::cli

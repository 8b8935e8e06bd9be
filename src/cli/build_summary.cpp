#include "cli/build_summary.h"

#include <cstdio>

#include "core/version.h"

namespace strata::cli {

InputSummary summarize_input(const SliceStack& stack) {
    InputSummary input;
    input.source = stack.source;
    input.source_frame = stack.source_frame;
    input.width = stack.width;
    input.height = stack.height;
    input.depth = stack.depth;
    input.spacing_mm = stack.spacing_mm();
    input.index_to_world = stack.index_to_world;
    std::vector<int> index(65536, -1);
    for (std::size_t i = 0; i < stack.label_table.size(); ++i) {
        index[stack.label_table[i].value] = static_cast<int>(i);
        input.labels.push_back({stack.label_table[i]});
    }
    std::vector<std::uint32_t> last_seen(input.labels.size(), UINT32_MAX);
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        for (std::uint16_t v : stack.slice(k)) {
            const int l = index[v];
            if (l < 0) {
                continue;
            }
            InputLabelSummary& s = input.labels[l];
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
    const Vec3 spacing = input.spacing_mm;
    const double voxel_ml = spacing.x * spacing.y * spacing.z / 1000.0;
    for (InputLabelSummary& s : input.labels) {
        s.volume_ml = static_cast<double>(s.voxels) * voxel_ml;
    }
    return input;
}

std::vector<ObjectSummary> summarize_objects(const SliceStack& stack,
                                             const Reconstruction& result,
                                             const std::vector<LabelContourStats>& contour_stats) {
    std::vector<ObjectSummary> objects;
    for (const LabelInfo& label : stack.label_table) {
        ObjectSummary o;
        o.label = label.value;
        o.name = label.name;
        for (const LabelContourStats& s : contour_stats) {
            if (s.label == label.value) {
                o.contours = s;
                break;
            }
        }
        for (const MedialCounts& c : result.medial_counts) {
            if (c.label == label.value) {
                o.medial = {c.curves, c.points, c.unmatched_runs, c.unmatched_points};
                break;
            }
        }
        objects.push_back(o);
    }
    return objects;
}

SurfaceSummary summarize_surface(const ObjectSurface& surface,
                                 const RepairRecord& repairs,
                                 const MeshReport& check,
                                 const std::filesystem::path& file) {
    SurfaceSummary s;
    s.label = surface.label;
    s.file = file;
    s.vertices = check.vertex_count;
    s.triangles = check.triangle_count;
    s.components = check.components.size();
    s.genus = component_genera(check);
    s.closed_manifold = is_closed_manifold(check);
    s.volume_ml = check.signed_volume / 1000.0;
    s.slabs = surface.slabs;
    s.caps = surface.caps;
    s.steiner_points = surface.steiner_points;
    s.fallback_corner_slices = repairs.corner_slices.size();
    s.fallback_partly_unsimplified_slices = repairs.near_neighbour_slices.size();
    s.fallback_unsimplified_slices = std::uint32_t(repairs.original_slices.size());
    s.fallback_split_slabs = repairs.split_slabs;
    s.verified = surface.verification.ok();
    s.topology_mismatches = surface.topology_mismatches;
    s.failed_slabs = surface.failed_slabs;
    if (!s.closed_manifold) {
        s.problems = check.problems;
    }
    return s;
}

std::vector<LevelSummary> summarize_levels(const MultiresMesh& model, double mm_per_px) {
    std::vector<LevelSummary> levels;
    for (std::uint32_t level = 0; level < level_count(model); ++level) {
        const MultiresCut cut = select_cut_at_level(model, level);
        LevelSummary l;
        l.level = level;
        for (const std::uint32_t c : cut.clusters) {
            l.triangles += model.clusters[c].triangles.size();
        }
        l.clusters = cut.clusters.size();
        l.error_px = cut.error_px;
        l.error_mm = cut.error_px * mm_per_px;
        levels.push_back(l);
    }
    return levels;
}

Json input_json(const InputSummary& input) {
    Json j;
    j["source"] = input.source;
    j["source_frame"] = input.source_frame;
    j["dims"] = {input.width, input.height, input.depth};
    j["spacing_mm"] = {input.spacing_mm.x, input.spacing_mm.y, input.spacing_mm.z};
    Json affine = Json::array();
    for (int r = 0; r < 3; ++r) {
        const auto& row = input.index_to_world.linear[r];
        affine.push_back({row[0], row[1], row[2], input.index_to_world.translation[r]});
    }
    affine.push_back({0, 0, 0, 1});
    j["index_to_world_lps_mm"] = affine;
    Json labels = Json::array();
    for (const InputLabelSummary& s : input.labels) {
        Json e;
        e["value"] = s.label.value;
        e["name"] = s.label.name;
        e["color_srgb"] = {s.label.color[0], s.label.color[1], s.label.color[2]};
        e["voxels"] = s.voxels;
        e["slices"] = s.slices;
        e["first_slice"] = s.first_slice;
        e["last_slice"] = s.last_slice;
        e["volume_ml"] = s.volume_ml;
        labels.push_back(e);
    }
    j["labels"] = labels;
    return j;
}

Json warnings_json(const std::vector<Warning>& warnings) {
    Json w = Json::array();
    for (const Warning& warning : warnings) {
        w.push_back(
            {{"stage", warning.stage}, {"where", warning.where}, {"message", warning.message}});
    }
    return w;
}

namespace {

Json surface_json(const SurfaceSummary& s) {
    Json j = {{"label", s.label},
              {"file", s.file.string()},
              {"vertices", s.vertices},
              {"triangles", s.triangles},
              {"components", s.components},
              {"genus", s.genus},
              {"closed_manifold", s.closed_manifold},
              {"volume_ml", s.volume_ml},
              {"slabs", s.slabs},
              {"caps", s.caps},
              {"steiner_points", s.steiner_points},
              {"fallback_corner_slices", s.fallback_corner_slices},
              {"fallback_partly_unsimplified_slices", s.fallback_partly_unsimplified_slices},
              {"fallback_unsimplified_slices", s.fallback_unsimplified_slices},
              {"fallback_split_slabs", s.fallback_split_slabs},
              {"verified", s.verified},
              {"topology_mismatches", s.topology_mismatches},
              {"failed_slabs", s.failed_slabs}};
    if (s.levels) {
        Json levels = Json::array();
        for (const LevelSummary& l : *s.levels) {
            levels.push_back({{"level", l.level},
                              {"triangles", l.triangles},
                              {"clusters", l.clusters},
                              {"error_px", l.error_px},
                              {"error_mm", l.error_mm}});
        }
        j["levels"] = levels;
        j["groups"] = s.groups;
    }
    if (!s.closed_manifold) {
        j["problems"] = s.problems;
    }
    return j;
}

Json object_json(const ObjectSummary& o, double tolerance_px, const BuildSummary& summary) {
    Json j;
    j["label"] = o.label;
    j["name"] = o.name;
    const LabelContourStats& c = o.contours;
    j["contours"] = {{"contours", c.contours},
                     {"holes", c.holes},
                     {"slices", c.slices},
                     {"max_nesting_depth", c.max_depth},
                     {"points_original", c.points_original},
                     {"points_simplified", c.points_simplified},
                     {"max_deviation_px", c.max_deviation_px},
                     {"tolerance_px", tolerance_px},
                     {"links", c.links},
                     {"hole_links", c.hole_links}};
    j["medial"] = {{"curves", o.medial.curves},
                   {"points", o.medial.points},
                   {"unmatched_runs", o.medial.unmatched_runs},
                   {"unmatched_points", o.medial.unmatched_points}};
    for (const SurfaceSummary& surface : summary.surfaces) {
        if (surface.label == o.label) {
            j["surface"] = surface_json(surface);
        }
    }
    return j;
}

Json lods_json(const LodSummary& lods) {
    Json j = {{"file", lods.file.string()},
              {"compression", lods.compression},
              {"total_bytes", lods.total_bytes}};
    Json list = Json::array();
    for (const LodObjectSummary& o : lods.objects) {
        Json levels = Json::array();
        for (const LodLevelStats& l : o.levels) {
            levels.push_back({{"error_mm", l.error_mm},
                              {"triangles", l.triangles},
                              {"vertices", l.vertices},
                              {"bytes", l.bytes},
                              {"model_level", l.model_level}});
        }
        list.push_back({{"name", o.name}, {"label", o.label}, {"levels", levels}});
    }
    j["objects"] = list;
    return j;
}

}  // namespace

std::string build_summary_json(const BuildSummary& summary) {
    Json j;
    j["strata_version"] = kVersion;
    j["input"] = input_json(summary.input);
    Json objects = Json::array();
    for (const ObjectSummary& o : summary.objects) {
        objects.push_back(object_json(o, summary.tolerance_px, summary));
    }
    j["objects"] = objects;
    if (summary.scene) {
        j["scene"] = summary.scene->string();
    }
    if (summary.model) {
        const ProgressiveStats& stats = summary.model->stats;
        j["model"] = {{"file", summary.model->file.string()}, {"objects", summary.model->objects},
                      {"total_bytes", stats.total_bytes},     {"base_bytes", stats.base_bytes},
                      {"chunk_bytes", stats.chunk_bytes},     {"chunks", stats.chunks}};
    }
    if (summary.lods) {
        j["lods"] = lods_json(*summary.lods);
    }
    j["output_dir"] = summary.output_dir.string();
    Json timings = Json::object();
    for (const TimingSummary& t : summary.timings) {
        timings[t.step] = t.seconds;
    }
    j["timings_s"] = timings;
    Json cpu_timings = Json::object();
    for (const TimingSummary& t : summary.timings) {
        cpu_timings[t.step] = t.cpu_seconds;
    }
    j["cpu_timings_s"] = cpu_timings;
    j["warnings"] = warnings_json(summary.warnings);
    return j.dump(2) + "\n";
}

std::string format_vec(Vec3 v) {
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%g x %g x %g", v.x, v.y, v.z);
    return buf;
}

void print_input(std::ostream& out, const InputSummary& input) {
    out << "input:   " << input.source << " (frame " << input.source_frame << ")\n";
    out << "dims:    " << input.width << " x " << input.height << " x " << input.depth << '\n';
    out << "spacing: " << format_vec(input.spacing_mm) << " mm\n";
    out << "affine (voxel index -> LPS mm):\n";
    for (int r = 0; r < 3; ++r) {
        char buf[160];
        const auto& row = input.index_to_world.linear[r];
        std::snprintf(buf, sizeof(buf), "  [%10.5g %10.5g %10.5g | %10.5g]\n", row[0], row[1],
                      row[2], input.index_to_world.translation[r]);
        out << buf;
    }
    out << "labels:  " << input.labels.size() << '\n';
    for (const InputLabelSummary& s : input.labels) {
        const LabelInfo& l = s.label;
        char buf[256];
        std::snprintf(
            buf, sizeof(buf), "  %5u  %-32s  #%02x%02x%02x  %9llu voxels  slices %u-%u  %.2f mL\n",
            unsigned(l.value), l.name.c_str(), l.color[0], l.color[1], l.color[2],
            static_cast<unsigned long long>(s.voxels), s.first_slice, s.last_slice, s.volume_ml);
        out << buf;
    }
}

void print_build_report(std::ostream& out, const BuildSummary& summary) {
    print_input(out, summary.input);
    out << "contours (tolerance " << summary.tolerance_px << " px):\n";
    for (const LabelContourStats& s : summary.contour_stats) {
        char buf[256];
        std::snprintf(buf, sizeof(buf),
                      "  %5u  %6u contours (%u holes) on %u slices, %llu -> %llu points, "
                      "max deviation %.3f px\n",
                      unsigned(s.label), s.contours, s.holes, s.slices,
                      static_cast<unsigned long long>(s.points_original),
                      static_cast<unsigned long long>(s.points_simplified), s.max_deviation_px);
        out << buf;
    }
    out << "surfaces (slice spacing " << summary.slice_spacing_px << " px):\n";
    for (const SurfaceSummary& s : summary.surfaces) {
        char buf[320];
        std::snprintf(buf, sizeof(buf),
                      "  %5u  %8zu triangles, %zu component(s), %s, %.2f mL, %u fallback "
                      "slice(s), %u mismatch(es) -> %s\n",
                      unsigned(s.label), s.triangles, s.components,
                      s.closed_manifold ? "closed manifold" : "NOT CLOSED", s.volume_ml,
                      s.fallback_unsimplified_slices, s.topology_mismatches,
                      s.file.string().c_str());
        out << buf;
        if (s.levels) {
            out << "         levels (triangles, error mm):";
            for (const LevelSummary& level : *s.levels) {
                std::snprintf(buf, sizeof(buf), " %zu %.3g", level.triangles, level.error_mm);
                out << (level.level == 0 ? "" : " ->") << buf;
            }
            out << '\n';
        }
    }
    if (summary.model) {
        const ProgressiveStats& stats = summary.model->stats;
        char buf[256];
        std::snprintf(buf, sizeof(buf),
                      "model: %s (%zu bytes: base %zu, %zu refinement chunks %zu)\n",
                      summary.model->file.string().c_str(), stats.total_bytes, stats.base_bytes,
                      stats.chunks, stats.chunk_bytes);
        out << buf;
    }
    if (summary.scene) {
        out << "scene: " << summary.scene->string() << '\n';
    }
    if (summary.lods) {
        out << "lods: " << summary.lods->file.string() << " (" << summary.lods->total_bytes
            << " bytes, " << summary.lods->compression << ")\n";
    }
    out << "timings:";
    for (std::size_t i = 0; i < summary.timings.size(); ++i) {
        out << (i == 0 ? " " : ", ") << summary.timings[i].step << ' ' << summary.timings[i].seconds
            << " s";
    }
    out << "\nwrote " << summary.summary_file.string() << '\n';
}

void print_warnings(std::ostream& out, const std::vector<Warning>& warnings) {
    for (const Warning& w : warnings) {
        out << "strata: warning: " << w.stage << ": " << w.where << ": " << w.message << '\n';
    }
}

}  // namespace strata::cli

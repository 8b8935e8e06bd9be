#include "cli/file_summaries.h"

#include <cstdio>

namespace strata::cli {

Json extract_json(const ExtractSummary& summary) {
    Json objects = Json::array();
    for (const ExtractedObject& o : summary.objects) {
        Json j = {{"label", o.label},
                  {"name", o.name},
                  {"triangles", o.triangles},
                  {"full_resolution_triangles", o.full_resolution_triangles},
                  {"error_mm", o.error_mm}};
        if (o.error_px) {
            j["error_px"] = *o.error_px;
        }
        j["closed_manifold"] = o.closed_manifold;
        objects.push_back(std::move(j));
    }
    return {{"output", summary.output},
            {"max_error_mm", summary.max_error_mm},
            {"objects", objects},
            {"warnings", warnings_json(summary.warnings)}};
}

void print_extract(std::ostream& out, const ExtractSummary& summary) {
    for (const ExtractedObject& o : summary.objects) {
        char buf[256];
        std::snprintf(buf, sizeof(buf),
                      "  %5lld  %-24s %8zu triangles (of %zu), error <= %.3g mm\n",
                      static_cast<long long>(o.label), o.name.c_str(), o.triangles,
                      o.full_resolution_triangles, o.error_mm);
        out << buf;
    }
    out << "wrote " << summary.output << '\n';
}

Json file_info_json(const FileInfo& info) {
    Json objects = Json::array();
    for (const FileObjectInfo& o : info.objects) {
        Json levels = Json::array();
        for (const FileLevelInfo& level : o.levels) {
            levels.push_back({{"level", level.level},
                              {"triangles", level.triangles},
                              {"clusters", level.clusters},
                              {"error_mm", level.error_mm},
                              {"fine_error_mm", level.fine_error_mm},
                              {"chunk_bytes", level.chunk_bytes}});
        }
        objects.push_back({{"name", o.name},
                           {"label", o.label},
                           {"vertices", o.vertices},
                           {"groups", o.groups},
                           {"base_bytes", o.base_bytes},
                           {"levels", levels}});
    }
    return {{"file", info.file},
            {"generator", info.generator},
            {"total_bytes", info.total_bytes},
            {"objects", objects}};
}

void print_file_info(std::ostream& out, const FileInfo& info) {
    out << info.file << ": progressive glTF, " << info.total_bytes << " bytes, "
        << info.objects.size() << " object(s), generator '" << info.generator << "'\n";
    for (const FileObjectInfo& o : info.objects) {
        out << "  " << o.name << " (label " << o.label << "): base " << o.base_bytes << " bytes, "
            << o.groups << " splits\n";
        out << "    level  triangles  clusters  error mm  to level 0 mm  chunk bytes\n";
        for (const FileLevelInfo& level : o.levels) {
            char buf[160];
            std::snprintf(buf, sizeof(buf), "    %5u  %9zu  %8zu  %8.3f  %13.3f  %11zu\n",
                          level.level, level.triangles, level.clusters, level.error_mm,
                          level.fine_error_mm, level.chunk_bytes);
            out << buf;
        }
    }
}

ContoursInfo summarize_contours(const PlanarContours& contours) {
    ContoursInfo info;
    info.source = contours.source;
    info.frame = contours.frame;
    info.normal = contours.normal;
    info.reference = contours.reference;
    for (const ContourObject& o : contours.objects) {
        StructureInfo s;
        s.number = o.number;
        s.name = o.name;
        s.interpreted_type = o.interpreted_type;
        s.color = o.color;
        s.planes = o.planes.size();
        for (const ContourPlane& plane : o.planes) {
            s.contours += plane.contours.size();
        }
        s.markers = o.markers.size();
        if (!o.planes.empty()) {
            s.plane_range_mm = std::array<double, 2>{o.planes.front().w, o.planes.back().w};
        }
        info.structures.push_back(std::move(s));
    }
    return info;
}

Json contours_info_json(const ContoursInfo& info) {
    Json objects = Json::array();
    for (const StructureInfo& s : info.structures) {
        Json j = {{"number", s.number},
                  {"name", s.name},
                  {"interpreted_type", s.interpreted_type},
                  {"color_srgb", {s.color[0], s.color[1], s.color[2]}},
                  {"planes", s.planes},
                  {"contours", s.contours},
                  {"markers", s.markers}};
        if (s.plane_range_mm) {
            j["plane_range_mm"] = {(*s.plane_range_mm)[0], (*s.plane_range_mm)[1]};
        }
        objects.push_back(j);
    }
    Json j = {{"source", info.source},
              {"frame", info.frame},
              {"plane_normal", {info.normal.x, info.normal.y, info.normal.z}},
              {"structures", objects},
              {"warnings", warnings_json(info.warnings)}};
    if (info.reference) {
        const PlaneGrid& g = *info.reference;
        j["reference_grid"] = {
            {"columns", g.columns}, {"rows", g.rows}, {"pixel_mm", {g.pixel_mm[0], g.pixel_mm[1]}}};
    }
    return j;
}

void print_contours_info(std::ostream& out, const ContoursInfo& info) {
    out << "input:   " << info.source << " (planar contours, frame " << info.frame << ")\n";
    out << "normal:  " << format_vec(info.normal) << '\n';
    if (info.reference) {
        out << "grid:    " << info.reference->columns << " x " << info.reference->rows << ", "
            << info.reference->pixel_mm[0] << " x " << info.reference->pixel_mm[1]
            << " mm pixels (reference CT)\n";
    }
    out << "structures: " << info.structures.size() << '\n';
    for (const StructureInfo& s : info.structures) {
        char buf[256];
        std::snprintf(buf, sizeof(buf),
                      "  %5d  %-28s  #%02x%02x%02x  %-10s %4zu planes  %5zu contours", s.number,
                      s.name.c_str(), s.color[0], s.color[1], s.color[2],
                      s.interpreted_type.c_str(), s.planes, s.contours);
        out << buf;
        if (s.plane_range_mm) {
            std::snprintf(buf, sizeof(buf), "  %.2f..%.2f mm", (*s.plane_range_mm)[0],
                          (*s.plane_range_mm)[1]);
            out << buf;
        }
        if (s.markers > 0) {
            out << "  " << s.markers << " markers";
        }
        out << '\n';
    }
}

}  // namespace strata::cli

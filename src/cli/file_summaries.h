#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "cli/build_summary.h"
#include "core/report.h"
#include "core/types.h"
#include "input/planar_contours.h"

// The reports of `strata extract` and `strata info`, as cli/build_summary.h does for `strata
// build`: typed values filled once by the command, rendered twice (JSON for --json, text for the
// terminal); neither rendering reads the other.

namespace strata::cli {

/// One object of `strata extract`: its cut at the bound.
struct ExtractedObject {
    std::int64_t label = 0;
    std::string name;
    std::size_t triangles = 0;
    std::size_t full_resolution_triangles = 0;
    double error_mm = 0.0;
    std::optional<double> error_px;  ///< when extracted from a label stack (not from a file)
    bool closed_manifold = false;
};

/// What `strata extract` wrote.
struct ExtractSummary {
    std::string output;
    double max_error_mm = 0.0;
    std::vector<ExtractedObject> objects;
    std::vector<Warning> warnings;
};

Json extract_json(const ExtractSummary& summary);

/// The terminal report of `strata extract` (on `out`; the warnings are not part of it).
void print_extract(std::ostream& out, const ExtractSummary& summary);

/// One level of an object of a progressive file.
struct FileLevelInfo {
    std::uint32_t level = 0;
    std::size_t triangles = 0;
    std::size_t clusters = 0;
    double error_mm = 0.0;
    double fine_error_mm = 0.0;  ///< bound against the finest level (format version 3)
    std::size_t chunk_bytes = 0;
};

/// One object of a progressive file.
struct FileObjectInfo {
    std::string name;
    std::int64_t label = -1;
    std::size_t vertices = 0;
    std::size_t groups = 0;
    std::size_t base_bytes = 0;
    std::vector<FileLevelInfo> levels;
};

/// `strata info FILE.glb`: what a progressive file holds.
struct FileInfo {
    std::string file;
    std::string generator;
    std::size_t total_bytes = 0;
    std::vector<FileObjectInfo> objects;
};

Json file_info_json(const FileInfo& info);
void print_file_info(std::ostream& out, const FileInfo& info);

/// One structure of a planar contour file, as read and cleaned.
struct StructureInfo {
    std::int32_t number = 0;
    std::string name;
    std::string interpreted_type;
    ColorSrgb8 color{};
    std::size_t planes = 0;
    std::size_t contours = 0;
    std::size_t markers = 0;
    std::optional<std::array<double, 2>> plane_range_mm;  ///< first and last plane, when any
};

/// `strata info` of planar contours (RTSTRUCT, contour JSON).
struct ContoursInfo {
    std::string source;
    std::string frame;
    Vec3 normal;
    std::optional<PlaneGrid> reference;
    std::vector<StructureInfo> structures;
    std::vector<Warning> warnings;
};

/// `contours` summarised per structure (the warnings are left to the caller).
ContoursInfo summarize_contours(const PlanarContours& contours);

Json contours_info_json(const ContoursInfo& info);
void print_contours_info(std::ostream& out, const ContoursInfo& info);

}  // namespace strata::cli

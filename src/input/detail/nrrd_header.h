#pragma once

// The NRRD header as read_nrrd checks it (nrrd_header.cpp); internal to strata_input.
// Format: "Definition of NRRD File Format", Teem 1.9+; segments: 3D Slicer's
// vtkMRMLSegmentationStorageNode (SegmentN_Name/_Color/_LabelValue key:=value pairs).

#include <cstddef>
#include <cstdint>
#include <istream>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/report.h"
#include "core/types.h"
#include "input/detail/voxel_decode.h"
#include "input/slice_stack.h"

namespace strata::detail::nrrd {

/// A number as header fields write it: surrounding white space and a leading '+' allowed.
std::optional<double> parse_double(std::string_view text);
std::optional<std::int64_t> parse_int(std::string_view text);

/// NRRD type spellings (format.html section 5, "type").
std::optional<ScalarType> parse_type(std::string_view text);

struct NrrdHeader {
    std::map<std::string, std::string> fields;  // canonical field name -> description
    std::vector<std::pair<std::string, std::string>> key_values;
    bool has_blank_line = false;  // false: the header ran to the end of the file
};

/// Reads the header up to its blank line (or the end of the file): the magic NRRD0001..5, then
/// fields ("name: value", by canonical name; an unknown one is ignored with a warning) and
/// key/value pairs ("key:=value").
NrrdHeader read_header(std::istream& in, const std::string& where, Report& report);

/// One entry per axis of a per-axis field: "(x,y,z)" vectors, quoted strings or bare words.
std::vector<std::string> split_axis_values(std::string_view text,
                                           const std::string& field,
                                           const std::string& where);

/// "(x,y,z)" with `size` components.
std::optional<std::vector<double>> parse_vector(std::string_view text, std::size_t size);

struct Space {
    std::string frame;     // "LPS", "RAS", "LAS", ... or "none"
    Vec3 to_lps{1, 1, 1};  // sign per world axis converting to LPS
    bool is_patient = true;
};

/// A 'space' name (long or short spelling); nullopt for an unknown one.
std::optional<Space> parse_space(std::string_view name);

/// Millimetres per 'space units' unit; 0 for an unknown unit.
double unit_to_mm(std::string_view unit);

/// True for the 'kinds' of a spatial axis: domain, space, ??? or none.
bool is_spatial_kind(std::string_view kind);

struct Segment {
    std::string name;
    std::optional<ColorSrgb8> color;
    std::optional<std::int64_t> label_value;
};

/// The 3D Slicer segments of the key/value pairs, by segment index.
std::map<int, Segment> parse_segments(const NrrdHeader& header, const std::string& where);

/// The label table of the segments, by value (one warning per label value two segments share).
std::vector<LabelInfo> segment_label_table(const std::map<int, Segment>& segments,
                                           const std::string& where,
                                           Report& report);

/// The value of a field, or nullptr when absent.
const std::string* find_field(const NrrdHeader& header, const std::string& name);

/// The value of a field the format requires; refused when absent.
const std::string& require_field(const NrrdHeader& header,
                                 const std::string& name,
                                 const std::string& where);

/// Per-axis field values, checked to number `dimension`.
std::vector<std::string> axis_values(const std::string& value,
                                     const std::string& field,
                                     std::size_t dimension,
                                     const std::string& where);

}  // namespace strata::detail::nrrd

// The NRRD header's text: fields and key/value pairs read line by line, and the field values
// read_nrrd checks (types, vectors, spaces, units, kinds, 3D Slicer segments).
#include "input/detail/nrrd_header.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <istream>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/error.h"
#include "input/detail/text.h"

namespace strata::detail::nrrd {

namespace {

// NRRD headers are a few KiB; this only stops a binary file from being read as one long header.
constexpr std::size_t kMaxHeaderBytes = std::size_t(1) << 20;

/// A number as header fields write it: surrounding white space and a leading '+' allowed.
template <typename T>
std::optional<T> parse_field_number(std::string_view text) {
    text = trim(text);
    if (!text.empty() && text.front() == '+') {
        text.remove_prefix(1);
    }
    return parse_number<T>(text);
}

/// Maps the spellings the format allows (older versions drop the spaces) to one name.
std::string canonical_field(std::string_view name) {
    static const std::map<std::string_view, std::string_view> kAliases = {
        {"centerings", "centers"}, {"blocksize", "block size"}, {"oldmin", "old min"},
        {"oldmax", "old max"},     {"datafile", "data file"},   {"lineskip", "line skip"},
        {"byteskip", "byte skip"}, {"axismins", "axis mins"},   {"axismaxs", "axis maxs"},
    };
    const auto it = kAliases.find(name);
    return std::string(it != kAliases.end() ? it->second : name);
}

bool is_known_field(const std::string& name) {
    static const std::set<std::string> kFields = {
        "content",
        "type",
        "dimension",
        "block size",
        "encoding",
        "endian",
        "min",
        "max",
        "old min",
        "old max",
        "data file",
        "line skip",
        "byte skip",
        "number",
        "sample units",
        "sizes",
        "spacings",
        "thicknesses",
        "axis mins",
        "axis maxs",
        "centers",
        "labels",
        "units",
        "kinds",
        "space",
        "space dimension",
        "space units",
        "space origin",
        "space directions",
        "measurement frame",
    };
    return kFields.count(name) != 0;
}

/// Reads one line ('\n' or "\r\n" terminated); false at the end of the file.
bool read_line(std::istream& in, std::string& line, std::size_t& total, const std::string& where) {
    line.clear();
    std::streambuf* buffer = in.rdbuf();
    bool is_any = false;
    for (;;) {
        const int ch = buffer->sbumpc();
        if (ch == std::char_traits<char>::eof()) {
            in.setstate(std::ios::eofbit);
            break;
        }
        is_any = true;
        if (++total > kMaxHeaderBytes) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": header longer than 1 MiB without the blank line that ends it");
        }
        if (ch == '\n') {
            break;
        }
        line.push_back(static_cast<char>(ch));
    }
    if (!line.empty() && line.back() == '\r') {
        line.pop_back();
    }
    return is_any;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Small helpers

std::optional<double> parse_double(std::string_view text) {
    return parse_field_number<double>(text);
}

std::optional<std::int64_t> parse_int(std::string_view text) {
    return parse_field_number<std::int64_t>(text);
}

// ---------------------------------------------------------------------------------------------
// Stored voxel types

/// NRRD type spellings (format.html section 5, "type").
std::optional<ScalarType> parse_type(std::string_view text) {
    struct Spelling {
        std::string_view name;
        ScalarType type;
    };
    static constexpr Spelling kSpellings[] = {
        {"signed char", ScalarType::Int8},
        {"int8", ScalarType::Int8},
        {"int8_t", ScalarType::Int8},
        {"uchar", ScalarType::UInt8},
        {"unsigned char", ScalarType::UInt8},
        {"uint8", ScalarType::UInt8},
        {"uint8_t", ScalarType::UInt8},
        {"short", ScalarType::Int16},
        {"short int", ScalarType::Int16},
        {"signed short", ScalarType::Int16},
        {"signed short int", ScalarType::Int16},
        {"int16", ScalarType::Int16},
        {"int16_t", ScalarType::Int16},
        {"ushort", ScalarType::UInt16},
        {"unsigned short", ScalarType::UInt16},
        {"unsigned short int", ScalarType::UInt16},
        {"uint16", ScalarType::UInt16},
        {"uint16_t", ScalarType::UInt16},
        {"int", ScalarType::Int32},
        {"signed int", ScalarType::Int32},
        {"int32", ScalarType::Int32},
        {"int32_t", ScalarType::Int32},
        {"uint", ScalarType::UInt32},
        {"unsigned int", ScalarType::UInt32},
        {"uint32", ScalarType::UInt32},
        {"uint32_t", ScalarType::UInt32},
        {"longlong", ScalarType::Int64},
        {"long long", ScalarType::Int64},
        {"long long int", ScalarType::Int64},
        {"signed long long", ScalarType::Int64},
        {"signed long long int", ScalarType::Int64},
        {"int64", ScalarType::Int64},
        {"int64_t", ScalarType::Int64},
        {"ulonglong", ScalarType::UInt64},
        {"unsigned long long", ScalarType::UInt64},
        {"unsigned long long int", ScalarType::UInt64},
        {"uint64", ScalarType::UInt64},
        {"uint64_t", ScalarType::UInt64},
        {"float", ScalarType::Float32},
        {"double", ScalarType::Float64},
    };
    for (const Spelling& s : kSpellings) {
        if (s.name == text) {
            return s.type;
        }
    }
    return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Header

NrrdHeader read_header(std::istream& in, const std::string& where, Report& report) {
    NrrdHeader header;
    std::string line;
    std::size_t total = 0;
    if (!read_line(in, line, total, where) || line.size() < 4 || line.compare(0, 4, "NRRD") != 0) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": bad magic, expected a first line \"NRRD0001\" .. \"NRRD0005\"");
    }
    if (line.size() != 8 || line.compare(0, 7, "NRRD000") != 0 || line[7] < '1' || line[7] > '5') {
        throw Error(ErrorCode::Unsupported, where + ": magic \"" + line.substr(0, 16) +
                                                "\", expected NRRD0001 .. NRRD0005");
    }
    int line_number = 1;
    while (read_line(in, line, total, where)) {
        ++line_number;
        if (line.empty()) {
            header.has_blank_line = true;
            break;
        }
        if (line.front() == '#') {
            continue;
        }
        const std::string at = where + ": header line " + std::to_string(line_number);
        const std::size_t colon = line.find(':');
        if (colon == std::string::npos || colon == 0) {
            throw Error(ErrorCode::InvalidInput,
                        at + ": \"" + line.substr(0, 80) +
                            "\" is neither \"field: value\" nor \"key:=value\"");
        }
        if (colon + 1 < line.size() && line[colon + 1] == '=') {
            header.key_values.emplace_back(line.substr(0, colon), line.substr(colon + 2));
            continue;
        }
        const std::string name = canonical_field(trim(std::string_view(line).substr(0, colon)));
        const std::string value(trim(std::string_view(line).substr(colon + 1)));
        if (!is_known_field(name)) {
            report.warn("input", at, "ignored unknown NRRD field '" + name + "'");
            continue;
        }
        if (!header.fields.emplace(name, value).second) {
            throw Error(ErrorCode::InvalidInput,
                        at + ": header field '" + name + "' given twice, expected once");
        }
        if (name == "data file" && value.rfind("LIST", 0) == 0) {
            break;  // note: the lines that follow are data file names, not fields
        }
    }
    return header;
}

/// One entry per axis of a per-axis field: "(x,y,z)" vectors, quoted strings or bare words.
std::vector<std::string> split_axis_values(std::string_view text,
                                           const std::string& field,
                                           const std::string& where) {
    std::vector<std::string> values;
    std::size_t n = 0;
    while (n < text.size()) {
        if (text[n] == ' ' || text[n] == '\t') {
            ++n;
            continue;
        }
        const char open = text[n];
        if (open == '(' || open == '"') {
            const char close = open == '(' ? ')' : '"';
            const std::size_t end = text.find(close, n + 1);
            if (end == std::string_view::npos) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": header field '" + field + "': missing '" + close + "'");
            }
            values.emplace_back(text.substr(n, end + 1 - n));
            n = end + 1;
        } else {
            const std::size_t start = n;
            while (n < text.size() && text[n] != ' ' && text[n] != '\t') {
                ++n;
            }
            values.emplace_back(text.substr(start, n - start));
        }
    }
    return values;
}

/// "(x,y,z)" with `size` components.
std::optional<std::vector<double>> parse_vector(std::string_view text, std::size_t size) {
    text = trim(text);
    if (text.size() < 2 || text.front() != '(' || text.back() != ')') {
        return std::nullopt;
    }
    text = text.substr(1, text.size() - 2);
    std::vector<double> values;
    std::size_t start = 0;
    for (;;) {
        const std::size_t comma = text.find(',', start);
        const auto value = parse_double(text.substr(start, comma - start));
        if (!value || !std::isfinite(*value)) {
            return std::nullopt;
        }
        values.push_back(*value);
        if (comma == std::string_view::npos) {
            break;
        }
        start = comma + 1;
    }
    if (values.size() != size) {
        return std::nullopt;
    }
    return values;
}

std::optional<Space> parse_space(std::string_view name) {
    struct Named {
        std::string_view long_name, short_name, frame;
        Vec3 to_lps;
    };
    static constexpr Named kPatientSpaces[] = {
        {"left-posterior-superior", "LPS", "LPS", {1, 1, 1}},
        {"right-anterior-superior", "RAS", "RAS", {-1, -1, 1}},
        {"left-anterior-superior", "LAS", "LAS", {1, -1, 1}},
    };
    for (const Named& s : kPatientSpaces) {
        if (name == s.long_name || name == s.short_name) {
            return Space{std::string(s.frame), s.to_lps, true};
        }
    }
    if (name == "scanner-xyz" || name == "3D-right-handed" || name == "3D-left-handed") {
        return Space{std::string(name), {1, 1, 1}, false};
    }
    return std::nullopt;
}

double unit_to_mm(std::string_view unit) {
    if (unit == "mm" || unit.empty()) {
        return 1.0;
    }
    if (unit == "m") {
        return 1000.0;
    }
    if (unit == "cm") {
        return 10.0;
    }
    if (unit == "um" || unit == "micron" || unit == "microns") {
        return 0.001;
    }
    return 0.0;
}

bool is_spatial_kind(std::string_view kind) {
    return kind == "domain" || kind == "space" || kind == "???" || kind == "none";
}

// ---------------------------------------------------------------------------------------------
// 3D Slicer segmentation metadata

std::map<int, Segment> parse_segments(const NrrdHeader& header, const std::string& where) {
    std::map<int, Segment> segments;
    for (const auto& [key, value] : header.key_values) {
        if (key.rfind("Segment", 0) != 0) {
            continue;
        }
        const std::size_t underscore = key.find('_');
        if (underscore == std::string::npos || underscore == 7) {
            continue;
        }
        const auto index = parse_int(std::string_view(key).substr(7, underscore - 7));
        if (!index || *index < 0 || *index > 1'000'000) {
            continue;
        }
        const std::string_view what = std::string_view(key).substr(underscore + 1);
        Segment& segment = segments[static_cast<int>(*index)];
        const std::string at = where + ": " + key;
        if (what == "Name") {
            segment.name = std::string(trim(value));
        } else if (what == "Color") {
            const std::vector<std::string_view> words = split_words(value);
            ColorSrgb8 color{};
            if (words.size() != 3) {
                throw Error(ErrorCode::InvalidInput,
                            at + " = \"" + value + "\", expected three numbers 0..1");
            }
            for (int c = 0; c < 3; ++c) {
                const auto component = parse_double(words[c]);
                if (!component || !(*component >= 0.0 && *component <= 1.0)) {
                    throw Error(ErrorCode::InvalidInput,
                                at + " = \"" + value + "\", expected three numbers 0..1");
                }
                color[c] = static_cast<std::uint8_t>(std::lround(255.0 * *component));
            }
            segment.color = color;
        } else if (what == "LabelValue") {
            const auto label = parse_int(value);
            if (!label || *label < 1 || *label > 65535) {
                throw Error(ErrorCode::InvalidInput,
                            at + " = \"" + value + "\", expected a label value 1..65535");
            }
            segment.label_value = *label;
        }
    }
    return segments;
}

std::vector<LabelInfo> segment_label_table(const std::map<int, Segment>& segments,
                                           const std::string& where,
                                           Report& report) {
    std::vector<LabelInfo> table;
    for (const auto& [index, segment] : segments) {
        // note: as 3D Slicer, a segment without LabelValue has label 1 (one segment per layer)
        const auto value = static_cast<std::uint16_t>(segment.label_value.value_or(1));
        const auto same = std::find_if(table.begin(), table.end(),
                                       [&](const LabelInfo& l) { return l.value == value; });
        if (same != table.end()) {
            report.warn("input", where,
                        "segments '" + same->name + "' and '" + segment.name +
                            "' share label value " + std::to_string(value) +
                            "; keeping the first name");
            continue;
        }
        LabelInfo info;
        info.value = value;
        info.name = segment.name.empty() ? "Segment_" + std::to_string(index) : segment.name;
        info.color = segment.color.value_or(palette_color(value));
        table.push_back(std::move(info));
    }
    std::sort(table.begin(), table.end(),
              [](const LabelInfo& a, const LabelInfo& b) { return a.value < b.value; });
    return table;
}

// ---------------------------------------------------------------------------------------------

const std::string* find_field(const NrrdHeader& header, const std::string& name) {
    const auto it = header.fields.find(name);
    return it != header.fields.end() ? &it->second : nullptr;
}

const std::string& require_field(const NrrdHeader& header,
                                 const std::string& name,
                                 const std::string& where) {
    const std::string* value = find_field(header, name);
    if (value == nullptr) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": header field '" + name + "' is missing, expected it");
    }
    return *value;
}

/// Per-axis field values, checked to number `dimension`.
std::vector<std::string> axis_values(const std::string& value,
                                     const std::string& field,
                                     std::size_t dimension,
                                     const std::string& where) {
    std::vector<std::string> values = split_axis_values(value, field, where);
    if (values.size() != dimension) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": header field '" + field + "' has " + std::to_string(values.size()) +
                        " values, expected " + std::to_string(dimension) + " (dimension)");
    }
    return values;
}

}  // namespace strata::detail::nrrd

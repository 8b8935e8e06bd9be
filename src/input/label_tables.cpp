// Colour tables naming the labels of a segmentation, format detected by content:
// - 3D Slicer colour table (`.ctbl`/`.txt`): "# comment" lines, then "value name r g b a" with
//   colour components 0..255 (vtkMRMLColorTableStorageNode);
// - ITK-SNAP label description: "IDX -R- -G- -B- -A-- VIS MSH \"LABEL\"" with A in 0..1;
// - JSON object: {"1": "spleen", ...} (TotalSegmentator class maps) or
//   {"1": {"name": "spleen", "color": [r, g, b]}} with components 0..255 (or all within 0..1).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "input/detail/readers.h"
#include "input/detail/text.h"

namespace strata::detail {

namespace {

// Colour tables are a few KiB; this only stops a wrongly named huge file from being slurped.
constexpr std::uintmax_t kMaxTableBytes = std::uintmax_t(64) << 20;
// Between the fields of a text table line ('\r': a stray carriage return also separates).
constexpr std::string_view kFieldSeparators = " \t\r";

/// A real number, all of `text`, and finite.
std::optional<double> parse_finite(std::string_view text) {
    const auto value = parse_number<double>(text);
    if (!value || !std::isfinite(*value)) {
        return std::nullopt;
    }
    return value;
}

std::string read_text(const std::filesystem::path& file, const std::string& where) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::file_status status = fs::status(file, ec);
    if (status.type() == fs::file_type::not_found) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": no such colour table file " + file.string());
    }
    if (ec || status.type() != fs::file_type::regular) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": colour table " + file.string() +
                        " is not a regular file (a FIFO, device or folder), expected a text or "
                        "JSON file");
    }
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        throw Error(ErrorCode::Io, where + ": cannot open colour table " + file.string() + ": " +
                                       std::strerror(errno));
    }
    // note: read in pieces and stop at the cap, whatever size the file system reports
    std::string text;
    char buffer[1 << 16];
    while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
        text.append(buffer, static_cast<std::size_t>(in.gcount()));
        if (text.size() > kMaxTableBytes) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": more than " + std::to_string(kMaxTableBytes) +
                            " bytes is too large for a colour table (at most 64 MiB expected)");
        }
    }
    if (in.bad()) {
        throw Error(ErrorCode::Io, where + ": read error");
    }
    return text;
}

/// Adds an entry, rejecting duplicates; value 0 (background) is skipped.
void add_entry(std::vector<LabelInfo>& table,
               long long value,
               std::string name,
               ColorSrgb8 color,
               const std::string& at) {
    if (value < 0 || value > 65535) {
        throw Error(ErrorCode::InvalidInput,
                    at + ": label value " + std::to_string(value) + ", expected 0..65535");
    }
    if (value == 0) {
        return;
    }
    const auto label = static_cast<std::uint16_t>(value);
    if (std::any_of(table.begin(), table.end(),
                    [&](const LabelInfo& l) { return l.value == label; })) {
        throw Error(ErrorCode::InvalidInput,
                    at + ": label value " + std::to_string(value) + " is listed twice");
    }
    if (name.empty()) {
        name = "label " + std::to_string(value);
    }
    table.push_back({label, std::move(name), color});
}

std::uint8_t color_component(std::string_view word, const std::string& at, const char* expected) {
    const auto value = parse_number<long long>(word);
    if (!value || *value < 0 || *value > 255) {
        throw Error(ErrorCode::InvalidInput, at + ": colour component \"" + std::string(word) +
                                                 "\", expected an integer 0..255 (" + expected +
                                                 ")");
    }
    return static_cast<std::uint8_t>(*value);
}

/// "IDX R G B A VIS MSH "LABEL"" (ITK-SNAP label description).
void parse_itksnap_line(std::string_view line,
                        std::vector<LabelInfo>& table,
                        const std::string& at) {
    const char* expected = "IDX -R- -G- -B- -A-- VIS MSH \"LABEL\"";
    const std::size_t quote = line.find('"');
    const std::size_t end = line.rfind('"');
    if (quote == std::string_view::npos || end == quote) {
        throw Error(ErrorCode::InvalidInput,
                    at + ": label name is not quoted, expected ITK-SNAP fields " + expected);
    }
    const std::vector<std::string_view> words =
        split_words(line.substr(0, quote), kFieldSeparators);
    if (words.size() != 7) {
        throw Error(ErrorCode::InvalidInput, at + ": " + std::to_string(words.size()) +
                                                 " numbers before the label name, expected 7 (" +
                                                 expected + ")");
    }
    const auto value = parse_number<long long>(words[0]);
    if (!value) {
        throw Error(ErrorCode::InvalidInput, at + ": label value \"" + std::string(words[0]) +
                                                 "\" is not an integer, expected " + expected);
    }
    ColorSrgb8 color{};
    for (int c = 0; c < 3; ++c) {
        color[c] = color_component(words[1 + c], at, expected);
    }
    const auto alpha = parse_finite(words[4]);
    const auto visible = parse_number<long long>(words[5]);
    const auto mesh = parse_number<long long>(words[6]);
    if (!alpha || *alpha < 0 || *alpha > 1 || !visible || !mesh) {
        throw Error(
            ErrorCode::InvalidInput,
            at + ": -A-- VIS MSH must be a number 0..1 and two integers, expected " + expected);
    }
    add_entry(table, *value, std::string(line.substr(quote + 1, end - quote - 1)), color, at);
}

/// "value name r g b a" (3D Slicer colour table; names have no spaces).
void parse_slicer_line(std::string_view line,
                       std::vector<LabelInfo>& table,
                       const std::string& at) {
    const char* expected = "value name r g b a";
    const std::vector<std::string_view> words = split_words(line, kFieldSeparators);
    if (words.size() < 5 || words.size() > 6) {
        throw Error(ErrorCode::InvalidInput, at + ": " + std::to_string(words.size()) +
                                                 " fields, expected 3D Slicer colour table "
                                                 "fields \"" +
                                                 expected + "\"");
    }
    const auto value = parse_number<long long>(words[0]);
    if (!value) {
        throw Error(ErrorCode::InvalidInput, at + ": label value \"" + std::string(words[0]) +
                                                 "\" is not an integer, expected \"" + expected +
                                                 "\"");
    }
    ColorSrgb8 color{};
    for (int c = 0; c < 3; ++c) {
        color[c] = color_component(words[2 + c], at, expected);
    }
    if (words.size() == 6) {
        color_component(words[5], at, expected);  // alpha: checked, unused
    }
    add_entry(table, *value, std::string(words[1]), color, at);
}

std::vector<LabelInfo> parse_text_table(const std::string& text, const std::string& where) {
    std::vector<LabelInfo> table;
    enum class Format { Unknown, Slicer, ItkSnap } format = Format::Unknown;
    std::size_t start = 0;
    int line_number = 0;
    while (start <= text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) {
            end = text.size();
        }
        const std::string_view line = trim(std::string_view(text).substr(start, end - start));
        start = end + 1;
        ++line_number;
        if (line.empty() || line.front() == '#') {
            continue;
        }
        const std::string at = where + ":" + std::to_string(line_number);
        // note: the format is fixed by the first entry: a quoted name means ITK-SNAP
        const Format line_format =
            line.find('"') != std::string_view::npos ? Format::ItkSnap : Format::Slicer;
        if (format == Format::Unknown) {
            format = line_format;
        } else if (line_format != format) {
            throw Error(
                ErrorCode::InvalidInput,
                at + ": entry in " + (line_format == Format::ItkSnap ? "ITK-SNAP" : "3D Slicer") +
                    " format, expected " + (format == Format::ItkSnap ? "ITK-SNAP" : "3D Slicer") +
                    " format as in the first entry");
        }
        if (format == Format::ItkSnap) {
            parse_itksnap_line(line, table, at);
        } else {
            parse_slicer_line(line, table, at);
        }
    }
    return table;
}

/// 1-based line of the first occurrence of "key" in the JSON text (for messages).
int line_of_key(const std::string& text, const std::string& key) {
    const std::size_t at = text.find('"' + key + '"');
    if (at == std::string::npos) {
        return 0;
    }
    return 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
}

ColorSrgb8 json_color(const nlohmann::json& value, const std::string& at) {
    const char* expected = "expected [r, g, b] with integers 0..255 or numbers 0..1";
    if (!value.is_array() || value.size() < 3 || value.size() > 4) {
        throw Error(ErrorCode::InvalidInput,
                    at + ": \"color\" is " + value.dump() + ", " + expected);
    }
    bool is_unit_range = true;  // all three within 0..1 and at least one not an integer
    bool has_fraction = false;
    for (int c = 0; c < 3; ++c) {
        if (!value[c].is_number()) {
            throw Error(ErrorCode::InvalidInput,
                        at + ": \"color\" is " + value.dump() + ", " + expected);
        }
        const double v = value[c].get<double>();
        is_unit_range = is_unit_range && v >= 0.0 && v <= 1.0;
        has_fraction = has_fraction || v != std::floor(v);
    }
    ColorSrgb8 color{};
    for (int c = 0; c < 3; ++c) {
        const double v = value[c].get<double>();
        if (is_unit_range && has_fraction) {
            color[c] = static_cast<std::uint8_t>(std::lround(255.0 * v));
        } else if (v >= 0.0 && v <= 255.0 && v == std::floor(v)) {
            color[c] = static_cast<std::uint8_t>(v);
        } else {
            throw Error(ErrorCode::InvalidInput,
                        at + ": \"color\" is " + value.dump() + ", " + expected);
        }
    }
    return color;
}

std::vector<LabelInfo> parse_json_table(const std::string& text, const std::string& where) {
    nlohmann::json root;
    try {
        root = nlohmann::json::parse(text);
    } catch (const nlohmann::json::parse_error& e) {
        const std::size_t byte = std::min<std::size_t>(e.byte, text.size());
        const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + byte, '\n'));
        throw Error(ErrorCode::InvalidInput,
                    where + ":" + std::to_string(line) + ": malformed JSON: " + e.what());
    }
    if (!root.is_object()) {
        throw Error(
            ErrorCode::InvalidInput,
            where + ": JSON colour table is not an object, expected {\"1\": \"name\", ...}");
    }
    std::vector<LabelInfo> table;
    for (const auto& [key, value] : root.items()) {
        const std::string at = where + ":" + std::to_string(line_of_key(text, key));
        const auto label = parse_number<long long>(key);
        if (!label) {
            throw Error(ErrorCode::InvalidInput,
                        at + ": key \"" + key + "\" is not an integer label value 0..65535");
        }
        const auto label_value =
            static_cast<std::uint16_t>(std::clamp<long long>(*label, 0, 65535));
        if (value.is_string()) {
            add_entry(table, *label, value.get<std::string>(), palette_color(label_value), at);
        } else if (value.is_object()) {
            const auto name = value.find("name");
            if (name == value.end() || !name->is_string()) {
                throw Error(ErrorCode::InvalidInput,
                            at + ": label " + key +
                                " has no string \"name\", expected "
                                "{\"name\": \"...\", \"color\": [r, g, b]}");
            }
            const auto color = value.find("color");
            add_entry(table, *label, name->get<std::string>(),
                      color != value.end() ? json_color(*color, at) : palette_color(label_value),
                      at);
        } else {
            throw Error(ErrorCode::InvalidInput,
                        at + ": label " + key + " is " + value.dump() +
                            ", expected a name or {\"name\": \"...\", \"color\": [r, g, b]}");
        }
    }
    return table;
}

}  // namespace

std::vector<LabelInfo> read_color_table(const std::filesystem::path& file) {
    const std::string where = file.filename().string();
    std::string text = read_text(file, where);
    if (text.rfind("\xEF\xBB\xBF", 0) == 0) {
        text.erase(0, 3);  // UTF-8 byte order mark
    }
    const std::string_view content = trim(text);
    std::vector<LabelInfo> table =
        !content.empty() && (content.front() == '{' || content.front() == '[')
            ? parse_json_table(text, where)
            : parse_text_table(text, where);
    if (table.empty()) {
        throw Error(ErrorCode::InvalidInput,
                    where +
                        ": colour table has no label entries (other than 0), expected "
                        "3D Slicer, ITK-SNAP or JSON entries");
    }
    std::sort(table.begin(), table.end(),
              [](const LabelInfo& a, const LabelInfo& b) { return a.value < b.value; });
    return table;
}

}  // namespace strata::detail

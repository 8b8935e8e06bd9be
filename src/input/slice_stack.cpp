#include "input/slice_stack.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include "core/error.h"

namespace strata {

namespace {

std::string format_bytes(long double bytes) {
    const char* units[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
    int u = 0;
    while (bytes >= 1024.0L && u < 6) {
        bytes /= 1024.0L;
        ++u;
    }
    std::ostringstream s;
    s.precision(u == 0 ? 0 : 1);
    s << std::fixed << static_cast<double>(bytes) << ' ' << units[u];
    return s.str();
}

}  // namespace

void check_stack_dimensions(std::uint64_t width,
                            std::uint64_t height,
                            std::uint64_t depth,
                            const std::string& where,
                            std::uint64_t max_bytes) {
    std::ostringstream dims;
    dims << width << 'x' << height << 'x' << depth;
    if (width == 0 || height == 0 || depth == 0) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": empty dimensions " + dims.str() + ", expected all positive");
    }
    // note: long double so that absurd headers (2^63 per axis) still give a number to print
    const long double bytes = static_cast<long double>(width) * height * depth * 2.0L;
    if (width > 0xFFFFFFFFu || height > 0xFFFFFFFFu || depth > 0xFFFFFFFFu ||
        bytes > static_cast<long double>(max_bytes)) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": dimensions " + dims.str() + " would need " + format_bytes(bytes) +
                        " of memory for the label images, more than the limit of " +
                        format_bytes(static_cast<long double>(max_bytes)));
    }
}

void check_spacing(Vec3 spacing_mm, const std::string& where) {
    for (int i = 0; i < 3; ++i) {
        if (!std::isfinite(spacing_mm[i]) || spacing_mm[i] <= 0.0) {
            std::ostringstream s;
            s << where << ": spacing " << spacing_mm.x << ',' << spacing_mm.y << ',' << spacing_mm.z
              << " has a " << (std::isfinite(spacing_mm[i]) ? "" : "non-finite ") << "value "
              << spacing_mm[i] << " along axis "
              << "xyz"[i] << ", expected finite positive millimetres";
            throw Error(ErrorCode::InvalidInput, s.str());
        }
    }
}

void override_spacing(SliceStack& stack, Vec3 spacing_mm) {
    check_spacing(spacing_mm, "--spacing");
    for (int c = 0; c < 3; ++c) {
        Vec3 column = stack.index_to_world.column(c);
        const double length = norm(column);
        // note: a degenerate direction (zero column) falls back to the identity axis
        Vec3 unit = length > 0 ? (1.0 / length) * column : Vec3{};
        if (length <= 0) {
            unit[c] = 1.0;
        }
        for (int r = 0; r < 3; ++r) {
            stack.index_to_world.linear[r][c] = unit[r] * spacing_mm[c];
        }
    }
}

std::vector<std::uint16_t> present_labels(const SliceStack& stack) {
    std::vector<bool> seen(65536, false);
    for (std::uint16_t v : stack.labels) {
        seen[v] = true;
    }
    std::vector<std::uint16_t> values;
    for (std::uint32_t v = 1; v < seen.size(); ++v) {
        if (seen[v]) {
            values.push_back(static_cast<std::uint16_t>(v));
        }
    }
    return values;
}

ColorSrgb8 palette_color(std::uint16_t value) {
    // note: a fixed 20-colour qualitative palette (Glasbey-like), cycled by label value
    static constexpr ColorSrgb8 kPalette[] = {
        {230, 25, 75},   {60, 180, 75},   {255, 225, 25},  {0, 130, 200},   {245, 130, 48},
        {145, 30, 180},  {70, 240, 240},  {240, 50, 230},  {210, 245, 60},  {250, 190, 212},
        {0, 128, 128},   {220, 190, 255}, {170, 110, 40},  {255, 250, 200}, {128, 0, 0},
        {170, 255, 195}, {128, 128, 0},   {255, 215, 180}, {0, 0, 128},     {128, 128, 128},
    };
    constexpr std::size_t n = sizeof(kPalette) / sizeof(kPalette[0]);
    return kPalette[(value + n - 1) % n];
}

void complete_label_table(SliceStack& stack) {
    const std::vector<std::uint16_t> present = present_labels(stack);
    std::vector<LabelInfo> table;
    table.reserve(present.size());
    for (std::uint16_t v : present) {
        auto it = std::find_if(stack.label_table.begin(), stack.label_table.end(),
                               [v](const LabelInfo& l) { return l.value == v; });
        if (it != stack.label_table.end()) {
            table.push_back(*it);
            if (table.back().name.empty()) {
                table.back().name = "label " + std::to_string(v);
            }
        } else {
            table.push_back({v, "label " + std::to_string(v), palette_color(v)});
        }
    }
    stack.label_table = std::move(table);
}

namespace {

std::string lowercase(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

}  // namespace

void select_labels(SliceStack& stack, const std::vector<std::string>& selectors) {
    std::vector<bool> keep(65536, false);
    for (const std::string& written : selectors) {
        // note: "liver, spleen" splits into "liver" and " spleen": spaces around a name are not
        // part of it (names with inner spaces, "Left Lung", still match)
        const std::size_t first = written.find_first_not_of(" \t");
        if (first == std::string::npos) {
            throw Error(ErrorCode::InvalidInput,
                        "--labels: an empty entry in the list, expected label values or names "
                        "separated by commas");
        }
        const std::string selector =
            written.substr(first, written.find_last_not_of(" \t") - first + 1);
        bool found = false;
        for (const LabelInfo& label : stack.label_table) {
            if (std::to_string(label.value) == selector ||
                lowercase(label.name) == lowercase(selector)) {
                keep[label.value] = true;
                found = true;
            }
        }
        if (!found) {
            std::string available;
            for (const LabelInfo& label : stack.label_table) {
                available += (available.empty() ? "" : ", ") + std::to_string(label.value) + " (" +
                             label.name + ")";
            }
            throw Error(ErrorCode::InvalidInput,
                        "--labels: '" + selector + "' matches no label of " + stack.source +
                            "; available: " + (available.empty() ? "none" : available));
        }
    }
    for (std::uint16_t& v : stack.labels) {
        if (!keep[v]) {
            v = 0;
        }
    }
    std::erase_if(stack.label_table, [&](const LabelInfo& l) { return !keep[l.value]; });
}

}  // namespace strata

#include "input/write_slice_stack.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <system_error>

#include <nlohmann/json.hpp>

#include "core/atomic_write.h"
#include "core/error.h"
#include "input/detail/image_files.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

/// Writes a PNG through a temporary file renamed into place. `pixels` holds `channels` values
/// per pixel: 8-bit bytes, or 16-bit values when `sixteen_bit`.
void write_png_atomically(const fs::path& file,
                          const void* pixels,
                          std::uint32_t width,
                          std::uint32_t height,
                          int channels,
                          bool sixteen_bit) {
    // note: the writer picks the format by extension, so the temporary keeps ".png"
    fs::path tmp = file;
    std::string tmp_name = file.stem().string();
    tmp_name.insert(tmp_name.begin(), '.');
    tmp_name += ".tmp.png";
    tmp.replace_filename(tmp_name);
    std::string message;
    if (!detail::write_png_file(tmp, pixels, width, height, channels, sixteen_bit, message)) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw Error(ErrorCode::Io, file.string() + ": cannot write PNG: " + message);
    }
    std::error_code ec;
    fs::rename(tmp, file, ec);
    if (ec) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw Error(ErrorCode::Io,
                    file.string() + ": cannot rename temporary file: " + ec.message());
    }
}

}  // namespace

void write_png_stack(const SliceStack& stack, const fs::path& dir) {
    const fs::path slices = dir / "slices";
    std::error_code ec;
    fs::create_directories(slices, ec);
    if (ec) {
        throw Error(ErrorCode::Io, slices.string() + ": cannot create folder: " + ec.message());
    }
    const bool sixteen_bit = std::any_of(stack.labels.begin(), stack.labels.end(),
                                         [](std::uint16_t v) { return v > 255; });
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        char name[32];
        std::snprintf(name, sizeof(name), "slice_%04u.png", k);
        const auto slice = stack.slice(k);
        if (sixteen_bit) {
            write_png_atomically(slices / name, slice.data(), stack.width, stack.height, 1, true);
        } else {
            std::vector<std::uint8_t> bytes(slice.size());
            std::transform(slice.begin(), slice.end(), bytes.begin(),
                           [](std::uint16_t v) { return static_cast<std::uint8_t>(v); });
            write_png_atomically(slices / name, bytes.data(), stack.width, stack.height, 1, false);
        }
    }
    nlohmann::ordered_json meta;
    meta["dims"] = {stack.width, stack.height, stack.depth};
    const Vec3 spacing = stack.spacing_mm();
    meta["spacing_mm"] = {spacing.x, spacing.y, spacing.z};
    meta["origin_mm"] = {stack.index_to_world.translation.x, stack.index_to_world.translation.y,
                         stack.index_to_world.translation.z};
    meta["frame"] = "LPS";
    nlohmann::ordered_json matrix = nlohmann::ordered_json::array();
    for (int r = 0; r < 3; ++r) {
        const auto& row = stack.index_to_world.linear[r];
        matrix.push_back({row[0], row[1], row[2], stack.index_to_world.translation[r]});
    }
    matrix.push_back({0, 0, 0, 1});
    meta["index_to_world_mm"] = matrix;
    meta["slice_axis"] = "k (third index); slice_0000 is the first slice";
    meta["png_layout"] = std::string(sixteen_bit ? "16" : "8") +
                         "-bit greyscale; PNG column = i (first index), PNG row = j (second index)";
    meta["value_type"] = "labels";
    meta["source"] = stack.source;
    nlohmann::ordered_json labels = nlohmann::ordered_json::object();
    nlohmann::ordered_json colors = nlohmann::ordered_json::object();
    for (const LabelInfo& label : stack.label_table) {
        labels[std::to_string(label.value)] = label.name;
        colors[std::to_string(label.value)] = {label.color[0], label.color[1], label.color[2]};
    }
    meta["labels"] = labels;
    meta["colors"] = colors;
    write_file_atomically(dir / "meta.json", meta.dump(1) + "\n");
}

void write_rgb_png(const RgbImage& image, const fs::path& file) {
    if (file.has_parent_path()) {
        std::error_code ec;
        fs::create_directories(file.parent_path(), ec);
        if (ec) {
            throw Error(ErrorCode::Io,
                        file.parent_path().string() + ": cannot create folder: " + ec.message());
        }
    }
    write_png_atomically(file, image.rgb.data(), image.width, image.height, 3, false);
}

}  // namespace strata

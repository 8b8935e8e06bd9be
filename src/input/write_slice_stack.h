#pragma once

#include <filesystem>

#include "core/rgb_image.h"
#include "input/slice_stack.h"

namespace strata {

/// Writes `stack` as a PNG stack: DIR/slices/slice_KKKK.png
/// (8-bit greyscale when every label is <= 255, else 16-bit; column = i, row = j) and
/// DIR/meta.json (dims, spacing, LPS index_to_world_mm, label names and colours), which
/// read_slice_stack(DIR) reads back exactly. Each file is written atomically.
/// Throws Error{Io} when a file cannot be written.
void write_png_stack(const SliceStack& stack, const std::filesystem::path& dir);

/// Writes an RGB picture as PNG, atomically. Throws Error{Io} when it cannot be written.
void write_rgb_png(const RgbImage& image, const std::filesystem::path& file);

}  // namespace strata

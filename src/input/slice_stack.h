#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/types.h"

namespace strata {

/// One object of a label map: its value in the images, its name and display colour.
struct LabelInfo {
    std::uint16_t value = 0;  ///< pixel value in the label images (never 0: 0 is background)
    std::string name;         ///< structure name ("liver"), never empty
    ColorSrgb8 color{};       ///< display colour, sRGB 8 bit
};

/// A stack of segmented slices: the input of the reconstruction pipeline.
///
/// Pixel (i, j) of slice k is `labels[(k * height + j) * width + i]`; i is the column (x), j the
/// row (y). Inside the reconstruction the centre of pixel (i, j) lies at (i + 0.5, j + 0.5) px
/// (docs/test-catalogue.md); `index_to_world` maps voxel indices (i, j, k), with pixel centres
/// at integer indices (the NIfTI/ITK convention), to patient LPS millimetres.
struct SliceStack {
    std::uint32_t width = 0;            ///< pixels per row (x)
    std::uint32_t height = 0;           ///< rows per slice (y)
    std::uint32_t depth = 0;            ///< number of slices (z)
    std::vector<std::uint16_t> labels;  ///< width * height * depth label values, 0 = background

    Affine3 index_to_world;  ///< voxel index -> patient LPS mm (columns: direction * spacing)
    std::vector<LabelInfo> label_table;  ///< one entry per non-zero label present or named
    std::string source;        ///< where the stack came from (file or folder, or "phantom NAME")
    std::string source_frame;  ///< frame the file declared its world in ("RAS", "LPS", "none")

    std::size_t slice_size() const { return std::size_t(width) * height; }
    std::span<const std::uint16_t> slice(std::uint32_t k) const {
        return {labels.data() + std::size_t(k) * slice_size(), slice_size()};
    }
    std::span<std::uint16_t> slice(std::uint32_t k) {
        return {labels.data() + std::size_t(k) * slice_size(), slice_size()};
    }
    std::uint16_t at(std::uint32_t i, std::uint32_t j, std::uint32_t k) const {
        return labels[(std::size_t(k) * height + j) * width + i];
    }
    /// Spacing in mm along i, j, k: the lengths of the affine's columns.
    Vec3 spacing_mm() const {
        return {norm(index_to_world.column(0)), norm(index_to_world.column(1)),
                norm(index_to_world.column(2))};
    }
};

/// Upper bound on the bytes a stack may occupy in memory before readers refuse it
/// (Error{InvalidInput} saying how much it would need). 8 GiB by default.
inline constexpr std::uint64_t kMaxStackBytes = std::uint64_t(8) << 30;

/// Checks dimensions before allocating: all positive and width*height*depth*2 bytes at most
/// `max_bytes`. Throws Error{InvalidInput} naming `where`, the dims and the memory needed.
void check_stack_dimensions(std::uint64_t width,
                            std::uint64_t height,
                            std::uint64_t depth,
                            const std::string& where,
                            std::uint64_t max_bytes = kMaxStackBytes);

/// Checks that spacing values are finite and positive; throws Error{InvalidInput} naming `where`.
void check_spacing(Vec3 spacing_mm, const std::string& where);

/// Replaces the affine's column lengths by `spacing_mm`, keeping directions and origin
/// (the CLI's --spacing override). Throws Error{InvalidInput} for non-positive values.
void override_spacing(SliceStack& stack, Vec3 spacing_mm);

/// Sorted distinct non-zero label values present in the images.
std::vector<std::uint16_t> present_labels(const SliceStack& stack);

/// Adds a LabelInfo for every present label that has none, named "label N" and coloured from
/// the fixed palette; drops table entries whose label is absent. Keeps the table sorted by value.
void complete_label_table(SliceStack& stack);

/// Fixed palette of distinct colours (used when neither the file nor a colour table names one).
ColorSrgb8 palette_color(std::uint16_t value);

}  // namespace strata

namespace strata {

/// Keeps only the labels named by `selectors` (each a label value like "5" or a name like
/// "liver", case-insensitive) and sets every other pixel to background. Throws
/// Error{InvalidInput} for a selector that matches no label, listing the available ones.
void select_labels(SliceStack& stack, const std::vector<std::string>& selectors);

}  // namespace strata

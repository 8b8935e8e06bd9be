#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "input/slice_stack.h"

namespace strata {

/// Statistics that tell a label map from an intensity image (a greyscale picture, a CT) read as
/// one by mistake. In a label map every object is a region: a pixel's neighbours in its slice
/// mostly carry its value. In an intensity image neighbouring pixels differ by noise and shading,
/// so its many values are scattered in specks.
struct LabelMapStatistics {
    std::size_t labels = 0;             ///< distinct non-zero values
    std::size_t foreground_pixels = 0;  ///< non-zero pixels
    /// Of the in-slice neighbour pairs (4-neighbourhood) with a non-zero pixel, the share whose
    /// two pixels carry the same value.
    double neighbour_agreement = 1.0;
    /// Share of the non-zero pixels that no 4-neighbour in their slice shares the value with.
    double isolated_share = 0.0;
    /// Share of the labels whose pixels are mostly isolated (more than half of them).
    double speckled_label_share = 0.0;
};

/// One pass over the stack's pixels.
LabelMapStatistics label_map_statistics(const SliceStack& stack);

/// The reason the stack is evidently not a label map (many labels, most of them speckled, pixels
/// agreeing with few neighbours), or nothing. Deliberately conservative: every label map of the
/// shared data (FreeSurfer's 188 labels with their thin cortical ribbons included) passes with a
/// wide margin, see tests/input/label_map_check_test.cpp.
std::optional<std::string> intensity_image_evidence(const LabelMapStatistics& statistics);

/// Throws Error{InvalidInput} naming the stack's source, what was found and what to do
/// (--labels, or --force-label-map) when `intensity_image_evidence` finds evidence.
void check_is_label_map(const SliceStack& stack);

}  // namespace strata

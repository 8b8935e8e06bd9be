#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "phantom/solids.h"

namespace strata {

// A whole-body-like label map for the speed and memory benchmark (issue 19): the 117 classes
// of TotalSegmentator (v1 class map: organs, lung lobes, 25 vertebrae, 24 ribs, heart and
// vessels, muscles, bones, brain and skull) drawn as organ-like analytic solids on a
// 512 x 512 x 1000 grid of 1 mm pixels and 1.5 mm slices, head at the last slice. Anatomy is
// approximate: sizes, positions, overlaps and topology (vertebral arches and hip bones of genus
// 1, a skull shell, multi-component cartilages) are what a real segmentation has, not its
// shapes.

inline constexpr std::uint32_t kWholeBodyWidth = 512;
inline constexpr std::uint32_t kWholeBodyHeight = 512;
inline constexpr std::uint32_t kWholeBodyDepth = 1000;
inline constexpr double kWholeBodySliceSpacingPx = 1.5;  ///< d: 1.5 mm slices of 1 mm pixels

/// One class of the map: its TotalSegmentator value and name, and its solid in px (x = column
/// towards the patient's left, y = row towards posterior, z = k * d towards superior).
struct LabelledSolid {
    std::uint16_t label = 0;
    std::string name;
    Solid solid;
};

/// The 117 classes in painting order (later ones cover earlier ones where they overlap).
std::vector<LabelledSolid> whole_body_solids();

}  // namespace strata

// Links between slices follow the connectivity of R's middle layer (the AND of the two slices):
// foreground 8-connected, so pixels meeting only at a corner are one overlap piece, one link.
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "contours/extract_contours.h"
#include "input/slice_stack.h"

namespace strata {
namespace {

TEST(LinkConnectivity, DiagonalOverlapIsOneLink) {
    SliceStack stack;
    stack.width = 5;
    stack.height = 5;
    stack.depth = 2;
    stack.labels.assign(std::size_t(stack.width) * stack.height * stack.depth, 0);
    for (std::uint32_t k = 0; k < 2; ++k) {
        for (const std::uint32_t p : {1u, 2u}) {  // pixels (1, 1) and (2, 2): a corner apart
            stack.labels[(std::size_t(k) * stack.height + p) * stack.width + p] = 1;
        }
    }
    stack.label_table.push_back({1, "diagonal", {200, 80, 80}});
    const SliceContours contours = extract_contours(stack, {});
    std::vector<RegionLink> foreground;
    for (const RegionLink& link : contours.links) {
        if (!link.is_background && link.label == 1) {
            foreground.push_back(link);
        }
    }
    ASSERT_EQ(foreground.size(), 1u);
    EXPECT_EQ(foreground[0].pixels, 2u);
    EXPECT_EQ(foreground[0].lower_regions, (std::vector<std::uint32_t>{0}));
    EXPECT_EQ(foreground[0].upper_regions, (std::vector<std::uint32_t>{0}));
}

}  // namespace
}  // namespace strata

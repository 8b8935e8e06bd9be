#include "input/slice_stack.h"

#include <string>

#include <gtest/gtest.h>

#include "core/error.h"

namespace strata {
namespace {

SliceStack small_stack() {
    SliceStack s;
    s.width = 4;
    s.height = 3;
    s.depth = 2;
    s.labels.assign(24, 0);
    s.labels[1] = 3;
    s.labels[13] = 7;
    s.labels[14] = 300;
    s.source = "test";
    return s;
}

TEST(SliceStack, AbsurdDimensionsSayHowMuchMemory) {
    try {
        check_stack_dimensions(100000, 100000, 100000, "huge.nii");
        FAIL();
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        const std::string m = e.what();
        EXPECT_NE(m.find("huge.nii"), std::string::npos) << m;
        EXPECT_NE(m.find("100000x100000x100000"), std::string::npos) << m;
        EXPECT_NE(m.find("1.8 PiB"), std::string::npos) << m;
    }
}

TEST(SliceStack, EmptyDimensionsRejected) {
    try {
        check_stack_dimensions(10, 0, 5, "x");
        FAIL();
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        EXPECT_NE(std::string(e.what()).find("10x0x5"), std::string::npos) << e.what();
    }
    EXPECT_NO_THROW(check_stack_dimensions(512, 512, 300, "ok"));
}

TEST(SliceStack, NonPositiveOrNanSpacingRejected) {
    EXPECT_THROW(check_spacing({1, 0, 1}, "s"), Error);
    EXPECT_THROW(check_spacing({1, 1, -2}, "s"), Error);
    EXPECT_THROW(check_spacing({std::nan(""), 1, 1}, "s"), Error);
    EXPECT_NO_THROW(check_spacing({0.5, 0.5, 5}, "s"));
}

TEST(SliceStack, OverrideSpacingKeepsDirections) {
    SliceStack s = small_stack();
    s.index_to_world.linear = {{{-2, 0, 0}, {0, 0, 3}, {0, 1, 0}}};
    s.index_to_world.translation = {1, 2, 3};
    override_spacing(s, {0.5, 0.25, 4});
    EXPECT_DOUBLE_EQ(s.index_to_world.linear[0][0], -0.5);
    EXPECT_DOUBLE_EQ(s.index_to_world.linear[2][1], 0.25);
    EXPECT_DOUBLE_EQ(s.index_to_world.linear[1][2], 4);
    EXPECT_EQ(s.index_to_world.translation, (Vec3{1, 2, 3}));
    EXPECT_THROW(override_spacing(s, {0, 1, 1}), Error);
}

TEST(SliceStack, CompleteLabelTableNamesEveryPresentLabel) {
    SliceStack s = small_stack();
    s.label_table = {{7, "liver", {1, 2, 3}}, {9, "absent", {0, 0, 0}}};
    complete_label_table(s);
    ASSERT_EQ(s.label_table.size(), 3u);
    EXPECT_EQ(s.label_table[0].value, 3);
    EXPECT_EQ(s.label_table[0].name, "label 3");
    EXPECT_EQ(s.label_table[1].name, "liver");
    EXPECT_EQ(s.label_table[1].color, (ColorSrgb8{1, 2, 3}));
    EXPECT_EQ(s.label_table[2].value, 300);
    EXPECT_NE(palette_color(1), palette_color(2));
}

TEST(SliceStack, SelectLabelsByValueAndName) {
    SliceStack s = small_stack();
    s.label_table = {{7, "Liver", {1, 2, 3}}};
    complete_label_table(s);
    select_labels(s, {"liver", "300"});
    EXPECT_EQ(s.labels[1], 0);
    EXPECT_EQ(s.labels[13], 7);
    EXPECT_EQ(s.labels[14], 300);
    ASSERT_EQ(s.label_table.size(), 2u);
    try {
        select_labels(s, {"spleen"});
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("available: 7 (Liver), 300"), std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace strata

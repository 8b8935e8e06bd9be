// Colour tables: 3D Slicer, ITK-SNAP and JSON, detected by content.

#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "input/detail/readers.h"
#include "support/input_files.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::throws_error;

fs::path table_file(const std::string& name, const std::string& text) {
    return test::write_file(test::current_test_dir("color_table_") / name, text);
}

TEST(ColorTable, ReadsSlicerTable) {
    const fs::path file = table_file("colors.ctbl",
                                     "# Color table file /tmp/colors.ctbl\n"
                                     "# 3 values\n"
                                     "0 Background 0 0 0 0\n"
                                     "7 left_kidney 185 102 83 255\n"
                                     "2 liver 221 130 101 255\r\n");
    const std::vector<LabelInfo> table = detail::read_color_table(file);
    ASSERT_EQ(table.size(), 2u);  // 0 skipped, sorted by value
    EXPECT_EQ(table[0].value, 2);
    EXPECT_EQ(table[0].name, "liver");
    EXPECT_EQ(table[0].color, (ColorSrgb8{221, 130, 101}));
    EXPECT_EQ(table[1].value, 7);
    EXPECT_EQ(table[1].name, "left_kidney");
}

TEST(ColorTable, ReadsItkSnapLabelDescription) {
    const fs::path file =
        table_file("labels.txt",
                   "################################################\n"
                   "# ITK-SnAP Label Description File\n"
                   "#    IDX:   Zero-based index\n"
                   "#    IDX   -R-  -G-  -B-  -A--  VIS MSH  LABEL\n"
                   "################################################\n"
                   "    0     0    0    0        0  0  0    \"Clear Label\"\n"
                   "    1   255    0    0        1  1  1    \"Right lung\"\n"
                   "   12     0  255  128      0.5  1  0    \"Aorta thoracic\"\n");
    const std::vector<LabelInfo> table = detail::read_color_table(file);
    ASSERT_EQ(table.size(), 2u);
    EXPECT_EQ(table[0].value, 1);
    EXPECT_EQ(table[0].name, "Right lung");
    EXPECT_EQ(table[0].color, (ColorSrgb8{255, 0, 0}));
    EXPECT_EQ(table[1].value, 12);
    EXPECT_EQ(table[1].color, (ColorSrgb8{0, 255, 128}));
}

TEST(ColorTable, ReadsJsonNames) {
    const fs::path file = table_file("map.json",
                                     "{\"0\": \"background\", \"3\": \"kidney_left\", "
                                     "\"1\": \"spleen\"}");
    const std::vector<LabelInfo> table = detail::read_color_table(file);
    ASSERT_EQ(table.size(), 2u);
    EXPECT_EQ(table[0].value, 1);
    EXPECT_EQ(table[0].name, "spleen");
    EXPECT_EQ(table[0].color, palette_color(1));
    EXPECT_EQ(table[1].name, "kidney_left");
}

TEST(ColorTable, ReadsJsonObjectsWithColours) {
    const fs::path file =
        table_file("map.json",
                   "{\n \"4\": {\"name\": \"gallbladder\", \"color\": [10, 20, 30]},\n"
                   " \"5\": {\"name\": \"liver\", \"color\": [0.5, 0, 1]},\n"
                   " \"6\": {\"name\": \"stomach\"}\n}\n");
    const std::vector<LabelInfo> table = detail::read_color_table(file);
    ASSERT_EQ(table.size(), 3u);
    EXPECT_EQ(table[0].color, (ColorSrgb8{10, 20, 30}));
    EXPECT_EQ(table[1].color, (ColorSrgb8{128, 0, 255}));  // 0..1 components
    EXPECT_EQ(table[2].color, palette_color(6));
}

TEST(ColorTable, ReadsTotalSegmentatorClassMap) {
    const std::vector<LabelInfo> table = detail::read_color_table(
        test::shared_data_dir() / "totalsegmentator_abdomen" / "class_map_total.json");
    ASSERT_FALSE(table.empty());
    EXPECT_EQ(table.front().value, 1);
    EXPECT_EQ(table.front().name, "spleen");
    EXPECT_EQ(table[4].value, 5);
    EXPECT_EQ(table[4].name, "liver");
    EXPECT_EQ(table.back().value, 117);
    for (std::size_t n = 1; n < table.size(); ++n) {
        EXPECT_LT(table[n - 1].value, table[n].value);
    }
}

TEST(ColorTable, MissingFileIsInvalidInputLikeAMissingInput) {
    EXPECT_TRUE(throws_error(
        [] { detail::read_color_table(test::fresh_temp_dir("color_table_missing") / "none.ctbl"); },
        ErrorCode::InvalidInput, "none.ctbl: no such colour table file"));
}

TEST(ColorTable, MalformedSlicerLineNamesFileAndLine) {
    const fs::path file = table_file("colors.ctbl", "# header\n1 liver 1 2 3 255\n2 spleen 4 5\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "colors.ctbl:3: 4 fields, expected 3D Slicer colour table fields"));
}

TEST(ColorTable, ColourComponentOutOfRangeIsRejected) {
    const fs::path file = table_file("colors.ctbl", "1 liver 1 256 3 255\n");
    EXPECT_TRUE(
        throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                     "colors.ctbl:1: colour component \"256\", expected an integer 0..255"));
}

TEST(ColorTable, NonIntegerValueIsRejected) {
    const fs::path file = table_file("colors.ctbl", "1.5 liver 1 2 3 255\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "colors.ctbl:1: label value \"1.5\" is not an integer"));
}

TEST(ColorTable, ValueAbove65535IsRejected) {
    const fs::path file = table_file("colors.ctbl", "70000 liver 1 2 3 255\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "colors.ctbl:1: label value 70000, expected 0..65535"));
}

TEST(ColorTable, DuplicateValueIsRejected) {
    const fs::path file = table_file("colors.ctbl", "1 liver 1 2 3 255\n\n1 spleen 1 2 3 255\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "colors.ctbl:3: label value 1 is listed twice"));
}

TEST(ColorTable, ItkSnapLineWithMissingFieldsIsRejected) {
    const fs::path file = table_file("labels.txt", "1 255 0 0 1 1 \"lung\"\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "labels.txt:1: 6 numbers before the label name, expected 7"));
}

TEST(ColorTable, MixedFormatsAreRejected) {
    const fs::path file = table_file("labels.txt", "1 255 0 0 1 1 1 \"lung\"\n2 liver 1 2 3 255\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "labels.txt:2: entry in 3D Slicer format, expected ITK-SNAP"));
}

TEST(ColorTable, MalformedJsonNamesLine) {
    const fs::path file = table_file("map.json", "{\n \"1\": \"spleen\",\n \"2\": liver\n}\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "map.json:3: malformed JSON"));
}

TEST(ColorTable, NonIntegerJsonKeyIsRejected) {
    const fs::path file =
        table_file("map.json", "{\n \"1\": \"spleen\",\n \"two\": \"liver\"\n}\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "map.json:3: key \"two\" is not an integer label value"));
}

TEST(ColorTable, BadJsonColourIsRejected) {
    const fs::path file =
        table_file("map.json", "{\"1\": {\"name\": \"spleen\", \"color\": [300, 0, 0]}}");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "map.json:1: \"color\" is [300,0,0]"));
}

TEST(ColorTable, JsonArrayIsRejected) {
    const fs::path file = table_file("map.json", "[\"spleen\"]");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "map.json: JSON colour table is not an object"));
}

TEST(ColorTable, EmptyTableIsRejected) {
    const fs::path file = table_file("colors.ctbl", "# nothing\n0 Background 0 0 0 0\n");
    EXPECT_TRUE(throws_error([&] { detail::read_color_table(file); }, ErrorCode::InvalidInput,
                             "colors.ctbl: colour table has no label entries"));
}

}  // namespace
}  // namespace strata

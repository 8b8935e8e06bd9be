// Every real file of ../shared/data read end to end through read_slice_stack().

#include <cmath>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "input/read_slice_stack.h"
#include "support/input_files.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

SliceStack read(const fs::path& path, const fs::path& color_table = {}) {
    ReadOptions options;
    options.color_table = color_table;
    Report report;
    return read_slice_stack(path, options, report);
}

void expect_spacing(const SliceStack& s, Vec3 expected, double tolerance) {
    const Vec3 sp = s.spacing_mm();
    EXPECT_NEAR(sp.x, expected.x, tolerance);
    EXPECT_NEAR(sp.y, expected.y, tolerance);
    EXPECT_NEAR(sp.z, expected.z, tolerance);
}

TEST(SharedData, TotalSegmentatorWithClassMap) {
    const fs::path dir = test::shared_data_dir() / "totalsegmentator_abdomen";
    const SliceStack s = read(dir / "example_seg.nii.gz", dir / "class_map_total.json");
    EXPECT_EQ(s.width, 122u);
    EXPECT_EQ(s.height, 101u);
    EXPECT_EQ(s.depth, 30u);
    expect_spacing(s, {3, 3, 3}, 1e-3);
    EXPECT_EQ(s.source_frame, "RAS");
    EXPECT_EQ(s.label_table.size(), 41u);  // data README: 41 structures present
    std::ifstream in(dir / "class_map_total.json");
    const nlohmann::json map = nlohmann::json::parse(in);
    for (const LabelInfo& l : s.label_table) {
        const std::string key = std::to_string(l.value);
        ASSERT_TRUE(map.contains(key)) << "label " << key << " not in the class map";
        EXPECT_EQ(l.name, map.at(key).get<std::string>());
    }
}

TEST(SharedData, NiivueTorso) {
    const SliceStack s = read(test::shared_data_dir() / "niivue_torso" / "torsoLabel.nii.gz");
    EXPECT_EQ(s.width, 384u);
    EXPECT_EQ(s.height, 320u);
    EXPECT_EQ(s.depth, 89u);
    expect_spacing(s, {0.782, 0.782, 5}, 2e-3);
    EXPECT_EQ(s.label_table.size(), 11u);
}

TEST(SharedData, FreesurferPngStackWithSidecar) {
    const SliceStack s = read(test::shared_data_dir() / "freesurfer_aparc_aseg");
    EXPECT_EQ(s.width, 128u);
    EXPECT_EQ(s.height, 172u);
    EXPECT_EQ(s.depth, 133u);
    expect_spacing(s, {1, 1, 1}, 1e-6);
    EXPECT_EQ(s.source_frame, "RAS");
    // RAS -> LPS: the x and y origin change sign
    EXPECT_NEAR(s.index_to_world.translation.x, 69.233, 1e-3);
    EXPECT_NEAR(s.index_to_world.translation.y, 68.484, 1e-3);
    EXPECT_NEAR(s.index_to_world.translation.z, -49.4387, 1e-3);
    EXPECT_GT(s.label_table.size(), 150u);
    EXPECT_LE(s.label_table.size(), 188u);
    for (const LabelInfo& l : s.label_table) {
        EXPECT_NE(l.name.rfind("label ", 0), 0u) << "label " << l.value << " has no name";
    }
}

TEST(SharedData, TerrainBinaryStack) {
    const SliceStack s = read(test::shared_data_dir() / "terrain_volcano");
    EXPECT_EQ(s.width, 87u);
    EXPECT_EQ(s.height, 61u);
    EXPECT_EQ(s.depth, 21u);
    expect_spacing(s, {10000, 10000, 5000}, 1e-6);
    ASSERT_EQ(s.label_table.size(), 1u);
    EXPECT_EQ(s.label_table[0].value, 255);
    EXPECT_EQ(s.label_table[0].name, "ground at or above the slice height");
}

TEST(SharedData, LungTumourNrrd) {
    const SliceStack s =
        read(test::shared_data_dir() / "pyradiomics_lung_tumor" / "lung2_label.nrrd");
    EXPECT_EQ(s.width, 512u);
    EXPECT_EQ(s.height, 512u);
    EXPECT_EQ(s.depth, 61u);
    expect_spacing(s, {0.627, 0.627, 5}, 2e-3);
    EXPECT_EQ(s.source_frame, "LPS");
    ASSERT_GE(s.label_table.size(), 1u);
    EXPECT_EQ(test::count_labelled_slices(s), 11u);  // data README: 11 slices carry the tumour
}

TEST(SharedData, BrainTumourNrrd) {
    const SliceStack s =
        read(test::shared_data_dir() / "pyradiomics_brain_tumor" / "brain1_label.nrrd");
    EXPECT_EQ(s.width, 256u);
    EXPECT_EQ(s.height, 256u);
    EXPECT_EQ(s.depth, 25u);
    expect_spacing(s, {0.781, 0.781, 6.5}, 2e-3);
    EXPECT_EQ(test::count_labelled_slices(s), 7u);  // data README: 7 slices carry the tumour
}

}  // namespace
}  // namespace strata

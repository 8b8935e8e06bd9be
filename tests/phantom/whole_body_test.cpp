// The whole-body benchmark phantom (phantom/whole_body.h): TotalSegmentator's 117 classes by
// the class map shipped with its example in ../shared/data, each drawn, on the stated grid,
// painted as the last solid (in order) that contains each pixel centre.

#include "phantom/whole_body.h"

#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "phantom/catalogue.h"
#include "support/test_paths.h"

namespace strata {
namespace {

// note: one test, so the map (a few seconds) is generated once
TEST(WholeBodyPhantom, TotalSegmentatorsClassesOnTheStatedGridPaintedInOrder) {
    std::ifstream in(test::shared_data_dir() / "totalsegmentator_abdomen" / "class_map_total.json");
    ASSERT_TRUE(in) << "class_map_total.json of ../shared/data";
    const nlohmann::json classes = nlohmann::json::parse(in);
    ASSERT_EQ(classes.size(), 117u);

    const Phantom p = make_phantom("whole_body");
    EXPECT_EQ(p.stack.width, 512u);
    EXPECT_EQ(p.stack.height, 512u);
    EXPECT_EQ(p.stack.depth, 1000u);
    EXPECT_EQ(p.stack.spacing_mm().z, 1.5);
    std::map<std::uint16_t, std::string> table;
    for (const LabelInfo& l : p.stack.label_table) {
        table[l.value] = l.name;
    }
    ASSERT_EQ(table.size(), 117u);
    for (const auto& [value, name] : classes.items()) {
        EXPECT_EQ(table[static_cast<std::uint16_t>(std::stoi(value))], name.get<std::string>());
    }
    std::vector<std::size_t> voxels(118, 0);
    for (std::uint16_t v : p.stack.labels) {
        ASSERT_LE(v, 117);
        ++voxels[v];
    }
    for (std::uint16_t v = 1; v <= 117; ++v) {
        EXPECT_GT(voxels[v], 1000u) << table[v];
    }
    EXPECT_FALSE(std::find(benchmark_phantom_names().begin(), benchmark_phantom_names().end(),
                           "whole_body") == benchmark_phantom_names().end());

    // Each pixel is the last solid in painting order that contains its centre (contains(), on
    // every 4th pixel of every 8th row of a few slices): checks the rasteriser and the
    // painter's skipping of solids outside their z bounds.
    const std::vector<LabelledSolid> solids = whole_body_solids();
    for (std::uint32_t k : {40u, 380u, 560u, 640u, 700u, 930u}) {
        const double z = k * kWholeBodySliceSpacingPx;
        std::set<std::uint16_t> seen;
        for (std::uint32_t j = 1; j < p.stack.height; j += 8) {
            for (std::uint32_t i = 2; i < p.stack.width; i += 4) {
                std::uint16_t expected = 0;
                for (const LabelledSolid& s : solids) {
                    if (contains(s.solid, {i + 0.5, j + 0.5, z})) {
                        expected = s.label;
                    }
                }
                ASSERT_EQ(p.stack.at(i, j, k), expected) << i << ", " << j << ", " << k;
                seen.insert(expected);
            }
        }
        EXPECT_GE(seen.size(), 3u) << "slice " << k;
    }
}

}  // namespace
}  // namespace strata

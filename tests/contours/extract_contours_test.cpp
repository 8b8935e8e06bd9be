#include "contours/extract_contours.h"

#include <random>
#include <string>

#include <gtest/gtest.h>

#include "support/polygon_checks.h"
#include "support/property.h"

namespace strata {
namespace {

/// Builds a one-slice or multi-slice stack from rows of text: '#' (or a digit) is foreground.
SliceStack stack_from_rows(const std::vector<std::vector<std::string>>& slices) {
    SliceStack s;
    s.height = static_cast<std::uint32_t>(slices.at(0).size());
    s.width = static_cast<std::uint32_t>(slices.at(0).at(0).size());
    s.depth = static_cast<std::uint32_t>(slices.size());
    s.labels.assign(s.slice_size() * s.depth, 0);
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t j = 0; j < s.height; ++j) {
            for (std::uint32_t i = 0; i < s.width; ++i) {
                const char c = slices[k][j][i];
                s.labels[(k * s.height + j) * s.width + i] =
                    c == '#' ? 1 : (c >= '1' && c <= '9' ? c - '0' : 0);
            }
        }
    }
    complete_label_table(s);
    return s;
}

SliceContourSet trace(const SliceStack& s, std::uint32_t k = 0) {
    std::vector<std::uint16_t> labels;
    for (const LabelInfo& l : s.label_table) {
        labels.push_back(l.value);
    }
    return trace_slice_contours(s, k, labels);
}

TEST(ExtractContours, SinglePixelIsUnitSquareCounterClockwise) {
    const SliceContourSet set = trace(stack_from_rows({{"...", ".#.", "..."}}));
    ASSERT_EQ(set.contours.size(), 1u);
    const Contour& c = set.contours[0];
    EXPECT_FALSE(c.is_hole);
    EXPECT_EQ(c.parent, -1);
    EXPECT_EQ(c.points, (std::vector<Vec2>{{1, 1}, {2, 1}, {2, 2}, {1, 2}}));
    EXPECT_DOUBLE_EQ(test::signed_area(c.points), 1.0);
}

TEST(ExtractContours, HoleIsClockwiseAndNested) {
    const SliceContourSet set = trace(stack_from_rows({{"###", "#.#", "###"}}));
    ASSERT_EQ(set.contours.size(), 2u);
    const Contour& outer = set.contours[0];
    const Contour& hole = set.contours[1];
    EXPECT_FALSE(outer.is_hole);
    EXPECT_TRUE(hole.is_hole);
    EXPECT_DOUBLE_EQ(test::signed_area(outer.points), 9.0);
    EXPECT_DOUBLE_EQ(test::signed_area(hole.points), -1.0);
    EXPECT_EQ(hole.parent, 0);
    EXPECT_EQ(hole.depth, 1u);
    EXPECT_EQ(set.labels.at(0).background_count, 2u);
}

TEST(ExtractContours, IslandInHoleThreeLevels) {
    const SliceContourSet set = trace(stack_from_rows({{
        "#######",
        "#.....#",
        "#.###.#",
        "#.#.#.#",
        "#.###.#",
        "#.....#",
        "#######",
    }}));
    ASSERT_EQ(set.contours.size(), 4u);
    std::vector<std::uint32_t> depths;
    for (const Contour& c : set.contours) {
        depths.push_back(c.depth);
        EXPECT_EQ(c.is_hole, c.depth % 2 == 1);
        if (c.parent >= 0) {
            EXPECT_EQ(set.contours[c.parent].depth + 1, c.depth);
            EXPECT_TRUE(test::inside_even_odd(set.contours[c.parent].points, c.points[0]));
        }
    }
    std::sort(depths.begin(), depths.end());
    EXPECT_EQ(depths, (std::vector<std::uint32_t>{0, 1, 2, 3}));
}

TEST(ExtractContours, DiagonalForegroundPairIsOneContourWithCutSaddle) {
    const SliceContourSet set = trace(stack_from_rows({{"#.", ".#"}}));
    ASSERT_EQ(set.contours.size(), 1u);  // 8-connected foreground
    const Contour& c = set.contours[0];
    EXPECT_EQ(c.points.size(), 10u);
    EXPECT_DOUBLE_EQ(test::signed_area(c.points), 2.25);
    EXPECT_TRUE(test::is_simple_polygon(c.points));
}

TEST(ExtractContours, DiagonalBackgroundPairIsTwoHoles) {
    const SliceContourSet set = trace(stack_from_rows({{"####", "#.##", "##.#", "####"}}));
    ASSERT_EQ(set.contours.size(), 3u);  // 4-connected background: two holes
    int holes = 0;
    for (const Contour& c : set.contours) {
        EXPECT_TRUE(test::is_simple_polygon(c.points));
        if (c.is_hole) {
            ++holes;
            EXPECT_DOUBLE_EQ(test::signed_area(c.points), -0.875);
        }
    }
    EXPECT_EQ(holes, 2);
    EXPECT_TRUE(test::polygons_disjoint(set.contours[1].points, set.contours[2].points));
}

TEST(ExtractContours, FullFrameObjectClosedAlongBorder) {
    const SliceContourSet set = trace(stack_from_rows({{"####", "####", "####"}}));
    ASSERT_EQ(set.contours.size(), 1u);
    EXPECT_DOUBLE_EQ(test::signed_area(set.contours[0].points), 12.0);
    for (const Vec2 p : set.contours[0].points) {
        EXPECT_TRUE(p.x == 0 || p.x == 4 || p.y == 0 || p.y == 3);
    }
}

TEST(ExtractContours, OnePixelLineHasPositiveArea) {
    const SliceContourSet set = trace(stack_from_rows({{"........", ".######.", "........"}}));
    ASSERT_EQ(set.contours.size(), 1u);
    EXPECT_DOUBLE_EQ(test::signed_area(set.contours[0].points), 6.0);
    EXPECT_TRUE(test::is_simple_polygon(set.contours[0].points));
}

TEST(ExtractContours, LabelsAreSeparateObjects) {
    const SliceContourSet set = trace(stack_from_rows({{"1122", "1122"}}));
    ASSERT_EQ(set.contours.size(), 2u);
    EXPECT_EQ(set.contours[0].label, 1);
    EXPECT_EQ(set.contours[1].label, 2);
    EXPECT_EQ(set.labels.size(), 2u);
}

/// Random masks: every contour simple, contours of a label pairwise disjoint, orientation by
/// kind, and the even-odd rasterisation of the contours at pixel centres equals the mask.
TEST(ExtractContoursProperty, RandomMasksGiveSimplePixelExactContours) {
    const int iterations = test::property_iterations(300);
    for (int seed = 0; seed < iterations; ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        std::mt19937 rng(static_cast<std::uint32_t>(seed));
        const std::uint32_t w = 3 + rng() % 14;
        const std::uint32_t h = 3 + rng() % 14;
        const double density = 0.2 + 0.6 * (rng() % 1000) / 1000.0;
        SliceStack s;
        s.width = w;
        s.height = h;
        s.depth = 1;
        s.labels.resize(w * h);
        for (auto& v : s.labels) {
            v = (rng() % 1000) / 1000.0 < density ? static_cast<std::uint16_t>(1 + rng() % 2) : 0;
        }
        complete_label_table(s);
        const SliceContourSet set = trace(s);
        for (const SliceLabelRegions& regions : set.labels) {
            std::vector<const Contour*> mine;
            for (const Contour& c : set.contours) {
                if (c.label == regions.label) {
                    mine.push_back(&c);
                }
            }
            for (std::size_t a = 0; a < mine.size(); ++a) {
                ASSERT_TRUE(test::is_simple_polygon(mine[a]->points));
                EXPECT_EQ(test::signed_area(mine[a]->points) < 0, mine[a]->is_hole);
                EXPECT_EQ(mine[a]->is_hole, mine[a]->depth % 2 == 1);
                for (std::size_t b = a + 1; b < mine.size(); ++b) {
                    ASSERT_TRUE(test::polygons_disjoint(mine[a]->points, mine[b]->points));
                }
            }
            for (std::uint32_t j = 0; j < h; ++j) {
                for (std::uint32_t i = 0; i < w; ++i) {
                    bool inside = false;
                    for (const Contour* c : mine) {
                        inside ^= test::inside_even_odd(c->points, {i + 0.5, j + 0.5});
                    }
                    ASSERT_EQ(inside, s.at(i, j, 0) == regions.label)
                        << "pixel " << i << "," << j << " label " << regions.label;
                }
            }
        }
    }
}

TEST(LinkSlices, OverlapInTwoPiecesGivesTwoLinks) {
    const SliceStack s = stack_from_rows({
        {".......", ".#####.", "......."},
        {".......", ".#...#.", "......."},
    });
    const auto lower = trace(s, 0);
    const auto upper = trace(s, 1);
    const auto links = link_slices(s, 0, lower, upper, {1});
    ASSERT_EQ(links.size(), 2u);
    for (const RegionLink& l : links) {
        EXPECT_FALSE(l.is_background);
        EXPECT_EQ(l.lower_regions, (std::vector<std::uint32_t>{0}));
        EXPECT_EQ(l.pixels, 1u);
    }
    EXPECT_EQ(links[0].upper_regions, (std::vector<std::uint32_t>{0}));
    EXPECT_EQ(links[1].upper_regions, (std::vector<std::uint32_t>{1}));
}

TEST(LinkSlices, NoOverlapNoLink) {
    const SliceStack s = stack_from_rows({{"##....", "##...."}, {"...##.", "...##."}});
    EXPECT_TRUE(link_slices(s, 0, trace(s, 0), trace(s, 1), {1}).empty());
}

TEST(LinkSlices, HolesJoinWhenTouchingEdgeToEdge) {
    // hole at (2,2) on slice 0 and at (3,2) on slice 1: no shared pixel, but edge to edge
    const SliceStack s = stack_from_rows({
        {"######", "######", "##.###", "######", "######"},
        {"######", "######", "###.##", "######", "######"},
    });
    const auto links = link_slices(s, 0, trace(s, 0), trace(s, 1), {1});
    int background = 0;
    for (const RegionLink& l : links) {
        if (l.is_background) {
            ++background;
            EXPECT_EQ(l.lower_regions, (std::vector<std::uint32_t>{1}));
            EXPECT_EQ(l.upper_regions, (std::vector<std::uint32_t>{1}));
        }
    }
    EXPECT_EQ(background, 1);
}

TEST(LinkSlices, HoleOpeningToOutsideLinksToRegionZero) {
    const SliceStack s = stack_from_rows({
        {"#####", "#...#", "#####"},
        {"#####", "#....", "#####"},
    });
    const auto links = link_slices(s, 0, trace(s, 0), trace(s, 1), {1});
    bool found = false;
    for (const RegionLink& l : links) {
        if (l.is_background) {
            EXPECT_EQ(l.lower_regions, (std::vector<std::uint32_t>{0, 1}));
            found = true;
        }
    }
    EXPECT_TRUE(found);
}

TEST(ExtractContours, EmptySliceBreaksLinks) {
    SliceStack s = stack_from_rows({{"##", "##"}, {"..", ".."}, {"##", "##"}});
    ContourOptions options;
    const SliceContours contours = extract_contours(s, options);
    ASSERT_EQ(contours.slices.size(), 3u);
    EXPECT_TRUE(contours.slices[1].contours.empty());
    EXPECT_TRUE(contours.links.empty());
}

TEST(ExtractContours, DeterministicForAnyThreadCount) {
    std::mt19937 rng(7);
    SliceStack s;
    s.width = 40;
    s.height = 30;
    s.depth = 9;
    s.labels.resize(s.slice_size() * s.depth);
    for (auto& v : s.labels) {
        v = rng() % 3 == 0 ? 1 : 0;
    }
    complete_label_table(s);
    ContourOptions one;
    one.threads = 1;
    ContourOptions many;
    many.threads = 4;
    const SliceContours a = extract_contours(s, one);
    const SliceContours b = extract_contours(s, many);
    ASSERT_EQ(a.slices.size(), b.slices.size());
    for (std::size_t k = 0; k < a.slices.size(); ++k) {
        ASSERT_EQ(a.slices[k].contours.size(), b.slices[k].contours.size());
        for (std::size_t c = 0; c < a.slices[k].contours.size(); ++c) {
            EXPECT_EQ(a.slices[k].contours[c].points, b.slices[k].contours[c].points);
            EXPECT_EQ(a.slices[k].contours[c].simplified, b.slices[k].contours[c].simplified);
        }
    }
    EXPECT_EQ(a.links.size(), b.links.size());
}

}  // namespace
}  // namespace strata

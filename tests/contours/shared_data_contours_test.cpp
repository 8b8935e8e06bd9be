// Contours of the real data in ../shared/data and of the catalogue's branching phantoms.

#include <map>
#include <numeric>
#include <set>

#include <gtest/gtest.h>

#include "contours/extract_contours.h"
#include "input/read_slice_stack.h"
#include "phantom/catalogue.h"
#include "support/polygon_checks.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

std::vector<Vec2> simplified_polygon(const Contour& c) {
    std::vector<Vec2> p;
    for (std::uint32_t i : c.simplified) {
        p.push_back(c.points[i]);
    }
    return p;
}

/// Checks every slice: simplified contours simple, pairwise disjoint within a label, deviation
/// bound respected (recomputed by brute force), orientation kept.
void check_contours(const SliceContours& contours) {
    for (std::size_t k = 0; k < contours.slices.size(); ++k) {
        SCOPED_TRACE("slice " + std::to_string(k));
        const auto& set = contours.slices[k];
        std::map<std::uint16_t, std::vector<std::vector<Vec2>>> by_label;
        for (const Contour& c : set.contours) {
            ASSERT_GE(c.simplified.size(), 3u);
            ASSERT_EQ(c.edge_deviation_px.size(), c.simplified.size());
            const std::vector<Vec2> poly = simplified_polygon(c);
            ASSERT_TRUE(test::is_simple_polygon(poly)) << "label " << c.label;
            EXPECT_EQ(test::signed_area(poly) < 0, c.is_hole);
            // one-sided distance of the original points from their simplified edge
            const std::size_t n = c.simplified.size();
            for (std::size_t e = 0; e < n; ++e) {
                const Vec2 a = c.points[c.simplified[e]];
                const Vec2 b = c.points[c.simplified[(e + 1) % n]];
                const std::size_t end =
                    e + 1 < n ? c.simplified[e + 1] : c.points.size() + c.simplified[0];
                double worst = 0;
                for (std::size_t i = c.simplified[e]; i <= end; ++i) {
                    const Vec2 p = c.points[i % c.points.size()];
                    const Vec2 ab = b - a;
                    const double len2 = dot(ab, ab);
                    const double t = len2 > 0 ? std::clamp(dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
                    worst = std::max(worst, norm(p - (a + t * ab)));
                }
                EXPECT_LE(worst, contours.tolerance_px + 1e-9);
                EXPECT_NEAR(worst, c.edge_deviation_px[e], 1e-9);
            }
            by_label[c.label].push_back(poly);
        }
        for (const auto& [label, polys] : by_label) {
            for (std::size_t a = 0; a < polys.size(); ++a) {
                for (std::size_t b = a + 1; b < polys.size(); ++b) {
                    ASSERT_TRUE(test::polygons_disjoint(polys[a], polys[b]))
                        << "label " << label << " contours " << a << " and " << b << " touch";
                }
            }
        }
    }
}

SliceContours extract(const SliceStack& stack) {
    ContourOptions options;
    return extract_contours(stack, options);
}

class SharedDataContours : public ::testing::TestWithParam<std::string> {};

TEST_P(SharedDataContours, SimpleDisjointWithinTolerance) {
    Report report;
    const SliceStack stack =
        read_slice_stack(test::shared_data_dir() / GetParam(), ReadOptions{}, report);
    const SliceContours contours = extract(stack);
    std::size_t count = 0;
    for (const auto& s : contours.slices) {
        count += s.contours.size();
    }
    EXPECT_GT(count, 0u);
    check_contours(contours);
}

// note: the macro's own generated lambda shadows a parameter when given a name generator
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wshadow"
INSTANTIATE_TEST_SUITE_P(AllFiles,
                         SharedDataContours,
                         ::testing::Values("totalsegmentator_abdomen/example_seg.nii.gz",
                                           "niivue_torso/torsoLabel.nii.gz",
                                           "freesurfer_aparc_aseg",
                                           "terrain_volcano",
                                           "pyradiomics_lung_tumor/lung2_label.nrrd",
                                           "pyradiomics_brain_tumor/brain1_label.nrrd"),
                         [](const auto& info) {
                             std::string name = info.param.substr(0, info.param.find('/'));
                             return name;
                         });

/// Cycle rank of the foreground overlap graph (regions as nodes, links as edges): E - V + C.
int overlap_cycles(const SliceContours& contours, std::uint16_t label, int* components) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> node;
    for (std::uint32_t k = 0; k < contours.slices.size(); ++k) {
        for (const auto& r : contours.slices[k].labels) {
            if (r.label == label) {
                for (std::uint32_t f = 0; f < r.foreground_count; ++f) {
                    node[{k, f}] = static_cast<int>(node.size());
                }
            }
        }
    }
    std::vector<int> parent(node.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int x) {
        while (parent[x] != x) {
            x = parent[x] = parent[parent[x]];
        }
        return x;
    };
    int edges = 0;
    for (const RegionLink& l : contours.links) {
        if (l.label != label || l.is_background) {
            continue;
        }
        ++edges;
        const int a = node.at({l.lower_slice, l.lower_regions.at(0)});
        const int b = node.at({l.lower_slice + 1, l.upper_regions.at(0)});
        parent[find(a)] = find(b);
    }
    std::set<int> roots;
    for (std::size_t i = 0; i < parent.size(); ++i) {
        roots.insert(find(static_cast<int>(i)));
    }
    *components = static_cast<int>(roots.size());
    return edges - static_cast<int>(node.size()) + *components;
}

TEST(CatalogueLinks, YBranchIsATree) {
    const SliceContours c = extract(make_phantom("t13_y_branch_1to2").stack);
    int components = 0;
    EXPECT_EQ(overlap_cycles(c, 1, &components), 0);
    EXPECT_EQ(components, 1);
    check_contours(c);
}

TEST(CatalogueLinks, NToMTreeHasFourLinksAtTheBranch) {
    const SliceContours c = extract(make_phantom("t16_n_to_m_tree").stack);
    int at_branch = 0;
    for (const RegionLink& l : c.links) {
        at_branch += (!l.is_background && l.lower_slice == 5) ? 1 : 0;
    }
    EXPECT_EQ(at_branch, 4);  // B-2, B-3
    int components = 0;
    EXPECT_EQ(overlap_cycles(c, 1, &components), 0);
    EXPECT_EQ(components, 1);
}

TEST(CatalogueLinks, TorusOnSideIsOneCycle) {
    const SliceContours c = extract(make_phantom("t18_torus_on_side").stack);
    int components = 0;
    EXPECT_EQ(overlap_cycles(c, 1, &components), 1);
    EXPECT_EQ(components, 1);
    check_contours(c);
}

TEST(CatalogueLinks, ShiftedDiscsLinkOnlyWhenOverlapping) {
    int components = 0;
    const SliceContours a = extract(make_phantom("t29_shifted_nonoverlap_a").stack);
    EXPECT_TRUE(a.links.empty());
    overlap_cycles(a, 1, &components);
    EXPECT_EQ(components, 5);
    const SliceContours b = extract(make_phantom("t29_shifted_nonoverlap_b").stack);
    overlap_cycles(b, 1, &components);
    EXPECT_EQ(components, 1);
}

TEST(CatalogueContours, BoxSimplifiesToFourCorners) {
    const SliceContours c = extract(make_phantom("t03_box_sharp").stack);
    for (const auto& set : c.slices) {
        ASSERT_EQ(set.contours.size(), 1u);
        EXPECT_EQ(set.contours[0].simplified.size(), 4u);
        EXPECT_EQ(test::signed_area(simplified_polygon(set.contours[0])), 2400.0);
    }
}

TEST(CatalogueContours, SpiralAndThinFeaturesStaySimple) {
    check_contours(extract(make_phantom("t06_spiral").stack));
    check_contours(extract(make_phantom("t27_thin_features").stack));
    check_contours(extract(make_phantom("t24_tiny_objects_and_needle").stack));
    check_contours(extract(make_phantom("t25_touching_discs_g0").stack));
}

TEST(CatalogueContours, SpeckleNoiseExtractsEveryComponent) {
    const Phantom p = make_phantom("t35_speckle_noise");
    const SliceContours c = extract(p.stack);
    check_contours(c);
    std::size_t contours = 0;
    for (const auto& s : c.slices) {
        contours += s.contours.size();
    }
    EXPECT_GT(contours, 1500u);
}

}  // namespace
}  // namespace strata

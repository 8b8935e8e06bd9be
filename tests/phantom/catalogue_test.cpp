#include "phantom/catalogue.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"

namespace strata {
namespace {

// Phantoms are generated once per test binary (T36 runs its acceptance test, T33 its draws).
const Phantom& phantom(const std::string& name) {
    static std::map<std::string, Phantom> cache;
    auto it = cache.find(name);
    if (it == cache.end()) {
        it = cache.emplace(name, make_phantom(name)).first;
    }
    return it->second;
}

bool fg(const SliceStack& s, std::uint32_t i, std::uint32_t j, std::uint32_t k) {
    return s.at(i, j, k) != 0;
}

std::uint32_t count_pixels(const SliceStack& s, std::uint32_t k) {
    const auto slice = s.slice(k);
    return static_cast<std::uint32_t>(
        std::count_if(slice.begin(), slice.end(), [](std::uint16_t v) { return v != 0; }));
}

// 8-connected foreground regions of slice k.
std::uint32_t count_regions(const SliceStack& s, std::uint32_t k) {
    const std::int64_t w = s.width, h = s.height;
    std::vector<std::uint8_t> seen(static_cast<std::size_t>(w * h), 0);
    std::uint32_t regions = 0;
    std::vector<std::int64_t> stack;
    for (std::int64_t start = 0; start < w * h; ++start) {
        if (s.slice(k)[static_cast<std::size_t>(start)] == 0 ||
            seen[static_cast<std::size_t>(start)]) {
            continue;
        }
        ++regions;
        seen[static_cast<std::size_t>(start)] = 1;
        stack.push_back(start);
        while (!stack.empty()) {
            const std::int64_t p = stack.back();
            stack.pop_back();
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    const std::int64_t x = p % w + dx, y = p / w + dy;
                    if (x < 0 || y < 0 || x >= w || y >= h) {
                        continue;
                    }
                    const auto q = static_cast<std::size_t>(y * w + x);
                    if (s.slice(k)[q] != 0 && !seen[q]) {
                        seen[q] = 1;
                        stack.push_back(y * w + x);
                    }
                }
            }
        }
    }
    return regions;
}

// Foreground components under the declared semantics: 8-connected in-plane, joined between
// consecutive slices where they share a pixel position.
std::uint32_t count_components_3d(const SliceStack& s) {
    const std::int64_t w = s.width, h = s.height, d = s.depth;
    std::vector<std::uint8_t> seen(s.labels.size(), 0);
    std::vector<std::int64_t> stack;
    std::uint32_t components = 0;
    for (std::int64_t start = 0; start < w * h * d; ++start) {
        if (s.labels[static_cast<std::size_t>(start)] == 0 ||
            seen[static_cast<std::size_t>(start)]) {
            continue;
        }
        ++components;
        seen[static_cast<std::size_t>(start)] = 1;
        stack.push_back(start);
        while (!stack.empty()) {
            const std::int64_t p = stack.back();
            stack.pop_back();
            const std::int64_t x = p % w, y = (p / w) % h, z = p / (w * h);
            for (std::int64_t dz = -1; dz <= 1; ++dz) {
                for (std::int64_t dy = -1; dy <= 1; ++dy) {
                    for (std::int64_t dx = -1; dx <= 1; ++dx) {
                        if (dz != 0 && (dx != 0 || dy != 0)) {
                            continue;
                        }
                        const std::int64_t nx = x + dx, ny = y + dy, nz = z + dz;
                        if (nx < 0 || ny < 0 || nz < 0 || nx >= w || ny >= h || nz >= d) {
                            continue;
                        }
                        const std::int64_t q = (nz * h + ny) * w + nx;
                        if (s.labels[static_cast<std::size_t>(q)] != 0 &&
                            !seen[static_cast<std::size_t>(q)]) {
                            seen[static_cast<std::size_t>(q)] = 1;
                            stack.push_back(q);
                        }
                    }
                }
            }
        }
    }
    return components;
}

struct Size {
    std::uint32_t width, height, depth;
    double d;
};

const std::map<std::string, Size>& catalogue_sizes() {
    static const std::map<std::string, Size> kSizes = {
        {"t01_sphere", {128, 128, 22, 4}},
        {"t02_ellipsoid_tilted", {160, 160, 31, 3}},
        {"t03_box_sharp", {128, 128, 11, 4}},
        {"t04_cylinder_aniso10", {128, 128, 8, 10}},
        {"t05_c_shape_twist", {160, 160, 20, 3}},
        {"t06_spiral", {256, 256, 10, 3}},
        {"t07_star_to_circle", {160, 160, 13, 3}},
        {"t08_comb_retracting", {192, 128, 12, 3}},
        {"t09_annulus_tube", {128, 128, 16, 4}},
        {"t10_internal_cavity", {128, 128, 20, 4}},
        {"t11_island_in_hole", {128, 128, 12, 4}},
        {"t13_y_branch_1to2", {128, 128, 31, 2}},
        {"t14_merge_2to1", {128, 128, 31, 2}},
        {"t15_trident_1to3", {160, 160, 31, 2}},
        {"t16_n_to_m_tree", {128, 128, 12, 4}},
        {"t18_torus_on_side", {128, 128, 51, 2}},
        {"t19_plate_two_holes", {256, 128, 8, 4}},
        {"t21_appear_midstack", {128, 128, 20, 4}},
        {"t22_empty_slices_inside", {128, 128, 17, 4}},
        {"t22_empty_slices_inside_b", {128, 128, 17, 4}},
        {"t23_single_slice_object", {64, 64, 11, 4}},
        {"t24_tiny_objects_and_needle", {64, 64, 12, 3}},
        {"t25_touching_discs_gm2", {128, 64, 6, 4}},
        {"t25_touching_discs_g0", {128, 64, 6, 4}},
        {"t25_touching_discs_g1", {128, 64, 6, 4}},
        {"t25_touching_discs_g2", {128, 64, 6, 4}},
        {"t27_thin_features", {128, 128, 6, 3}},
        {"t29_shifted_nonoverlap_a", {256, 64, 5, 4}},
        {"t29_shifted_nonoverlap_b", {256, 64, 5, 4}},
        {"t31_aniso_branch_d10", {128, 128, 7, 10}},
        {"t32_huge_contour", {4096, 4096, 10, 4}},
        {"t33_many_components", {512, 512, 40, 2}},
        {"t34_border_touch", {128, 128, 33, 4}},
        {"t34_border_touch_b", {128, 128, 33, 4}},
        {"t35_speckle_noise", {128, 128, 22, 4}},
        {"t36_organ_like", {256, 256, 24, 6.25}},
    };
    return kSizes;
}

TEST(Catalogue, NamesCoverEveryCaseAndTheDemos) {
    std::vector<std::string> expected;
    for (const auto& [name, size] : catalogue_sizes()) {
        expected.push_back(name);
    }
    for (const char* demo :
         {"sphere", "ellipsoid", "torus", "branching", "hollow_sphere", "scene"}) {
        expected.push_back(demo);
    }
    std::vector<std::string> names = phantom_names();
    EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
    std::sort(names.begin(), names.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(names, expected);
}

TEST(Catalogue, EveryCaseHasTheStatedSizeAndMetadata) {
    for (const auto& [name, size] : catalogue_sizes()) {
        if (name == "t32_huge_contour") {
            continue;  // HugeContourSlice
        }
        SCOPED_TRACE(name);
        const Phantom& p = phantom(name);
        EXPECT_EQ(p.name, name);
        EXPECT_EQ(p.catalogue_id, "T" + name.substr(1, 2));
        EXPECT_EQ(p.stack.width, size.width);
        EXPECT_EQ(p.stack.height, size.height);
        EXPECT_EQ(p.stack.depth, size.depth);
        EXPECT_EQ(p.slice_spacing_px, size.d);
        EXPECT_EQ(p.stack.labels.size(), std::size_t(size.width) * size.height * size.depth);
        EXPECT_EQ(p.stack.source, "phantom " + name);
        const double mm = name == "t36_organ_like" ? 0.8 : 1.0;
        EXPECT_EQ(p.pixel_mm, mm);
        const Vec3 spacing = p.stack.spacing_mm();
        EXPECT_DOUBLE_EQ(spacing.x, mm);
        EXPECT_DOUBLE_EQ(spacing.y, mm);
        EXPECT_DOUBLE_EQ(spacing.z, size.d * mm);
        EXPECT_EQ(p.stack.index_to_world.translation, Vec3{});
        ASSERT_TRUE(p.expected.has_value());
        EXPECT_EQ(p.expected->genus.size(), p.expected->surfaces);
        EXPECT_TRUE(std::is_sorted(p.expected->genus.rbegin(), p.expected->genus.rend()));
        EXPECT_FALSE(p.objects.empty());
        EXPECT_FALSE(p.description.empty());
        // every label drawn is named, coloured from the palette
        std::set<std::uint16_t> drawn(p.stack.labels.begin(), p.stack.labels.end());
        drawn.erase(0);
        EXPECT_FALSE(drawn.empty());
        for (std::uint16_t v : drawn) {
            auto it = std::find_if(p.stack.label_table.begin(), p.stack.label_table.end(),
                                   [v](const LabelInfo& l) { return l.value == v; });
            ASSERT_NE(it, p.stack.label_table.end()) << "label " << v;
            EXPECT_FALSE(it->name.empty());
            EXPECT_EQ(it->color, palette_color(v));
        }
        for (const PhantomObject& o : p.objects) {
            EXPECT_EQ(o.solid.has_value(), !p.slice_defined) << o.name;
        }
    }
}

TEST(Catalogue, SolidDefinedCasesRasteriseTheirSolidsAtPixelCentres) {
    for (const auto& [name, size] : catalogue_sizes()) {
        if (name == "t32_huge_contour" || name == "t33_many_components") {
            continue;
        }
        const Phantom& p = phantom(name);
        if (p.slice_defined) {
            continue;
        }
        SCOPED_TRACE(name);
        int differences = 0;
        for (std::uint32_t k = 0; k < p.stack.depth; ++k) {
            for (std::uint32_t j = 0; j < p.stack.height; ++j) {
                for (std::uint32_t i = 0; i < p.stack.width; ++i) {
                    const Vec3 c{i + 0.5, j + 0.5, k * p.slice_spacing_px};
                    bool in = false;
                    for (const PhantomObject& o : p.objects) {
                        in = in || contains(*o.solid, c);
                    }
                    differences += in != fg(p.stack, i, j, k);
                }
            }
        }
        EXPECT_EQ(differences, 0);
    }
}

TEST(Catalogue, T01FirstAndLastSlicesAreEmpty) {
    const SliceStack& s = phantom("t01_sphere").stack;
    EXPECT_EQ(count_pixels(s, 0), 0u);
    EXPECT_EQ(count_pixels(s, 21), 0u);
    // radius sqrt(156) ~ 12.5 px at z = 4
    EXPECT_NEAR(count_pixels(s, 1), 3.14159 * 156, 30);
    EXPECT_TRUE(fg(s, 64 + 11, 64, 1));  // 11.5^2 + 0.5^2 + 38^2 <= 40^2
    EXPECT_FALSE(fg(s, 64 + 12, 64, 1));
}

TEST(Catalogue, T03EverySliceIsTheSameRectangle) {
    const SliceStack& s = phantom("t03_box_sharp").stack;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t j = 0; j < s.height; ++j) {
            for (std::uint32_t i = 0; i < s.width; ++i) {
                ASSERT_EQ(fg(s, i, j, k), i >= 34 && i < 94 && j >= 44 && j < 84)
                    << i << "," << j << "," << k;
            }
        }
        EXPECT_EQ(count_pixels(s, k), 60u * 40u);
    }
}

TEST(Catalogue, T04AndT09SlicesAreIdentical) {
    for (const char* name : {"t04_cylinder_aniso10", "t09_annulus_tube", "t19_plate_two_holes"}) {
        const SliceStack& s = phantom(name).stack;
        for (std::uint32_t k = 1; k < s.depth; ++k) {
            EXPECT_TRUE(std::equal(s.slice(0).begin(), s.slice(0).end(), s.slice(k).begin()))
                << name << " slice " << k;
        }
    }
    EXPECT_FALSE(fg(phantom("t09_annulus_tube").stack, 64, 64, 0));
    EXPECT_TRUE(fg(phantom("t09_annulus_tube").stack, 64 + 30, 64, 0));
    EXPECT_FALSE(fg(phantom("t19_plate_two_holes").stack, 88, 64, 3));
    EXPECT_FALSE(fg(phantom("t19_plate_two_holes").stack, 168, 64, 3));
    EXPECT_TRUE(fg(phantom("t19_plate_two_holes").stack, 128, 64, 3));
}

TEST(Catalogue, T05WedgeRotatesSixDegreesPerSlice) {
    const SliceStack& s = phantom("t05_c_shape_twist").stack;
    for (std::uint32_t k : {0u, 5u, 19u}) {
        const double gap = 6.0 * k * std::numbers::pi / 180;
        const auto at = [&](double angle) {
            return fg(s, std::uint32_t(80 + 40 * std::cos(angle)),
                      std::uint32_t(80 + 40 * std::sin(angle)), k);
        };
        EXPECT_FALSE(at(gap)) << k;
        EXPECT_TRUE(at(gap + std::numbers::pi)) << k;
    }
}

TEST(Catalogue, T07StarBecomesACircle) {
    const SliceStack& s = phantom("t07_star_to_circle").stack;
    EXPECT_TRUE(fg(s, 80 + 53, 80, 0));    // outer vertex at 0 deg, radius 55
    EXPECT_FALSE(fg(s, 80 + 36, 80, 12));  // circle radius 35
    std::uint32_t disc = 0;
    for (std::uint32_t j = 0; j < s.height; ++j) {
        for (std::uint32_t i = 0; i < s.width; ++i) {
            const double dx = i + 0.5 - 80, dy = j + 0.5 - 80;
            const bool in = dx * dx + dy * dy <= 35.0 * 35.0;
            disc += in;
            EXPECT_EQ(fg(s, i, j, 12), in);
        }
    }
    EXPECT_EQ(count_pixels(s, 12), disc);
}

TEST(Catalogue, T08TeethShrinkSixPixelsPerSlice) {
    const SliceStack& s = phantom("t08_comb_retracting").stack;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        const std::uint32_t length = k <= 8 ? 48 - 6 * k : 0;
        for (std::uint32_t tooth = 0; tooth < 6; ++tooth) {
            std::uint32_t column = 0;
            for (std::uint32_t j = 0; j < 80; ++j) {
                column += fg(s, 30 + 20 * tooth + 2, j, k);
            }
            EXPECT_EQ(column, length) << "tooth " << tooth << " slice " << k;
            EXPECT_FALSE(fg(s, 30 + 20 * tooth + 4, 79, k));
        }
        EXPECT_EQ(count_regions(s, k), 1u);
    }
}

TEST(Catalogue, T10AndT11HolesAndIslandsOnTheirSlices) {
    const SliceStack& cavity = phantom("t10_internal_cavity").stack;
    for (std::uint32_t k = 0; k < cavity.depth; ++k) {
        EXPECT_EQ(fg(cavity, 64, 64, k), k < 7 || k > 12) << k;
    }
    const SliceStack& island = phantom("t11_island_in_hole").stack;
    for (std::uint32_t k = 0; k < island.depth; ++k) {
        EXPECT_EQ(fg(island, 64, 64, k), k >= 3 && k <= 8) << k;
        EXPECT_TRUE(fg(island, 64 + 50, 64, k));
        EXPECT_FALSE(fg(island, 64 + 30, 64, k));
    }
}

TEST(Catalogue, BranchingSlicesSplitWhereStated) {
    const SliceStack& y = phantom("t13_y_branch_1to2").stack;
    for (std::uint32_t k = 0; k < y.depth; ++k) {
        EXPECT_EQ(count_regions(y, k), k <= 23 ? 1u : 2u) << "T13 slice " << k;
    }
    const SliceStack& trident = phantom("t15_trident_1to3").stack;
    EXPECT_EQ(count_regions(trident, 22), 1u);
    EXPECT_EQ(count_regions(trident, 23), 3u);
    const SliceStack& aniso = phantom("t31_aniso_branch_d10").stack;
    EXPECT_EQ(count_regions(aniso, 4), 1u);  // z = 40
    EXPECT_EQ(count_regions(aniso, 5), 2u);  // z = 50
    const SliceStack& tree = phantom("t16_n_to_m_tree").stack;
    for (std::uint32_t k = 0; k < tree.depth; ++k) {
        EXPECT_EQ(count_regions(tree, k), k <= 5 ? 2u : 3u) << "T16 slice " << k;
    }
}

TEST(Catalogue, T14IsT13Reversed) {
    const SliceStack& a = phantom("t13_y_branch_1to2").stack;
    const SliceStack& b = phantom("t14_merge_2to1").stack;
    for (std::uint32_t k = 0; k < a.depth; ++k) {
        EXPECT_TRUE(
            std::equal(a.slice(k).begin(), a.slice(k).end(), b.slice(a.depth - 1 - k).begin()))
            << k;
    }
}

TEST(Catalogue, T18RegionsPerSlice) {
    const SliceStack& s = phantom("t18_torus_on_side").stack;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        std::uint32_t expected = 0;
        if (k >= 6 && k <= 14) {
            expected = 1;
        } else if (k >= 15 && k <= 35) {
            expected = 2;
        } else if (k >= 36 && k <= 44) {
            expected = 1;
        }
        EXPECT_EQ(count_regions(s, k), expected) << "slice " << k;
    }
}

TEST(Catalogue, T21BallOnlyOnSlices8To11) {
    const SliceStack& s = phantom("t21_appear_midstack").stack;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        EXPECT_EQ(count_regions(s, k), k >= 8 && k <= 11 ? 2u : 1u) << k;
    }
}

TEST(Catalogue, T22AndT23EmptySlices) {
    const SliceStack& a = phantom("t22_empty_slices_inside").stack;
    const SliceStack& b = phantom("t22_empty_slices_inside_b").stack;
    for (std::uint32_t k = 0; k < a.depth; ++k) {
        EXPECT_EQ(count_pixels(a, k) == 0, k >= 7 && k <= 9) << k;
        EXPECT_EQ(count_pixels(b, k) == 0, k == 8) << k;
    }
    const SliceStack& single = phantom("t23_single_slice_object").stack;
    for (std::uint32_t k = 0; k < single.depth; ++k) {
        EXPECT_EQ(count_pixels(single, k) != 0, k == 5) << k;
    }
    EXPECT_FALSE(phantom("t23_single_slice_object").objects[0].gt_applies);
}

TEST(Catalogue, T24PixelListsAreExact) {
    const SliceStack& s = phantom("t24_tiny_objects_and_needle").stack;
    std::set<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> expected;
    for (auto [i, j] : std::vector<std::pair<std::uint32_t, std::uint32_t>>{{8, 8},
                                                                            {20, 8},
                                                                            {21, 8},
                                                                            {32, 8},
                                                                            {33, 8},
                                                                            {32, 9},
                                                                            {33, 9},
                                                                            {20, 24},
                                                                            {21, 24},
                                                                            {20, 25},
                                                                            {32, 24},
                                                                            {33, 25}}) {
        expected.insert({i, j, 6});
    }
    for (std::uint32_t i = 8; i <= 10; ++i) {
        for (std::uint32_t j = 24; j <= 26; ++j) {
            expected.insert({i, j, 6});
        }
    }
    for (std::uint32_t k = 2; k <= 9; ++k) {
        expected.insert({50, 50, k});
    }
    std::set<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> found;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t j = 0; j < s.height; ++j) {
            for (std::uint32_t i = 0; i < s.width; ++i) {
                if (fg(s, i, j, k)) {
                    found.insert({i, j, k});
                }
            }
        }
    }
    EXPECT_EQ(found, expected);
    EXPECT_EQ(count_regions(s, 6), 7u);  // six objects + the needle
    EXPECT_EQ(count_components_3d(s), 7u);
}

TEST(Catalogue, T25TouchingDiscsShareAnEightPixelNeck) {
    const SliceStack& g0 = phantom("t25_touching_discs_g0").stack;
    for (std::uint32_t k = 0; k < g0.depth; ++k) {
        for (std::uint32_t j = 0; j < g0.height; ++j) {
            const bool neck = j >= 28 && j <= 35;
            EXPECT_EQ(fg(g0, 53, j, k), neck) << "row " << j;
            EXPECT_EQ(fg(g0, 54, j, k), neck) << "row " << j;
        }
        EXPECT_EQ(count_regions(g0, k), 1u);
        EXPECT_EQ(count_regions(phantom("t25_touching_discs_gm2").stack, k), 1u);
        EXPECT_EQ(count_regions(phantom("t25_touching_discs_g1").stack, k), 2u);
        EXPECT_EQ(count_regions(phantom("t25_touching_discs_g2").stack, k), 2u);
    }
    EXPECT_EQ(phantom("t25_touching_discs_g1").expected->surfaces, 2u);
    EXPECT_EQ(phantom("t25_touching_discs_g0").expected->surfaces, 1u);
}

TEST(Catalogue, T27MovingLineShiftsOneColumnPerSlice) {
    const Phantom& p = phantom("t27_thin_features");
    const SliceStack& s = p.stack;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t i = 0; i < 40; ++i) {
            for (std::uint32_t j = 90; j < 128; ++j) {
                EXPECT_EQ(fg(s, i, j, k), i == 10 + k && j >= 96 && j < 124) << i << "," << j;
            }
        }
        EXPECT_TRUE(fg(s, 10, 79, k));
        EXPECT_FALSE(fg(s, 10, 80, k));
        EXPECT_TRUE(fg(s, 69, 20, k));
        EXPECT_FALSE(fg(s, 70, 20, k));
        EXPECT_FALSE(fg(s, 11, 21, k));
        EXPECT_EQ(count_regions(s, k), 3u);
    }
    EXPECT_EQ(count_components_3d(s), 8u);
    ASSERT_EQ(p.objects.size(), 3u);
    EXPECT_FALSE(p.objects[2].gt_applies);
    EXPECT_EQ(p.expected->genus, (std::vector<std::uint32_t>{1, 0, 0, 0, 0, 0, 0, 0}));
}

TEST(Catalogue, T29ShiftedDiscsOverlapOnlyInVariantB) {
    const SliceStack& a = phantom("t29_shifted_nonoverlap_a").stack;
    const SliceStack& b = phantom("t29_shifted_nonoverlap_b").stack;
    for (std::uint32_t k = 0; k < a.depth; ++k) {
        EXPECT_TRUE(fg(a, 20 + 40 * k, 32, k));
        EXPECT_TRUE(fg(b, 20 + 20 * k, 32, k));
    }
    EXPECT_EQ(count_components_3d(a), 5u);
    EXPECT_EQ(count_components_3d(b), 1u);
    EXPECT_FALSE(phantom("t29_shifted_nonoverlap_a").objects[0].gt_applies);
    EXPECT_TRUE(phantom("t29_shifted_nonoverlap_b").objects[0].gt_applies);
}

TEST(Catalogue, T34ClippedBallAndFullSlices) {
    const SliceStack& a = phantom("t34_border_touch").stack;
    EXPECT_TRUE(fg(a, 0, 64, 16));
    EXPECT_EQ(count_components_3d(a), 1u);
    const SliceStack& b = phantom("t34_border_touch_b").stack;
    for (std::uint32_t k = 0; k < b.depth; ++k) {
        EXPECT_EQ(count_pixels(b, k) == b.slice_size(), k >= 10 && k <= 12) << k;
    }
}

TEST(Catalogue, T33DrawsThreeHundredBallsFrom332Candidates) {
    const Phantom& p = phantom("t33_many_components");
    ASSERT_TRUE(p.draws.has_value());
    EXPECT_EQ(p.draws->seed, 1234u);
    EXPECT_EQ(p.draws->drawn, 332u);
    EXPECT_EQ(p.draws->accepted, 300u);
    EXPECT_EQ(count_components_3d(p.stack), 300u);
}

TEST(Catalogue, T35FlipsExactly1763Pixels) {
    const Phantom& p = phantom("t35_speckle_noise");
    ASSERT_TRUE(p.draws.has_value());
    EXPECT_EQ(p.draws->seed, 7u);
    EXPECT_EQ(p.draws->drawn, 22u * 128u * 128u);
    EXPECT_EQ(p.draws->accepted, 1763u);
    const SliceStack& clean = phantom("t01_sphere").stack;
    std::size_t flipped = 0;
    for (std::size_t i = 0; i < clean.labels.size(); ++i) {
        flipped += (clean.labels[i] != 0) != (p.stack.labels[i] != 0);
    }
    EXPECT_EQ(flipped, 1763u);
    EXPECT_EQ(p.expected->surfaces, 1609u);
    EXPECT_EQ(p.expected->solid_components, 1367u);
    EXPECT_EQ(p.expected->genus.front(), 1u);
}

TEST(Catalogue, T36AcceptsTheEighteenthAttempt) {
    const Phantom& p = phantom("t36_organ_like");
    ASSERT_TRUE(p.draws.has_value());
    EXPECT_EQ(p.draws->seed, 36u);
    EXPECT_EQ(p.draws->drawn, 18u);
    const SliceStack& s = p.stack;
    EXPECT_EQ(count_pixels(s, 0), 0u);
    EXPECT_EQ(count_pixels(s, s.depth - 1), 0u);
    std::uint32_t most_regions = 0;
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t t = 0; t < s.width; ++t) {
            EXPECT_FALSE(fg(s, t, 0, k) || fg(s, t, s.height - 1, k) || fg(s, 0, t, k) ||
                         fg(s, s.width - 1, t, k));
        }
        most_regions = std::max(most_regions, count_regions(s, k));
    }
    EXPECT_GE(most_regions, 2u);
    EXPECT_EQ(count_components_3d(s), 1u);
    // The accepted attempt's first body Gaussian, as numpy draws it on attempt 18.
    const auto& g = std::get<GaussianLevelSet>(p.objects[0].solid->nodes.back());
    ASSERT_EQ(g.blobs.size(), 7u);
    EXPECT_NEAR(g.blobs[0].centre.x, 183.68186132, 1e-7);
    EXPECT_NEAR(g.blobs[0].centre.y, 125.52717469, 1e-7);
    EXPECT_NEAR(g.blobs[0].centre.z, 95.05625712, 1e-7);
    EXPECT_NEAR(g.blobs[0].sigma, 34.117193802641935, 1e-12);
}

TEST(Catalogue, HugeContourSlice) {
    const Phantom& p = phantom("t32_huge_contour");
    ASSERT_EQ(p.stack.width, 4096u);
    ASSERT_EQ(p.stack.height, 4096u);
    ASSERT_EQ(p.stack.depth, 10u);
    // "about 15 000 boundary pixels per slice": foreground pixels with a background 4-neighbour
    const SliceStack& s = p.stack;
    for (std::uint32_t k : {0u, 9u}) {
        std::uint32_t boundary = 0;
        for (std::uint32_t j = 1; j + 1 < s.height; ++j) {
            for (std::uint32_t i = 1; i + 1 < s.width; ++i) {
                if (fg(s, i, j, k) && (!fg(s, i - 1, j, k) || !fg(s, i + 1, j, k) ||
                                       !fg(s, i, j - 1, k) || !fg(s, i, j + 1, k))) {
                    ++boundary;
                }
            }
        }
        EXPECT_GT(boundary, 14000u);
        EXPECT_LT(boundary, 16500u);
    }
    // spot checks of the radius on slice 3 against the formula
    const Solid& solid = *p.objects[0].solid;
    for (std::uint32_t j = 500; j < 3600; j += 97) {
        for (std::uint32_t i = 0; i < 4096; i += 13) {
            ASSERT_EQ(fg(s, i, j, 3), contains(solid, {i + 0.5, j + 0.5, 12.0}));
        }
    }
    EXPECT_EQ(count_regions(s, 3), 1u);
}

TEST(Catalogue, SceneHasFourNamedLabels) {
    const Phantom& p = phantom("scene");
    EXPECT_EQ(p.stack.width, 128u);
    EXPECT_EQ(p.stack.height, 128u);
    EXPECT_EQ(p.stack.depth, 40u);
    EXPECT_EQ(p.slice_spacing_px, 2.0);
    ASSERT_EQ(p.stack.label_table.size(), 4u);
    const std::vector<std::string> names = {"sphere", "torus", "vessel", "ellipsoid"};
    std::set<std::uint16_t> drawn(p.stack.labels.begin(), p.stack.labels.end());
    for (std::uint16_t v = 1; v <= 4; ++v) {
        EXPECT_EQ(p.stack.label_table[v - 1].value, v);
        EXPECT_EQ(p.stack.label_table[v - 1].name, names[v - 1]);
        EXPECT_TRUE(drawn.count(v)) << v;
    }
    EXPECT_EQ(p.expected->surfaces, 4u);
    EXPECT_EQ(p.expected->genus, (std::vector<std::uint32_t>{1, 0, 0, 0}));
    // objects never overlap or touch (one component per label)
    EXPECT_EQ(count_components_3d(p.stack), 4u);
    const Phantom& hollow = phantom("hollow_sphere");
    EXPECT_FALSE(fg(hollow.stack, 64, 64, 10));
    EXPECT_TRUE(fg(hollow.stack, 64 + 30, 64, 10));
    EXPECT_EQ(hollow.expected->surfaces, 2u);
}

TEST(Catalogue, DemosMatchTheirCatalogueCases) {
    for (auto [demo, id] :
         std::vector<std::pair<std::string, std::string>>{{"sphere", "t01_sphere"},
                                                          {"ellipsoid", "t02_ellipsoid_tilted"},
                                                          {"torus", "t18_torus_on_side"},
                                                          {"branching", "t13_y_branch_1to2"}}) {
        const Phantom& a = phantom(demo);
        EXPECT_EQ(a.stack.labels, phantom(id).stack.labels) << demo;
        EXPECT_EQ(a.stack.source, "phantom " + demo);
    }
}

TEST(Catalogue, ResamplingKeepsThePhysicalExtent) {
    PhantomOptions options;
    options.slice_spacing_px = 2.0;
    options.pixel_mm = 0.5;
    const Phantom fine = make_phantom("t01_sphere", options);
    EXPECT_EQ(fine.stack.depth, 43u);  // z = 0 ... 84
    EXPECT_EQ(fine.slice_spacing_px, 2.0);
    EXPECT_DOUBLE_EQ(fine.stack.spacing_mm().z, 1.0);
    EXPECT_DOUBLE_EQ(fine.stack.spacing_mm().x, 0.5);
    EXPECT_FALSE(fine.expected.has_value());
    const SliceStack& coarse = phantom("t01_sphere").stack;
    for (std::uint32_t k = 0; k < coarse.depth; ++k) {
        EXPECT_TRUE(std::equal(coarse.slice(k).begin(), coarse.slice(k).end(),
                               fine.stack.slice(2 * k).begin()))
            << k;
    }
    options.slice_spacing_px = 3.0;
    options.pixel_mm.reset();
    const Phantom cyl = make_phantom("t04_cylinder_aniso10", options);
    EXPECT_EQ(cyl.stack.depth, 24u);  // floor(70 / 3) + 1
    // the catalogue's own spacing is not a resampling
    options.slice_spacing_px = 10.0;
    EXPECT_TRUE(make_phantom("t04_cylinder_aniso10", options).expected.has_value());
    // T36 keeps the accepted solid and only resamples it
    options.slice_spacing_px = 12.5;
    const Phantom organ = make_phantom("t36_organ_like", options);
    EXPECT_EQ(organ.stack.depth, 12u);
    EXPECT_EQ(organ.draws->drawn, 18u);
    for (std::uint32_t k = 0; k < organ.stack.depth; ++k) {
        const SliceStack& s = phantom("t36_organ_like").stack;
        EXPECT_TRUE(std::equal(organ.stack.slice(k).begin(), organ.stack.slice(k).end(),
                               s.slice(2 * k).begin()));
    }
}

void expect_invalid(const std::string& name,
                    const PhantomOptions& options,
                    const std::vector<std::string>& fragments) {
    try {
        make_phantom(name, options);
        ADD_FAILURE() << "expected an error for " << name;
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
        for (const std::string& f : fragments) {
            EXPECT_NE(std::string(e.what()).find(f), std::string::npos) << e.what();
        }
    }
}

TEST(Catalogue, UnknownNameListsTheValidNames) {
    expect_invalid("t99_nothing", {},
                   {"unknown phantom 't99_nothing'", "t01_sphere", "t36_organ_like", "scene"});
}

TEST(Catalogue, BadOptionsAreRejected) {
    PhantomOptions spacing;
    spacing.slice_spacing_px = 2.0;
    for (const char* name :
         {"t16_n_to_m_tree", "t24_tiny_objects_and_needle", "t35_speckle_noise"}) {
        expect_invalid(name, spacing, {name, "slice-defined"});
    }
    spacing.slice_spacing_px = -1.0;
    expect_invalid("t01_sphere", spacing, {"phantom t01_sphere", "slice spacing -1 px"});
    spacing.slice_spacing_px = std::nan("");
    expect_invalid("t01_sphere", spacing, {"slice spacing"});
    spacing.slice_spacing_px = 1e-9;
    expect_invalid("t01_sphere", spacing, {"slices"});
    PhantomOptions pixel;
    pixel.pixel_mm = 0.0;
    expect_invalid("sphere", pixel, {"pixel size 0 mm"});
}

TEST(Catalogue, OtherSeedsDrawOtherCases) {
    PhantomOptions options;
    options.seed = 1;
    const Phantom balls = make_phantom("t33_many_components", options);
    EXPECT_EQ(balls.draws->accepted, 300u);
    EXPECT_NE(balls.stack.labels, phantom("t33_many_components").stack.labels);
    ASSERT_TRUE(balls.expected.has_value());  // holds for any accepted draw
    EXPECT_EQ(count_components_3d(balls.stack), 300u);
    options.seed = 8;
    const Phantom speckle = make_phantom("t35_speckle_noise", options);
    EXPECT_FALSE(speckle.expected.has_value());  // the catalogue's counts are for seed 7
    EXPECT_NEAR(double(speckle.draws->accepted), 1800.0, 200.0);
}

TEST(NumpyRandom, MatchesNumpyDefaultRng) {
    // numpy 1.24: np.random.default_rng(seed).bit_generator.random_raw()
    const std::vector<std::pair<std::uint64_t, std::vector<std::uint64_t>>> raw = {
        {1234, {0xfa08fef3fab6bbbaULL, 0x615481f7fce9ac81ULL}},
        {7, {0xa00641a9f1e54a8bULL, 0xe5afcdbcaf266a95ULL}},
        {0, {0xa30febcfd9c2825fULL, 0x4510bdf882d9d721ULL}},
        {(std::uint64_t(1) << 40) + 5, {0x01369aef039fedebULL, 0x5f61b40473314316ULL}},
        {36, {0x2e3df8636218ede6ULL, 0x65f2d8276cb75d82ULL}},
    };
    for (const auto& [seed, values] : raw) {
        NumpyRandom rng(seed);
        for (std::uint64_t v : values) {
            EXPECT_EQ(rng.next_uint64(), v) << "seed " << seed;
        }
    }
    NumpyRandom rng(1234);
    EXPECT_EQ(rng.random(), 0.9766997666981422);
    EXPECT_EQ(rng.random(), 0.3801957350196178);
    EXPECT_EQ(rng.random(), 0.9232462337639554);
    NumpyRandom organ(36);
    EXPECT_EQ(organ.uniform(51.2, 204.8), 78.94524281203243);
    EXPECT_EQ(organ.uniform(51.2, 204.8), 112.36916644899867);
    EXPECT_EQ(organ.uniform(30, 120), 110.44491632128901);
    EXPECT_EQ(organ.uniform(15, 35), 23.067720150293336);
}

}  // namespace
}  // namespace strata

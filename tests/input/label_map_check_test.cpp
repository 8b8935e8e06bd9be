// An intensity image taken for a label map (issue 18): refused by evident statistics, while every
// label map of ../shared/data and of the phantom catalogue passes.

#include "input/label_map_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include <gtest/gtest.h>

#include "core/error.h"
#include "input/read_slice_stack.h"
#include "phantom/catalogue.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

SliceStack blank_stack(std::uint32_t w, std::uint32_t h, std::uint32_t d) {
    SliceStack s;
    s.width = w;
    s.height = h;
    s.depth = d;
    s.labels.assign(std::size_t(w) * h * d, 0);
    s.source = "test stack";
    return s;
}

/// A greyscale picture as a camera or scanner gives it: a bright smooth blob on a dim
/// background, plus noise; 8 slices of 96 x 96 as in the issue.
SliceStack greyscale_picture(double noise) {
    SliceStack s = blank_stack(96, 96, 8);
    std::mt19937 random(18);
    std::uniform_real_distribution<double> jitter(-noise, noise);
    for (std::uint32_t k = 0; k < s.depth; ++k) {
        for (std::uint32_t j = 0; j < s.height; ++j) {
            for (std::uint32_t i = 0; i < s.width; ++i) {
                const double dx = i - 48.0, dy = j - 44.0 - 2.0 * k;
                const double v = 30.0 + 200.0 * std::exp(-(dx * dx + dy * dy) / (2 * 25.0 * 25.0));
                s.labels[(std::size_t(k) * s.height + j) * s.width + i] =
                    std::uint16_t(std::clamp(std::lround(v + jitter(random)), 1L, 255L));
            }
        }
    }
    return s;
}

/// A CT-like slab: 16-bit values around 1000 with noise, 4 slices of 64 x 64.
SliceStack ct_slab() {
    SliceStack s = blank_stack(64, 64, 4);
    std::mt19937 random(24);
    std::normal_distribution<double> tissue(1040.0, 25.0);
    for (std::uint16_t& v : s.labels) {
        v = std::uint16_t(std::lround(tissue(random)));
    }
    return s;
}

/// Many small objects (a label map with 300 labels): 300 discs of radius 3 px, each its label.
SliceStack many_small_objects() {
    SliceStack s = blank_stack(20 * 9, 15 * 9, 3);
    std::uint16_t label = 0;
    for (std::uint32_t cy = 0; cy < 15; ++cy) {
        for (std::uint32_t cx = 0; cx < 20; ++cx) {
            ++label;
            for (std::uint32_t k = 0; k < s.depth; ++k) {
                for (int dy = -3; dy <= 3; ++dy) {
                    for (int dx = -3; dx <= 3; ++dx) {
                        if (dx * dx + dy * dy <= 9) {
                            const std::uint32_t i = cx * 9 + 4 + dx, j = cy * 9 + 4 + dy;
                            s.labels[(std::size_t(k) * s.height + j) * s.width + i] = label;
                        }
                    }
                }
            }
        }
    }
    return s;
}

TEST(LabelMapCheck, StatisticsOfAHandCountedStack) {
    // 3 x 2, one slice:  1 1 2
    //                    0 3 2
    // pairs with a non-zero pixel: (1,1) (1,2) (0,3) (3,2) across, (1,0) (1,3) (2,2) down: 7,
    // of which (1,1) and (2,2) agree; pixel 3 is isolated, so are none of 1 or 2.
    SliceStack s = blank_stack(3, 2, 1);
    s.labels = {1, 1, 2, 0, 3, 2};
    const LabelMapStatistics st = label_map_statistics(s);
    EXPECT_EQ(st.labels, 3u);
    EXPECT_EQ(st.foreground_pixels, 5u);
    EXPECT_DOUBLE_EQ(st.neighbour_agreement, 2.0 / 7.0);
    EXPECT_DOUBLE_EQ(st.isolated_share, 1.0 / 5.0);
    EXPECT_DOUBLE_EQ(st.speckled_label_share, 1.0 / 3.0);
}

TEST(LabelMapCheck, GreyscalePicturesAreRefused) {
    for (const double noise : {4.0, 12.0, 40.0}) {
        const SliceStack s = greyscale_picture(noise);
        const LabelMapStatistics st = label_map_statistics(s);
        EXPECT_GE(st.labels, 200u) << "noise " << noise;
        EXPECT_TRUE(intensity_image_evidence(st)) << "noise " << noise;
        try {
            check_is_label_map(s);
            ADD_FAILURE() << "noise " << noise << ": not refused";
        } catch (const Error& e) {
            EXPECT_EQ(e.code(), ErrorCode::InvalidInput);
            const std::string what = e.what();
            EXPECT_NE(what.find("test stack"), std::string::npos) << what;
            EXPECT_NE(what.find("intensity image"), std::string::npos) << what;
            EXPECT_NE(what.find("--labels"), std::string::npos) << what;
            EXPECT_NE(what.find("--force-label-map"), std::string::npos) << what;
        }
    }
    EXPECT_TRUE(intensity_image_evidence(label_map_statistics(ct_slab())));
}

TEST(LabelMapCheck, ManySmallObjectsAreALabelMap) {
    const LabelMapStatistics st = label_map_statistics(many_small_objects());
    EXPECT_EQ(st.labels, 300u);
    EXPECT_FALSE(intensity_image_evidence(st));
}

TEST(LabelMapCheck, EveryPhantomIsALabelMap) {
    for (const std::string& name : phantom_names()) {
        const LabelMapStatistics st = label_map_statistics(make_phantom(name).stack);
        EXPECT_FALSE(intensity_image_evidence(st)) << name;
    }
}

TEST(LabelMapCheck, EverySharedDataLabelMapPasses) {
    const fs::path data = test::shared_data_dir();
    for (const fs::path& input :
         {data / "totalsegmentator_abdomen" / "example_seg.nii.gz",
          data / "niivue_torso" / "torsoLabel.nii.gz", data / "freesurfer_aparc_aseg",
          data / "pyradiomics_lung_tumor" / "lung2_label.nrrd",
          data / "pyradiomics_brain_tumor" / "brain1_label.nrrd", data / "terrain_volcano"}) {
        Report report;
        const SliceStack s = read_slice_stack(input, ReadOptions{}, report);
        const LabelMapStatistics st = label_map_statistics(s);
        std::printf("%s: %zu labels, agreement %.3f, isolated %.4f, speckled labels %.3f\n",
                    input.filename().c_str(), st.labels, st.neighbour_agreement, st.isolated_share,
                    st.speckled_label_share);
        EXPECT_FALSE(intensity_image_evidence(st)) << input;
        EXPECT_NO_THROW(check_is_label_map(s)) << input;
    }
}

}  // namespace
}  // namespace strata

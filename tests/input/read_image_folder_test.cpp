#include <fstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "input/read_slice_stack.h"
#include "input/write_slice_stack.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

/// Writes one image with OpenImageIO (any channel count / pixel type) for the error cases.
void write_image(const fs::path& file,
                 int width,
                 int height,
                 int channels,
                 OIIO::TypeDesc type,
                 const void* pixels) {
    auto out = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(out) << OIIO::geterror();
    OIIO::ImageSpec spec(width, height, channels, type);
    ASSERT_TRUE(out->open(file.string(), spec));
    ASSERT_TRUE(out->write_image(type, pixels));
    ASSERT_TRUE(out->close());
}

void write_grey8(const fs::path& file, int width, int height, std::uint8_t value) {
    std::vector<std::uint8_t> px(std::size_t(width) * height, value);
    write_image(file, width, height, 1, OIIO::TypeDesc::UINT8, px.data());
}

SliceStack read(const fs::path& path) {
    Report report;
    return read_slice_stack(path, ReadOptions{}, report);
}

std::string error_of(const fs::path& path, ErrorCode expected) {
    try {
        read(path);
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), expected) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "no error for " << path;
    return {};
}

TEST(ReadImageFolder, NaturalSortOfNames) {
    const fs::path dir = test::fresh_temp_dir("folder_natural");
    // slice values equal their intended index, names sort wrongly as plain strings
    for (int k : {1, 2, 10, 9}) {
        write_grey8(dir / ("img_" + std::to_string(k) + ".png"), 5, 4,
                    static_cast<std::uint8_t>(k));
    }
    const SliceStack s = read(dir);
    ASSERT_EQ(s.depth, 4u);
    EXPECT_EQ(s.at(0, 0, 0), 1);
    EXPECT_EQ(s.at(0, 0, 1), 2);
    EXPECT_EQ(s.at(0, 0, 2), 9);
    EXPECT_EQ(s.at(0, 0, 3), 10);
    EXPECT_EQ(s.label_table.size(), 4u);
}

TEST(ReadImageFolder, PngStackRoundTripIsExact) {
    SliceStack s;
    s.width = 7;
    s.height = 5;
    s.depth = 3;
    s.labels.resize(7 * 5 * 3);
    for (std::size_t i = 0; i < s.labels.size(); ++i) {
        s.labels[i] = static_cast<std::uint16_t>((i * 37) % 5 == 0 ? 0 : 1000 + i % 4);
    }
    s.index_to_world.linear = {{{0.7, 0, 0}, {0, 0.7, 0}, {0, 0, 5}}};
    s.index_to_world.translation = {-10, 20.5, 3};
    s.label_table = {{1000, "liver", {200, 100, 50}}};
    complete_label_table(s);
    const fs::path dir = test::fresh_temp_dir("folder_roundtrip");
    write_png_stack(s, dir);
    const SliceStack r = read(dir);
    EXPECT_EQ(r.width, s.width);
    EXPECT_EQ(r.height, s.height);
    EXPECT_EQ(r.depth, s.depth);
    EXPECT_EQ(r.labels, s.labels);
    for (int a = 0; a < 3; ++a) {
        for (int b = 0; b < 3; ++b) {
            EXPECT_DOUBLE_EQ(r.index_to_world.linear[a][b], s.index_to_world.linear[a][b]);
        }
    }
    EXPECT_EQ(r.index_to_world.translation, s.index_to_world.translation);
    ASSERT_EQ(r.label_table.size(), s.label_table.size());
    EXPECT_EQ(r.label_table[0].name, "liver");
    EXPECT_EQ(r.label_table[0].color, (ColorSrgb8{200, 100, 50}));
    // reading the slices/ folder itself finds the sidecar one level up
    EXPECT_EQ(read(dir / "slices").labels, s.labels);
}

TEST(ReadImageFolder, SixteenBitLabels) {
    const fs::path dir = test::fresh_temp_dir("folder_16bit");
    std::vector<std::uint16_t> px = {0, 1, 65535, 4000};
    write_image(dir / "a.png", 2, 2, 1, OIIO::TypeDesc::UINT16, px.data());
    const SliceStack s = read(dir);
    EXPECT_EQ(s.at(1, 1, 0), 4000);
    EXPECT_EQ(s.at(0, 1, 0), 65535);
}

TEST(ReadImageFolder, MismatchedSliceSizesRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_mismatch");
    write_grey8(dir / "s0.png", 8, 8, 1);
    write_grey8(dir / "s1.png", 8, 7, 1);
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("slice 1 (s1.png): size 8x7, expected 8x8"), std::string::npos) << m;
}

TEST(ReadImageFolder, ColourImageWithDifferentChannelsRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_rgb");
    std::vector<std::uint8_t> px = {1, 1, 1, 2, 3, 4};
    write_image(dir / "s0.png", 2, 1, 3, OIIO::TypeDesc::UINT8, px.data());
    const std::string m = error_of(dir, ErrorCode::Unsupported);
    EXPECT_NE(m.find("differing channels at pixel (1, 0)"), std::string::npos) << m;
}

TEST(ReadImageFolder, GreyColourImageAccepted) {
    const fs::path dir = test::fresh_temp_dir("folder_rgb_grey");
    std::vector<std::uint8_t> px = {5, 5, 5, 0, 0, 0};
    write_image(dir / "s0.png", 2, 1, 3, OIIO::TypeDesc::UINT8, px.data());
    Report report;
    const SliceStack s = read_slice_stack(dir, ReadOptions{}, report);
    EXPECT_EQ(s.at(0, 0, 0), 5);
    EXPECT_EQ(report.warnings.size(), 1u);
}

TEST(ReadImageFolder, FloatImagesUnsupported) {
    const fs::path dir = test::fresh_temp_dir("folder_float");
    std::vector<float> px = {0.f, 1.f, 2.f, 3.f};
    write_image(dir / "s0.tif", 2, 2, 1, OIIO::TypeDesc::FLOAT, px.data());
    const std::string m = error_of(dir, ErrorCode::Unsupported);
    EXPECT_NE(m.find("expected 8- or 16-bit unsigned integer labels"), std::string::npos) << m;
}

TEST(ReadImageFolder, TruncatedPngRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_truncated");
    std::vector<std::uint8_t> px(64 * 64);
    for (std::size_t i = 0; i < px.size(); ++i) {
        px[i] = static_cast<std::uint8_t>(i * 7);
    }
    write_image(dir / "s0.png", 64, 64, 1, OIIO::TypeDesc::UINT8, px.data());
    const auto size = fs::file_size(dir / "s0.png");
    fs::resize_file(dir / "s0.png", size / 2);
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("s0.png"), std::string::npos) << m;
}

TEST(ReadImageFolder, GarbageFileWithImageExtensionRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_garbage");
    std::ofstream(dir / "s0.png") << "this is not a PNG";
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("s0.png: cannot read image"), std::string::npos) << m;
}

TEST(ReadImageFolder, EmptyFolderRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_empty");
    std::ofstream(dir / "notes.txt") << "no images";
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("no image files"), std::string::npos) << m;
}

TEST(ReadImageFolder, SidecarDimsMustMatch) {
    const fs::path dir = test::fresh_temp_dir("folder_sidecar_dims");
    write_grey8(dir / "s0.png", 4, 4, 1);
    std::ofstream(dir / "meta.json") << R"({"dims": [4, 4, 2], "spacing_mm": [1, 1, 1]})";
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("dims 4x4x2 disagree with the images: 4x4x1"), std::string::npos) << m;
}

TEST(ReadImageFolder, SidecarZeroSpacingRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_sidecar_spacing");
    write_grey8(dir / "s0.png", 4, 4, 1);
    std::ofstream(dir / "meta.json") << R"({"spacing_mm": [1, 0, 1]})";
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("expected finite positive millimetres"), std::string::npos) << m;
}

TEST(ReadImageFolder, SidecarMalformedJsonRejected) {
    const fs::path dir = test::fresh_temp_dir("folder_sidecar_json");
    write_grey8(dir / "s0.png", 4, 4, 1);
    std::ofstream(dir / "meta.json") << R"({"dims": [4, 4, )";
    const std::string m = error_of(dir, ErrorCode::InvalidInput);
    EXPECT_NE(m.find("meta.json: not valid JSON"), std::string::npos) << m;
}

TEST(ReadMultipageTiff, PagesBecomeSlices) {
    const fs::path dir = test::fresh_temp_dir("multipage");
    const fs::path file = dir / "stack.tif";
    auto out = OIIO::ImageOutput::create(file.string());
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->supports("multiimage"));
    std::vector<OIIO::ImageSpec> specs(3, OIIO::ImageSpec(6, 4, 1, OIIO::TypeDesc::UINT16));
    ASSERT_TRUE(out->open(file.string(), 3, specs.data()));
    for (int k = 0; k < 3; ++k) {
        if (k > 0) {
            ASSERT_TRUE(out->open(file.string(), specs[k], OIIO::ImageOutput::AppendSubimage));
        }
        std::vector<std::uint16_t> px(24, static_cast<std::uint16_t>(10 * (k + 1)));
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT16, px.data()));
    }
    ASSERT_TRUE(out->close());
    const SliceStack s = read(file);
    ASSERT_EQ(s.depth, 3u);
    EXPECT_EQ(s.at(5, 3, 2), 30);
    EXPECT_EQ(s.at(0, 0, 0), 10);
}

TEST(ReadSliceStack, MissingPathIsInvalidInput) {
    const std::string m = error_of("/nonexistent/strata/input.nii", ErrorCode::InvalidInput);
    EXPECT_NE(m.find("no such file or folder"), std::string::npos) << m;
}

TEST(ReadSliceStack, UnknownFormatUnsupported) {
    const fs::path dir = test::fresh_temp_dir("unknown_format");
    std::ofstream(dir / "brain.mgz") << "xxxx";
    const std::string m = error_of(dir / "brain.mgz", ErrorCode::Unsupported);
    EXPECT_NE(m.find("mri_convert"), std::string::npos) << m;
}

TEST(ReadSliceStack, SpacingOverrideApplied) {
    const fs::path dir = test::fresh_temp_dir("spacing_override");
    write_grey8(dir / "s0.png", 4, 4, 1);
    ReadOptions options;
    options.spacing_mm = Vec3{0.5, 0.5, 3};
    Report report;
    const SliceStack s = read_slice_stack(dir, options, report);
    EXPECT_EQ(s.spacing_mm(), (Vec3{0.5, 0.5, 3}));
}

TEST(ReadSliceStack, AbsurdSizeRefusedBeforeReading) {
    const fs::path dir = test::fresh_temp_dir("absurd_size");
    write_grey8(dir / "s0.png", 64, 64, 1);
    write_grey8(dir / "s1.png", 64, 64, 1);
    ReadOptions options;
    options.max_bytes = 1000;
    Report report;
    try {
        read_slice_stack(dir, options, report);
        FAIL();
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("would need 16.0 KiB"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace strata

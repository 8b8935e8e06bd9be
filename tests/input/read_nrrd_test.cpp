// NRRD reading: headers written here as text, data raw, gzip or ascii; and the real files.

#include <array>
#include <cstdint>
#include <cstring>
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
using test::count_labelled_slices;
using test::encode;
using test::gzip;
using test::ramp;
using test::throws_error;
using test::write_file;

fs::path temp_dir() {
    return test::current_test_dir("nrrd_");
}

/// A header for a 4x3x2 volume; `fields` are extra lines (each ending in "\n").
std::string header(const std::string& type,
                   const std::string& encoding,
                   const std::string& fields) {
    return "NRRD0004\n# test file\ntype: " + type +
           "\ndimension: 3\nsizes: 4 3 2\nencoding: " + encoding + "\n" + fields;
}

const std::string kLps =
    "space: left-posterior-superior\n"
    "space directions: (0.5,0,0) (0,0.75,0) (0,0,2.5)\n"
    "space origin: (-10,20,30)\n";

SliceStack read(const fs::path& path, ReadOptions options = {}) {
    Report report;
    return detail::read_nrrd(path, options, report);
}

void expect_affine_near(const Affine3& actual,
                        std::array<std::array<double, 4>, 3> rows,
                        double tolerance = 1e-12) {
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(actual.linear[r][c], rows[r][c], tolerance)
                << "linear[" << r << "][" << c << "]";
        }
        EXPECT_NEAR(actual.translation[r], rows[r][3], tolerance) << "translation[" << r << "]";
    }
}

// ---------------------------------------------------------------------------------------------
// Reading

TEST(ReadNrrd, ReadsRawUcharLps) {
    const std::vector<std::uint8_t> values = ramp(24);
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "raw", kLps) + "\n" + encode(values));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.width, 4u);
    EXPECT_EQ(stack.height, 3u);
    EXPECT_EQ(stack.depth, 2u);
    EXPECT_EQ(stack.labels, std::vector<std::uint16_t>(values.begin(), values.end()));
    EXPECT_EQ(stack.at(3, 2, 1), values[23]);
    expect_affine_near(stack.index_to_world,
                       {{{0.5, 0, 0, -10}, {0, 0.75, 0, 20}, {0, 0, 2.5, 30}}});
    EXPECT_EQ(stack.source_frame, "LPS");
    EXPECT_EQ(stack.source, file.string());
    EXPECT_TRUE(stack.label_table.empty());
}

TEST(ReadNrrd, ReadsGzipLittleEndianShort) {
    std::vector<std::int16_t> values(24);
    for (std::size_t n = 0; n < values.size(); ++n) {
        values[n] = static_cast<std::int16_t>(n * 100);
    }
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("short", "gzip", "endian: little\n" + kLps) +
                                              "\n" + gzip(encode(values)));
    const SliceStack stack = read(file);
    for (std::size_t n = 0; n < values.size(); ++n) {
        EXPECT_EQ(stack.labels[n], n * 100);
    }
}

TEST(ReadNrrd, ReadsBigEndianUint32) {
    std::vector<std::uint32_t> values(24, 7);
    values[1] = 65535;
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("unsigned int", "raw", "endian: big\n") + "\n" + encode(values, true));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.at(1, 0, 0), 65535);
    EXPECT_EQ(stack.at(0, 0, 0), 7);
}

TEST(ReadNrrd, ReadsAsciiEncoding) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd", header("float", "ascii", "") +
                                   "\n0 1 2 3\n4 5 6 0\n1.0 2 3 4\n5 6 0 1\n2 3 4 5\n6,0,1,2\n");
    const SliceStack stack = read(file);
    const std::vector<std::uint8_t> values = ramp(24);
    EXPECT_EQ(stack.labels, std::vector<std::uint16_t>(values.begin(), values.end()));
}

TEST(ReadNrrd, NoSpaceUsesSpacingsAndFrameNone) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("uchar", "raw", "spacings: 0.5 0.25 4\n") + "\n" + encode(ramp(24)));
    const SliceStack stack = read(file);
    expect_affine_near(stack.index_to_world, {{{0.5, 0, 0, 0}, {0, 0.25, 0, 0}, {0, 0, 4, 0}}});
    EXPECT_EQ(stack.source_frame, "none");
}

TEST(ReadNrrd, NoSpacingAtAllUsesOneMillimetreAndWarns) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "raw", "") + "\n" + encode(ramp(24)));
    Report report;
    const SliceStack stack = detail::read_nrrd(file, {}, report);
    expect_affine_near(stack.index_to_world, {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}});
    ASSERT_EQ(report.warnings.size(), 1u);
    EXPECT_NE(report.warnings[0].message.find("1 mm"), std::string::npos);
}

TEST(ReadNrrd, RasSpaceConvertedToLps) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw",
               "space: right-anterior-superior\nspace directions: (0.5,0.1,0) (0,0.75,0) "
               "(0,0,2.5)\nspace origin: (-10,20,30)\n") +
            "\n" + encode(ramp(24)));
    const SliceStack stack = read(file);
    expect_affine_near(stack.index_to_world,
                       {{{-0.5, 0, 0, 10}, {-0.1, -0.75, 0, -20}, {0, 0, 2.5, 30}}});
    EXPECT_EQ(stack.source_frame, "RAS");
}

TEST(ReadNrrd, LasSpaceConvertedToLps) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw",
               "space: LAS\nspace directions: (1,0,0) (0,1,0) (0,0,1)\nspace origin: (1,2,3)\n") +
            "\n" + encode(ramp(24)));
    const SliceStack stack = read(file);
    expect_affine_near(stack.index_to_world, {{{1, 0, 0, 1}, {0, -1, 0, -2}, {0, 0, 1, 3}}});
    EXPECT_EQ(stack.source_frame, "LAS");
}

TEST(ReadNrrd, SpaceDimensionWithoutNamedSpace) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw", "space dimension: 3\nspace directions: (2,0,0) (0,2,0) (0,0,2)\n") +
            "\n" + encode(ramp(24)));
    const SliceStack stack = read(file);
    expect_affine_near(stack.index_to_world, {{{2, 0, 0, 0}, {0, 2, 0, 0}, {0, 0, 2, 0}}});
    EXPECT_EQ(stack.source_frame, "none");
}

TEST(ReadNrrd, DetachedHeaderReadsRelativeDataFile) {
    const fs::path dir = temp_dir();
    fs::create_directories(dir / "data");
    write_file(dir / "data" / "vol.raw.gz", gzip(encode(ramp(24))));
    const fs::path file =
        write_file(dir / "vol.nhdr", header("uint8", "gz", kLps + "data file: data/vol.raw.gz\n"));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.at(2, 1, 1), ramp(24)[(1 * 3 + 1) * 4 + 2]);
}

TEST(ReadNrrd, ByteSkipMinusOneReadsTheLastBytes) {
    const fs::path dir = temp_dir();
    write_file(dir / "vol.raw", std::string(100, '\x55') + encode(ramp(24)));
    const fs::path file =
        write_file(dir / "vol.nhdr", header("uchar", "raw", "data file: vol.raw\nbyte skip: -1\n"));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.labels.front(), 0);
    EXPECT_EQ(stack.labels.back(), ramp(24).back());
}

TEST(ReadNrrd, LineSkipAndByteSkip) {
    const fs::path dir = temp_dir();
    write_file(dir / "vol.pgm", "P5\n# junk\n4 6\n255\nXYZ" + encode(ramp(24)));
    const fs::path file =
        write_file(dir / "vol.nhdr",
                   header("uchar", "raw", "data file: ./vol.pgm\nline skip: 4\nbyte skip: 3\n"));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.labels, std::vector<std::uint16_t>({0, 1, 2, 3, 4, 5, 6, 0, 1, 2, 3, 4,
                                                        5, 6, 0, 1, 2, 3, 4, 5, 6, 0, 1, 2}));
}

TEST(ReadNrrd, AcceptsTypeSpellings) {
    struct Case {
        std::string type;
        std::size_t bytes;
        bool is_real;
    };
    const Case cases[] = {
        {"signed char", 1, false}, {"int8_t", 1, false},    {"unsigned char", 1, false},
        {"uint8", 1, false},       {"short int", 2, false}, {"int16", 2, false},
        {"ushort", 2, false},      {"uint16_t", 2, false},  {"int", 2 * 2, false},
        {"int32", 4, false},       {"uint", 4, false},      {"unsigned int", 4, false},
        {"longlong", 8, false},    {"int64", 8, false},     {"unsigned long long", 8, false},
        {"uint64", 8, false},      {"float", 4, true},      {"double", 8, true},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.type);
        std::string data(24 * c.bytes, '\0');
        for (std::size_t n = 0; n < 24; ++n) {
            if (c.is_real && c.bytes == 4) {
                const float v = static_cast<float>(n);
                std::memcpy(data.data() + n * 4, &v, 4);
            } else if (c.is_real) {
                const double v = static_cast<double>(n);
                std::memcpy(data.data() + n * 8, &v, 8);
            } else {
                data[n * c.bytes] = static_cast<char>(n);  // little endian, small values
            }
        }
        const fs::path file = write_file(temp_dir() / "t.nrrd",
                                         header(c.type, "raw", "endian: little\n") + "\n" + data);
        const SliceStack stack = read(file);
        for (std::size_t n = 0; n < 24; ++n) {
            EXPECT_EQ(stack.labels[n], n);
        }
    }
}

TEST(ReadNrrd, SegNrrdLabelTable) {
    const std::string fields =
        kLps +
        "Segment0_ID:=Segment_1\nSegment0_Name:=liver\nSegment0_Color:=0.5 0.25 1\n"
        "Segment0_LabelValue:=5\nSegment0_Layer:=0\n"
        "Segment1_Name:=spleen\nSegment1_Color:=0 1 0\nSegment1_LabelValue:=2\n"
        "Segment1_Layer:=0\nSegmentation_MasterRepresentation:=Binary labelmap\n";
    std::vector<std::uint8_t> values(24, 0);
    values[3] = 5;
    values[10] = 2;
    const fs::path file = write_file(temp_dir() / "a.seg.nrrd",
                                     header("uchar", "gzip", fields) + "\n" + gzip(encode(values)));
    const SliceStack stack = read(file);
    ASSERT_EQ(stack.label_table.size(), 2u);
    EXPECT_EQ(stack.label_table[0].value, 2);
    EXPECT_EQ(stack.label_table[0].name, "spleen");
    EXPECT_EQ(stack.label_table[0].color, (ColorSrgb8{0, 255, 0}));
    EXPECT_EQ(stack.label_table[1].value, 5);
    EXPECT_EQ(stack.label_table[1].name, "liver");
    EXPECT_EQ(stack.label_table[1].color, (ColorSrgb8{128, 64, 255}));
    EXPECT_EQ(stack.at(3, 0, 0), 5);
}

TEST(ReadNrrd, SegNrrd4DWithOneLayerIsRead) {
    const std::string text =
        "NRRD0004\ntype: unsigned char\ndimension: 4\nspace: left-posterior-superior\n"
        "sizes: 1 4 3 2\nspace directions: none (0.5,0,0) (0,0.5,0) (0,0,3)\n"
        "kinds: list domain domain domain\nencoding: raw\nspace origin: (0,0,0)\n"
        "Segment0_Name:=tumour\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n\n";
    const fs::path file = write_file(temp_dir() / "a.seg.nrrd", text + encode(ramp(24)));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.width, 4u);
    EXPECT_EQ(stack.height, 3u);
    EXPECT_EQ(stack.depth, 2u);
    EXPECT_NEAR(stack.spacing_mm().z, 3.0, 1e-12);
    ASSERT_EQ(stack.label_table.size(), 1u);
    EXPECT_EQ(stack.label_table[0].name, "tumour");
}

TEST(ReadNrrd, SegNrrdWithSeveralLayersIsUnsupported) {
    const std::string text =
        "NRRD0004\ntype: unsigned char\ndimension: 4\nspace: left-posterior-superior\n"
        "sizes: 2 4 3 2\nspace directions: none (0.5,0,0) (0,0.5,0) (0,0,3)\n"
        "kinds: list domain domain domain\nencoding: raw\n"
        "Segment0_Name:=a\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n"
        "Segment1_Name:=b\nSegment1_LabelValue:=1\nSegment1_Layer:=1\n\n";
    const fs::path file = write_file(temp_dir() / "a.seg.nrrd", text + encode(ramp(48)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported,
                             "a.seg.nrrd: segmentation with 2 layers"));
}

TEST(ReadNrrd, VectorVolumeIsUnsupported) {
    const std::string text =
        "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 4 3 2\nkinds: RGB-color domain domain "
        "domain\nencoding: raw\n\n";
    const fs::path file = write_file(temp_dir() / "rgb.nrrd", text + encode(ramp(72)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported,
                             "non-spatial axis 0 (kind 'RGB-color') has 3 samples"));
}

TEST(ReadNrrd, TwoDimensionalImageIsOneSlice) {
    const std::string text = "NRRD0001\ntype: uchar\ndimension: 2\nsizes: 4 3\nencoding: raw\n\n";
    const fs::path file = write_file(temp_dir() / "a.nrrd", text + encode(ramp(12)));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.depth, 1u);
    EXPECT_EQ(stack.labels.size(), 12u);
}

TEST(ReadNrrd, UnknownFieldIsWarnedAndKeyValuesIgnored) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw", kLps + "frobnicate: 3\nmy key:=a: b\n") + "\n" + encode(ramp(24)));
    Report report;
    detail::read_nrrd(file, {}, report);
    ASSERT_EQ(report.warnings.size(), 1u);
    EXPECT_NE(report.warnings[0].message.find("frobnicate"), std::string::npos);
}

TEST(ReadNrrd, ReportsProgressPerSlice) {
    std::vector<std::size_t> done;
    ReadOptions options;
    options.progress = [&](std::string_view, std::size_t n, std::size_t total) {
        EXPECT_EQ(total, 2u);
        done.push_back(n);
    };
    read(write_file(temp_dir() / "a.nrrd", header("uchar", "raw", "") + "\n" + encode(ramp(24))),
         options);
    EXPECT_EQ(done, (std::vector<std::size_t>{1, 2}));
}

// ---------------------------------------------------------------------------------------------
// Bad input

TEST(ReadNrrd, MissingFileIsIoError) {
    EXPECT_TRUE(throws_error([] { read(temp_dir() / "absent.nrrd"); }, ErrorCode::Io,
                             "absent.nrrd: cannot open"));
}

TEST(ReadNrrd, BadMagicIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd", "NRRX0004\ntype: uchar\n\n");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "a.nrrd: bad magic"));
}

TEST(ReadNrrd, FutureVersionIsUnsupported) {
    const fs::path file = write_file(temp_dir() / "a.nrrd", "NRRD0009\ntype: uchar\n\n");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported, "NRRD0009"));
}

TEST(ReadNrrd, MissingSizesIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd",
                                     "NRRD0004\ntype: uchar\ndimension: 3\nencoding: raw\n\nxxxx");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: header field 'sizes' is missing"));
}

TEST(ReadNrrd, SizesCountMustMatchDimension) {
    const fs::path file = write_file(
        temp_dir() / "lung2_label.nrrd",
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3\nencoding: raw\n\nxxxxxxxxxxxx");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "lung2_label.nrrd: header field 'sizes' has 2 values, expected 3 "
                             "(dimension)"));
}

TEST(ReadNrrd, SpaceDirectionsCountMustMatchDimension) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("uchar", "raw", "space: LPS\nspace directions: (1,0,0) (0,1,0)\n") +
                       "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "'space directions' has 2 values, expected 3"));
}

TEST(ReadNrrd, UnknownEncodingIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "zip", "") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "unknown encoding 'zip', expected raw, gzip or ascii"));
}

TEST(ReadNrrd, Bzip2IsUnsupported) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "bzip2", "") + "\nBZh9");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported,
                             "encoding 'bzip2' is not supported"));
}

TEST(ReadNrrd, UnknownTypeIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd", header("quaternion", "raw", "") + "\n");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "header field 'type' is \"quaternion\""));
}

TEST(ReadNrrd, BlockTypeIsUnsupported) {
    const fs::path file = write_file(temp_dir() / "a.nrrd", header("block", "raw", "") + "\n");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported, "type 'block'"));
}

TEST(ReadNrrd, MissingEndianForMultiByteTypeIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd",
                                     header("short", "raw", "") + "\n" + std::string(48, '\0'));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "header field 'endian' is missing"));
}

TEST(ReadNrrd, DetachedDataFileMissingIsIoError) {
    const fs::path file =
        write_file(temp_dir() / "vol.nhdr", header("uchar", "raw", "data file: nowhere.raw\n"));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Io,
                             "vol.nhdr: data file nowhere.raw: cannot open"));
}

TEST(ReadNrrd, DataFileListIsUnsupported) {
    const fs::path file = write_file(temp_dir() / "vol.nhdr",
                                     header("uchar", "raw", "data file: LIST\nslice0.raw\n"));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported, "several data files"));
}

TEST(ReadNrrd, HeaderWithoutDataIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd", header("uchar", "raw", ""));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "truncated"));
}

TEST(ReadNrrd, TruncatedRawDataIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "raw", "") + "\n" + encode(ramp(20)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: truncated: expected 24 bytes of voxel data, found 20"));
}

TEST(ReadNrrd, TruncatedGzipDataIsRejected) {
    const fs::path file = write_file(temp_dir() / "a.nrrd",
                                     header("uchar", "gzip", "") + "\n" + gzip(encode(ramp(20))));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "truncated: expected 24 bytes of voxel data, found 20"));
}

TEST(ReadNrrd, CutGzipStreamIsRejected) {
    std::string compressed = gzip(encode(ramp(4000)));
    compressed.resize(compressed.size() / 2);
    const std::string text =
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 20 20 10\nencoding: gzip\n\n";
    const fs::path file = write_file(temp_dir() / "a.nrrd", text + compressed);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "truncated: expected 4000 bytes of voxel data"));
}

TEST(ReadNrrd, CorruptGzipIsRejected) {
    std::string compressed = gzip(encode(ramp(24)));
    for (std::size_t n = 10; n < compressed.size(); ++n) {
        compressed[n] = static_cast<char>(compressed[n] ^ 0xa5);
    }
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "gzip", "") + "\n" + compressed);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "corrupt gzip data"));
}

TEST(ReadNrrd, ZeroSpacingIsRejected) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw", "space: LPS\nspace directions: (1,0,0) (0,0,0) (0,0,1)\n") + "\n" +
            encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: space directions: spacing 1,0,1"));
}

TEST(ReadNrrd, NegativeSpacingIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("uchar", "raw", "spacings: 1 -2 1\n") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: spacings: spacing 1,-2,1 has a value -2"));
}

TEST(ReadNrrd, NanSpacingIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("uchar", "raw", "spacings: 1 1 nan\n") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "non-finite value"));
}

TEST(ReadNrrd, NonFiniteDirectionIsRejected) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd",
        header("uchar", "raw", "space: LPS\nspace directions: (1,0,0) (0,nan,0) (0,0,1)\n") + "\n" +
            encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "'space directions' has \"(0,nan,0)\" on axis 1"));
}

TEST(ReadNrrd, EmptyDimensionIsRejected) {
    const std::string text = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 0 2\nencoding: raw\n\n";
    const fs::path file = write_file(temp_dir() / "a.nrrd", text);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: empty dimensions 4x0x2"));
}

TEST(ReadNrrd, AbsurdDimsFailBeforeAllocating) {
    const std::string text =
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\n";
    const fs::path file = write_file(temp_dir() / "huge.nrrd", text);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "huge.nrrd: dimensions 100000x100000x100000 would need 1.8 PiB"));
}

TEST(ReadNrrd, OverflowingSizeIsRejected) {
    const std::string text =
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 3 99999999999999999999999\nencoding: "
        "raw\n\n";
    const fs::path file = write_file(temp_dir() / "a.nrrd", text);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "'sizes' has \"99999999999999999999999\" on axis 2"));
}

TEST(ReadNrrd, NonIntegerFloatLabelIsRejected) {
    std::vector<float> values(24, 1.0f);
    values[(1 * 3 + 0) * 4 + 2] = 0.5f;  // voxel (2,0,1)
    const fs::path file = write_file(
        temp_dir() / "a.nrrd", header("float", "raw", "endian: little\n") + "\n" + encode(values));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: voxel (2,0,1) has value 0.5, expected an integer label"));
}

TEST(ReadNrrd, NegativeLabelIsRejected) {
    std::vector<std::int32_t> values(24, 0);
    values[7] = -1;  // voxel (3,1,0)
    const fs::path file = write_file(
        temp_dir() / "a.nrrd", header("int", "raw", "endian: little\n") + "\n" + encode(values));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "voxel (3,1,0) has value -1"));
}

TEST(ReadNrrd, BadAsciiValueIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd", header("uchar", "ascii", "") + "\n1 2 x3 4\n");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "ascii voxel value 2 \"x3\" is not a number"));
}

TEST(ReadNrrd, ByteSkipMinusOneWithGzipIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.nrrd",
                   header("uchar", "gzip", "byte skip: -1\n") + "\n" + gzip(encode(ramp(24))));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "'byte skip: -1' is only allowed with raw encoding"));
}

TEST(ReadNrrd, DuplicateFieldIsRejected) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd", header("uchar", "raw", "type: short\n") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "header line 7: header field 'type' given twice"));
}

TEST(ReadNrrd, MalformedLineIsRejected) {
    const fs::path file = write_file(
        temp_dir() / "a.nrrd", header("uchar", "raw", "no colon here\n") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nrrd: header line 7: \"no colon here\""));
}

TEST(ReadNrrd, BadSegmentColorIsRejected) {
    const fs::path file =
        write_file(temp_dir() / "a.seg.nrrd",
                   header("uchar", "raw", "Segment0_Color:=0.5 2 0\n") + "\n" + encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.seg.nrrd: Segment0_Color = \"0.5 2 0\", expected three numbers"));
}

// ---------------------------------------------------------------------------------------------
// Real files (../shared/data)

TEST(ReadNrrd, PyradiomicsLungLabel) {
    const SliceStack stack =
        read(test::shared_data_dir() / "pyradiomics_lung_tumor" / "lung2_label.nrrd");
    EXPECT_EQ(stack.width, 512u);
    EXPECT_EQ(stack.height, 512u);
    EXPECT_EQ(stack.depth, 61u);
    EXPECT_EQ(stack.source_frame, "LPS");
    expect_affine_near(stack.index_to_world,
                       {{{0.6269531, 0, 0, -170.5}, {0, 0.6269531, 0, -324.5}, {0, 0, 5, -360}}},
                       1e-6);
    const std::vector<std::uint16_t> present = present_labels(stack);
    ASSERT_FALSE(present.empty());
    EXPECT_EQ(count_labelled_slices(stack), 11u);  // README: 11 slices carry the tumour
}

TEST(ReadNrrd, PyradiomicsBrainLabel) {
    const SliceStack stack =
        read(test::shared_data_dir() / "pyradiomics_brain_tumor" / "brain1_label.nrrd");
    EXPECT_EQ(stack.width, 256u);
    EXPECT_EQ(stack.height, 256u);
    EXPECT_EQ(stack.depth, 25u);
    // space directions (0.78125,0,0) (0,-0.78125,0) (0,0,6.5) in LPS: kept as given.
    EXPECT_NEAR(stack.index_to_world.linear[1][1], -0.78125, 1e-9);
    EXPECT_NEAR(stack.index_to_world.linear[2][2], 6.5, 1e-9);
    EXPECT_NEAR(stack.index_to_world.translation.y, 99.609375, 1e-9);
    EXPECT_EQ(count_labelled_slices(stack), 7u);  // README: 7 slices carry the tumour
}

}  // namespace
}  // namespace strata

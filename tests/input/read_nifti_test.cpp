// NIfTI-1/2 reading (headers built byte by byte here) and the NIfTI-1 writer.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "input/detail/readers.h"
#include "input/write_nifti.h"
#include "support/input_files.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::encode;
using test::gzip;
using test::put;
using test::ramp;
using test::throws_error;
using test::write_file;

// ---------------------------------------------------------------------------------------------
// Fixtures: NIfTI files assembled byte by byte

/// Header fields of a test file; defaults: 4x3x2 uint8, 1 mm, no qform/sform.
struct NiftiFields {
    int version = 1;
    bool big_endian = false;
    std::array<std::int64_t, 8> dim{3, 4, 3, 2, 1, 1, 1, 1};
    std::int16_t datatype = 2;
    std::int16_t bitpix = 8;
    std::array<double, 8> pixdim{1, 1, 1, 1, 0, 0, 0, 0};
    double vox_offset = -1;  // -1: right after the header and 4 extension-flag bytes
    double scl_slope = 0;
    double scl_inter = 0;
    int qform_code = 0;
    int sform_code = 0;
    std::array<double, 3> quatern{};  // b, c, d
    std::array<double, 3> qoffset{};
    std::array<std::array<double, 4>, 3> srow{};
    std::string magic;  // empty: "n+1" / "n+2" single-file magic
    std::uint8_t xyzt_units = 2;
};

/// The header and the bytes up to vox_offset (zeros: no extensions).
std::string nifti_header(const NiftiFields& f) {
    const bool be = f.big_endian;
    const std::size_t size = f.version == 1 ? 348 : 540;
    const double offset = f.vox_offset < 0 ? double(size + 4) : f.vox_offset;
    std::string h(std::max<std::size_t>(size, std::size_t(std::max(0.0, offset))), '\0');
    if (f.version == 1) {
        put<std::int32_t>(h, 0, 348, be);
        for (int d = 0; d < 8; ++d) {
            put<std::int16_t>(h, 40 + 2 * d, static_cast<std::int16_t>(f.dim[d]), be);
            put<float>(h, 76 + 4 * d, static_cast<float>(f.pixdim[d]), be);
        }
        put<std::int16_t>(h, 70, f.datatype, be);
        put<std::int16_t>(h, 72, f.bitpix, be);
        put<float>(h, 108, static_cast<float>(offset), be);
        put<float>(h, 112, static_cast<float>(f.scl_slope), be);
        put<float>(h, 116, static_cast<float>(f.scl_inter), be);
        h[123] = static_cast<char>(f.xyzt_units);
        put<std::int16_t>(h, 252, static_cast<std::int16_t>(f.qform_code), be);
        put<std::int16_t>(h, 254, static_cast<std::int16_t>(f.sform_code), be);
        for (int q = 0; q < 3; ++q) {
            put<float>(h, 256 + 4 * q, static_cast<float>(f.quatern[q]), be);
            put<float>(h, 268 + 4 * q, static_cast<float>(f.qoffset[q]), be);
        }
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) {
                put<float>(h, 280 + 16 * r + 4 * c, static_cast<float>(f.srow[r][c]), be);
            }
        }
        const std::string magic = f.magic.empty() ? std::string("n+1\0", 4) : f.magic;
        std::memcpy(h.data() + 344, magic.data(), std::min<std::size_t>(magic.size(), 4));
    } else {
        put<std::int32_t>(h, 0, 540, be);
        const std::string magic = f.magic.empty() ? std::string("n+2\0\r\n\032\n", 8) : f.magic;
        std::memcpy(h.data() + 4, magic.data(), std::min<std::size_t>(magic.size(), 8));
        put<std::int16_t>(h, 12, f.datatype, be);
        put<std::int16_t>(h, 14, f.bitpix, be);
        for (int d = 0; d < 8; ++d) {
            put<std::int64_t>(h, 16 + 8 * d, f.dim[d], be);
            put<double>(h, 104 + 8 * d, f.pixdim[d], be);
        }
        put<std::int64_t>(h, 168, static_cast<std::int64_t>(offset), be);
        put<double>(h, 176, f.scl_slope, be);
        put<double>(h, 184, f.scl_inter, be);
        put<std::int32_t>(h, 344, f.qform_code, be);
        put<std::int32_t>(h, 348, f.sform_code, be);
        for (int q = 0; q < 3; ++q) {
            put<double>(h, 352 + 8 * q, f.quatern[q], be);
            put<double>(h, 376 + 8 * q, f.qoffset[q], be);
        }
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) {
                put<double>(h, 400 + 32 * r + 8 * c, f.srow[r][c], be);
            }
        }
        put<std::int32_t>(h, 500, f.xyzt_units, be);
    }
    return h;
}

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

SliceStack read(const fs::path& path, ReadOptions options = {}) {
    Report report;
    return detail::read_nifti(path, options, report);
}

/// The file `name` in a fresh folder for this test, holding header + data.
fs::path nifti_file(const std::string& name, const NiftiFields& fields, const std::string& data) {
    const fs::path dir = test::current_test_dir("read_nifti_");
    const std::string bytes = nifti_header(fields) + data;
    const bool is_gz = name.size() > 3 && name.substr(name.size() - 3) == ".gz";
    return write_file(dir / name, is_gz ? gzip(bytes) : bytes);
}

fs::path temp_dir() {
    return test::current_test_dir("nifti_");
}

void expect_affine_near(const Affine3& actual, const Affine3& expected, double tolerance) {
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(actual.linear[r][c], expected.linear[r][c], tolerance)
                << "linear[" << r << "][" << c << "]";
        }
        EXPECT_NEAR(actual.translation[r], expected.translation[r], tolerance)
            << "translation[" << r << "]";
    }
}

Affine3 make_affine(std::array<std::array<double, 4>, 3> rows) {
    Affine3 a;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            a.linear[r][c] = rows[r][c];
        }
        a.translation[r] = rows[r][3];
    }
    return a;
}

// ---------------------------------------------------------------------------------------------
// Reading

TEST(ReadNifti, ReadsDimsAndValuesInRasterOrder) {
    const std::vector<std::uint8_t> values = ramp(24);
    const fs::path file = nifti_file("a.nii", {}, encode(values));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.width, 4u);
    EXPECT_EQ(stack.height, 3u);
    EXPECT_EQ(stack.depth, 2u);
    ASSERT_EQ(stack.labels.size(), 24u);
    for (std::uint32_t k = 0; k < 2; ++k) {
        for (std::uint32_t j = 0; j < 3; ++j) {
            for (std::uint32_t i = 0; i < 4; ++i) {
                EXPECT_EQ(stack.at(i, j, k), values[(k * 3 + j) * 4 + i]);
            }
        }
    }
    EXPECT_EQ(stack.source, file.string());
}

TEST(ReadNifti, PixdimAffineWhenNoQformOrSform) {
    NiftiFields f;
    f.pixdim = {1, 0.5, 0.75, 2.5, 0, 0, 0, 0};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    expect_affine_near(stack.index_to_world,
                       make_affine({{{0.5, 0, 0, 0}, {0, 0.75, 0, 0}, {0, 0, 2.5, 0}}}), 1e-12);
    EXPECT_EQ(stack.source_frame, "none");
}

TEST(ReadNifti, SformConvertedFromRasToLps) {
    NiftiFields f;
    f.sform_code = 2;
    f.srow = {{{0.5, 0.25, 0, -10}, {0, 2, 0, 20}, {0.125, 0, 3, 30}}};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    // LPS = diag(-1, -1, 1) * RAS, translation included.
    expect_affine_near(stack.index_to_world,
                       make_affine({{{-0.5, -0.25, 0, 10}, {0, -2, 0, -20}, {0.125, 0, 3, 30}}}),
                       1e-12);
    EXPECT_EQ(stack.source_frame, "RAS");
    const Vec3 world = stack.index_to_world.apply({1, 1, 1});
    EXPECT_NEAR(world.x, 10 - 0.75, 1e-12);
    EXPECT_NEAR(world.y, -22, 1e-12);
    EXPECT_NEAR(world.z, 33.125, 1e-12);
}

TEST(ReadNifti, SformWinsOverQform) {
    NiftiFields f;
    f.sform_code = 1;
    f.qform_code = 1;
    f.srow = {{{2, 0, 0, 1}, {0, 2, 0, 2}, {0, 0, 2, 3}}};
    f.quatern = {0, 0, 1};  // 180 degrees about z: would flip x and y
    f.qoffset = {-100, -100, -100};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    expect_affine_near(stack.index_to_world,
                       make_affine({{{-2, 0, 0, -1}, {0, -2, 0, -2}, {0, 0, 2, 3}}}), 1e-12);
}

TEST(ReadNifti, QformUsedWhenSformCodeIsZero) {
    NiftiFields f;
    f.qform_code = 1;
    f.sform_code = 0;
    f.srow = {{{9, 0, 0, 9}, {0, 9, 0, 9}, {0, 0, 9, 9}}};  // ignored: sform_code 0
    // 90 degrees about z: a = d = sqrt(1/2); R = [[0,-1,0],[1,0,0],[0,0,1]]; qfac -1 flips k.
    f.quatern = {0, 0, std::sqrt(0.5)};
    f.qoffset = {5, 6, 7};
    f.pixdim = {-1, 2, 3, 4, 0, 0, 0, 0};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    // RAS: columns R*(2,3,-4) = [[0,-3,0],[2,0,0],[0,0,-4]], offset (5,6,7); then LPS.
    expect_affine_near(stack.index_to_world,
                       make_affine({{{0, 3, 0, -5}, {-2, 0, 0, -6}, {0, 0, -4, 7}}}), 1e-6);
    EXPECT_EQ(stack.source_frame, "RAS");
}

TEST(ReadNifti, MetreUnitsScaledToMillimetres) {
    NiftiFields f;
    f.xyzt_units = 1;  // metres
    f.pixdim = {1, 0.001, 0.002, 0.003, 0, 0, 0, 0};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    const Vec3 spacing = stack.spacing_mm();
    EXPECT_NEAR(spacing.x, 1.0, 1e-6);
    EXPECT_NEAR(spacing.y, 2.0, 1e-6);
    EXPECT_NEAR(spacing.z, 3.0, 1e-6);
}

TEST(ReadNifti, ReadsGzip) {
    const std::vector<std::uint8_t> values = ramp(24);
    const SliceStack stack = read(nifti_file("a.nii.gz", {}, encode(values)));
    EXPECT_EQ(stack.labels, std::vector<std::uint16_t>(values.begin(), values.end()));
}

TEST(ReadNifti, ReadsBigEndianInt16) {
    NiftiFields f;
    f.big_endian = true;
    f.datatype = 4;
    f.bitpix = 16;
    std::vector<std::int16_t> values(24);
    for (std::size_t n = 0; n < values.size(); ++n) {
        values[n] = static_cast<std::int16_t>(n * 1000);
    }
    const SliceStack stack = read(nifti_file("a.nii", f, encode(values, true)));
    for (std::size_t n = 0; n < values.size(); ++n) {
        EXPECT_EQ(stack.labels[n], n * 1000);
    }
}

TEST(ReadNifti, ReadsNifti2Float64Gzip) {
    NiftiFields f;
    f.version = 2;
    f.datatype = 64;
    f.bitpix = 64;
    f.sform_code = 1;
    f.srow = {{{1, 0, 0, 0.5}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
    std::vector<double> values(24);
    for (std::size_t n = 0; n < values.size(); ++n) {
        values[n] = static_cast<double>(65535 - n);
    }
    const SliceStack stack = read(nifti_file("a.nii.gz", f, encode(values)));
    ASSERT_EQ(stack.labels.size(), 24u);
    EXPECT_EQ(stack.labels.front(), 65535);
    EXPECT_EQ(stack.labels.back(), 65535 - 23);
    EXPECT_NEAR(stack.index_to_world.translation.x, -0.5, 1e-12);
}

TEST(ReadNifti, ReadsNifti2BigEndian) {
    NiftiFields f;
    f.version = 2;
    f.big_endian = true;
    f.datatype = 512;
    f.bitpix = 16;
    std::vector<std::uint16_t> values(24, 300);
    values[5] = 40000;
    const SliceStack stack = read(nifti_file("a.nii", f, encode(values, true)));
    EXPECT_EQ(stack.at(1, 1, 0), 40000);
    EXPECT_EQ(stack.at(0, 0, 0), 300);
}

template <typename T>
void check_datatype_reads(std::int16_t code, std::int16_t bitpix) {
    SCOPED_TRACE("datatype " + std::to_string(code));
    NiftiFields f;
    f.datatype = code;
    f.bitpix = bitpix;
    std::vector<T> values(24);
    for (std::size_t n = 0; n < values.size(); ++n) {
        values[n] = static_cast<T>(n * 5);
    }
    const SliceStack stack =
        read(nifti_file("t" + std::to_string(code) + ".nii", f, encode(values)));
    ASSERT_EQ(stack.labels.size(), 24u);
    for (std::size_t n = 0; n < values.size(); ++n) {
        EXPECT_EQ(stack.labels[n], n * 5);
    }
}

TEST(ReadNifti, AcceptsEveryIntegerAndRealDatatype) {
    check_datatype_reads<std::uint8_t>(2, 8);
    check_datatype_reads<std::int8_t>(256, 8);
    check_datatype_reads<std::uint16_t>(512, 16);
    check_datatype_reads<std::int16_t>(4, 16);
    check_datatype_reads<std::uint32_t>(768, 32);
    check_datatype_reads<std::int32_t>(8, 32);
    check_datatype_reads<std::int64_t>(1024, 64);
    check_datatype_reads<std::uint64_t>(1280, 64);
    check_datatype_reads<float>(16, 32);
    check_datatype_reads<double>(64, 64);
}

TEST(ReadNifti, AppliesSclSlopeAndInter) {
    NiftiFields f;
    f.datatype = 4;
    f.bitpix = 16;
    f.scl_slope = 0.5;
    f.scl_inter = 10;
    std::vector<std::int16_t> values(24);
    for (std::size_t n = 0; n < values.size(); ++n) {
        values[n] = static_cast<std::int16_t>(2 * n - 20);  // -> n
    }
    const SliceStack stack = read(nifti_file("a.nii", f, encode(values)));
    for (std::size_t n = 0; n < values.size(); ++n) {
        EXPECT_EQ(stack.labels[n], n);
    }
}

TEST(ReadNifti, SkipsExtensionsUpToVoxOffset) {
    NiftiFields f;
    f.vox_offset = 480;
    std::string header = nifti_header(f);
    header[348] = 1;  // extension flag; the extension bytes are junk to be skipped
    std::fill(header.begin() + 352, header.end(), '\x7f');
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path file =
        write_file(test::fresh_temp_dir(test->name()) / "a.nii", header + encode(ramp(24)));
    const SliceStack stack = read(file);
    EXPECT_EQ(stack.at(3, 0, 0), 3);
}

/// Header + one extension (esize padded to a multiple of 16) + voxel data.
std::string with_extension(NiftiFields f, std::int32_t ecode, const std::string& content) {
    const std::size_t esize = (8 + content.size() + 15) / 16 * 16;
    f.vox_offset = double(352 + esize);
    std::string bytes = nifti_header(f);
    bytes[348] = 1;
    put<std::int32_t>(bytes, 352, static_cast<std::int32_t>(esize), f.big_endian);
    put<std::int32_t>(bytes, 356, ecode, f.big_endian);
    std::memcpy(bytes.data() + 360, content.data(), content.size());
    return bytes;
}

TEST(ReadNifti, LabelTableFromCaretExtension) {
    const std::string xml =
        "<?xml version=\"1.0\"?><CaretExtension><VolumeInformation Index=\"0\"><LabelTable>"
        "<Label Key=\"3\" Red=\"0.0\" Green=\"0.5019607843137255\" Blue=\"1.0\" "
        "Alpha=\"1\"><![CDATA[kidney_left]]></Label>\n"
        "<Label Key=\"0\" Red=\"0\" Green=\"0\" Blue=\"0\" Alpha=\"0\">background</Label>\n"
        "<Label Key=\"1\" Red=\"1\" Green=\"0\" Blue=\"0\">A &amp; B</Label>\n"
        "<Label Key=\"2\">no colour</Label>\n"
        "</LabelTable></VolumeInformation></CaretExtension>";
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path file = write_file(test::fresh_temp_dir(test->name()) / "a.nii",
                                     with_extension({}, 0, xml) + encode(ramp(24)));
    const SliceStack stack = read(file);
    ASSERT_EQ(stack.label_table.size(), 3u);
    EXPECT_EQ(stack.label_table[0].value, 1);
    EXPECT_EQ(stack.label_table[0].name, "A & B");
    EXPECT_EQ(stack.label_table[0].color, (ColorSrgb8{255, 0, 0}));
    EXPECT_EQ(stack.label_table[1].name, "no colour");
    EXPECT_EQ(stack.label_table[1].color, palette_color(2));
    EXPECT_EQ(stack.label_table[2].name, "kidney_left");
    EXPECT_EQ(stack.label_table[2].color, (ColorSrgb8{0, 128, 255}));
    EXPECT_EQ(stack.at(3, 0, 0), 3);
}

TEST(ReadNifti, MalformedExtensionIsWarnedNotFatal) {
    std::string bytes = with_extension({}, 4, "whatever");
    put<std::int32_t>(bytes, 352, 4000, false);  // esize beyond vox_offset
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    const fs::path file =
        write_file(test::fresh_temp_dir(test->name()) / "a.nii", bytes + encode(ramp(24)));
    Report report;
    const SliceStack stack = detail::read_nifti(file, {}, report);
    EXPECT_TRUE(stack.label_table.empty());
    ASSERT_EQ(report.warnings.size(), 1u);
    EXPECT_NE(report.warnings[0].message.find("malformed NIfTI extension at byte 352"),
              std::string::npos);
    EXPECT_EQ(stack.labels.size(), 24u);
}

TEST(ReadNifti, TwoDimensionalImageIsOneSlice) {
    NiftiFields f;
    f.dim = {2, 4, 3, 0, 0, 0, 0, 0};
    f.pixdim = {1, 0.5, 0.5, 0, 0, 0, 0, 0};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(12))));
    EXPECT_EQ(stack.depth, 1u);
    EXPECT_EQ(stack.labels.size(), 12u);
    EXPECT_DOUBLE_EQ(stack.spacing_mm().z, 1.0);
}

TEST(ReadNifti, FourDWithOneVolumeIsAccepted) {
    NiftiFields f;
    f.dim = {4, 4, 3, 2, 1, 1, 1, 1};
    const SliceStack stack = read(nifti_file("a.nii", f, encode(ramp(24))));
    EXPECT_EQ(stack.depth, 2u);
}

TEST(ReadNifti, ReportsProgressPerSlice) {
    NiftiFields f;
    f.dim = {3, 4, 3, 5, 1, 1, 1, 1};
    std::vector<std::size_t> done;
    ReadOptions options;
    options.progress = [&](std::string_view what, std::size_t n, std::size_t total) {
        EXPECT_EQ(what, "slices");
        EXPECT_EQ(total, 5u);
        done.push_back(n);
    };
    read(nifti_file("a.nii", f, encode(ramp(60))), options);
    EXPECT_EQ(done, (std::vector<std::size_t>{1, 2, 3, 4, 5}));
}

// ---------------------------------------------------------------------------------------------
// Bad input

TEST(ReadNifti, MissingFileIsIoError) {
    EXPECT_TRUE(throws_error([] { read(temp_dir() / "absent.nii"); }, ErrorCode::Io, "absent.nii"));
}

TEST(ReadNifti, TruncatedHeaderIsRejected) {
    const std::string header = nifti_header({}).substr(0, 200);
    const fs::path file = write_file(temp_dir() / "short.nii", header);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "short.nii: truncated header: found 200 of 348 bytes"));
}

TEST(ReadNifti, TinyFileIsRejected) {
    const fs::path file = write_file(temp_dir() / "tiny.nii", "ab");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "truncated header"));
}

TEST(ReadNifti, TruncatedRawDataIsRejected) {
    const fs::path file = nifti_file("cut.nii", {}, encode(ramp(20)));
    EXPECT_TRUE(throws_error(
        [&] { read(file); }, ErrorCode::InvalidInput,
        "cut.nii: truncated: expected 24 bytes of voxel data after vox_offset 352, found 20"));
}

TEST(ReadNifti, TruncatedGzipDataIsRejected) {
    NiftiFields f;
    f.dim = {3, 64, 64, 4, 1, 1, 1, 1};
    // note: pseudo-random voxels, so that half the compressed file is half the voxel data
    std::vector<std::uint8_t> noise(64 * 64 * 4);
    std::uint32_t state = 42;
    for (std::uint8_t& v : noise) {
        state = state * 1664525u + 1013904223u;
        v = static_cast<std::uint8_t>(state >> 24);
    }
    const std::string whole = gzip(nifti_header(f) + encode(noise));
    const fs::path file = write_file(temp_dir() / "cut.nii.gz", whole.substr(0, whole.size() / 2));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "truncated: expected 16384 bytes of voxel data after vox_offset 352"));
}

TEST(ReadNifti, CorruptGzipIsRejected) {
    std::string bytes = gzip(nifti_header({}) + encode(ramp(24)));
    for (std::size_t n = 12; n < bytes.size() - 8; ++n) {
        bytes[n] = static_cast<char>(bytes[n] ^ 0x5a);
    }
    const fs::path file = write_file(temp_dir() / "bad.nii.gz", bytes);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "corrupt gzip data"));
}

TEST(ReadNifti, GzipCrcMismatchIsRejected) {
    std::string bytes = gzip(nifti_header({}) + encode(ramp(24)));
    bytes[bytes.size() - 6] = static_cast<char>(bytes[bytes.size() - 6] ^ 1);  // CRC32 trailer
    const fs::path file = write_file(temp_dir() / "crc.nii.gz", bytes);
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "corrupt gzip data"));
}

TEST(ReadNifti, BadMagicIsRejected) {
    NiftiFields f;
    f.magic = std::string("xyz\0", 4);
    const fs::path file = nifti_file("magic.nii", f, encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "magic.nii: bad magic at byte 344, expected \"n+1\""));
}

TEST(ReadNifti, NotNiftiSizeofHdrIsRejected) {
    const fs::path file = write_file(temp_dir() / "text.nii", std::string(400, 'x'));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "not a NIfTI file: sizeof_hdr is 2021161080, expected 348"));
}

TEST(ReadNifti, HeaderImagePairIsUnsupported) {
    NiftiFields f;
    f.magic = std::string("ni1\0", 4);
    f.vox_offset = 0;
    const fs::path file = nifti_file("pair.hdr", f, "");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported, ".hdr + .img"));
}

TEST(ReadNifti, ZeroSpacingIsRejected) {
    NiftiFields f;
    f.pixdim = {1, 1, 0, 1, 0, 0, 0, 0};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "pixdim[2] = 0 (voxel size along j), expected a finite positive"));
}

TEST(ReadNifti, NegativeSpacingIsRejected) {
    NiftiFields f;
    f.pixdim = {1, -0.5, 1, 1, 0, 0, 0, 0};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "pixdim[1] = -0.5"));
}

TEST(ReadNifti, NanSpacingIsRejected) {
    NiftiFields f;
    f.pixdim = {1, 1, 1, std::numeric_limits<double>::quiet_NaN(), 0, 0, 0, 0};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "pixdim[3] = nan"));
}

TEST(ReadNifti, ZeroSformColumnIsRejected) {
    NiftiFields f;
    f.sform_code = 1;
    f.srow = {{{1, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 1, 0}}};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "a.nii: sform: spacing"));
}

TEST(ReadNifti, SingularSformIsRejected) {
    NiftiFields f;
    f.sform_code = 1;
    f.srow = {{{1, 1, 0, 0}, {1, 1, 0, 0}, {0, 0, 1, 0}}};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "sform matrix is singular"));
}

TEST(ReadNifti, EmptyDimensionIsRejected) {
    NiftiFields f;
    f.dim = {3, 4, 0, 2, 1, 1, 1, 1};
    const fs::path file = nifti_file("a.nii", f, "");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nii: empty dimensions 4x0x2"));
}

TEST(ReadNifti, NegativeDimensionIsRejected) {
    NiftiFields f;
    f.dim = {3, 4, -3, 2, 1, 1, 1, 1};
    const fs::path file = nifti_file("a.nii", f, "");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "dim[2] = -3"));
}

TEST(ReadNifti, DimCountOutOfRangeIsRejected) {
    NiftiFields f;
    f.dim = {9, 4, 3, 2, 1, 1, 1, 1};
    const fs::path file = nifti_file("a.nii", f, "");
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "dim[0] = 9, expected 2..7"));
}

TEST(ReadNifti, AbsurdDimsFailBeforeAllocating) {
    NiftiFields f;
    f.version = 2;
    f.dim = {3, 100000, 100000, 100000, 1, 1, 1, 1};
    const fs::path file = nifti_file("huge.nii", f, "");
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "huge.nii: dimensions 100000x100000x100000 would need 1.8 PiB"));
}

TEST(ReadNifti, MaxBytesOptionIsHonoured) {
    ReadOptions options;
    options.max_bytes = 40;  // 24 voxels need 48 bytes
    const fs::path file = nifti_file("a.nii", {}, encode(ramp(24)));
    EXPECT_TRUE(
        throws_error([&] { read(file, options); }, ErrorCode::InvalidInput, "would need 48 bytes"));
}

TEST(ReadNifti, MultiVolume4DIsUnsupported) {
    NiftiFields f;
    f.dim = {4, 4, 3, 2, 5, 1, 1, 1};
    const fs::path file = nifti_file("a.nii", f, encode(ramp(120)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported,
                             "a.nii: 4D NIfTI with 5 volumes; expected a single 3D label volume"));
}

TEST(ReadNifti, ComplexDatatypeIsUnsupported) {
    NiftiFields f;
    f.datatype = 32;
    f.bitpix = 64;
    const fs::path file = nifti_file("a.nii", f, std::string(24 * 8, '\0'));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported,
                             "datatype 32 (complex64) is not supported"));
}

TEST(ReadNifti, RgbDatatypeIsUnsupported) {
    NiftiFields f;
    f.datatype = 128;
    f.bitpix = 24;
    const fs::path file = nifti_file("a.nii", f, std::string(24 * 3, '\0'));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::Unsupported, "(rgb24)"));
}

TEST(ReadNifti, UnknownDatatypeIsRejected) {
    NiftiFields f;
    f.datatype = 3;
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "unknown datatype code 3"));
}

TEST(ReadNifti, BitpixMismatchIsRejected) {
    NiftiFields f;
    f.datatype = 512;
    f.bitpix = 8;
    const fs::path file = nifti_file("a.nii", f, std::string(48, '\0'));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "bitpix 8 does not match datatype uint16, expected 16"));
}

TEST(ReadNifti, VoxOffsetInsideHeaderIsRejected) {
    NiftiFields f;
    f.vox_offset = 100;
    const fs::path file = nifti_file("a.nii", f, encode(ramp(24)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput, "vox_offset 100"));
}

TEST(ReadNifti, NonIntegerFloatLabelIsRejected) {
    NiftiFields f;
    f.datatype = 16;
    f.bitpix = 32;
    std::vector<float> values(24, 1.0f);
    values[(1 * 3 + 2) * 4 + 3] = 2.5f;  // voxel (3,2,1)
    const fs::path file = nifti_file("a.nii", f, encode(values));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "a.nii: voxel (3,2,1) has value 2.5, expected an integer label"));
}

TEST(ReadNifti, NegativeLabelIsRejected) {
    NiftiFields f;
    f.datatype = 4;
    f.bitpix = 16;
    std::vector<std::int16_t> values(24, 0);
    values[5] = -3;  // voxel (1,1,0)
    const fs::path file = nifti_file("a.nii", f, encode(values));
    EXPECT_TRUE(
        throws_error([&] { read(file); }, ErrorCode::InvalidInput, "voxel (1,1,0) has value -3"));
}

TEST(ReadNifti, LabelAbove65535IsRejected) {
    NiftiFields f;
    f.datatype = 768;
    f.bitpix = 32;
    std::vector<std::uint32_t> values(24, 0);
    values[23] = 70000;
    const fs::path file = nifti_file("a.nii", f, encode(values));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "voxel (3,2,1) has value 70000"));
}

TEST(ReadNifti, ScaledNonIntegerLabelNamesScaling) {
    NiftiFields f;
    f.scl_slope = 0.5;
    const fs::path file = nifti_file("a.nii", f, encode(std::vector<std::uint8_t>(24, 3)));
    EXPECT_TRUE(throws_error([&] { read(file); }, ErrorCode::InvalidInput,
                             "value 1.5 (stored 3 * scl_slope 0.5 + scl_inter 0)"));
}

// ---------------------------------------------------------------------------------------------
// Real files (../shared/data)

TEST(ReadNifti, TotalSegmentatorExampleLabelsAreClassMapKeys) {
    const fs::path dir = test::shared_data_dir() / "totalsegmentator_abdomen";
    const SliceStack stack = read(dir / "example_seg.nii.gz");
    EXPECT_EQ(stack.width, 122u);
    EXPECT_EQ(stack.height, 101u);
    EXPECT_EQ(stack.depth, 30u);
    const Vec3 spacing = stack.spacing_mm();
    EXPECT_NEAR(spacing.x, 3.0, 1e-6);
    EXPECT_NEAR(spacing.y, 3.0, 1e-6);
    EXPECT_NEAR(spacing.z, 3.0, 1e-6);
    EXPECT_EQ(stack.source_frame, "RAS");
    // sform_code 2, srow_x = (3, 0, 0, -177.956...): LPS negates x and y.
    EXPECT_NEAR(stack.index_to_world.linear[0][0], -3.0, 1e-6);
    EXPECT_NEAR(stack.index_to_world.translation.x, 177.95632934570312, 1e-4);
    EXPECT_NEAR(stack.index_to_world.translation.y, -11.319000244140625, 1e-4);
    EXPECT_NEAR(stack.index_to_world.translation.z, 94.3017578125, 1e-4);

    const std::vector<std::uint16_t> present = present_labels(stack);
    EXPECT_EQ(present.size(), 41u);
    EXPECT_EQ(present.back(), 117);
    EXPECT_TRUE(std::binary_search(present.begin(), present.end(), 5));  // liver
    const std::vector<LabelInfo> classes = detail::read_color_table(dir / "class_map_total.json");
    std::set<std::uint16_t> keys;
    for (const LabelInfo& c : classes) {
        keys.insert(c.value);
    }
    for (std::uint16_t v : present) {
        EXPECT_TRUE(keys.count(v)) << "label " << v << " not in class_map_total.json";
    }
    // The file names its labels itself (Caret <LabelTable> extension), as the class map does.
    ASSERT_EQ(stack.label_table.size(), classes.size());
    for (std::size_t n = 0; n < classes.size(); ++n) {
        EXPECT_EQ(stack.label_table[n].value, classes[n].value);
        EXPECT_EQ(stack.label_table[n].name, classes[n].name);
    }
    EXPECT_EQ(stack.label_table[0].color, (ColorSrgb8{0, 255, 0}));  // spleen: 0.0 1.0 0.0
}

TEST(ReadNifti, NiivueTorsoGridAndSpacing) {
    const SliceStack stack = read(test::shared_data_dir() / "niivue_torso" / "torsoLabel.nii.gz");
    EXPECT_EQ(stack.width, 384u);
    EXPECT_EQ(stack.height, 320u);
    EXPECT_EQ(stack.depth, 89u);
    const Vec3 spacing = stack.spacing_mm();
    EXPECT_NEAR(spacing.x, 0.782, 1e-6);
    EXPECT_NEAR(spacing.y, 0.782, 1e-6);
    EXPECT_NEAR(spacing.z, 5.0, 1e-6);
    const std::vector<std::uint16_t> present = present_labels(stack);
    EXPECT_EQ(present, (std::vector<std::uint16_t>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11}));
}

// ---------------------------------------------------------------------------------------------
// Writing

SliceStack small_stack(std::uint16_t max_label) {
    SliceStack stack;
    stack.width = 5;
    stack.height = 4;
    stack.depth = 3;
    stack.labels.resize(60);
    for (std::size_t n = 0; n < stack.labels.size(); ++n) {
        stack.labels[n] = static_cast<std::uint16_t>((n * 37) % (max_label + 1u));
    }
    stack.index_to_world = make_affine({{{0.8, 0, 0, -120.5}, {0, 0.8, 0, 33.25}, {0, 0, 2.5, 7}}});
    return stack;
}

/// |a - b| <= 1e-6 relative to the magnitude (NIfTI-1 stores float32: ~6e-8 relative).
void expect_affine_close(const Affine3& actual, const Affine3& expected) {
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(actual.linear[r][c], expected.linear[r][c],
                        1e-6 * std::max(1.0, std::abs(expected.linear[r][c])));
        }
        EXPECT_NEAR(actual.translation[r], expected.translation[r],
                    1e-6 * std::max(1.0, std::abs(expected.translation[r])));
    }
}

TEST(WriteNifti, RoundTripUint8Gzip) {
    const SliceStack stack = small_stack(200);
    const fs::path file = temp_dir() / "out.nii.gz";
    write_nifti(stack, file);
    EXPECT_EQ(read_bytes(file).substr(0, 2), "\x1f\x8b");
    const SliceStack back = read(file);
    EXPECT_EQ(back.width, 5u);
    EXPECT_EQ(back.height, 4u);
    EXPECT_EQ(back.depth, 3u);
    EXPECT_EQ(back.labels, stack.labels);
    expect_affine_close(back.index_to_world, stack.index_to_world);
    EXPECT_EQ(back.source_frame, "RAS");
}

TEST(WriteNifti, RoundTripUint16Raw) {
    const SliceStack stack = small_stack(60000);
    const fs::path file = temp_dir() / "out.nii";
    write_nifti(stack, file);
    const std::string bytes = read_bytes(file);
    ASSERT_EQ(bytes.size(), 352u + 60 * 2);
    EXPECT_EQ(bytes[70], '\0');  // datatype 512 = 0x0200 little endian
    EXPECT_EQ(bytes[71], '\x02');
    EXPECT_EQ(read(file).labels, stack.labels);
}

TEST(WriteNifti, ChoosesUint8WhenLabelsFit) {
    const fs::path file = temp_dir() / "out.nii";
    write_nifti(small_stack(255), file);
    const std::string bytes = read_bytes(file);
    EXPECT_EQ(bytes.size(), 352u + 60);
    EXPECT_EQ(bytes[70], '\x02');
}

TEST(WriteNifti, RoundTripRotatedAffine) {
    SliceStack stack = small_stack(9);
    // Rotation by 30 degrees about (1, 2, 2)/3, spacings 0.7, 0.9, 3, reflected k (det < 0).
    const double angle = 30.0 * 3.14159265358979323846 / 180.0;
    const Vec3 u{1.0 / 3, 2.0 / 3, 2.0 / 3};
    const double co = std::cos(angle), si = std::sin(angle);
    const double rot[3][3] = {
        {co + u.x * u.x * (1 - co), u.x * u.y * (1 - co) - u.z * si,
         u.x * u.z * (1 - co) + u.y * si},
        {u.y * u.x * (1 - co) + u.z * si, co + u.y * u.y * (1 - co),
         u.y * u.z * (1 - co) - u.x * si},
        {u.z * u.x * (1 - co) - u.y * si, u.z * u.y * (1 - co) + u.x * si,
         co + u.z * u.z * (1 - co)},
    };
    const double spacing[3] = {0.7, 0.9, -3.0};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            stack.index_to_world.linear[r][c] = rot[r][c] * spacing[c];
        }
    }
    stack.index_to_world.translation = {-12.345678, 98.7654321, -0.5};
    const fs::path file = temp_dir() / "rotated.nii";
    write_nifti(stack, file);
    const SliceStack back = read(file);
    EXPECT_EQ(back.labels, stack.labels);
    expect_affine_close(back.index_to_world, stack.index_to_world);

    // The qform alone (sform_code patched to 0) describes the same grid.
    std::string bytes = read_bytes(file);
    bytes[254] = 0;
    bytes[255] = 0;
    const fs::path qform_only = write_file(file.parent_path() / "qform.nii", bytes);
    const SliceStack from_qform = read(qform_only);
    expect_affine_near(from_qform.index_to_world, stack.index_to_world, 1e-4);
}

TEST(WriteNifti, RoundTripRealFile) {
    const SliceStack stack = read(test::shared_data_dir() / "niivue_torso" / "torsoLabel.nii.gz");
    const fs::path file = temp_dir() / "torso.nii.gz";
    write_nifti(stack, file);
    const SliceStack back = read(file);
    EXPECT_EQ(back.labels, stack.labels);
    expect_affine_close(back.index_to_world, stack.index_to_world);
}

TEST(WriteNifti, RejectsOtherExtensions) {
    const fs::path file = temp_dir() / "out.nrrd";
    EXPECT_TRUE(throws_error([&] { write_nifti(small_stack(3), file); }, ErrorCode::InvalidInput,
                             "expected a file name ending in .nii or .nii.gz"));
    EXPECT_FALSE(fs::exists(file));
}

TEST(WriteNifti, RejectsInconsistentStack) {
    SliceStack stack = small_stack(3);
    stack.labels.pop_back();
    EXPECT_TRUE(throws_error([&] { write_nifti(stack, temp_dir() / "out.nii"); },
                             ErrorCode::InvalidInput, "5x4x3 with 59 labels"));
}

TEST(WriteNifti, RejectsDimsBeyondNifti1) {
    SliceStack stack;
    stack.width = 40000;
    stack.height = 1;
    stack.depth = 1;
    stack.labels.resize(40000);
    EXPECT_TRUE(throws_error([&] { write_nifti(stack, temp_dir() / "out.nii"); },
                             ErrorCode::Unsupported, "exceed NIfTI-1's limit of 32767"));
}

TEST(WriteNifti, FailureLeavesExistingFileUntouched) {
    const fs::path file = temp_dir() / "keep.nii";
    write_file(file, "previous");
    SliceStack stack = small_stack(3);
    stack.index_to_world.linear[1] = {0, 0, 0};  // zero column: degenerate
    EXPECT_THROW(write_nifti(stack, file), Error);
    EXPECT_EQ(read_bytes(file), "previous");
}

}  // namespace
}  // namespace strata

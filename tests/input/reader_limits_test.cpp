// Boundaries of the header and value checks the readers make, each side of every limit tested
// (issue 24 item 2; its mutation script found these unguarded): NIfTI dim[0] 1 and 8 (the valid
// range is 2..7; 8 would read past dim[7]), every other NIfTI-1 field the reader checks
// (sizeof_hdr, dims, volumes, pixdim, vox_offset, bitpix, form codes, quaternion length), the NRRD
// fields (magic, dimension, sizes, space dimension, line and byte skip, segment label values and
// colours), and labels just above 65535 given as floats. The glTF reader's are in
// tests/exporters/read_progressive_limits_test.cpp.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/report.h"
#include "input/detail/readers.h"
#include "input/slice_stack.h"
#include "input/write_nifti.h"
#include "support/input_files.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using test::throws_error;
using test::write_file;

SliceStack read_with(SliceStack (*reader)(const fs::path&, const ReadOptions&, Report&),
                     const fs::path& path) {
    Report report;
    return reader(path, {}, report);
}

/// A valid 4 x 3 x 2 NIfTI-1 file (written by write_nifti) whose dim[0] is then set to `rank`.
fs::path nifti_with_rank(std::int16_t rank) {
    SliceStack stack;
    stack.width = 4;
    stack.height = 3;
    stack.depth = 2;
    stack.labels.assign(24, 1);
    stack.label_table.push_back({1, "one", {200, 80, 80}});
    const fs::path file = test::current_test_dir("limits_") / "a.nii";
    write_nifti(stack, file);
    std::string bytes;
    {
        std::ifstream in(file, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    test::put(bytes, 40, rank, false);  // dim[0] of the NIfTI-1 header
    return write_file(file, bytes);
}

TEST(ReaderLimits, NiftiRankTwoToSevenOnly) {
    // the unpatched file has rank 3; 2 and 7 are the limits (dims above 3 are 1)
    for (const std::int16_t rank : {std::int16_t(3), std::int16_t(7)}) {
        EXPECT_NO_THROW(read_with(detail::read_nifti, nifti_with_rank(rank))) << rank;
    }
    for (const std::int16_t rank : {std::int16_t(0), std::int16_t(1), std::int16_t(8)}) {
        EXPECT_TRUE(throws_error([&] { read_with(detail::read_nifti, nifti_with_rank(rank)); },
                                 ErrorCode::InvalidInput,
                                 "dim[0] = " + std::to_string(rank) + ", expected 2..7"))
            << rank;
    }
}

/// The valid 4 x 3 x 2 NIfTI-1 file of nifti_with_rank, with `patch` applied to its bytes.
template <typename Patch>
fs::path nifti_patched(const std::string& name, Patch&& patch) {
    std::string bytes = test::read_file(nifti_with_rank(3));
    patch(bytes);
    return write_file(test::current_test_dir("limits_") / (name + ".nii"), bytes);
}

/// One side of a header field's limit: `value` written at `offset` is accepted (empty
/// `fragment`) or refused with InvalidInput (or `code`) and a message containing `fragment`.
template <typename T>
void expect_nifti_field(const std::string& field,
                        std::size_t offset,
                        T value,
                        const std::string& fragment,
                        ErrorCode code = ErrorCode::InvalidInput) {
    const fs::path file =
        nifti_patched(field, [&](std::string& b) { test::put(b, offset, value, false); });
    SCOPED_TRACE(field + " = " + std::to_string(value));
    if (fragment.empty()) {
        EXPECT_NO_THROW(read_with(detail::read_nifti, file));
    } else {
        EXPECT_TRUE(throws_error([&] { read_with(detail::read_nifti, file); }, code, fragment));
    }
}

TEST(ReaderLimits, NiftiHeaderFieldsEachSideOfTheirLimits) {
    // sizeof_hdr: exactly 348 (NIfTI-1)
    expect_nifti_field("sizeof_hdr", 0, std::int32_t(348), "");
    expect_nifti_field("sizeof_hdr", 0, std::int32_t(347), "sizeof_hdr is 347");
    expect_nifti_field("sizeof_hdr", 0, std::int32_t(349), "sizeof_hdr is 349");
    // dim[1..3]: at least 1 (a width of 1 reads the first column's worth of bytes)
    expect_nifti_field("dim[1]", 42, std::int16_t(1), "");
    expect_nifti_field("dim[1]", 42, std::int16_t(0),
                       "empty dimensions 0x3x2, expected all positive");
    expect_nifti_field("dim[1]", 42, std::int16_t(-1), "dim[1] = -1, expected a positive size");
    // dim[4] of a 4D header: exactly one volume
    const auto four_d = [](std::int16_t volumes, const std::string& fragment, ErrorCode code) {
        const fs::path file = nifti_patched("dim4", [&](std::string& b) {
            test::put(b, 40, std::int16_t(4), false);
            test::put(b, 48, volumes, false);
        });
        SCOPED_TRACE("dim[4] = " + std::to_string(volumes));
        if (fragment.empty()) {
            EXPECT_NO_THROW(read_with(detail::read_nifti, file));
        } else {
            EXPECT_TRUE(throws_error([&] { read_with(detail::read_nifti, file); }, code, fragment));
        }
    };
    four_d(1, "", ErrorCode::InvalidInput);
    four_d(0, "empty dimension", ErrorCode::InvalidInput);
    four_d(2, "with 2 volumes; expected a single 3D label volume", ErrorCode::Unsupported);
    // pixdim[1..3]: finite and positive
    expect_nifti_field("pixdim[1]", 80, 1e-3f, "");
    expect_nifti_field("pixdim[1]", 80, 0.0f, "pixdim[1] = 0");
    expect_nifti_field("pixdim[1]", 80, -1.0f, "pixdim[1] = -1");
    expect_nifti_field("pixdim[3]", 88, std::numeric_limits<float>::infinity(), "pixdim[3] = ");
    // vox_offset: a whole number of bytes, 348 (the header, no extension flag) or at least 352;
    // 349..351 would start the voxels inside the extension flag (351 was read, one byte shifted)
    expect_nifti_field("vox_offset", 108, 352.0f, "");
    expect_nifti_field("vox_offset", 108, 351.0f, "vox_offset 351, expected");
    expect_nifti_field("vox_offset", 108, 349.0f, "vox_offset 349, expected");
    expect_nifti_field("vox_offset", 108, 347.0f, "vox_offset 347, expected");
    expect_nifti_field("vox_offset", 108, 352.5f, "vox_offset 352.5, expected");
    {
        // 348: the voxels right after the header
        const fs::path file = nifti_patched("vox_offset_348", [](std::string& b) {
            test::put(b, 108, 348.0f, false);
            b.erase(348, 4);
        });
        const SliceStack stack = read_with(detail::read_nifti, file);
        EXPECT_EQ(stack.labels, std::vector<std::uint16_t>(24, 1));
    }
    // bitpix: as its datatype (uint8: 8)
    expect_nifti_field("bitpix", 72, std::int16_t(8), "");
    expect_nifti_field("bitpix", 72, std::int16_t(16), "bitpix 16 does not match");
    // sform_code and qform_code: 0 (unset) or positive
    expect_nifti_field("sform_code", 254, std::int16_t(0), "");
    expect_nifti_field("sform_code", 254, std::int16_t(-1),
                       "expected 0 (unset) or a positive code");
    expect_nifti_field("qform_code", 252, std::int16_t(0), "");
    expect_nifti_field("qform_code", 252, std::int16_t(-1),
                       "expected 0 (unset) or a positive code");
}

TEST(ReaderLimits, NiftiQuaternionAtMostUnitLength) {
    // qform only (sform_code 0): the written quaternion (0, 0, 1) has length exactly 1; the
    // reader allows 1e-4 for float rounding, no more
    const auto quaternion = [](float d, const std::string& fragment) {
        const fs::path file = nifti_patched("quatern", [&](std::string& b) {
            test::put(b, 254, std::int16_t(0), false);
            test::put(b, 256, 0.0f, false);
            test::put(b, 260, 0.0f, false);
            test::put(b, 264, d, false);
        });
        SCOPED_TRACE("quatern_d = " + std::to_string(d));
        if (fragment.empty()) {
            EXPECT_NO_THROW(read_with(detail::read_nifti, file));
        } else {
            EXPECT_TRUE(throws_error([&] { read_with(detail::read_nifti, file); },
                                     ErrorCode::InvalidInput, fragment));
        }
    };
    quaternion(1.0f, "");
    quaternion(1.00004f, "");
    quaternion(1.0002f, "expected at most 1");
}

TEST(ReaderLimits, NrrdDimensionAtLeastOne) {
    const fs::path dir = test::current_test_dir("limits_");
    const fs::path zero = write_file(
        dir / "zero.nrrd", "NRRD0004\ntype: uchar\ndimension: 0\nsizes: \nencoding: ascii\n\n");
    EXPECT_TRUE(throws_error([&] { read_with(detail::read_nrrd, zero); }, ErrorCode::InvalidInput,
                             "header field 'dimension' is \"0\""));
    // dimension 1 passes the field's check; the reader then wants 2 or 3 spatial axes
    const fs::path one =
        write_file(dir / "one.nrrd",
                   "NRRD0004\ntype: uchar\ndimension: 1\nsizes: 3\nencoding: ascii\n\n1 2 3\n");
    EXPECT_TRUE(throws_error([&] { read_with(detail::read_nrrd, one); }, ErrorCode::Unsupported,
                             "1 spatial axes, expected 2"));
}

/// A 2 x 1 x 1 ascii NRRD with `fields` added to its header: read (empty `fragment`) or refused
/// with `code` and a message containing `fragment`.
void expect_nrrd(const std::string& name,
                 const std::string& magic,
                 const std::string& fields,
                 const std::string& fragment,
                 ErrorCode code = ErrorCode::InvalidInput,
                 const std::string& data = "0 1\n") {
    SCOPED_TRACE(name + ": " + magic + " " + fields);
    const fs::path file =
        write_file(test::current_test_dir("limits_") / (name + ".nrrd"),
                   magic + "\ntype: uchar\nencoding: ascii\n" + fields + "\n" + data);
    if (fragment.empty()) {
        EXPECT_NO_THROW(read_with(detail::read_nrrd, file));
    } else {
        EXPECT_TRUE(throws_error([&] { read_with(detail::read_nrrd, file); }, code, fragment));
    }
}

TEST(ReaderLimits, NrrdHeaderFieldsEachSideOfTheirLimits) {
    const std::string volume = "dimension: 3\nsizes: 2 1 1\n";
    // magic: NRRD0001 .. NRRD0005
    expect_nrrd("magic1", "NRRD0001", volume, "");
    expect_nrrd("magic5", "NRRD0005", volume, "");
    expect_nrrd("magic0", "NRRD0000", volume, "expected NRRD0001 .. NRRD0005",
                ErrorCode::Unsupported);
    expect_nrrd("magic6", "NRRD0006", volume, "expected NRRD0001 .. NRRD0005",
                ErrorCode::Unsupported);
    // dimension: 1..16 (16 passes the field's check; then the axes are too many)
    expect_nrrd("dimension17", "NRRD0004", "dimension: 17\nsizes: 2" + std::string(32, ' ') + "\n",
                "header field 'dimension' is \"17\", expected 1..16");
    expect_nrrd("dimension16", "NRRD0004",
                "dimension: 16\nsizes: 2 1 1 1 1 1 1 1 1 1 1 1 1 1 1 1\n", "spatial axes",
                ErrorCode::Unsupported);
    // sizes: at least 1 on every axis
    expect_nrrd("sizes1", "NRRD0004", "dimension: 3\nsizes: 1 1 1\n", "", ErrorCode::InvalidInput,
                "1\n");
    expect_nrrd("sizes0", "NRRD0004", "dimension: 3\nsizes: 2 0 1\n", "expected all positive");
    expect_nrrd("sizes-1", "NRRD0004", "dimension: 3\nsizes: 2 -1 1\n",
                "'sizes' has \"-1\" on axis 1, expected a positive integer");
    // space dimension: 3 only (0 is malformed, 2 and 4 are other worlds)
    expect_nrrd("space3", "NRRD0004", volume + "space dimension: 3\n", "");
    expect_nrrd("space0", "NRRD0004", volume + "space dimension: 0\n",
                "'space dimension' is \"0\", expected a positive integer");
    expect_nrrd("space2", "NRRD0004", volume + "space dimension: 2\n", "expected 3 (a 3D world)",
                ErrorCode::Unsupported);
    expect_nrrd("space4", "NRRD0004", volume + "space dimension: 4\n", "expected 3 (a 3D world)",
                ErrorCode::Unsupported);
    // line skip: 0 or more; byte skip: -1 (the data are the file's last bytes) or more
    expect_nrrd("lineskip0", "NRRD0004", volume + "line skip: 0\n", "");
    expect_nrrd("lineskip-1", "NRRD0004", volume + "line skip: -1\n",
                "'line skip' is \"-1\", expected 0 or more lines");
    const std::string raw = "NRRD0004\ntype: uchar\nencoding: raw\ndimension: 3\nsizes: 2 1 1\n";
    const fs::path dir = test::current_test_dir("limits_");
    {
        const SliceStack stack =
            read_with(detail::read_nrrd,
                      write_file(dir / "byteskip-1.nrrd",
                                 raw + "byte skip: -1\n\n" + std::string("\x07\x00\x02", 3)));
        EXPECT_EQ(stack.labels, (std::vector<std::uint16_t>{0, 2}));
    }
    EXPECT_TRUE(throws_error(
        [&] {
            read_with(detail::read_nrrd,
                      write_file(dir / "byteskip-2.nrrd",
                                 raw + "byte skip: -2\n\n" + std::string(2, '\1')));
        },
        ErrorCode::InvalidInput, "'byte skip' is \"-2\", expected -1 or more bytes"));
    // a .seg.nrrd segment's label value: 1..65535; its colour: three numbers 0..1
    expect_nrrd("label1", "NRRD0004", volume + "Segment0_LabelValue:=1\n", "");
    expect_nrrd("label65535", "NRRD0004", volume + "Segment0_LabelValue:=65535\n", "");
    expect_nrrd("label0", "NRRD0004", volume + "Segment0_LabelValue:=0\n",
                "expected a label value 1..65535");
    expect_nrrd("label65536", "NRRD0004", volume + "Segment0_LabelValue:=65536\n",
                "expected a label value 1..65535");
    expect_nrrd("colour1", "NRRD0004", volume + "Segment0_Color:=0 0.5 1\n", "");
    expect_nrrd("colour-above", "NRRD0004", volume + "Segment0_Color:=0 0.5 1.01\n",
                "expected three numbers 0..1");
    expect_nrrd("colour-below", "NRRD0004", volume + "Segment0_Color:=-0.01 0.5 1\n",
                "expected three numbers 0..1");
}

TEST(ReaderLimits, FloatLabelsUpTo65535) {
    const fs::path dir = test::current_test_dir("limits_");
    const std::string head =
        "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\nencoding: ascii\n\n";
    const SliceStack stack =
        read_with(detail::read_nrrd, write_file(dir / "top.nrrd", head + "0 65535\n"));
    EXPECT_EQ(stack.labels, (std::vector<std::uint16_t>{0, 65535}));
    EXPECT_TRUE(throws_error(
        [&] { read_with(detail::read_nrrd, write_file(dir / "above.nrrd", head + "0 65536\n")); },
        ErrorCode::InvalidInput, "65536"));
    EXPECT_TRUE(throws_error(
        [&] { read_with(detail::read_nrrd, write_file(dir / "below.nrrd", head + "-1 0\n")); },
        ErrorCode::InvalidInput, "-1"));
}

}  // namespace
}  // namespace strata

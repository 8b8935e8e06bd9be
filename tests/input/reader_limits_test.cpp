// Boundaries of the header and value checks the readers make, each side of every limit tested
// (issue 24's mutation script found these unguarded): NIfTI dim[0] 1 and 8 (the valid range is
// 2..7; 8 would read past dim[7]), NRRD dimension 0, and labels just above 65535 given as floats.
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
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

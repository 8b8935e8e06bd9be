#include "core/atomic_write.h"

#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"
#include "support/test_paths.h"

namespace strata {
namespace {

std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(AtomicWrite, WritesAndReplaces) {
    const auto dir = test::fresh_temp_dir("atomic_write_replace");
    const auto file = dir / "sub" / "a.txt";
    write_file_atomically(file, "first");
    EXPECT_EQ(slurp(file), "first");
    write_file_atomically(file, "second, longer");
    EXPECT_EQ(slurp(file), "second, longer");
    // no temporary files left behind
    int entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir / "sub")) {
        ++entries;
    }
    EXPECT_EQ(entries, 1);
}

TEST(AtomicWrite, FailingWriterKeepsOldFile) {
    const auto dir = test::fresh_temp_dir("atomic_write_fail");
    const auto file = dir / "a.txt";
    write_file_atomically(file, "old");
    EXPECT_THROW(write_file_atomically(file,
                                       [](std::ostream& out) {
                                           out << "partial";
                                           throw Error(ErrorCode::Internal, "writer failed");
                                       }),
                 Error);
    EXPECT_EQ(slurp(file), "old");
    int entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir)) {
        ++entries;
    }
    EXPECT_EQ(entries, 1) << "temporary file not removed";
}

TEST(AtomicWrite, UnwritableLocationIsIoError) {
    const auto dir = test::fresh_temp_dir("atomic_write_unwritable");
    write_file_atomically(dir / "plain", "x");
    try {
        write_file_atomically(dir / "plain" / "child.txt", "y");
        FAIL() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Io);
        EXPECT_NE(std::string(e.what()).find("plain"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace strata

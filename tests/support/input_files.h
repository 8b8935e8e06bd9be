#pragma once

// Helpers for tests that write input files (NIfTI, NRRD, colour tables) and check what is read
// back from them: labels or errors. Independent of the readers' own byte and zlib code.
// Header-only.

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>
#include <zlib.h>

#include <gtest/gtest.h>

#include "core/error.h"
#include "input/slice_stack.h"
#include "support/test_paths.h"

namespace strata::test {

/// A fresh empty folder named `prefix` + "<suite>_<test>" for the running test.
inline std::filesystem::path current_test_dir(const std::string& prefix) {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    return fresh_temp_dir(prefix + test->test_suite_name() + "_" + test->name());
}

/// Writes `bytes` to `path` as they are; returns `path`.
inline std::filesystem::path write_file(const std::filesystem::path& path,
                                        const std::string& bytes) {
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
}

/// Stores `value` at byte `offset` of `bytes` in little- or big-endian order.
template <typename T>
void put(std::string& bytes, std::size_t offset, T value, bool big_endian) {
    auto raw = std::bit_cast<std::array<char, sizeof(T)>>(value);
    if (big_endian != (std::endian::native == std::endian::big)) {
        std::reverse(raw.begin(), raw.end());
    }
    std::memcpy(bytes.data() + offset, raw.data(), sizeof(T));
}

/// `values` as raw bytes, one after the other, little-endian unless `big_endian`.
template <typename T>
std::string encode(const std::vector<T>& values, bool big_endian = false) {
    std::string bytes(values.size() * sizeof(T), '\0');
    for (std::size_t n = 0; n < values.size(); ++n) {
        put(bytes, n * sizeof(T), values[n], big_endian);
    }
    return bytes;
}

/// `bytes` compressed as one gzip member (header, deflate data, CRC trailer).
inline std::string gzip(const std::string& bytes) {
    z_stream s{};
    EXPECT_EQ(deflateInit2(&s, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    std::string out(deflateBound(&s, static_cast<uLong>(bytes.size())) + 64, '\0');
    s.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
    s.avail_in = static_cast<uInt>(bytes.size());
    s.next_out = reinterpret_cast<Bytef*>(out.data());
    s.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&s, Z_FINISH), Z_STREAM_END);
    out.resize(s.total_out);
    deflateEnd(&s);
    return out;
}

/// 0, 1, 2, ... 6, 0, 1, ... (`count` values): distinct along each row of the 4x3x2 test grid.
inline std::vector<std::uint8_t> ramp(std::size_t count) {
    std::vector<std::uint8_t> values(count);
    for (std::size_t n = 0; n < count; ++n) {
        values[n] = static_cast<std::uint8_t>(n % 7);
    }
    return values;
}

/// How many slices of `stack` hold at least one non-zero label.
inline std::size_t count_labelled_slices(const SliceStack& stack) {
    std::size_t count = 0;
    for (std::uint32_t k = 0; k < stack.depth; ++k) {
        const auto s = stack.slice(k);
        if (std::any_of(s.begin(), s.end(), [](std::uint16_t v) { return v != 0; })) {
            ++count;
        }
    }
    return count;
}

/// Success when `f()` throws a strata::Error with `code` whose message contains `fragment`;
/// use as EXPECT_TRUE(throws_error([&] { ... }, ErrorCode::InvalidInput, "voxel (3,1,0)")).
template <typename F>
::testing::AssertionResult throws_error(F&& f, ErrorCode code, const std::string& fragment) {
    try {
        f();
    } catch (const Error& e) {
        if (e.code() != code) {
            return ::testing::AssertionFailure() << "code " << to_string(e.code()) << " ("
                                                 << e.what() << "), expected " << to_string(code);
        }
        if (std::string(e.what()).find(fragment) == std::string::npos) {
            return ::testing::AssertionFailure()
                   << "message \"" << e.what() << "\" lacks \"" << fragment << "\"";
        }
        return ::testing::AssertionSuccess() << e.what();
    }
    return ::testing::AssertionFailure() << "no strata::Error thrown";
}

}  // namespace strata::test

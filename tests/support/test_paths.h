#pragma once

#include <filesystem>
#include <string>

namespace strata::test {

/// ../shared/data beside the checkout (real test data).
std::filesystem::path shared_data_dir();

/// The built `strata` executable.
std::filesystem::path cli_path();

/// A fresh empty folder for one test, under the build tree's temp dir; removed by the caller
/// or left for inspection.
std::filesystem::path fresh_temp_dir(const std::string& name);

/// The bytes of a file (empty when it cannot be read).
std::string read_file(const std::filesystem::path& path);

}  // namespace strata::test

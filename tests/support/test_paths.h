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

}  // namespace strata::test

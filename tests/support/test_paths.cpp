#include "support/test_paths.h"

#include <unistd.h>

namespace strata::test {

std::filesystem::path shared_data_dir() {
    return STRATA_SHARED_DATA_DIR;
}

std::filesystem::path cli_path() {
    return STRATA_CLI_PATH;
}

std::filesystem::path fresh_temp_dir(const std::string& name) {
    const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                      ("strata-test-" + std::to_string(::getpid())) / name;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return dir;
}

}  // namespace strata::test

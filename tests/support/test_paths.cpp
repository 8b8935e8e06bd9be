#include "support/test_paths.h"

#include <fstream>
#include <iterator>
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

std::string read_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace strata::test

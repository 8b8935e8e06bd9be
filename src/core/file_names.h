#pragma once

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

namespace strata {

/// The extension of `path` in lower case, with its dot (".ply"), for choosing a file format.
inline std::string lowercase_extension(const std::filesystem::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return ext;
}

}  // namespace strata

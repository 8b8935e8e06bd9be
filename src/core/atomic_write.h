#pragma once

#include <filesystem>
#include <functional>
#include <ostream>
#include <string_view>

namespace strata {

/// Writes a file atomically: `write` fills a temporary file next to `path`, which is flushed and
/// renamed over `path` only when everything succeeded. On failure the temporary file is removed,
/// an existing `path` is left untouched, and Error{Io} (or whatever `write` threw) propagates.
/// Parent folders are created.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write);

/// Convenience overload for a ready buffer.
void write_file_atomically(const std::filesystem::path& path, std::string_view bytes);

}  // namespace strata

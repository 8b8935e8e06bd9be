#pragma once

#include <cstddef>
#include <functional>
#include <string_view>

namespace strata {

/// Progress callback: `done` of `total` units of `what` ("slices", "slice pairs") finished.
/// May be called from worker threads, one call at a time.
using ProgressFn = std::function<void(std::string_view what, std::size_t done, std::size_t total)>;

}  // namespace strata

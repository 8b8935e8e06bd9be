#pragma once

#include <algorithm>
#include <cstdint>

namespace strata {

/// Image pixels [x0, x1) x [y0, y1); empty when x1 <= x0 or y1 <= y0.
struct PixelBox {
    std::int64_t x0 = 0;
    std::int64_t y0 = 0;
    std::int64_t x1 = 0;
    std::int64_t y1 = 0;

    bool empty() const { return x1 <= x0 || y1 <= y0; }
    /// The smallest box holding both (an empty box contributes nothing).
    PixelBox united(const PixelBox& o) const {
        if (empty()) {
            return o;
        }
        if (o.empty()) {
            return *this;
        }
        return {std::min(x0, o.x0), std::min(y0, o.y0), std::max(x1, o.x1), std::max(y1, o.y1)};
    }
};

}  // namespace strata

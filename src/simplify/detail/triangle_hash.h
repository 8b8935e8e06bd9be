#pragma once

// Hashing a triangle by its vertex ids, for the simplifier's tables keyed by triangles.

#include <array>
#include <cstddef>
#include <cstdint>

namespace strata::detail {

/// Hash of a triangle's vertex ids in order (a rotated triangle hashes differently).
struct TriangleHash {
    std::size_t operator()(const std::array<std::uint32_t, 3>& t) const {
        std::uint64_t h = std::uint64_t(t[0]) * 0x9e3779b97f4a7c15ull ^
                          std::uint64_t(t[1]) * 0xc2b2ae3d27d4eb4full ^
                          std::uint64_t(t[2]) * 0x165667b19e3779f9ull;
        return std::size_t(h ^ (h >> 29));
    }
};

}  // namespace strata::detail

#pragma once

// What the NIfTI reader and writer share; internal to strata_input.

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstring>

#include "core/types.h"

namespace strata::detail {

/// Bytes of a NIfTI-1 header (sizeof_hdr), before its 4-byte extension flag.
inline constexpr std::size_t kNifti1HeaderBytes = 348;

/// Writes `value` little-endian at `bytes`.
template <typename T>
void store_le(unsigned char* bytes, T value) {
    auto raw = std::bit_cast<std::array<unsigned char, sizeof(T)>>(value);
    if constexpr (std::endian::native == std::endian::big) {
        std::reverse(raw.begin(), raw.end());
    }
    std::memcpy(bytes, raw.data(), sizeof(T));
}

/// RAS <-> LPS: negates the first two rows of an affine (its own inverse).
inline Affine3 flip_ras_lps(Affine3 affine) {
    for (int row = 0; row < 2; ++row) {
        for (int col = 0; col < 3; ++col) {
            affine.linear[row][col] = -affine.linear[row][col];
        }
        affine.translation[row] = -affine.translation[row];
    }
    return affine;
}

}  // namespace strata::detail

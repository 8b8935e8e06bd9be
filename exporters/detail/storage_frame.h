#pragma once

// The frame the glTF writers store positions in: grid coordinates of the slice space (x px,
// y px, z in slices), x negated when the slice frame mirrors, so that the node matrix that maps
// them to patient LPS mm is a rotation times positive scales.

#include <array>
#include <filesystem>

#include "core/slice_frame.h"

namespace strata::detail {

struct StorageFrame {
    double flip_x = 1.0;              ///< -1 when the slice frame mirrors
    double slice_spacing_px = 1.0;    ///< d: a stored z of 1 is d px of slice space
    std::array<double, 16> matrix{};  ///< storage -> LPS mm, column-major (glTF node matrix)
};

/// The storage frame of `frame`.
/// \throw Error{InvalidInput} naming `path` when the frame has a non-finite entry, a zero or
/// sheared column (a glTF node cannot hold a shear), or a non-positive slice spacing or error
/// scale.
StorageFrame storage_frame(const std::filesystem::path& path, const SliceFrame& frame);

}  // namespace strata::detail

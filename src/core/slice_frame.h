#pragma once

#include <array>

namespace strata {

/// Where a reconstruction's slice space (x, y px on the contour grid, slice k at z = k d) lies in
/// the patient frame: what an exporter needs to place slice-space models.
struct SliceFrame {
    /// Row-major 3 x 3: patient LPS mm per slice-space unit along x, y (px) and z (px, so a slice
    /// step is d times the third column). Columns must be orthogonal (a voxel grid without shear).
    std::array<double, 9> linear{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::array<double, 3> origin{};  ///< LPS mm of the slice-space origin
    double slice_spacing_px = 1.0;   ///< d
    double error_mm_per_px = 1.0;    ///< mm per px of in-plane error (the larger in-plane spacing)
};

}  // namespace strata

#include "exporters/detail/storage_frame.h"

#include <cmath>
#include <string>

#include "core/error.h"
#include "core/types.h"

namespace strata::detail {

StorageFrame storage_frame(const std::filesystem::path& path, const SliceFrame& frame) {
    const auto fail = [&](const std::string& what) {
        throw Error(ErrorCode::InvalidInput, path.string() + ": " + what);
    };
    const auto& l = frame.linear;
    const auto column = [&](int c) { return Vec3{l[c], l[3 + c], l[6 + c]}; };
    for (const double v : l) {
        if (!std::isfinite(v)) {
            fail("the slice frame has a non-finite entry");
        }
    }
    if (!(frame.slice_spacing_px > 0.0) || !std::isfinite(frame.slice_spacing_px) ||
        !(frame.error_mm_per_px > 0.0)) {
        fail("slice spacing and error scale must be positive");
    }
    for (int a = 0; a < 3; ++a) {
        if (!(norm(column(a)) > 0.0)) {
            fail("the slice frame's column " + std::to_string(a) + " is zero");
        }
        for (int b = a + 1; b < 3; ++b) {
            if (std::abs(dot(column(a), column(b))) > 1e-6 * norm(column(a)) * norm(column(b))) {
                fail("the voxel grid is sheared (columns " + std::to_string(a) + " and " +
                     std::to_string(b) +
                     " of the affine are not orthogonal): a glTF node cannot hold the "
                     "transform; resample the volume to an orthogonal grid");
            }
        }
    }
    StorageFrame s;
    s.flip_x = dot(cross(column(0), column(1)), column(2)) < 0.0 ? -1.0 : 1.0;
    s.slice_spacing_px = frame.slice_spacing_px;
    const std::array<double, 3> scale{s.flip_x, 1.0, s.slice_spacing_px};
    for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) {
            s.matrix[4 * c + r] = l[3 * r + c] * scale[c];
        }
    }
    s.matrix[12] = frame.origin[0];
    s.matrix[13] = frame.origin[1];
    s.matrix[14] = frame.origin[2];
    s.matrix[15] = 1.0;
    return s;
}

}  // namespace strata::detail

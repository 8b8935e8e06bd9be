#pragma once

#include <filesystem>

#include "input/slice_stack.h"

namespace strata {

/// Writes `stack` as a single-file NIfTI-1 volume: `.nii`, or gzip-compressed when `file` ends in
/// `.nii.gz`. Voxels are uint8 when every label is at most 255, else uint16; no scaling. The
/// world is written as sform and qform (both code 1, scanner anatomical) from `index_to_world`
/// converted from LPS to RAS; units mm. sform stores the affine exactly up to float32 rounding
/// (relative error ~6e-8); qform is the nearest rotation with the affine's column lengths as
/// pixdim, so it differs from the sform only for sheared affines. The file appears atomically:
/// on failure an existing `file` is left untouched.
/// Throws Error{InvalidInput} if `file` does not end in `.nii`/`.nii.gz`, if the stack is empty
/// or inconsistent (labels.size() != width*height*depth) or its affine is degenerate;
/// Error{Unsupported} if a dimension exceeds NIfTI-1's 32767; Error{Io} if writing fails.
void write_nifti(const SliceStack& stack, const std::filesystem::path& file);

}  // namespace strata

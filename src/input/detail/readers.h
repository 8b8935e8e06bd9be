#pragma once

// Format readers behind read_slice_stack(); internal to strata_input.

#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/report.h"
#include "input/read_slice_stack.h"
#include "input/slice_stack.h"

namespace strata::detail {

// Deflate (gzip, zlib, PNG) expands at most 1032:1 (RFC 1951: a 258-byte match costs at least 2
// bits), so a compressed stream of N bytes holds at most N * 1032 bytes of data.
inline constexpr std::uint64_t kMaxDeflateRatio = 1032;

// Other image compressions (LZW, JPEG, ...) are bounded generously at 4096:1.
inline constexpr std::uint64_t kMaxOtherRatio = 4096;

/// Folder of 2D images (PNG, TIFF, JPEG, ... via OpenImageIO), natural sort, optional meta.json.
SliceStack read_image_folder(const std::filesystem::path& folder,
                             const ReadOptions& options,
                             Report& report);

/// One image file as a stack: a (multi-page) TIFF through read_multipage_tiff, any other image
/// as one slice (OpenImageIO).
SliceStack read_single_image(const std::filesystem::path& file,
                             const ReadOptions& options,
                             Report& report);

/// Multi-page TIFF: one page per slice.
SliceStack read_multipage_tiff(const std::filesystem::path& file,
                               const ReadOptions& options,
                               Report& report);

/// NIfTI-1 or NIfTI-2, `.nii` or `.nii.gz`; affine from sform, else qform, else pixdim; RAS->LPS.
SliceStack read_nifti(const std::filesystem::path& file,
                      const ReadOptions& options,
                      Report& report);

/// NRRD (`.nrrd`, `.seg.nrrd`, detached `.nhdr`), raw or gzip; space directions/origin -> LPS
/// affine; Slicer segment names, colours and label values from `.seg.nrrd` fields.
SliceStack read_nrrd(const std::filesystem::path& file, const ReadOptions& options, Report& report);

/// Reads a colour table (3D Slicer `.ctbl`/`.txt`, ITK-SNAP label description, JSON object
/// {"value": "name"} or {"value": {"name": ..., "color": [r, g, b]}}). Format by content.
std::vector<LabelInfo> read_color_table(const std::filesystem::path& file);

}  // namespace strata::detail

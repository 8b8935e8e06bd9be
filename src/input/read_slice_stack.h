#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include "core/progress.h"
#include "core/report.h"
#include "input/slice_stack.h"

namespace strata {

/// How to read an input stack.
struct ReadOptions {
    /// Spacing in mm along x, y, z replacing the file's (directions and origin kept).
    std::optional<Vec3> spacing_mm;
    /// Colour table naming labels the file leaves unnamed: 3D Slicer `.ctbl`/`.txt`, ITK-SNAP
    /// label description, or a JSON object {"1": "spleen", ...}. Empty: none.
    std::filesystem::path color_table;
    /// A NRRD detached data file the user allows although it lies outside the header's folder
    /// (the CLI's --allow-data-file). Empty: data files must lie beside their header.
    std::filesystem::path allowed_data_file;
    /// Readers refuse stacks whose label images would need more bytes than this.
    std::uint64_t max_bytes = kMaxStackBytes;
    /// Called as slices are read (may be empty).
    ProgressFn progress;
};

/// Reads a label stack from `path`: a folder of 2D images (natural sort of names; a `meta.json`
/// sidecar, as write_slice_stack writes it, gives affine and names), a multi-page TIFF, NIfTI-1/2
/// (`.nii`, `.nii.gz`), or NRRD (`.nrrd`, `.seg.nrrd`, `.nhdr`). The result has a complete
/// label table (file names, else the colour table, else "label N" with the fixed palette).
/// Throws Error{InvalidInput} for malformed, truncated or inconsistent files, Error{Unsupported}
/// for valid files strata cannot use, Error{Io} when a file cannot be read. Notes legal oddities
/// (empty stack, dropped channels) in `report`.
SliceStack read_slice_stack(const std::filesystem::path& path,
                            const ReadOptions& options,
                            Report& report);

}  // namespace strata

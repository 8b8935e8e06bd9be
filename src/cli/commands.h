#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"

namespace strata::cli {

/// Options shared by every command that prints.
struct OutputOptions {
    bool json = false;   ///< machine-readable summary on stdout instead of text
    bool quiet = false;  ///< no progress and no text summary
};

/// `strata build`: input stack -> outputs under one folder.
struct BuildOptions {
    std::string input;              ///< file or folder; empty: the built-in phantom
    std::string phantom = "scene";  ///< built-in phantom used when `input` is empty
    std::filesystem::path output_dir = "strata-out";  ///< every output goes under this folder
    std::optional<Vec3> spacing_mm;                   ///< --spacing override (mm along x, y, z)
    std::vector<std::string> labels;                  ///< --labels: values or names; empty: all
    std::filesystem::path color_table;                ///< --color-table file
    std::filesystem::path debug_dir;  ///< --debug-dir: per-slice debug pictures; empty: none
    double tolerance_px = 0.5;        ///< contour simplification tolerance, pixels
    unsigned threads = 0;             ///< worker threads, 0 = all cores
    std::string mesh_format = "ply";  ///< per-object mesh files: ply, obj or stl
    OutputOptions output;
};

/// `strata phantom NAME -o DIR`.
struct PhantomCommandOptions {
    std::string name;
    std::filesystem::path output;            ///< folder (PNG stack) or file ending .nii/.nii.gz
    std::string format = "png";              ///< "png" (stack + meta.json) or "nifti"
    std::optional<double> slice_spacing_px;  ///< resample at this slice spacing (pixels)
    double pixel_mm = 1.0;                   ///< pixel size in mm
    bool list = false;                       ///< list the phantom names and exit
    OutputOptions output_options;
};

/// `strata info FILE`.
struct InfoOptions {
    std::string input;
    std::optional<Vec3> spacing_mm;
    std::filesystem::path color_table;
    OutputOptions output;
};

/// Parses "x,y,z" millimetres; throws Error{InvalidInput} naming the flag.
Vec3 parse_spacing(const std::string& text);

int run_build(const BuildOptions& options);
int run_phantom(const PhantomCommandOptions& options);
int run_info(const InfoOptions& options);

}  // namespace strata::cli

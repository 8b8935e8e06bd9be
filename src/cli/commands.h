#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/types.h"
#include "pipeline/reconstruct.h"
#include "simplify/multires_dag.h"

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
    std::filesystem::path allow_data_file;  ///< --allow-data-file: NRRD data outside its folder
    bool force_label_map = false;  ///< --force-label-map: build an intensity image's values
    /// --grid-step: snap every surface to exactly this grid (px); 0: 1/16, finer when needed
    double grid_step = 0.0;
    std::filesystem::path debug_dir;  ///< --debug-dir: per-slice debug pictures; empty: none
    double tolerance_px = 0.5;        ///< contour simplification tolerance, pixels
    unsigned threads = 0;             ///< worker threads, 0 = all cores
    std::string mesh_format = "ply";  ///< per-object mesh files: ply, obj or stl
    /// target triangles per multiresolution cluster (MultiresOptions' default, measured there)
    std::size_t cluster_triangles = MultiresOptions{}.cluster_triangles;
    /// labels through the stages together (ReconstructOptions::batch_labels)
    std::size_t batch_labels = ReconstructOptions{}.batch_labels;
    /// The progressive scene OUTPUT/model.<format>: "glb" (one file) or "gltf" (JSON, base
    /// buffer and one buffer file per level, for HTTP range requests).
    std::string model_format = "glb";
    /// --lod-levels: OUTPUT/lods.glb (MSFT_lod) with levels at these bounds ("0.5mm,2mm,8mm",
    /// px allowed) or this many levels ("3"); empty: not written.
    std::string lod_levels;
    std::string lod_compression = "draco";  ///< --lod-compression: draco or meshopt
    bool scene_meshopt = false;  ///< --scene-meshopt: scene.glb with EXT_meshopt_compression
    /// Planar contour input (RTSTRUCT): a CT slice file or folder whose grid the contours'
    /// pixel grid is aligned with; empty: a CT beside the RTSTRUCT in its frame, if any.
    std::string reference_ct;
    double contour_pitch_mm = 0.0;  ///< planar contour input: pixel pitch, mm; 0: automatic
    /// OUTPUT/scene.glb with plain float accessors instead of Draco (--scene-uncompressed).
    bool scene_uncompressed = false;
    OutputOptions output;
};

/// `strata extract INPUT --max-error E -o FILE`: one resolution of every object.
struct ExtractOptions {
    std::string input;                ///< label stack (as for build); empty: the built-in phantom
    std::string phantom = "scene";    ///< built-in phantom used when `input` is empty
    std::filesystem::path output;     ///< .ply, .obj, .stl (all objects, label per triangle) or
                                      ///< .glb/.gltf (one node per object)
    std::string max_error = "0.5mm";  ///< bound: "0.5mm", "2px" or a number of mm
    std::optional<Vec3> spacing_mm;
    std::vector<std::string> labels;
    std::filesystem::path color_table;
    std::filesystem::path allow_data_file;
    bool force_label_map = false;
    double tolerance_px = 0.5;
    unsigned threads = 0;
    OutputOptions output_options;
};

/// A declared error bound as the user wrote it: a value in mm or in pixels.
struct ErrorBound {
    double value = 0.5;
    bool in_pixels = false;
};

/// Parses "0.5mm", "2px", "0.5" (mm); throws Error{InvalidInput} naming the flag.
ErrorBound parse_error_bound(const std::string& text);

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
    std::filesystem::path allow_data_file;
    OutputOptions output;
};

/// Parses "x,y,z" millimetres; throws Error{InvalidInput} naming the flag.
Vec3 parse_spacing(const std::string& text);

int run_build(const BuildOptions& options);
int run_phantom(const PhantomCommandOptions& options);
int run_info(const InfoOptions& options);
int run_extract(const ExtractOptions& options);

}  // namespace strata::cli

// The `strata` command: flags -> options, messages and exit codes.
// Exit codes: 0 ok, 1 internal or I/O failure, 2 bad input or usage.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "cli/commands.h"
#include "core/error.h"
#include "core/version.h"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;

int report_error(const std::string& message, int code) {
    std::cerr << "strata: error: " << message << '\n';
    return code;
}

void add_output_flags(CLI::App& app, strata::cli::OutputOptions& output) {
    app.add_flag("--json", output.json, "Print a machine-readable JSON summary on stdout");
    app.add_flag("-q,--quiet", output.quiet, "No progress and no text summary");
}

/// "liver, spleen": CLI11 splits --labels at the commas; the spaces around an entry are not
/// part of the name.
CLI::Validator trimmed() {
    return CLI::Validator(
        [](std::string& text) {
            const std::size_t first = text.find_first_not_of(" \t");
            text = first == std::string::npos
                       ? std::string()
                       : text.substr(first, text.find_last_not_of(" \t") - first + 1);
            return std::string();
        },
        "", "trimmed");
}

void add_data_file_flag(CLI::App& app, std::filesystem::path& file) {
    app.add_option("--allow-data-file", file,
                   "Read this NRRD detached data file although it lies outside the header's "
                   "folder (refused otherwise)");
}

void add_force_label_map_flag(CLI::App& app, bool& force) {
    app.add_flag("--force-label-map", force,
                 "Build every value of the input as an object although the input looks like an "
                 "intensity image (many speckled values) rather than a label map");
}

void add_spacing_flag(CLI::App& app, std::optional<strata::Vec3>& spacing) {
    app.add_option_function<std::string>(
           "--spacing",
           [&spacing](const std::string& text) { spacing = strata::cli::parse_spacing(text); },
           "Voxel spacing in mm as X,Y,Z, replacing the file's")
        ->type_name("X,Y,Z");
}

/// `strata build` and its options, read into `build`.
CLI::App* add_build_command(CLI::App& app, strata::cli::BuildOptions& build) {
    CLI::App* build_cmd = app.add_subcommand(
        "build", "Reconstruct surfaces from a label stack (default: the built-in phantom)");
    build_cmd->add_option("input", build.input,
                          "Folder of slice images, multi-page TIFF, NIfTI (.nii/.nii.gz), NRRD "
                          "(.nrrd/.seg.nrrd/.nhdr), DICOM RTSTRUCT or contour JSON; omitted: the "
                          "built-in phantom");
    build_cmd->add_option("--reference-ct", build.reference_ct,
                          "RTSTRUCT input: CT slice file or folder whose pixel grid the contours' "
                          "grid is aligned with (default: a CT beside the RTSTRUCT, if any)");
    build_cmd
        ->add_option("--contour-pitch", build.contour_pitch_mm,
                     "Planar contour input: pixel pitch in mm of the grid the contours are "
                     "scan-converted on (default: a quarter of the CT pixel)")
        ->check(CLI::Range(0.0, 1e6));
    build_cmd
        ->add_option("--phantom", build.phantom, "Built-in phantom to use when no input is given")
        ->capture_default_str();
    build_cmd->add_option("-o,--output", build.output_dir, "Folder for every output")
        ->capture_default_str();
    add_spacing_flag(*build_cmd, build.spacing_mm);
    build_cmd
        ->add_option("--labels", build.labels,
                     "Labels to reconstruct, by value or name (comma separated); default all")
        ->delimiter(',')
        ->transform(trimmed());
    add_data_file_flag(*build_cmd, build.allow_data_file);
    add_force_label_map_flag(*build_cmd, build.force_label_map);
    build_cmd->add_option("--color-table", build.color_table,
                          "Colour table naming labels: 3D Slicer .ctbl/.txt, ITK-SNAP label "
                          "description, or JSON {\"value\": \"name\"}");
    build_cmd->add_option("--debug-dir", build.debug_dir,
                          "Write debug pictures per slice (contours) into this folder");
    build_cmd
        ->add_option("--tolerance", build.tolerance_px,
                     "Contour simplification tolerance in pixels")
        ->check(CLI::Range(0.0, 100.0))
        ->capture_default_str();
    build_cmd->add_option("--threads", build.threads, "Worker threads (0: all cores)")
        ->capture_default_str();
    build_cmd
        ->add_option("--mesh-format", build.mesh_format,
                     "Format of the per-object full-resolution meshes in OUTPUT/meshes")
        ->check(CLI::IsMember({"ply", "obj", "stl"}))
        ->capture_default_str();
    build_cmd
        ->add_option("--model-format", build.model_format,
                     "Format of the progressive scene OUTPUT/model.*: glb (one file) or gltf (JSON "
                     "plus a buffer file per level, for streaming)")
        ->check(CLI::IsMember({"glb", "gltf"}))
        ->capture_default_str();
    build_cmd->add_flag("--scene-uncompressed", build.scene_uncompressed,
                        "Write OUTPUT/scene.glb without Draco compression (plain float "
                        "accessors, for viewers without a Draco decoder)");
    build_cmd
        ->add_option("--batch-labels", build.batch_labels,
                     "Labels taken through the stages together; each batch's distance fields "
                     "are freed before the next (0: all at once: more memory, same output)")
        ->capture_default_str();
    build_cmd
        ->add_option("--cluster-triangles", build.cluster_triangles,
                     "Target triangles per cluster of the multiresolution model")
        ->check(CLI::Range(std::size_t{16}, std::size_t{1} << 20))
        ->capture_default_str();
    build_cmd
        ->add_option("--grid-step", build.grid_step,
                     "Snap every surface's vertices to exactly this grid (px in x, y; slices in "
                     "z), a power of two from 1/1024 to 1/2; an object that does not snap to it "
                     "fails the build (default: 1/16, halved up to 3 times when needed)")
        ->check(CLI::Validator(
            [](const std::string& text) {
                int exponent = 0;
                const double step = std::strtod(text.c_str(), nullptr);
                const bool ok =
                    std::frexp(step, &exponent) == 0.5 && exponent <= 0 && exponent >= -9;
                return ok ? std::string()
                          : "--grid-step " + text + ": expected a power of two from 1/1024 to 1/2";
            },
            "POWER OF TWO", "grid step"));
    build_cmd->add_option("--lod-levels", build.lod_levels,
                          "Also write OUTPUT/lods.glb (MSFT_lod, _LOD<i> node names): levels at "
                          "these error bounds (e.g. 0.5mm,2mm,8mm) or this many levels (e.g. 3)");
    build_cmd
        ->add_option("--lod-compression", build.lod_compression,
                     "Compression of lods.glb: draco (KHR_draco_mesh_compression) or meshopt "
                     "(EXT_meshopt_compression)")
        ->check(CLI::IsMember({"draco", "meshopt"}))
        ->capture_default_str();
    build_cmd->add_flag("--scene-meshopt", build.scene_meshopt,
                        "Write OUTPUT/scene.glb with EXT_meshopt_compression (16-bit positions per "
                        "object) for pipelines that prefer meshopt's decode speed");
    add_output_flags(*build_cmd, build.output);
    return build_cmd;
}

/// `strata phantom` and its options.
CLI::App* add_phantom_command(CLI::App& app, strata::cli::PhantomCommandOptions& phantom) {
    CLI::App* phantom_cmd =
        app.add_subcommand("phantom", "Write a built-in analytic phantom as a label stack");
    phantom_cmd->add_option("name", phantom.name, "Phantom name (see --list)");
    phantom_cmd->add_option("-o,--output", phantom.output,
                            "Output folder (PNG stack + meta.json) or .nii/.nii.gz file");
    phantom_cmd->add_option("--format", phantom.format, "png or nifti")
        ->check(CLI::IsMember({"png", "nifti"}))
        ->capture_default_str();
    phantom_cmd->add_option("--slice-spacing", phantom.slice_spacing_px,
                            "Resample at this slice spacing, in pixels (default: the phantom's)");
    phantom_cmd->add_option("--pixel-mm", phantom.pixel_mm, "Pixel size in mm")
        ->capture_default_str();
    phantom_cmd->add_flag("--list", phantom.list, "List the phantom names");
    add_output_flags(*phantom_cmd, phantom.output_options);
    return phantom_cmd;
}

/// `strata extract` and its options.
CLI::App* add_extract_command(CLI::App& app, strata::cli::ExtractOptions& extract) {
    CLI::App* extract_cmd = app.add_subcommand(
        "extract",
        "Write one resolution of every object within an error bound, from a label stack "
        "(reconstructed) or from a progressive .glb/.gltf written by strata build");
    extract_cmd->add_option(
        "input", extract.input,
        "Label stack as for `build`, or a strata .glb/.gltf; omitted: the built-in "
        "phantom");
    extract_cmd
        ->add_option("--phantom", extract.phantom, "Built-in phantom to use when no input is given")
        ->capture_default_str();
    extract_cmd
        ->add_option("--max-error", extract.max_error,
                     "Error bound of the slice sections against the input contours: 0.5mm, 2px, "
                     "or a number of mm")
        ->capture_default_str();
    extract_cmd
        ->add_option("-o,--output", extract.output,
                     "Output file: .ply/.obj/.stl (all objects, PLY keeps a label per triangle) or "
                     ".glb/.gltf (one node per object)")
        ->required();
    add_spacing_flag(*extract_cmd, extract.spacing_mm);
    extract_cmd
        ->add_option("--labels", extract.labels,
                     "Labels to extract, by value or name (comma separated); default all")
        ->delimiter(',')
        ->transform(trimmed());
    add_data_file_flag(*extract_cmd, extract.allow_data_file);
    add_force_label_map_flag(*extract_cmd, extract.force_label_map);
    extract_cmd->add_option("--color-table", extract.color_table, "Colour table naming labels");
    extract_cmd
        ->add_option("--tolerance", extract.tolerance_px,
                     "Contour simplification tolerance in pixels")
        ->check(CLI::Range(0.0, 100.0))
        ->capture_default_str();
    extract_cmd->add_option("--threads", extract.threads, "Worker threads (0: all cores)")
        ->capture_default_str();
    add_output_flags(*extract_cmd, extract.output_options);
    return extract_cmd;
}

/// `strata info` and its options.
CLI::App* add_info_command(CLI::App& app, strata::cli::InfoOptions& info) {
    CLI::App* info_cmd = app.add_subcommand(
        "info", "Describe an input stack, or a progressive .glb/.gltf written by strata build");
    info_cmd->add_option("input", info.input, "Input file or folder, or a strata .glb/.gltf")
        ->required();
    add_spacing_flag(*info_cmd, info.spacing_mm);
    info_cmd->add_option("--color-table", info.color_table, "Colour table naming labels");
    add_data_file_flag(*info_cmd, info.allow_data_file);
    add_output_flags(*info_cmd, info.output);
    return info_cmd;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"strata: error-bounded multiresolution surfaces from stacks of segmented slices"};
    app.require_subcommand(1);
    app.set_version_flag("--version", strata::kGenerator);

    strata::cli::BuildOptions build;
    CLI::App* build_cmd = add_build_command(app, build);
    strata::cli::PhantomCommandOptions phantom;
    CLI::App* phantom_cmd = add_phantom_command(app, phantom);
    strata::cli::ExtractOptions extract;
    CLI::App* extract_cmd = add_extract_command(app, extract);
    strata::cli::InfoOptions info;
    CLI::App* info_cmd = add_info_command(app, info);

    try {
        try {
            app.parse(argc, argv);
        } catch (const CLI::CallForHelp& e) {
            return app.exit(e);
        } catch (const CLI::CallForAllHelp& e) {
            return app.exit(e);
        } catch (const CLI::CallForVersion& e) {
            return app.exit(e);
        } catch (const CLI::ParseError& e) {
            std::string message = e.what();
            return report_error(message + " (see `strata --help`)", kExitBadInput);
        }
        if (build_cmd->parsed()) {
            return strata::cli::run_build(build);
        }
        if (phantom_cmd->parsed()) {
            if (!phantom.list && (phantom.name.empty() || phantom.output.empty())) {
                return report_error("phantom: expected NAME and -o OUTPUT (or --list)",
                                    kExitBadInput);
            }
            return strata::cli::run_phantom(phantom);
        }
        if (extract_cmd->parsed()) {
            return strata::cli::run_extract(extract);
        }
        if (info_cmd->parsed()) {
            return strata::cli::run_info(info);
        }
        return report_error("no command given (see `strata --help`)", kExitBadInput);
    } catch (const strata::Error& e) {
        const bool bad_input = e.code() == strata::ErrorCode::InvalidInput ||
                               e.code() == strata::ErrorCode::Unsupported;
        return report_error(e.what(), bad_input ? kExitBadInput : kExitFailure);
    } catch (const std::bad_alloc&) {
        return report_error("out of memory", kExitFailure);
    } catch (const std::exception& e) {
        return report_error(std::string("internal: ") + e.what(), kExitFailure);
    }
}

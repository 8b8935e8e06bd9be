// The `strata` executable end to end: exit codes, messages, outputs.

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/resource.h>
#include <sys/time.h>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mesh/mesh_checks.h"
#include "mesh/mesh_io.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

struct CliRun {
    int exit_code = -1;
    std::string out;
    std::string err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string quote(const std::string& s) {
    std::string q = "'";
    for (char c : s) {
        q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    }
    return q + "'";
}

CliRun run_cli(const std::vector<std::string>& args) {
    static int counter = 0;
    const fs::path dir = test::fresh_temp_dir("cli_run_" + std::to_string(counter++));
    std::string command = quote(test::cli_path().string());
    for (const std::string& a : args) {
        command += " " + quote(a);
    }
    command += " >" + quote((dir / "out").string()) + " 2>" + quote((dir / "err").string()) +
               " </dev/null";
    const int status = std::system(command.c_str());
    CliRun run;
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    run.out = slurp(dir / "out");
    run.err = slurp(dir / "err");
    return run;
}

TEST(Cli, HelpOnEveryCommand) {
    for (const char* command : {"build", "phantom", "info", "extract"}) {
        const CliRun r = run_cli({command, "--help"});
        EXPECT_EQ(r.exit_code, 0) << command << r.err;
        EXPECT_NE(r.out.find("--json"), std::string::npos) << command << r.out;
    }
    EXPECT_EQ(run_cli({"--help"}).exit_code, 0);
}

TEST(Cli, UnknownFlagIsUsageError) {
    const CliRun r = run_cli({"build", "--no-such-flag"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_EQ(r.err.rfind("strata: error: ", 0), 0u) << r.err;
}

TEST(Cli, MissingInputIsBadInput) {
    const CliRun r = run_cli({"info", "/nonexistent/scan.nii.gz"});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("strata: error: /nonexistent/scan.nii.gz: no such file or folder"),
              std::string::npos)
        << r.err;
}

TEST(Cli, BadSpacingIsBadInput) {
    const CliRun r = run_cli(
        {"build", "--spacing", "1,0,1", "-o", test::fresh_temp_dir("cli_bad_spacing").string()});
    EXPECT_EQ(r.exit_code, 2);
    EXPECT_NE(r.err.find("--spacing"), std::string::npos) << r.err;
    const CliRun r2 = run_cli({"build", "--spacing", "1,x,1"});
    EXPECT_EQ(r2.exit_code, 2);
    EXPECT_NE(r2.err.find("'x' is not a number"), std::string::npos) << r2.err;
}

TEST(Cli, CorruptFileIsBadInputNotCrash) {
    const fs::path dir = test::fresh_temp_dir("cli_corrupt");
    std::ofstream(dir / "broken.nii.gz", std::ios::binary) << "\x1f\x8b\x08garbage";
    const CliRun r = run_cli({"info", (dir / "broken.nii.gz").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(r.err.rfind("strata: error: ", 0), 0u) << r.err;
}

TEST(Cli, DefaultBuildUsesBuiltInPhantomAndWritesSummary) {
    const fs::path out = test::fresh_temp_dir("cli_default_build");
    const CliRun r = run_cli({"build", "-o", out.string(), "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json printed = nlohmann::json::parse(r.out);
    const nlohmann::json written = nlohmann::json::parse(slurp(out / "summary.json"));
    EXPECT_EQ(printed, written);
    EXPECT_GE(written.at("input").at("labels").size(), 2u);
    for (const auto& label : written.at("input").at("labels")) {
        EXPECT_GT(label.at("voxels").get<long>(), 0);
        EXPECT_FALSE(label.at("name").get<std::string>().empty());
    }
    // One verified closed surface per object, written as a mesh file, and the scene.
    ASSERT_EQ(written.at("objects").size(), written.at("input").at("labels").size());
    for (const auto& object : written.at("objects")) {
        const auto& surface = object.at("surface");
        EXPECT_TRUE(surface.at("closed_manifold").get<bool>());
        EXPECT_TRUE(surface.at("verified").get<bool>());
        EXPECT_GT(surface.at("triangles").get<long>(), 0);
        EXPECT_GT(surface.at("volume_ml").get<double>(), 0.0);
        const fs::path mesh = surface.at("file").get<std::string>();
        EXPECT_TRUE(fs::exists(mesh)) << mesh;
        EXPECT_EQ(mesh.parent_path(), out / "meshes");
    }
    EXPECT_TRUE(fs::exists(out / "scene.glb"));
    EXPECT_EQ(written.at("scene").get<std::string>(), (out / "scene.glb").string());
    // The progressive scene: every object, its size as reported.
    const auto& model = written.at("model");
    EXPECT_EQ(model.at("file").get<std::string>(), (out / "model.glb").string());
    EXPECT_EQ(model.at("objects"), written.at("objects").size());
    EXPECT_EQ(model.at("total_bytes").get<std::uintmax_t>(), fs::file_size(out / "model.glb"));
    EXPECT_GT(model.at("chunks").get<int>(), 0);
    EXPECT_LT(model.at("base_bytes").get<double>(), model.at("total_bytes").get<double>());
    // The multiresolution ladder: level 0 is the full surface; coarser levels have fewer
    // triangles and no smaller error.
    for (const auto& object : written.at("objects")) {
        const auto& surface = object.at("surface");
        const auto& levels = surface.at("levels");
        ASSERT_GE(levels.size(), 2u) << object.at("name");
        EXPECT_EQ(levels[0].at("triangles"), surface.at("triangles"));
        // contour tolerance 0.5 px plus the quantize stage's largest move of a contour vertex
        // (grid 1/16 px: at most 1/16 / sqrt(2) px); the phantom's pixels are 1 mm
        EXPECT_LE(levels[0].at("error_mm").get<double>(), 0.5 + 0.0625 / std::sqrt(2.0) + 1e-9);
        for (std::size_t i = 1; i < levels.size(); ++i) {
            EXPECT_LT(levels[i].at("triangles").get<long>(),
                      levels[i - 1].at("triangles").get<long>());
            EXPECT_GE(levels[i].at("error_mm").get<double>(),
                      levels[i - 1].at("error_mm").get<double>());
        }
    }
    EXPECT_TRUE(written.at("timings_s").contains("triangulate"));
}

/// CPU time (user + system) of the terminated children this process has waited for.
double children_cpu_seconds() {
    rusage usage{};
    getrusage(RUSAGE_CHILDREN, &usage);
    const auto seconds = [](const timeval& t) {
        return double(t.tv_sec) + 1e-6 * double(t.tv_usec);
    };
    return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

TEST(Cli, SummaryHasTheCpuTimeOfEveryStage) {
    const fs::path out = test::fresh_temp_dir("cli_cpu_timings");
    const double cpu_before = children_cpu_seconds();
    const CliRun r = run_cli({"build", "-o", out.string(), "--threads", "2", "--quiet"});
    const double process_cpu = children_cpu_seconds() - cpu_before;
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json written = nlohmann::json::parse(slurp(out / "summary.json"));
    const auto& wall = written.at("timings_s");
    const auto& cpu = written.at("cpu_timings_s");
    // the same stages, in the same order, each with a non-negative CPU time
    ASSERT_EQ(cpu.size(), wall.size());
    auto w = wall.begin();
    double sum = 0.0;
    for (auto c = cpu.begin(); c != cpu.end(); ++c, ++w) {
        EXPECT_EQ(c.key(), w.key());
        EXPECT_GE(c.value().get<double>(), 0.0) << c.key();
        sum += c.value().get<double>();
    }
    for (const char* stage : {"input", "contours", "triangulate", "simplify", "export"}) {
        EXPECT_TRUE(cpu.contains(stage)) << stage;
    }
    // the stages are parts of the process (clock ticks: 10 ms of slack)
    EXPECT_GT(sum, 0.0);
    EXPECT_LE(sum, process_cpu + 0.01);
}

TEST(Cli, MeshFormatOption) {
    const fs::path out = test::fresh_temp_dir("cli_mesh_format");
    const CliRun r =
        run_cli({"build", "--phantom", "sphere", "-o", out.string(), "--mesh-format", "stl"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(out / "meshes" / "sphere.stl"));
    const CliRun bad = run_cli({"build", "-o", out.string(), "--mesh-format", "vrml"});
    EXPECT_EQ(bad.exit_code, 2);
}

/// The JSON chunk of a .glb file.
nlohmann::json glb_json(const fs::path& path) {
    const std::string bytes = slurp(path);
    std::uint32_t length = 0;
    std::memcpy(&length, bytes.data() + 12, 4);
    return nlohmann::json::parse(bytes.substr(20, length));
}

TEST(Cli, SceneIsDracoCompressedUnlessAskedNotTo) {
    const fs::path out = test::fresh_temp_dir("cli_scene_draco");
    ASSERT_EQ(run_cli({"build", "--phantom", "sphere", "-o", (out / "a").string()}).exit_code, 0);
    ASSERT_EQ(run_cli({"build", "--phantom", "sphere", "-o", (out / "b").string(),
                       "--scene-uncompressed"})
                  .exit_code,
              0);
    const nlohmann::json draco = glb_json(out / "a" / "scene.glb");
    const nlohmann::json plain = glb_json(out / "b" / "scene.glb");
    EXPECT_EQ(draco.value("extensionsRequired", nlohmann::json::array()),
              nlohmann::json::array({"KHR_draco_mesh_compression"}));
    EXPECT_TRUE(
        draco["meshes"][0]["primitives"][0]["extensions"].contains("KHR_draco_mesh_compression"));
    EXPECT_FALSE(plain.contains("extensionsRequired"));
    EXPECT_TRUE(plain["accessors"][0].contains("bufferView"));
    EXPECT_LT(fs::file_size(out / "a" / "scene.glb"), fs::file_size(out / "b" / "scene.glb") / 3);
}

TEST(Cli, ExtractWritesOneResolutionWithinTheBound) {
    const fs::path out = test::fresh_temp_dir("cli_extract");
    const CliRun full = run_cli({"extract", "--phantom", "torus", "--max-error", "0px", "-o",
                                 (out / "full.ply").string(), "--json"});
    ASSERT_EQ(full.exit_code, 0) << full.err;
    const CliRun coarse = run_cli({"extract", "--phantom", "torus", "--max-error", "1.5px", "-o",
                                   (out / "coarse.ply").string(), "--json"});
    ASSERT_EQ(coarse.exit_code, 0) << coarse.err;
    const nlohmann::json f = nlohmann::json::parse(full.out).at("objects").at(0);
    const nlohmann::json c = nlohmann::json::parse(coarse.out).at("objects").at(0);
    EXPECT_EQ(f.at("triangles"), f.at("full_resolution_triangles"));
    EXPECT_LT(c.at("triangles").get<long>(), f.at("triangles").get<long>() / 2);
    EXPECT_LE(c.at("error_px").get<double>(), 1.5);
    // 0 px is below what the full resolution guarantees: the caller is told.
    EXPECT_NE(full.err.find("more than the bound asked for"), std::string::npos) << full.err;
    const TriMesh mesh = read_mesh(out / "coarse.ply");
    EXPECT_EQ(mesh.triangles.size(), c.at("triangles").get<std::size_t>());
    ASSERT_EQ(mesh.labels.size(), mesh.triangles.size());
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_EQ(component_genera(report), std::vector<int>{1});
}

TEST(Cli, ExtractRejectsBadBoundsAndOutputs) {
    const fs::path out = test::fresh_temp_dir("cli_extract_bad");
    const CliRun bound =
        run_cli({"extract", "--max-error", "fine", "-o", (out / "a.ply").string()});
    EXPECT_EQ(bound.exit_code, 2);
    EXPECT_NE(bound.err.find("--max-error: 'fine'"), std::string::npos) << bound.err;
    const CliRun negative =
        run_cli({"extract", "--max-error", "-1mm", "-o", (out / "a.ply").string()});
    EXPECT_EQ(negative.exit_code, 2);
    const CliRun extension = run_cli({"extract", "-o", (out / "a.vrml").string()});
    EXPECT_EQ(extension.exit_code, 2);
    EXPECT_NE(extension.err.find("expected .ply, .obj, .stl, .glb or .gltf"), std::string::npos)
        << extension.err;
    EXPECT_FALSE(fs::exists(out / "a.ply"));
}

// `strata build` writes the progressive model; `info` describes it and `extract` cuts it, with
// the same triangles and bounds as the extraction from the label stack (the file holds the
// model exactly, its errors in mm).
TEST(Cli, InfoAndExtractReadTheProgressiveModel) {
    const fs::path out = test::fresh_temp_dir("cli_progressive");
    const CliRun build = run_cli(
        {"build", "--phantom", "torus", "-o", out.string(), "--quiet", "--model-format", "gltf"});
    ASSERT_EQ(build.exit_code, 0) << build.err;
    const fs::path model = out / "model.gltf";
    ASSERT_TRUE(fs::exists(model));
    ASSERT_TRUE(fs::exists(out / "model.bin"));
    const nlohmann::json summary = nlohmann::json::parse(slurp(out / "summary.json"));
    const CliRun info = run_cli({"info", model.string(), "--json"});
    ASSERT_EQ(info.exit_code, 0) << info.err;
    const nlohmann::json described = nlohmann::json::parse(info.out);
    ASSERT_EQ(described.at("objects").size(), 1u);
    const auto& levels = described.at("objects").at(0).at("levels");
    const auto& built = summary.at("objects").at(0).at("surface").at("levels");
    ASSERT_EQ(levels.size(), built.size());
    for (std::size_t l = 0; l < levels.size(); ++l) {
        EXPECT_EQ(levels[l].at("triangles"), built[l].at("triangles")) << l;
        // the file's bounds are rounded up to 3 significant digits
        const double read_mm = levels[l].at("error_mm").get<double>();
        const double built_mm = built[l].at("error_mm").get<double>();
        EXPECT_GE(read_mm, built_mm * (1.0 - 1e-12)) << l;
        EXPECT_LE(read_mm, built_mm * (1.0 + 1e-2)) << l;
    }
    EXPECT_EQ(described.at("total_bytes"), summary.at("model").at("total_bytes"));

    const double bound_mm = built.back().at("error_mm").get<double>() * 0.6;
    const std::string bound = std::to_string(bound_mm) + "mm";
    const CliRun from_file = run_cli({"extract", model.string(), "--max-error", bound, "-o",
                                      (out / "file.ply").string(), "--json"});
    ASSERT_EQ(from_file.exit_code, 0) << from_file.err;
    const CliRun from_stack = run_cli({"extract", "--phantom", "torus", "--max-error", bound, "-o",
                                       (out / "stack.ply").string(), "--json"});
    ASSERT_EQ(from_stack.exit_code, 0) << from_stack.err;
    const auto f = nlohmann::json::parse(from_file.out).at("objects").at(0);
    const auto s = nlohmann::json::parse(from_stack.out).at("objects").at(0);
    EXPECT_EQ(f.at("triangles"), s.at("triangles"));
    EXPECT_LE(f.at("error_mm").get<double>(), bound_mm);
    EXPECT_GE(f.at("error_mm").get<double>(), s.at("error_mm").get<double>() * (1.0 - 1e-12));
    EXPECT_LE(f.at("error_mm").get<double>(), s.at("error_mm").get<double>() * (1.0 + 1e-2));
    const TriMesh mesh = read_mesh(out / "file.ply");
    EXPECT_EQ(mesh.triangles.size(), f.at("triangles").get<std::size_t>());
    const MeshReport report = check_mesh(mesh);
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_EQ(component_genera(report), std::vector<int>{1});
    EXPECT_GT(report.signed_volume, 0.0);

    // pixel bounds need the stack; broken files are bad input with the place named
    const CliRun px =
        run_cli({"extract", model.string(), "--max-error", "1px", "-o", (out / "px.ply").string()});
    EXPECT_EQ(px.exit_code, 2);
    EXPECT_NE(px.err.find("give the bound in mm"), std::string::npos) << px.err;
    { std::ofstream(out / "broken.glb", std::ios::binary) << "glTF\x02\0\0\0"; }
    const CliRun broken = run_cli({"info", (out / "broken.glb").string()});
    EXPECT_EQ(broken.exit_code, 2);
    EXPECT_NE(broken.err.find("broken.glb"), std::string::npos) << broken.err;
    const CliRun as_stack = run_cli({"build", model.string(), "-o", (out / "again").string()});
    EXPECT_EQ(as_stack.exit_code, 2);
    EXPECT_NE(as_stack.err.find("not a label stack"), std::string::npos) << as_stack.err;
}

TEST(Cli, PhantomPngAndNiftiReadBackWithSameDims) {
    const CliRun list = run_cli({"phantom", "--list"});
    ASSERT_EQ(list.exit_code, 0) << list.err;
    EXPECT_NE(list.out.find("sphere"), std::string::npos);
    const fs::path dir = test::fresh_temp_dir("cli_phantom");
    const CliRun png = run_cli({"phantom", "sphere", "-o", (dir / "png").string(), "--json"});
    ASSERT_EQ(png.exit_code, 0) << png.err;
    const CliRun nii =
        run_cli({"phantom", "sphere", "--format", "nifti", "-o", (dir / "s.nii.gz").string()});
    ASSERT_EQ(nii.exit_code, 0) << nii.err;
    const nlohmann::json expected = nlohmann::json::parse(png.out).at("stack");
    for (const fs::path& input : {dir / "png", dir / "s.nii.gz"}) {
        const CliRun info = run_cli({"info", input.string(), "--json"});
        ASSERT_EQ(info.exit_code, 0) << info.err;
        const nlohmann::json j = nlohmann::json::parse(info.out);
        EXPECT_EQ(j.at("dims"), expected.at("dims")) << input;
        ASSERT_EQ(j.at("labels").size(), expected.at("labels").size()) << input;
        for (std::size_t i = 0; i < j.at("labels").size(); ++i) {
            EXPECT_EQ(j.at("labels")[i].at("voxels"), expected.at("labels")[i].at("voxels"));
        }
    }
    const CliRun unknown = run_cli({"phantom", "no_such_shape", "-o", (dir / "x").string()});
    EXPECT_EQ(unknown.exit_code, 2);
    EXPECT_NE(unknown.err.find("sphere"), std::string::npos) << "should list valid names";
}

TEST(Cli, BuildReadsEverySharedDataInput) {
    const fs::path data = test::shared_data_dir();
    const std::vector<fs::path> inputs = {
        data / "totalsegmentator_abdomen" / "example_seg.nii.gz",
        data / "niivue_torso" / "torsoLabel.nii.gz",
        data / "freesurfer_aparc_aseg",
        data / "terrain_volcano",
        data / "pyradiomics_lung_tumor" / "lung2_label.nrrd",
        data / "pyradiomics_brain_tumor" / "brain1_label.nrrd",
    };
    for (const fs::path& input : inputs) {
        const fs::path out = test::fresh_temp_dir("cli_shared_" + input.stem().string());
        std::vector<std::string> args{"build", input.string(), "-o", out.string(), "--json"};
        if (input.filename() == "freesurfer_aparc_aseg") {
            // 188 labels take minutes under the sanitizers; every label is reconstructed in
            // large_data_surface_test (Release). Three small ones (ventricles, optic chiasm).
            args.insert(args.end(), {"--labels", "2,3,35"});
        }
        const CliRun r = run_cli(args);
        ASSERT_EQ(r.exit_code, 0) << input << ": " << r.err;
        const nlohmann::json j = nlohmann::json::parse(r.out);
        EXPECT_EQ(j.at("input").at("dims").size(), 3u);
        EXPECT_FALSE(j.at("input").at("labels").empty()) << input;
        for (const auto& object : j.at("objects")) {
            EXPECT_TRUE(object.at("surface").at("verified").get<bool>())
                << input << ": " << object.at("name");
        }
        // every object is in the progressive model (the torso's label 9 needs the contour
        // fallback of reconstruct: snapped with edge-midpoint contours it has two vertices
        // 1/256 px apart)
        EXPECT_EQ(j.at("model").at("objects"), j.at("objects").size())
            << input << ": " << j.at("warnings").dump();
        // and no warning says an object was left out of it (the retry's warning once did)
        for (const auto& warning : j.at("warnings")) {
            EXPECT_EQ(warning.at("message").get<std::string>().find("no progressive export"),
                      std::string::npos)
                << input << ": " << warning.dump();
        }
    }
}

TEST(Cli, LabelSelectionByName) {
    const fs::path data = test::shared_data_dir() / "totalsegmentator_abdomen";
    const fs::path out = test::fresh_temp_dir("cli_labels");
    const CliRun r = run_cli({"build", (data / "example_seg.nii.gz").string(), "--color-table",
                              (data / "class_map_total.json").string(), "--labels", "liver,spleen",
                              "-o", out.string(), "--json"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json labels = nlohmann::json::parse(r.out).at("input").at("labels");
    ASSERT_EQ(labels.size(), 2u);
    EXPECT_EQ(labels[0].at("name"), "spleen");
    EXPECT_EQ(labels[1].at("name"), "liver");
    // extract selects the objects of a progressive file the same way: by name or by value
    for (const std::string& selector : {std::string("LIVER"), labels[1].at("value").dump()}) {
        const CliRun one =
            run_cli({"extract", (out / "model.glb").string(), "--labels", selector, "--max-error",
                     "5mm", "-o", (out / "one.ply").string(), "--json"});
        ASSERT_EQ(one.exit_code, 0) << one.err;
        const nlohmann::json objects = nlohmann::json::parse(one.out).at("objects");
        ASSERT_EQ(objects.size(), 1u) << selector;
        EXPECT_EQ(objects[0].at("name"), "liver");
        const TriMesh mesh = read_mesh(out / "one.ply");
        EXPECT_EQ(mesh.triangles.size(), objects[0].at("triangles").get<std::size_t>());
        EXPECT_TRUE(is_closed_manifold(check_mesh(mesh)));
    }
    const CliRun unknown = run_cli({"extract", (out / "model.glb").string(), "--labels", "kidney",
                                    "-o", (out / "none.ply").string()});
    EXPECT_EQ(unknown.exit_code, 2);
    EXPECT_NE(unknown.err.find("matches no object"), std::string::npos) << unknown.err;
    const CliRun bad =
        run_cli({"build", (data / "example_seg.nii.gz").string(), "--labels", "no_such_organ", "-o",
                 test::fresh_temp_dir("cli_labels_bad").string()});
    EXPECT_EQ(bad.exit_code, 2);
    EXPECT_NE(bad.err.find("matches no label"), std::string::npos) << bad.err;
}

}  // namespace
}  // namespace strata

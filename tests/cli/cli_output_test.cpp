// `strata build` options and its output folder (issue 18): --labels with spaces, a missing
// colour table, -o checked before any work, one mesh file per object, the output folder all or
// nothing (staged and swapped in, locked, SIGINT leaves the previous outputs), an object that is
// not on a grid fails the build, an intensity image is not taken for a label map.

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <spawn.h>
#include <string>
#include <sys/file.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "input/slice_stack.h"
#include "input/write_slice_stack.h"
#include "phantom/catalogue.h"
#include "support/test_paths.h"

extern char** environ;

namespace strata {
namespace {

namespace fs = std::filesystem;

struct CliResult {
    int exit_code = -1;
    std::string err;
};

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Starts the CLI with `args` (stdout and stderr into `log_dir`); returns its pid.
pid_t spawn_cli(const std::vector<std::string>& args, const fs::path& log_dir) {
    const std::string cli = test::cli_path().string();
    const std::string out = (log_dir / "out").string();
    const std::string err = (log_dir / "err").string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(cli.c_str()));
    for (const std::string& a : args) {
        argv.push_back(const_cast<char*>(a.c_str()));
    }
    argv.push_back(nullptr);
    pid_t pid = -1;
    EXPECT_EQ(posix_spawn(&pid, cli.c_str(), &actions, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    return pid;
}

int wait_exit(pid_t pid) {
    int status = 0;
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

CliResult run_cli(const std::vector<std::string>& args) {
    static int counter = 0;
    const fs::path dir = test::fresh_temp_dir("cli_output_run_" + std::to_string(counter++));
    CliResult run;
    run.exit_code = wait_exit(spawn_cli(args, dir));
    run.err = slurp(dir / "err");
    return run;
}

/// Every regular file under `dir` (relative path -> bytes).
std::map<std::string, std::string> files_under(const fs::path& dir) {
    std::map<std::string, std::string> files;
    for (const auto& entry : fs::recursive_directory_iterator(dir)) {
        if (entry.is_regular_file()) {
            files[entry.path().lexically_relative(dir).string()] = slurp(entry.path());
        }
    }
    return files;
}

/// Names in `dir` (not recursive).
std::set<std::string> names_in(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
        names.insert(entry.path().filename().string());
    }
    return names;
}

/// A small PNG stack with three box-shaped labels named `names` (values 3, 7, 12).
fs::path three_label_stack(const std::string& name, const std::vector<std::string>& names) {
    SliceStack stack;
    stack.width = 24;
    stack.height = 24;
    stack.depth = 5;
    stack.labels.assign(stack.slice_size() * stack.depth, 0);
    const std::uint16_t values[3] = {3, 7, 12};
    for (std::uint32_t k = 1; k < 4; ++k) {
        for (int b = 0; b < 3; ++b) {
            for (std::uint32_t j = 4; j < 12; ++j) {
                for (int i = 2 + 7 * b; i < 7 + 7 * b; ++i) {
                    stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = values[b];
                }
            }
        }
    }
    for (int b = 0; b < 3; ++b) {
        stack.label_table.push_back({values[b], names[b], palette_color(values[b])});
    }
    const fs::path dir = test::fresh_temp_dir(name);
    write_png_stack(stack, dir);
    return dir;
}

TEST(CliOutput, LabelsWithSpacesAfterCommas) {
    const fs::path input = three_label_stack("cli_labels_spaces_in", {"liver", "spleen", "kidney"});
    const fs::path out = test::fresh_temp_dir("cli_labels_spaces_out");
    const CliResult r =
        run_cli({"build", input.string(), "-o", out.string(), "-q", "--labels", "liver, spleen"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(names_in(out / "meshes"), (std::set<std::string>{"liver.ply", "spleen.ply"}));
}

TEST(CliOutput, MissingColourTableIsBadInputLikeAMissingInput) {
    const fs::path input = three_label_stack("cli_missing_table_in", {"a", "b", "c"});
    const fs::path out = test::fresh_temp_dir("cli_missing_table_out");
    const CliResult r = run_cli({"build", input.string(), "-o", out.string(), "-q", "--color-table",
                                 (out / "absent.ctbl").string()});
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("absent.ctbl: no such colour table file"), std::string::npos) << r.err;
}

TEST(CliOutput, OutputNamingAFileIsRefusedBeforeAnyWork) {
    const fs::path dir = test::fresh_temp_dir("cli_output_file");
    std::ofstream(dir / "taken") << "not a folder";
    // note: the input does not exist either; the output is checked first, before any reading
    const CliResult build =
        run_cli({"build", (dir / "absent.nii").string(), "-o", (dir / "taken").string()});
    EXPECT_EQ(build.exit_code, 2) << build.err;
    EXPECT_NE(build.err.find("-o " + (dir / "taken").string() + ": exists and is not a folder"),
              std::string::npos)
        << build.err;
    EXPECT_EQ(slurp(dir / "taken"), "not a folder");
    fs::create_directories(dir / "folder.ply");
    const CliResult extract =
        run_cli({"extract", (dir / "absent.nii").string(), "-o", (dir / "folder.ply").string()});
    EXPECT_EQ(extract.exit_code, 2) << extract.err;
    EXPECT_NE(extract.err.find("exists and is not a regular file"), std::string::npos)
        << extract.err;
}

/// A greyscale picture (a smooth bright blob plus noise of +-`noise` grey levels) saved as a PNG
/// stack, as if it were a label map.
fs::path greyscale_stack(const std::string& name,
                         std::uint32_t size,
                         std::uint32_t depth,
                         int noise) {
    SliceStack stack;
    stack.width = size;
    stack.height = size;
    stack.depth = depth;
    stack.labels.assign(stack.slice_size() * stack.depth, 0);
    std::uint32_t state = 18;
    for (std::size_t p = 0; p < stack.labels.size(); ++p) {
        const double dx = double(p % size) - size / 2.0;
        const double dy = double((p / size) % size) - size / 2.0;
        const double r2 = (dx * dx + dy * dy) / (size * size / 16.0);
        state = state * 1664525u + 1013904223u;
        const int jitter = int(state >> 16) % (2 * noise + 1) - noise;
        stack.labels[p] = std::uint16_t(std::clamp(int(30 + 200 / (1 + r2)) + jitter, 1, 255));
    }
    const fs::path dir = test::fresh_temp_dir(name);
    write_png_stack(stack, dir);
    return dir;
}

TEST(CliOutput, IntensityImageIsRefusedUnlessForced) {
    // note: 8 slices of 96 x 96 as in issue 18, where 240 "labels" were built in 35 s
    const fs::path picture = greyscale_stack("cli_intensity_in", 96, 8, 12);
    const fs::path out = test::fresh_temp_dir("cli_intensity_out") / "out";
    for (const char* command : {"build", "extract"}) {
        const CliResult r = run_cli(
            {command, picture.string(), "-o", (out / (std::string(command) + ".ply")).string()});
        EXPECT_EQ(r.exit_code, 2) << command << ": " << r.err;
        EXPECT_NE(r.err.find("strata: error: " + picture.string() +
                             ": looks like an intensity image, not a label map"),
                  std::string::npos)
            << r.err;
        EXPECT_NE(r.err.find("--labels"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("--force-label-map"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(out / "model.glb"));
    }
    // the flag forces it (a small picture, so that building its specks stays quick)
    const fs::path small = greyscale_stack("cli_intensity_small_in", 20, 2, 40);
    const CliResult forced = run_cli(
        {"build", small.string(), "-o", (out / "forced").string(), "-q", "--force-label-map"});
    EXPECT_EQ(forced.exit_code, 0) << forced.err;
    const CliResult refused = run_cli({"build", small.string(), "-o", (out / "refused").string()});
    EXPECT_EQ(refused.exit_code, 2) << refused.err;
}

TEST(CliOutput, ObjectNotOnAGridFailsTheBuild) {
    // note: --grid-step 1/2 with no finer retry: the sphere's vertices between slices lie closer
    // than half a pixel, so its surface cannot snap; before, such an object was left out of
    // model.glb with exit 0
    SliceStack sphere = make_phantom("t01_sphere").stack;
    const fs::path input = test::fresh_temp_dir("cli_grid_in");
    write_png_stack(sphere, input);
    const fs::path parent = test::fresh_temp_dir("cli_grid");
    const fs::path out = parent / "out";
    ASSERT_EQ(run_cli({"build", input.string(), "-o", out.string(), "-q"}).exit_code, 0);
    const std::map<std::string, std::string> before = files_under(out);
    ASSERT_TRUE(before.contains("model.glb"));
    const CliResult r =
        run_cli({"build", input.string(), "-o", out.string(), "-q", "--grid-step", "0.5"});
    EXPECT_NE(r.exit_code, 0) << r.err;
    EXPECT_NE(r.err.find("label 1): its surface is not on a grid"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("would share the grid point"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("internal:"), std::string::npos) << r.err;
    // the previous build's outputs are untouched, nothing left beside them
    EXPECT_TRUE(files_under(out) == before);
    EXPECT_EQ(names_in(parent), (std::set<std::string>{"out"}));
    // the grid the default would reach (1/16) is accepted when named; others are refused
    const CliResult fine =
        run_cli({"build", input.string(), "-o", out.string(), "-q", "--grid-step", "0.0625"});
    EXPECT_EQ(fine.exit_code, 0) << fine.err;
    for (const char* bad : {"0.3", "1", "0", "-0.5", "0.0009765625e-1"}) {
        const CliResult refused =
            run_cli({"build", input.string(), "-o", out.string(), "-q", "--grid-step", bad});
        EXPECT_EQ(refused.exit_code, 2) << bad << ": " << refused.err;
        EXPECT_NE(refused.err.find("expected a power of two from 1/1024 to 1/2"), std::string::npos)
            << refused.err;
    }
}

TEST(CliOutput, EveryObjectGetsItsOwnMeshFile) {
    // "a" (3) and "a" (12) would both want a_12 beside the object named "a_12" (7)
    const fs::path input = three_label_stack("cli_unique_in", {"a", "a_12", "a"});
    const fs::path out = test::fresh_temp_dir("cli_unique_out");
    const CliResult r = run_cli({"build", input.string(), "-o", out.string(), "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const nlohmann::json summary = nlohmann::json::parse(slurp(out / "summary.json"));
    std::set<std::string> files;
    for (const auto& object : summary.at("objects")) {
        const std::string file = object.at("surface").at("file").get<std::string>();
        EXPECT_TRUE(files.insert(file).second) << "two objects write " << file;
        EXPECT_TRUE(fs::is_regular_file(file)) << file;
    }
    EXPECT_EQ(files.size(), 3u);
    EXPECT_EQ(names_in(out / "meshes").size(), 3u);
}

TEST(CliOutput, RebuildReplacesTheWholeFolder) {
    const fs::path input = three_label_stack("cli_rebuild_in", {"one", "two", "three"});
    const fs::path parent = test::fresh_temp_dir("cli_rebuild");
    const fs::path out = parent / "out";
    ASSERT_EQ(run_cli({"build", input.string(), "-o", out.string(), "-q"}).exit_code, 0);
    EXPECT_EQ(names_in(out / "meshes").size(), 3u);
    const CliResult r =
        run_cli({"build", input.string(), "-o", out.string(), "-q", "--labels", "two"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(names_in(out / "meshes"), (std::set<std::string>{"two.ply"}));
    // nothing but the output folder (and its lock, released) beside it
    for (const std::string& name : names_in(parent)) {
        EXPECT_TRUE(name == "out") << "left beside the output: " << name;
    }
    // a folder holding other files is not replaced
    const fs::path foreign = parent / "foreign";
    fs::create_directories(foreign);
    std::ofstream(foreign / "notes.txt") << "mine";
    const CliResult refused = run_cli({"build", input.string(), "-o", foreign.string(), "-q"});
    EXPECT_EQ(refused.exit_code, 2) << refused.err;
    EXPECT_NE(refused.err.find("no summary.json"), std::string::npos) << refused.err;
    EXPECT_EQ(names_in(foreign), (std::set<std::string>{"notes.txt"}));
}

TEST(CliOutput, ConcurrentBuildIntoTheSameFolderIsRefused) {
    const fs::path input = three_label_stack("cli_lock_in", {"one", "two", "three"});
    const fs::path parent = test::fresh_temp_dir("cli_lock");
    // hold the lock as a running build would
    const int fd = ::open((parent / ".out.strata-lock").c_str(), O_RDWR | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
    const CliResult r = run_cli({"build", input.string(), "-o", (parent / "out").string(), "-q"});
    ::close(fd);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find("another strata build is writing this folder"), std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(parent / "out"));
}

TEST(CliOutput, InterruptedBuildLeavesThePreviousOutputs) {
    const fs::path parent = test::fresh_temp_dir("cli_sigint");
    const fs::path out = parent / "out";
    // note: the previous build differs from the interrupted one (OBJ meshes, PLY then), so a
    // partly written new build shows even though builds are deterministic
    std::map<std::string, std::string> before;
    bool interrupted = false;
    for (int attempt = 0; attempt < 5 && !interrupted; ++attempt) {
        ASSERT_EQ(run_cli({"build", "-o", out.string(), "-q", "--mesh-format", "obj"}).exit_code,
                  0);
        before = files_under(out);
        ASSERT_FALSE(before.empty());
        // SIGINT as soon as the new build has written its first output file (anywhere beside
        // or in the output folder): the outputs are being written then
        const auto start = fs::file_time_type::clock::now();
        const pid_t pid =
            spawn_cli({"build", "-o", out.string(), "-q"}, test::fresh_temp_dir("cli_sigint_log"));
        bool written = false;
        int status = 0;
        while (!written && waitpid(pid, &status, WNOHANG) == 0) {
            std::error_code ec;
            for (auto it = fs::recursive_directory_iterator(parent, ec);
                 !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
                std::error_code time_ec;
                if (it->is_regular_file(time_ec) && it->path().filename() != "out" &&
                    it->path().filename() != "err" &&
                    fs::last_write_time(it->path(), time_ec) > start &&
                    it->path().string().find("/meshes/") != std::string::npos) {
                    written = true;
                    break;
                }
            }
        }
        if (!written) {
            continue;  // the build ended before the poll saw a file: try again
        }
        ::kill(pid, SIGINT);
        wait_exit(pid);
        const auto after = files_under(out);
        if (after == before) {
            interrupted = true;
            continue;
        }
        // note: the signal came after the swap: then the folder holds the whole new build (PLY
        // meshes, each listed in its summary), never a mix with the previous one
        const nlohmann::json summary = nlohmann::json::parse(after.at("summary.json"));
        std::set<std::string> listed;
        for (const auto& object : summary.at("objects")) {
            listed.insert(fs::path(object.at("surface").at("file").get<std::string>())
                              .lexically_relative(out)
                              .string());
        }
        for (const auto& [name, bytes] : after) {
            if (name.starts_with("meshes/")) {
                EXPECT_TRUE(listed.count(name) == 1 && name.ends_with(".ply")) << name;
            }
        }
    }
    ASSERT_TRUE(interrupted) << "no build could be interrupted while writing";
    for (const auto& entry : fs::recursive_directory_iterator(parent)) {
        const std::string name = entry.path().filename().string();
        EXPECT_EQ(name.find(".tmp"), std::string::npos) << entry.path();
        EXPECT_EQ(name.find("strata-tmp"), std::string::npos) << entry.path();
    }
}

}  // namespace
}  // namespace strata

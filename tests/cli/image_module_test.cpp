// The OpenImageIO module (src/input/detail/image_module.h): the strata program does not load
// OpenImageIO at start, NIfTI inputs build without the module, and 2D image inputs name the
// missing module instead of crashing.

#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <spawn.h>
#include <string>
#include <sys/wait.h>
#include <vector>

#include <gtest/gtest.h>

#include "input/slice_stack.h"
#include "input/write_nifti.h"
#include "input/write_slice_stack.h"
#include "support/test_paths.h"

extern char** environ;

namespace strata {
namespace {

namespace fs = std::filesystem;

struct StrataRun {
    int exit_code = -1;
    std::string out;
    std::string err;
};

/// Runs the strata program with `args` and `extra_env` ("NAME=value") added to the environment.
StrataRun run_strata(const std::vector<std::string>& args,
                     const std::vector<std::string>& extra_env,
                     const std::string& name) {
    const fs::path dir = test::fresh_temp_dir(name);
    const std::string cli = test::cli_path().string();
    const std::string out = (dir / "out").string();
    const std::string err = (dir / "err").string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv{const_cast<char*>(cli.c_str())};
    for (const std::string& a : args) {
        argv.push_back(const_cast<char*>(a.c_str()));
    }
    argv.push_back(nullptr);
    std::vector<std::string> env_strings(extra_env);
    for (char** e = environ; *e != nullptr; ++e) {
        env_strings.emplace_back(*e);
    }
    std::vector<char*> envp;
    for (std::string& e : env_strings) {
        envp.push_back(e.data());
    }
    envp.push_back(nullptr);
    pid_t pid = -1;
    EXPECT_EQ(posix_spawn(&pid, cli.c_str(), &actions, nullptr, argv.data(), envp.data()), 0);
    posix_spawn_file_actions_destroy(&actions);
    int status = 0;
    waitpid(pid, &status, 0);
    StrataRun run;
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    run.out = test::read_file(out);
    run.err = test::read_file(err);
    return run;
}

/// A 16 x 16 x 4 stack with one box label.
SliceStack box_stack() {
    SliceStack stack;
    stack.width = 16;
    stack.height = 16;
    stack.depth = 4;
    stack.labels.assign(stack.slice_size() * stack.depth, 0);
    for (std::uint32_t k = 1; k < 3; ++k) {
        for (std::uint32_t j = 4; j < 11; ++j) {
            for (std::uint32_t i = 3; i < 12; ++i) {
                stack.labels[(std::size_t(k) * stack.height + j) * stack.width + i] = 1;
            }
        }
    }
    return stack;
}

TEST(ImageModule, ProgramStartsWithoutOpenImageIO) {
    // The dynamic loader lists what the program loads at start (as ldd does) and exits.
    const StrataRun run =
        run_strata({"--version"}, {"LD_TRACE_LOADED_OBJECTS=1"}, "image_module_ldd");
    ASSERT_EQ(run.exit_code, 0) << run.err;
    EXPECT_NE(run.out.find("libc.so"), std::string::npos) << run.out;
    EXPECT_NE(run.out.find("libtiff"), std::string::npos) << run.out;
    EXPECT_EQ(run.out.find("OpenImageIO"), std::string::npos) << run.out;
}

TEST(ImageModule, NiftiBuildsWithoutTheModulePngNamesIt) {
    const fs::path dir = test::fresh_temp_dir("image_module_inputs");
    const SliceStack stack = box_stack();
    write_nifti(stack, dir / "box.nii");
    write_png_stack(stack, dir / "png");
    const std::string absent = "STRATA_IMAGE_MODULE=" + (dir / "absent.so").string();

    const StrataRun nifti =
        run_strata({"build", (dir / "box.nii").string(), "-o", (dir / "out_nifti").string(), "-q"},
                   {absent}, "image_module_nifti");
    EXPECT_EQ(nifti.exit_code, 0) << nifti.err;
    EXPECT_TRUE(fs::exists(dir / "out_nifti" / "model.glb"));

    const StrataRun png =
        run_strata({"build", (dir / "png").string(), "-o", (dir / "out_png").string(), "-q"},
                   {absent}, "image_module_png");
    EXPECT_EQ(png.exit_code, 1) << png.err;
    EXPECT_NE(png.err.find("strata: error: "), std::string::npos) << png.err;
    EXPECT_NE(png.err.find("libstrata_image_io.so not found"), std::string::npos) << png.err;
    EXPECT_NE(png.err.find("absent.so"), std::string::npos) << png.err;
    EXPECT_FALSE(fs::exists(dir / "out_png" / "model.glb"));

    // With the module where the program looks for it, the same PNG stack builds.
    const StrataRun found =
        run_strata({"build", (dir / "png").string(), "-o", (dir / "out_found").string(), "-q"}, {},
                   "image_module_found");
    EXPECT_EQ(found.exit_code, 0) << found.err;
    EXPECT_TRUE(fs::exists(dir / "out_found" / "model.glb"));
}

}  // namespace
}  // namespace strata

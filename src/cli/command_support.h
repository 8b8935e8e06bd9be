#pragma once

// What the `strata` commands share (commands.cpp: build and phantom; inspect_commands.cpp:
// extract and info); internal to the strata program.

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <unistd.h>
#include <vector>

#include "core/progress.h"
#include "core/report.h"
#include "exporters/scene_gltf.h"
#include "input/slice_stack.h"

namespace strata::cli {

using Clock = std::chrono::steady_clock;

/// Progress on a terminal: one line on stderr rewritten in place, at most ~10 times a second:
/// the stage, i of n, the time since the start, and an estimate of the stage's remaining time
/// (from its rate so far; the largest labels go first, so it errs long).
class TerminalProgress {
public:
    explicit TerminalProgress(bool quiet) : enabled_(!quiet && ::isatty(STDERR_FILENO) != 0) {}
    ~TerminalProgress() { finish(); }

    ProgressFn callback() {
        if (!enabled_) {
            return {};
        }
        return [this](std::string_view what, std::size_t done, std::size_t total) {
            const auto now = Clock::now();
            if (what != stage_) {
                stage_ = what;
                stage_start_ = now;
            }
            if (done < total && now - last_ < std::chrono::milliseconds(100)) {
                return;
            }
            last_ = now;
            const double elapsed = std::chrono::duration<double>(now - start_).count();
            const double in_stage = std::chrono::duration<double>(now - stage_start_).count();
            char estimate[64] = "";
            if (done > 0 && done < total && in_stage > 1.0) {
                std::snprintf(estimate, sizeof estimate, ", about %.0f s left in this stage",
                              in_stage * double(total - done) / double(done));
            }
            // note: \x1b[K clears what a longer earlier line left
            std::fprintf(stderr, "\rstrata: %.*s %zu of %zu, %.1f s%s\x1b[K",
                         static_cast<int>(what.size()), what.data(), done, total, elapsed,
                         estimate);
            std::fflush(stderr);
            open_ = true;
        };
    }
    void finish() {
        if (open_) {
            std::fputc('\n', stderr);
            open_ = false;
        }
    }

private:
    bool enabled_;
    bool open_ = false;
    Clock::time_point start_ = Clock::now();
    Clock::time_point last_{};
    std::string stage_;
    Clock::time_point stage_start_ = start_;
};

/// The stack a command works on: the input file or folder, else the named phantom; spacing
/// override and label selection applied.
SliceStack load_stack(const std::string& input,
                      const std::string& phantom,
                      const std::optional<Vec3>& spacing_mm,
                      const std::filesystem::path& color_table,
                      const std::vector<std::string>& labels,
                      TerminalProgress& progress,
                      Report& report,
                      const std::filesystem::path& allowed_data_file = {},
                      bool force_label_map = false);

/// Name and colour of a label from the stack's table (a generated name when absent).
SceneObject scene_object(const SliceStack& stack, std::uint16_t value);

/// True for a .glb / .gltf path (strata's progressive files as input).
bool is_gltf_path(const std::string& input);

}  // namespace strata::cli

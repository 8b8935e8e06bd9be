#pragma once

#include <filesystem>

namespace strata::cli {

/// The file that makes a folder a strata output folder (the build summary, written last).
inline constexpr char kSummaryFileName[] = "summary.json";

/// The output folder of `strata build`, all or nothing: every output is written into a hidden
/// sibling folder (`.NAME.strata-tmp-PID`), which replaces the output folder in one step when
/// the build is done (an atomic exchange of the two folders, then the old one is removed). A
/// failure, an exception or SIGINT/SIGTERM/SIGHUP before that removes the staging folder and
/// leaves the previous outputs untouched. A lock file beside the folder (`.NAME.strata-lock`,
/// flock) keeps two builds from writing the same folder at once.
class StagedOutputFolder {
public:
    /// Checks `final_dir` before any work: it must be a folder or absent, and an existing
    /// non-empty folder must hold a previous build (its summary.json), so that nothing else is
    /// replaced. Takes the lock, removes stale staging folders of killed runs, creates the
    /// staging folder and starts the signal watcher. Throws Error{InvalidInput} (exit 2) naming
    /// the folder and what was expected, Error{Io} when the folder cannot be created.
    explicit StagedOutputFolder(std::filesystem::path final_dir);
    /// Removes the staging folder unless committed; releases the lock.
    ~StagedOutputFolder();
    StagedOutputFolder(const StagedOutputFolder&) = delete;
    StagedOutputFolder& operator=(const StagedOutputFolder&) = delete;

    /// Where to write: the staging folder.
    const std::filesystem::path& path() const { return staging_; }
    /// The output folder the outputs will have once committed.
    const std::filesystem::path& final_path() const { return final_; }
    /// `file` (under the final folder) mapped into the staging folder; other paths unchanged.
    std::filesystem::path staged(const std::filesystem::path& file) const;

    /// Puts the staging folder in place of the output folder; the previous outputs are removed.
    void commit();

private:
    std::filesystem::path final_;
    std::filesystem::path staging_;
    std::filesystem::path lock_file_;
    int lock_fd_ = -1;
};

}  // namespace strata::cli

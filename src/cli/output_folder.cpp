#include "cli/output_folder.h"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <mutex>
#include <pthread.h>
#include <string>
#include <sys/file.h>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

#include "core/error.h"

namespace strata::cli {

namespace {

namespace fs = std::filesystem;

// The signal watcher: SIGINT, SIGTERM and SIGHUP are blocked in every thread (workers inherit
// the mask) and taken by one thread with sigwait, which removes the staging folder under the
// mutex that commit() holds, then ends the process as the signal would have.
std::mutex g_mutex;
fs::path g_staging;  // guarded by g_mutex; empty once committed or removed

sigset_t watched_signals() {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGHUP);
    return set;
}

void start_signal_watcher() {
    static std::once_flag once;
    std::call_once(once, [] {
        const sigset_t set = watched_signals();
        pthread_sigmask(SIG_BLOCK, &set, nullptr);
        std::thread([set] {
            int signal_number = 0;
            if (sigwait(&set, &signal_number) != 0) {
                return;
            }
            {
                std::lock_guard<std::mutex> lock(g_mutex);
                if (!g_staging.empty()) {
                    // note: workers may still be writing: the folder is moved aside and a file
                    // put in its place, so that they cannot create it again while it is removed
                    std::error_code ec;
                    const fs::path trash = g_staging.string() + "-interrupted";
                    fs::rename(g_staging, trash, ec);
                    const int blocker =
                        ::open(g_staging.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0600);
                    fs::remove_all(ec ? g_staging : trash, ec);
                    if (blocker >= 0) {
                        ::close(blocker);
                        ::unlink(g_staging.c_str());
                    }
                    g_staging.clear();
                }
            }
            std::signal(signal_number, SIG_DFL);
            const sigset_t one = [&] {
                sigset_t s;
                sigemptyset(&s);
                sigaddset(&s, signal_number);
                return s;
            }();
            pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
            std::raise(signal_number);
            std::_Exit(128 + signal_number);
        }).detach();
    });
}

std::string hidden_sibling(const fs::path& dir, const std::string& suffix) {
    return "." + dir.filename().string() + suffix;
}

}  // namespace

StagedOutputFolder::StagedOutputFolder(fs::path final_dir) {
    // note: "out/" has an empty filename; lexically_normal + parent of a trailing slash
    final_dir = final_dir.lexically_normal();
    if (final_dir.has_filename() == false) {
        final_dir = final_dir.parent_path();
    }
    if (final_dir.empty() || final_dir == "." || final_dir == "..") {
        final_dir = fs::absolute(final_dir).lexically_normal();
        if (!final_dir.has_filename()) {
            final_dir = final_dir.parent_path();
        }
    }
    final_ = final_dir;
    const std::string where = "-o " + final_.string();
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(final_, ec);
    if (status.type() != fs::file_type::not_found) {
        if (ec) {
            throw Error(ErrorCode::InvalidInput, where + ": " + ec.message());
        }
        if (status.type() != fs::file_type::directory) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": exists and is not a folder (a file or link), expected a "
                            "new folder or the output folder of an earlier build");
        }
        const bool is_empty = fs::is_empty(final_, ec);
        if (!ec && !is_empty && !fs::exists(final_ / kSummaryFileName, ec)) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": the folder holds files but no summary.json of an earlier build; "
                            "a build replaces its whole output folder, so give a new or empty "
                            "folder");
        }
    }
    fs::path parent = final_.parent_path();
    if (parent.empty()) {
        parent = ".";
    }
    fs::create_directories(parent, ec);
    if (ec) {
        throw Error(ErrorCode::Io,
                    where + ": cannot create " + parent.string() + ": " + ec.message());
    }

    lock_file_ = parent / hidden_sibling(final_, ".strata-lock");
    for (;;) {
        lock_fd_ = ::open(lock_file_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (lock_fd_ < 0) {
            throw Error(ErrorCode::Io, where + ": cannot create the lock file " +
                                           lock_file_.string() + ": " + std::strerror(errno));
        }
        if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
            const int error = errno;
            ::close(lock_fd_);
            lock_fd_ = -1;
            if (error == EWOULDBLOCK) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": another strata build is writing this folder (lock " +
                                lock_file_.string() +
                                " held); wait for it to finish or give another folder");
            }
            throw Error(ErrorCode::Io, where + ": cannot lock " + lock_file_.string() + ": " +
                                           std::strerror(error));
        }
        // note: the lock file may have been removed by the previous holder after we opened it
        struct stat held {};
        struct stat named {};
        if (::fstat(lock_fd_, &held) == 0 && ::stat(lock_file_.c_str(), &named) == 0 &&
            held.st_ino == named.st_ino && held.st_dev == named.st_dev) {
            break;
        }
        ::close(lock_fd_);
        lock_fd_ = -1;
    }

    // Staging folders of runs that were killed (SIGKILL, power loss): ours now, so removed.
    const std::string stale_prefix = hidden_sibling(final_, ".strata-tmp-");
    for (auto it = fs::directory_iterator(parent, ec); !ec && it != fs::directory_iterator();
         it.increment(ec)) {
        if (it->path().filename().string().rfind(stale_prefix, 0) == 0) {
            std::error_code remove_ec;
            fs::remove_all(it->path(), remove_ec);
        }
    }
    staging_ = parent / (stale_prefix + std::to_string(::getpid()));
    fs::create_directory(staging_, ec);
    if (ec) {
        ::close(lock_fd_);
        throw Error(ErrorCode::Io, where + ": cannot create the staging folder " +
                                       staging_.string() + ": " + ec.message());
    }
    start_signal_watcher();
    std::lock_guard<std::mutex> lock(g_mutex);
    g_staging = staging_;
}

StagedOutputFolder::~StagedOutputFolder() {
    {
        std::lock_guard<std::mutex> lock(g_mutex);
        if (!g_staging.empty()) {
            std::error_code ec;
            fs::remove_all(g_staging, ec);
            g_staging.clear();
        }
    }
    if (lock_fd_ >= 0) {
        ::unlink(lock_file_.c_str());
        ::close(lock_fd_);
    }
}

fs::path StagedOutputFolder::staged(const fs::path& file) const {
    const fs::path relative =
        fs::absolute(file).lexically_normal().lexically_relative(fs::absolute(final_));
    if (relative.empty() || *relative.begin() == "..") {
        return file;
    }
    return relative == "." ? staging_ : staging_ / relative;
}

void StagedOutputFolder::commit() {
    std::lock_guard<std::mutex> lock(g_mutex);
    if (g_staging.empty()) {
        throw Error(ErrorCode::Io, final_.string() + ": the staging folder is gone (interrupted)");
    }
    std::error_code ec;
    if (!fs::exists(final_, ec)) {
        if (::rename(staging_.c_str(), final_.c_str()) != 0) {
            throw Error(ErrorCode::Io, final_.string() + ": cannot move the outputs in place: " +
                                           std::strerror(errno));
        }
        g_staging.clear();
        return;
    }
    // note: renameat2(RENAME_EXCHANGE) swaps the two folders in one step; the staging name then
    // holds the previous outputs, removed afterwards
    if (::renameat2(AT_FDCWD, staging_.c_str(), AT_FDCWD, final_.c_str(), RENAME_EXCHANGE) == 0) {
        fs::remove_all(staging_, ec);
        g_staging.clear();
        return;
    }
    // Fallback (a file system without the exchange): two renames, the old folder kept until the
    // new one is in place.
    const fs::path old = staging_.string() + "-old";
    if (::rename(final_.c_str(), old.c_str()) != 0) {
        throw Error(ErrorCode::Io, final_.string() + ": cannot replace the previous outputs: " +
                                       std::strerror(errno));
    }
    if (::rename(staging_.c_str(), final_.c_str()) != 0) {
        const int error = errno;
        ::rename(old.c_str(), final_.c_str());
        throw Error(ErrorCode::Io, final_.string() + ": cannot move the outputs in place: " +
                                       std::strerror(error));
    }
    g_staging.clear();
    fs::remove_all(old, ec);
}

}  // namespace strata::cli

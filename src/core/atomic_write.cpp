#include "core/atomic_write.h"

#include <atomic>
#include <cstdio>
#include <fstream>
#include <string>
#include <system_error>
#include <unistd.h>

#include "core/error.h"

namespace strata {

namespace {

std::filesystem::path temporary_name(const std::filesystem::path& path) {
    static std::atomic<unsigned> counter{0};
    std::filesystem::path tmp = path;
    tmp += ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    return tmp;
}

}  // namespace

void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(std::ostream&)>& write) {
    std::error_code ec;
    if (path.has_parent_path()) {
        std::filesystem::create_directories(path.parent_path(), ec);
        if (ec) {
            throw Error(ErrorCode::Io, "cannot create folder " + path.parent_path().string() +
                                           ": " + ec.message());
        }
    }
    const std::filesystem::path tmp = temporary_name(path);
    try {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) {
            throw Error(ErrorCode::Io, "cannot open " + tmp.string() + " for writing");
        }
        write(out);
        out.flush();
        if (!out) {
            throw Error(ErrorCode::Io, "writing " + tmp.string() + " failed (disk full?)");
        }
        out.close();
        if (out.fail()) {
            throw Error(ErrorCode::Io, "closing " + tmp.string() + " failed");
        }
    } catch (...) {
        std::filesystem::remove(tmp, ec);
        throw;
    }
    std::filesystem::rename(tmp, path, ec);
    if (ec) {
        std::error_code ignored;
        std::filesystem::remove(tmp, ignored);
        throw Error(ErrorCode::Io,
                    "cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message());
    }
}

void write_file_atomically(const std::filesystem::path& path, std::string_view bytes) {
    write_file_atomically(path, [&](std::ostream& out) {
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    });
}

}  // namespace strata

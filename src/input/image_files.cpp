// The OpenImageIO module, opened with dlopen on first use (see detail/image_module.h for why),
// and the image calls through it.

#include "input/detail/image_files.h"

#include <array>
#include <cstdlib>
#include <dlfcn.h>
#include <mutex>
#include <system_error>
#include <vector>

#include "core/error.h"

namespace strata::detail {

namespace {

namespace fs = std::filesystem;

constexpr const char* kModuleName = "libstrata_image_io.so";
constexpr std::size_t kErrorSize = 2048;

/// Where the module may be, in order: STRATA_IMAGE_MODULE (a file; the only place looked when
/// set), beside the running program (the build tree), the installed module folder relative to
/// the program (bin/ -> lib/strata/), and the build tree's folder (test programs in build/tests).
std::vector<fs::path> module_candidates() {
    if (const char* forced = std::getenv("STRATA_IMAGE_MODULE"); forced != nullptr) {
        return {fs::path(forced)};
    }
    std::vector<fs::path> paths;
    std::error_code ec;
    const fs::path program = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
        paths.push_back(program.parent_path() / kModuleName);
        paths.push_back(program.parent_path() / STRATA_IMAGE_MODULE_INSTALL_DIR / kModuleName);
    }
    paths.push_back(fs::path(STRATA_IMAGE_MODULE_BUILD_DIR) / kModuleName);
    return paths;
}

const StrataImageApi* load_module(std::string& failure) {
    std::string tried;
    for (const fs::path& path : module_candidates()) {
        std::error_code ec;
        if (!fs::is_regular_file(path, ec)) {
            tried += (tried.empty() ? "" : ", ") + path.string();
            continue;
        }
        void* library = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (library == nullptr) {
            failure = path.string() + " cannot be loaded: " + dlerror();
            return nullptr;
        }
        using Entry = const StrataImageApi* (*)();
        auto entry = reinterpret_cast<Entry>(dlsym(library, "strata_image_api"));
        const StrataImageApi* api = entry != nullptr ? entry() : nullptr;
        if (api == nullptr || api->version != kStrataImageApiVersion) {
            failure = path.string() + " is not strata's image module of this version (interface " +
                      std::to_string(kStrataImageApiVersion) + ")";
            return nullptr;
        }
        return api;
    }
    failure = std::string(kModuleName) + " not found (looked at " + tried + ")";
    return nullptr;
}

/// The module, loaded once; throws Error (Io) naming `file` and why when it is unavailable.
const StrataImageApi& image_api(const fs::path& file) {
    static std::once_flag once;
    static const StrataImageApi* api = nullptr;
    static std::string failure;
    std::call_once(once, [] { api = load_module(failure); });
    if (api == nullptr) {
        throw Error(ErrorCode::Io, file.string() +
                                       ": 2D image files (PNG, JPEG, BMP, ...) need strata's "
                                       "OpenImageIO module: " +
                                       failure +
                                       "; reinstall strata, or give the slices as NIfTI, NRRD or "
                                       "TIFF, which do not need it");
    }
    return *api;
}

}  // namespace

ImageFile::ImageFile(const fs::path& file) : api_(&image_api(file)) {
    std::array<char, kErrorSize> error{};
    handle_ = api_->open(file.c_str(), &spec_, error.data(), error.size());
    if (handle_ == nullptr) {
        std::string message = error.data();
        if (message.empty()) {
            message = "unknown format or unreadable file";
        }
        throw Error(ErrorCode::InvalidInput, file.string() + ": cannot read image: " + message);
    }
}

ImageFile::~ImageFile() {
    api_->close(handle_);
}

bool ImageFile::read(int page, int channels, bool sixteen_bit, void* pixels, std::string& error) {
    std::array<char, kErrorSize> message{};
    const bool ok = api_->read(handle_, page, channels, sixteen_bit ? 1 : 0, pixels, message.data(),
                               message.size()) != 0;
    if (!ok) {
        error = message.data();
    }
    return ok;
}

bool write_png_file(const fs::path& file,
                    const void* pixels,
                    std::uint32_t width,
                    std::uint32_t height,
                    int channels,
                    bool sixteen_bit,
                    std::string& error) {
    const StrataImageApi& api = image_api(file);
    std::array<char, kErrorSize> message{};
    const bool ok =
        api.write_png(file.c_str(), pixels, static_cast<int>(width), static_cast<int>(height),
                      channels, sixteen_bit ? 1 : 0, message.data(), message.size()) != 0;
    if (!ok) {
        error = message.data();
    }
    return ok;
}

}  // namespace strata::detail

#pragma once

// 2D image files (PNG, JPEG, BMP, ...) through the OpenImageIO module (detail/image_module.h),
// which is loaded on the first call; internal to strata_input.

#include <cstdint>
#include <filesystem>
#include <string>

#include "input/detail/image_module.h"

namespace strata::detail {

/// One image opened for reading; throws Error (InvalidInput) naming the file when it cannot be
/// opened, and Error (Io) when the module is missing.
class ImageFile {
public:
    explicit ImageFile(const std::filesystem::path& file);
    ~ImageFile();
    ImageFile(const ImageFile&) = delete;
    ImageFile& operator=(const ImageFile&) = delete;

    const StrataImageSpec& spec() const { return spec_; }
    /// Reads subimage `page` with `channels` channels of 8-bit (`sixteen_bit` false) or 16-bit
    /// values into `pixels`; false with the decoder's reason in `error` on failure.
    bool read(int page, int channels, bool sixteen_bit, void* pixels, std::string& error);

private:
    const StrataImageApi* api_ = nullptr;
    void* handle_ = nullptr;
    StrataImageSpec spec_{};
};

/// Writes `pixels` (`channels` 8- or 16-bit values per pixel) as a PNG at `file` (the format is
/// chosen by the extension); false with the writer's reason in `error`. Throws Error (Io) when
/// the module is missing.
bool write_png_file(const std::filesystem::path& file,
                    const void* pixels,
                    std::uint32_t width,
                    std::uint32_t height,
                    int channels,
                    bool sixteen_bit,
                    std::string& error);

}  // namespace strata::detail

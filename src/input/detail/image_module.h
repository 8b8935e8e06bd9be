#pragma once

// The OpenImageIO module's interface: libstrata_image_io.so holds the only code that calls
// OpenImageIO, and strata opens it with dlopen the first time an input or output needs a 2D image
// format (PNG, JPEG, BMP, ...). OpenImageIO pulls in about 260 shared libraries whose relocation
// costs every process about 0.25 s of CPU; NIfTI, NRRD, TIFF and contour inputs never pay it.
// Plain C types only, so the module and strata share no C++ objects, exceptions or allocators.

#include <cstddef>

extern "C" {

/// Pixel types the module reports (anything else is kStrataPixelOther, named in `format_name`).
enum StrataPixelType : int { kStrataPixelOther = 0, kStrataPixelU8 = 8, kStrataPixelU16 = 16 };

/// The header of an opened image.
struct StrataImageSpec {
    int width;
    int height;
    int depth;
    int channels;
    int pixel_type;        ///< a StrataPixelType
    char format_name[32];  ///< OpenImageIO's name of the pixel type ("float", "uint8", ...)
};

/// The module's functions. Each returns 0 / nullptr on failure with the reason in `error`
/// (`error_size` bytes, NUL-terminated); none throws.
struct StrataImageApi {
    int version;  ///< kStrataImageApiVersion
    /// Opens an image for reading and fills `spec`; the handle is released by `close`.
    void* (*open)(const char* path, StrataImageSpec* spec, char* error, std::size_t error_size);
    /// Reads subimage `page` with `channels` channels as 8-bit (`sixteen_bit` 0) or 16-bit values.
    int (*read)(void* handle,
                int page,
                int channels,
                int sixteen_bit,
                void* pixels,
                char* error,
                std::size_t error_size);
    void (*close)(void* handle);
    /// Writes a PNG (format by the path's extension) of `channels` 8- or 16-bit values per pixel.
    int (*write_png)(const char* path,
                     const void* pixels,
                     int width,
                     int height,
                     int channels,
                     int sixteen_bit,
                     char* error,
                     std::size_t error_size);
};

inline constexpr int kStrataImageApiVersion = 1;

/// The one symbol the module exports.
const StrataImageApi* strata_image_api();
}

// libstrata_image_io.so: 2D image files read and written with OpenImageIO, behind the plain C
// interface of input/detail/image_module.h (loaded on first use by input/image_module.cpp).

#include <cstring>
#include <exception>
#include <memory>
#include <string>

#include <OpenImageIO/imageio.h>

#include "input/detail/image_module.h"

namespace {

void set_error(char* error, std::size_t error_size, const std::string& message) {
    if (error == nullptr || error_size == 0) {
        return;
    }
    const std::size_t n = std::min(message.size(), error_size - 1);
    std::memcpy(error, message.data(), n);
    error[n] = '\0';
}

void* open_image(const char* path, StrataImageSpec* spec, char* error, std::size_t error_size) {
    try {
        auto in = OIIO::ImageInput::open(path);
        if (!in) {
            set_error(error, error_size, OIIO::geterror());
            return nullptr;
        }
        const OIIO::ImageSpec& s = in->spec();
        spec->width = s.width;
        spec->height = s.height;
        spec->depth = s.depth;
        spec->channels = s.nchannels;
        spec->pixel_type = s.format == OIIO::TypeDesc::UINT8    ? kStrataPixelU8
                           : s.format == OIIO::TypeDesc::UINT16 ? kStrataPixelU16
                                                                : kStrataPixelOther;
        std::memset(spec->format_name, 0, sizeof(spec->format_name));
        std::strncpy(spec->format_name, s.format.c_str(), sizeof(spec->format_name) - 1);
        return in.release();
    } catch (const std::exception& e) {
        set_error(error, error_size, e.what());
        return nullptr;
    }
}

int read_image(void* handle,
               int page,
               int channels,
               int sixteen_bit,
               void* pixels,
               char* error,
               std::size_t error_size) {
    auto* in = static_cast<OIIO::ImageInput*>(handle);
    try {
        const OIIO::TypeDesc type = sixteen_bit ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
        if (!in->read_image(page, 0, 0, channels, type, pixels)) {
            set_error(error, error_size, in->geterror());
            return 0;
        }
        return 1;
    } catch (const std::exception& e) {
        set_error(error, error_size, e.what());
        return 0;
    }
}

void close_image(void* handle) {
    delete static_cast<OIIO::ImageInput*>(handle);
}

int write_png(const char* path,
              const void* pixels,
              int width,
              int height,
              int channels,
              int sixteen_bit,
              char* error,
              std::size_t error_size) {
    try {
        auto out = OIIO::ImageOutput::create(path);
        if (!out) {
            set_error(error, error_size, "OpenImageIO has no PNG writer: " + OIIO::geterror());
            return 0;
        }
        const OIIO::TypeDesc type = sixteen_bit ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
        const OIIO::ImageSpec spec(width, height, channels, type);
        bool ok = out->open(path, spec);
        if (ok) {
            ok = out->write_image(type, pixels);
            ok = out->close() && ok;
        }
        if (!ok) {
            set_error(error, error_size, out->geterror());
        }
        return ok ? 1 : 0;
    } catch (const std::exception& e) {
        set_error(error, error_size, e.what());
        return 0;
    }
}

const StrataImageApi kApi = {kStrataImageApiVersion, open_image, read_image, close_image,
                             write_png};

}  // namespace

extern "C" __attribute__((visibility("default"))) const StrataImageApi* strata_image_api() {
    return &kApi;
}

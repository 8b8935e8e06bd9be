#pragma once

// What the glTF writers (scene_gltf, progressive_gltf, lod_gltf, meshopt_scene) share: the patient
// -> glTF transform, colour and float conversions, file names in URIs and staged writes.

#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <string>
#include <unistd.h>

#include "core/error.h"
#include "core/file_names.h"

namespace strata::detail {

/// Throws Error{Unsupported} unless `path` ends in .glb or .gltf (case-insensitive).
inline void require_gltf_extension(const std::filesystem::path& path) {
    const std::string ext = lowercase_extension(path);
    if (ext != ".glb" && ext != ".gltf") {
        throw Error(ErrorCode::Unsupported, path.string() + ": unsupported extension '" +
                                                path.extension().string() +
                                                "', expected .glb or .gltf");
    }
}

/// LPS millimetres -> glTF metres, column-major (glTF `matrix`): the columns are the images of
/// +x (left -> glTF +X), +y (posterior -> glTF -Z) and +z (superior -> glTF +Y), times 0.001.
/// Determinant +1e-9: a rotation with uniform scale, not a mirror.
inline constexpr std::array<double, 16> kPatientToGltf{
    0.001, 0,     0,      0,  // image of +x_LPS
    0,     0,     -0.001, 0,  // image of +y_LPS
    0,     0.001, 0,      0,  // image of +z_LPS
    0,     0,     0,      1,
};

/// The name of the root node every writer puts its objects under (its matrix: kPatientToGltf,
/// or the storage frame's, which ends in patient LPS mm too).
inline constexpr char kRootNodeName[] = "patient";

/// sRGB-encoded channel in [0, 1] -> linear (IEC 61966-2-1).
inline double srgb_to_linear(double c) {
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// note: one coordinate per call (and strata_target_defaults' -fno-tree-slp-vectorize): GCC
// 12.2 at -O2 may drop the float rounding of adjacent double -> float conversions.
[[gnu::noinline]] inline float to_float(double x) {
    return static_cast<float>(x);
}

/// Percent-encodes everything but RFC 3986 unreserved characters (a file name as a relative
/// URI reference).
inline std::string uri_encode(const std::string& name) {
    static const char* const kHex = "0123456789ABCDEF";
    std::string out;
    for (unsigned char c : name) {
        if (std::isalnum(c) || c == '-' || c == '.' || c == '_' || c == '~') {
            out += static_cast<char>(c);
        } else {
            out += '%';
            out += kHex[c >> 4];
            out += kHex[c & 15];
        }
    }
    return out;
}

/// A unique name beside `path` for staging a file.
inline std::filesystem::path staging_name(const std::filesystem::path& path) {
    static std::atomic<unsigned> counter{0};
    std::filesystem::path staged = path;
    staged += ".staged." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    return staged;
}

}  // namespace strata::detail

// NIfTI-1 writer (input/write_nifti.h): a single-file volume, sform and qform from the stack's
// affine (LPS -> RAS), uint8 or uint16 labels, gzip through zlib when the name ends in .gz.

#include "input/write_nifti.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>
#include <zlib.h>

#include "core/atomic_write.h"
#include "core/error.h"
#include "input/detail/nifti_format.h"
#include "input/detail/readers.h"
#include "input/detail/text.h"
#include "input/detail/voxel_decode.h"

namespace strata {

namespace {

using detail::flip_ras_lps;
using detail::kChunkBytes;
using detail::kNifti1HeaderBytes;
using detail::store_le;

// ---------------------------------------------------------------------------------------------
// Writer helpers

/// 3x3 inverse transpose helper for the polar decomposition.
std::array<std::array<double, 3>, 3> inverse_transpose(
    const std::array<std::array<double, 3>, 3>& m) {
    std::array<std::array<double, 3>, 3> cof{};
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            const int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
            cof[r][c] = m[r1][c1] * m[r2][c2] - m[r1][c2] * m[r2][c1];
        }
    }
    const double det = m[0][0] * cof[0][0] + m[0][1] * cof[0][1] + m[0][2] * cof[0][2];
    for (auto& row : cof) {
        for (double& v : row) {
            v /= det;
        }
    }
    return cof;
}

struct Quaternion {
    double b = 0, c = 0, d = 0, qfac = 1;
    Vec3 voxel_mm{1, 1, 1};
};

/// Nearest qform (rotation, qfac, pixdim) to a RAS affine: column lengths give pixdim, the
/// normalised columns are made orthogonal by polar decomposition (exact for unsheared affines).
Quaternion affine_to_quaternion(const Affine3& ras) {
    Quaternion q;
    std::array<std::array<double, 3>, 3> m{};
    for (int c = 0; c < 3; ++c) {
        const Vec3 col = ras.column(c);
        q.voxel_mm[c] = norm(col);
        for (int r = 0; r < 3; ++r) {
            m[r][c] = col[r] / q.voxel_mm[c];
        }
    }
    Affine3 unit;
    unit.linear = m;
    if (unit.determinant() < 0) {
        q.qfac = -1;
        for (int r = 0; r < 3; ++r) {
            m[r][2] = -m[r][2];
        }
    }
    for (int iteration = 0; iteration < 50; ++iteration) {
        const auto it = inverse_transpose(m);
        double change = 0;
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) {
                const double next = 0.5 * (m[r][c] + it[r][c]);
                change = std::max(change, std::abs(next - m[r][c]));
                m[r][c] = next;
            }
        }
        if (change < 1e-15) {
            break;
        }
    }
    double a = m[0][0] + m[1][1] + m[2][2] + 1.0;
    double b, c, d;
    if (a > 0.5) {
        a = 0.5 * std::sqrt(a);
        b = 0.25 * (m[2][1] - m[1][2]) / a;
        c = 0.25 * (m[0][2] - m[2][0]) / a;
        d = 0.25 * (m[1][0] - m[0][1]) / a;
    } else {
        const double xd = 1.0 + m[0][0] - (m[1][1] + m[2][2]);
        const double yd = 1.0 + m[1][1] - (m[0][0] + m[2][2]);
        const double zd = 1.0 + m[2][2] - (m[0][0] + m[1][1]);
        if (xd > 1.0) {
            b = 0.5 * std::sqrt(xd);
            c = 0.25 * (m[0][1] + m[1][0]) / b;
            d = 0.25 * (m[0][2] + m[2][0]) / b;
            a = 0.25 * (m[2][1] - m[1][2]) / b;
        } else if (yd > 1.0) {
            c = 0.5 * std::sqrt(yd);
            b = 0.25 * (m[0][1] + m[1][0]) / c;
            d = 0.25 * (m[1][2] + m[2][1]) / c;
            a = 0.25 * (m[0][2] - m[2][0]) / c;
        } else {
            d = 0.5 * std::sqrt(zd);
            b = 0.25 * (m[0][2] + m[2][0]) / d;
            c = 0.25 * (m[1][2] + m[2][1]) / d;
            a = 0.25 * (m[1][0] - m[0][1]) / d;
        }
        if (a < 0) {
            b = -b;
            c = -c;
            d = -d;
        }
    }
    q.b = b;
    q.c = c;
    q.d = d;
    return q;
}

bool ends_with_nocase(const std::string& text, std::string_view suffix) {
    if (text.size() < suffix.size()) {
        return false;
    }
    for (std::size_t n = 0; n < suffix.size(); ++n) {
        const char ch = text[text.size() - suffix.size() + n];
        if (std::tolower(static_cast<unsigned char>(ch)) != suffix[n]) {
            return false;
        }
    }
    return true;
}

std::string nifti1_header(const SliceStack& stack, bool is_uint8) {
    std::string header(kNifti1HeaderBytes + 4, '\0');  // + 4 zero bytes: no extensions
    auto* p = reinterpret_cast<unsigned char*>(header.data());
    store_le<std::int32_t>(p, 348);
    p[38] = 'r';  // "regular", as nifti1_io writes it
    const std::array<std::int16_t, 8> dim = {3,
                                             static_cast<std::int16_t>(stack.width),
                                             static_cast<std::int16_t>(stack.height),
                                             static_cast<std::int16_t>(stack.depth),
                                             1,
                                             1,
                                             1,
                                             1};
    for (int d = 0; d < 8; ++d) {
        store_le<std::int16_t>(p + 40 + 2 * d, dim[d]);
    }
    store_le<std::int16_t>(p + 70, is_uint8 ? 2 : 512);
    store_le<std::int16_t>(p + 72, is_uint8 ? 8 : 16);

    const Affine3 ras = flip_ras_lps(stack.index_to_world);
    const Quaternion q = affine_to_quaternion(ras);
    const std::array<float, 8> pixdim = {static_cast<float>(q.qfac),
                                         static_cast<float>(q.voxel_mm.x),
                                         static_cast<float>(q.voxel_mm.y),
                                         static_cast<float>(q.voxel_mm.z),
                                         0,
                                         0,
                                         0,
                                         0};
    for (int d = 0; d < 8; ++d) {
        store_le<float>(p + 76 + 4 * d, pixdim[d]);
    }
    store_le<float>(p + 108, static_cast<float>(kNifti1HeaderBytes + 4));  // vox_offset
    store_le<float>(p + 112, 1.0f);                                        // scl_slope
    store_le<float>(p + 116, 0.0f);                                        // scl_inter
    p[123] = 2;                                                            // xyzt_units: mm
    const char description[] = "strata label volume";
    std::memcpy(p + 148, description, sizeof(description) - 1);
    store_le<std::int16_t>(p + 252, 1);  // qform_code: scanner anatomical
    store_le<std::int16_t>(p + 254, 1);  // sform_code: scanner anatomical
    store_le<float>(p + 256, static_cast<float>(q.b));
    store_le<float>(p + 260, static_cast<float>(q.c));
    store_le<float>(p + 264, static_cast<float>(q.d));
    for (int r = 0; r < 3; ++r) {
        store_le<float>(p + 268 + 4 * r, static_cast<float>(ras.translation[r]));
        for (int c = 0; c < 3; ++c) {
            store_le<float>(p + 280 + 16 * r + 4 * c, static_cast<float>(ras.linear[r][c]));
        }
        store_le<float>(p + 280 + 16 * r + 12, static_cast<float>(ras.translation[r]));
    }
    std::memcpy(p + 344, "n+1\0", 4);
    return header;
}

/// Calls `sink(bytes, size)` with the voxel data in chunks of at most kChunkBytes.
template <typename Sink>
void emit_voxels(const SliceStack& stack, bool is_uint8, Sink&& sink) {
    std::vector<unsigned char> chunk;
    chunk.reserve(kChunkBytes);
    for (std::uint16_t label : stack.labels) {
        if (is_uint8) {
            chunk.push_back(static_cast<unsigned char>(label));
        } else {
            chunk.push_back(static_cast<unsigned char>(label & 0xFF));
            chunk.push_back(static_cast<unsigned char>(label >> 8));
        }
        if (chunk.size() + 2 > kChunkBytes) {
            sink(chunk.data(), chunk.size());
            chunk.clear();
        }
    }
    if (!chunk.empty()) {
        sink(chunk.data(), chunk.size());
    }
}

class GzipBuffer {
public:
    explicit GzipBuffer(const std::string& where) : where_(where) {
        // note: windowBits 15 + 16 asks zlib for a gzip wrapper (header and CRC trailer)
        if (deflateInit2(&stream_, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
            throw Error(ErrorCode::Internal, where_ + ": zlib: deflateInit2 failed");
        }
    }
    ~GzipBuffer() { deflateEnd(&stream_); }
    GzipBuffer(const GzipBuffer&) = delete;
    GzipBuffer& operator=(const GzipBuffer&) = delete;

    void add(const unsigned char* bytes, std::size_t size) { run(bytes, size, Z_NO_FLUSH); }
    std::string finish() {
        run(nullptr, 0, Z_FINISH);
        return std::move(out_);
    }

private:
    void run(const unsigned char* bytes, std::size_t size, int flush) {
        stream_.next_in = const_cast<unsigned char*>(bytes);
        stream_.avail_in = static_cast<uInt>(size);
        unsigned char buffer[1 << 16];
        int status = Z_OK;
        do {
            stream_.next_out = buffer;
            stream_.avail_out = sizeof(buffer);
            status = deflate(&stream_, flush);
            if (status == Z_STREAM_ERROR) {
                throw Error(ErrorCode::Internal, where_ + ": zlib: deflate failed");
            }
            out_.append(reinterpret_cast<const char*>(buffer), sizeof(buffer) - stream_.avail_out);
        } while (stream_.avail_out == 0 || (flush == Z_FINISH && status != Z_STREAM_END));
    }

    std::string where_;
    z_stream stream_{};
    std::string out_;
};

}  // namespace

void write_nifti(const SliceStack& stack, const std::filesystem::path& file) {
    const std::string where = file.filename().string();
    const std::string name = file.string();
    const bool is_gzip = ends_with_nocase(name, ".nii.gz");
    if (!is_gzip && !ends_with_nocase(name, ".nii")) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": cannot write NIfTI: expected a file name ending in .nii or .nii.gz");
    }
    if (stack.width == 0 || stack.height == 0 || stack.depth == 0 ||
        stack.labels.size() != std::size_t(stack.width) * stack.height * stack.depth) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": cannot write an empty or inconsistent stack: " +
                        std::to_string(stack.width) + "x" + std::to_string(stack.height) + "x" +
                        std::to_string(stack.depth) + " with " +
                        std::to_string(stack.labels.size()) + " labels");
    }
    constexpr std::uint32_t kMaxDim = 32767;
    if (stack.width > kMaxDim || stack.height > kMaxDim || stack.depth > kMaxDim) {
        throw Error(ErrorCode::Unsupported, where + ": dimensions " + std::to_string(stack.width) +
                                                "x" + std::to_string(stack.height) + "x" +
                                                std::to_string(stack.depth) +
                                                " exceed NIfTI-1's limit of 32767 per axis");
    }
    check_spacing(stack.spacing_mm(), where + ": index_to_world");
    const Vec3 spacing = stack.spacing_mm();
    if (std::abs(stack.index_to_world.determinant()) <= 1e-12 * spacing.x * spacing.y * spacing.z) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": index_to_world is singular, expected an invertible affine");
    }

    const bool is_uint8 = std::all_of(stack.labels.begin(), stack.labels.end(),
                                      [](std::uint16_t v) { return v <= 255; });
    const std::string header = nifti1_header(stack, is_uint8);
    if (is_gzip) {
        GzipBuffer gzip(where);
        gzip.add(reinterpret_cast<const unsigned char*>(header.data()), header.size());
        emit_voxels(stack, is_uint8,
                    [&](const unsigned char* bytes, std::size_t size) { gzip.add(bytes, size); });
        write_file_atomically(file, std::string_view(gzip.finish()));
    } else {
        write_file_atomically(file, [&](std::ostream& out) {
            out.write(header.data(), static_cast<std::streamsize>(header.size()));
            emit_voxels(stack, is_uint8, [&](const unsigned char* bytes, std::size_t size) {
                out.write(reinterpret_cast<const char*>(bytes), static_cast<std::streamsize>(size));
            });
        });
    }
}

}  // namespace strata

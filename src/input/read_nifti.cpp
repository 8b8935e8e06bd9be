// NIfTI-1 and NIfTI-2 label volumes, read with zlib only (no libnifti) so that every header
// field is validated before it is used (the writer is write_nifti.cpp).
//
// Formats: NIfTI-1 (https://nifti.nimh.nih.gov/pub/dist/src/niftilib/nifti1.h) and NIfTI-2
// (https://nifti.nimh.nih.gov/pub/dist/doc/nifti2.h). World transform as in nifti1.h
// "METHOD 3 / METHOD 2 / METHOD 1": sform if sform_code > 0, else the qform quaternion with qfac
// if qform_code > 0, else diag(pixdim); the quaternion <-> matrix formulas follow
// nifti_quatern_to_mat44 and nifti_mat44_to_quatern of nifti1_io.c. Label names and colours come
// from a Caret/CIFTI <LabelTable> extension when there is one (TotalSegmentator writes it).

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
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
using detail::format_number;
using detail::kChunkBytes;
using detail::kNifti1HeaderBytes;
using detail::LabelDecoder;
using detail::load;
using detail::parse_number;
using detail::ScalarType;
using detail::store_le;
using detail::ValueScaling;

constexpr std::size_t kNifti2HeaderBytes = 540;
// Extensions up to this size are read (for a label table); larger gaps before vox_offset are
// skipped unread.
constexpr std::uint64_t kMaxExtensionBytes = std::uint64_t(16) << 20;

// ---------------------------------------------------------------------------------------------
// Small helpers

// ---------------------------------------------------------------------------------------------
// gzip-or-plain input through zlib's gz* interface (it reads uncompressed files transparently)

class GzInput {
public:
    GzInput(const std::filesystem::path& file, std::string where) : where_(std::move(where)) {
        errno = 0;
        handle_ = gzopen(file.c_str(), "rb");
        if (handle_ == nullptr) {
            throw Error(ErrorCode::Io, where_ + ": cannot open " + file.string() + ": " +
                                           (errno != 0 ? std::strerror(errno) : "out of memory"));
        }
    }
    ~GzInput() { gzclose(handle_); }
    GzInput(const GzInput&) = delete;
    GzInput& operator=(const GzInput&) = delete;

    /// Reads up to `size` bytes; fewer only at the end of the data (a truncated file).
    /// Throws Error{InvalidInput} for corrupt gzip data, Error{Io} for read errors.
    std::size_t read(void* buffer, std::size_t size) {
        std::size_t total = 0;
        auto* bytes = static_cast<unsigned char*>(buffer);
        while (total < size) {
            const unsigned ask =
                static_cast<unsigned>(std::min<std::size_t>(size - total, 1u << 30));
            const int got = gzread(handle_, bytes + total, ask);
            if (got < 0) {
                throw_stream_error();
            }
            total += static_cast<std::size_t>(got);
            if (static_cast<unsigned>(got) < ask) {
                break;
            }
        }
        return total;
    }

    /// Skips `size` bytes; returns how many were there.
    std::uint64_t skip(std::uint64_t size) {
        std::vector<unsigned char> scratch(std::min<std::uint64_t>(size, kChunkBytes));
        std::uint64_t total = 0;
        while (total < size) {
            const std::size_t ask = std::min<std::uint64_t>(size - total, scratch.size());
            const std::size_t got = read(scratch.data(), ask);
            total += got;
            if (got < ask) {
                break;
            }
        }
        return total;
    }

    /// True when the file is gzip-compressed (valid after the first read).
    bool is_compressed() { return gzdirect(handle_) == 0; }

    /// After the voxel data of a gzip file: reads on to the end of the stream so that zlib
    /// checks its CRC and length trailer. A wrong or missing trailer (a file cut short) is
    /// refused; data beyond what the header promised is read and ignored.
    void check_trailer() {
        if (gzdirect(handle_) != 0) {
            return;
        }
        std::vector<unsigned char> scratch(std::size_t(1) << 16);
        for (;;) {
            const int got = gzread(handle_, scratch.data(), static_cast<unsigned>(scratch.size()));
            if (got < 0) {
                throw_stream_error();
            }
            if (got == 0) {
                break;
            }
        }
        int code = Z_OK;
        gzerror(handle_, &code);
        if (code == Z_BUF_ERROR) {
            throw Error(ErrorCode::InvalidInput,
                        where_ +
                            ": truncated gzip stream: it ends without its CRC/length trailer, "
                            "expected a complete gzip file (cut short in a copy or download?)");
        }
        if (code != Z_OK) {
            throw_stream_error();
        }
    }

private:
    [[noreturn]] void throw_stream_error() {
        int code = Z_OK;
        const char* message = gzerror(handle_, &code);
        if (code == Z_ERRNO) {
            throw Error(ErrorCode::Io, where_ + ": read error: " + std::strerror(errno));
        }
        if (code == Z_MEM_ERROR) {
            throw Error(ErrorCode::Internal, where_ + ": zlib: out of memory");
        }
        throw Error(ErrorCode::InvalidInput,
                    where_ + ": corrupt gzip data: " + (message != nullptr ? message : "unknown"));
    }

    std::string where_;
    gzFile handle_ = nullptr;
};

// ---------------------------------------------------------------------------------------------
// Header

struct NiftiHeader {
    int version = 1;    // 1 or 2
    bool swap = false;  // file byte order differs from ours
    std::size_t size = kNifti1HeaderBytes;
    std::array<std::int64_t, 8> dim{};
    int datatype = 0;
    int bitpix = 0;
    std::array<double, 8> pixdim{};
    double vox_offset = 0;
    double scl_slope = 0;
    double scl_inter = 0;
    int qform_code = 0;
    int sform_code = 0;
    std::array<double, 3> quatern{};  // b, c, d
    std::array<double, 3> qoffset{};
    std::array<std::array<double, 4>, 3> srow{};
    int xyzt_units = 0;
};

NiftiHeader parse_header(GzInput& in, const std::string& where) {
    std::array<unsigned char, kNifti2HeaderBytes> raw{};
    const std::size_t first = in.read(raw.data(), 4);
    if (first < 4) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": truncated header: file has " + std::to_string(first) +
                        " bytes, expected a 348-byte NIfTI-1 or 540-byte NIfTI-2 header");
    }
    NiftiHeader h;
    const auto sizeof_hdr = load<std::int32_t>(raw.data(), false);
    const auto sizeof_hdr_swapped = load<std::int32_t>(raw.data(), true);
    if (sizeof_hdr == 348 || sizeof_hdr == 540) {
        h.swap = false;
        h.version = sizeof_hdr == 348 ? 1 : 2;
    } else if (sizeof_hdr_swapped == 348 || sizeof_hdr_swapped == 540) {
        h.swap = true;
        h.version = sizeof_hdr_swapped == 348 ? 1 : 2;
    } else {
        throw Error(ErrorCode::InvalidInput,
                    where + ": not a NIfTI file: sizeof_hdr is " + std::to_string(sizeof_hdr) +
                        ", expected 348 (NIfTI-1) or 540 (NIfTI-2) in either byte order");
    }
    h.size = h.version == 1 ? kNifti1HeaderBytes : kNifti2HeaderBytes;
    const std::size_t rest = in.read(raw.data() + 4, h.size - 4);
    if (rest < h.size - 4) {
        throw Error(ErrorCode::InvalidInput, where + ": truncated header: found " +
                                                 std::to_string(rest + 4) + " of " +
                                                 std::to_string(h.size) + " bytes of the NIfTI-" +
                                                 std::to_string(h.version) + " header");
    }
    const unsigned char* p = raw.data();
    const bool s = h.swap;

    if (h.version == 1) {
        const std::string_view magic(reinterpret_cast<const char*>(p + 344), 4);
        if (magic == std::string_view("ni1\0", 4)) {
            throw Error(ErrorCode::Unsupported,
                        where +
                            ": NIfTI-1 header/image pair (magic \"ni1\", .hdr + .img) is not "
                            "supported; convert it to a single-file .nii or .nii.gz");
        }
        if (magic != std::string_view("n+1\0", 4)) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": bad magic at byte 344, expected \"n+1\" (single-file "
                            "NIfTI-1; Analyze 7.5 files are not supported)");
        }
        for (int d = 0; d < 8; ++d) {
            h.dim[d] = load<std::int16_t>(p + 40 + 2 * d, s);
            h.pixdim[d] = load<float>(p + 76 + 4 * d, s);
        }
        h.datatype = load<std::int16_t>(p + 70, s);
        h.bitpix = load<std::int16_t>(p + 72, s);
        h.vox_offset = load<float>(p + 108, s);
        h.scl_slope = load<float>(p + 112, s);
        h.scl_inter = load<float>(p + 116, s);
        h.xyzt_units = p[123];
        h.qform_code = load<std::int16_t>(p + 252, s);
        h.sform_code = load<std::int16_t>(p + 254, s);
        for (int q = 0; q < 3; ++q) {
            h.quatern[q] = load<float>(p + 256 + 4 * q, s);
            h.qoffset[q] = load<float>(p + 268 + 4 * q, s);
        }
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) {
                h.srow[r][c] = load<float>(p + 280 + 16 * r + 4 * c, s);
            }
        }
    } else {
        const std::string_view magic(reinterpret_cast<const char*>(p + 4), 8);
        if (magic.substr(0, 4) == std::string_view("ni2\0", 4)) {
            throw Error(ErrorCode::Unsupported,
                        where +
                            ": NIfTI-2 header/image pair (magic \"ni2\", .hdr + .img) is not "
                            "supported; convert it to a single-file .nii or .nii.gz");
        }
        if (magic.substr(0, 4) != std::string_view("n+2\0", 4)) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": bad magic at byte 4, expected \"n+2\" (single-file NIfTI-2)");
        }
        if (magic.substr(4) != std::string_view("\r\n\032\n", 4)) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": NIfTI-2 magic bytes 8..11 are not \\r\\n\\032\\n (file "
                            "transferred in text mode?)");
        }
        h.datatype = load<std::int16_t>(p + 12, s);
        h.bitpix = load<std::int16_t>(p + 14, s);
        for (int d = 0; d < 8; ++d) {
            h.dim[d] = load<std::int64_t>(p + 16 + 8 * d, s);
            h.pixdim[d] = load<double>(p + 104 + 8 * d, s);
        }
        const auto offset = load<std::int64_t>(p + 168, s);
        h.vox_offset = static_cast<double>(offset);
        h.scl_slope = load<double>(p + 176, s);
        h.scl_inter = load<double>(p + 184, s);
        h.qform_code = load<std::int32_t>(p + 344, s);
        h.sform_code = load<std::int32_t>(p + 348, s);
        for (int q = 0; q < 3; ++q) {
            h.quatern[q] = load<double>(p + 352 + 8 * q, s);
            h.qoffset[q] = load<double>(p + 376 + 8 * q, s);
        }
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) {
                h.srow[r][c] = load<double>(p + 400 + 32 * r + 8 * c, s);
            }
        }
        h.xyzt_units = load<std::int32_t>(p + 500, s);
    }
    return h;
}

struct DatatypeInfo {
    int code;
    const char* name;
    int bitpix;
    bool is_supported;
    ScalarType type;
};

constexpr DatatypeInfo kDatatypes[] = {
    {1, "binary", 1, false, ScalarType::UInt8},
    {2, "uint8", 8, true, ScalarType::UInt8},
    {4, "int16", 16, true, ScalarType::Int16},
    {8, "int32", 32, true, ScalarType::Int32},
    {16, "float32", 32, true, ScalarType::Float32},
    {32, "complex64", 64, false, ScalarType::UInt8},
    {64, "float64", 64, true, ScalarType::Float64},
    {128, "rgb24", 24, false, ScalarType::UInt8},
    {256, "int8", 8, true, ScalarType::Int8},
    {512, "uint16", 16, true, ScalarType::UInt16},
    {768, "uint32", 32, true, ScalarType::UInt32},
    {1024, "int64", 64, true, ScalarType::Int64},
    {1280, "uint64", 64, true, ScalarType::UInt64},
    {1536, "float128", 128, false, ScalarType::UInt8},
    {1792, "complex128", 128, false, ScalarType::UInt8},
    {2048, "complex256", 256, false, ScalarType::UInt8},
    {2304, "rgba32", 32, false, ScalarType::UInt8},
};

ScalarType check_datatype(const NiftiHeader& h, const std::string& where) {
    for (const DatatypeInfo& info : kDatatypes) {
        if (info.code != h.datatype) {
            continue;
        }
        if (!info.is_supported) {
            throw Error(ErrorCode::Unsupported,
                        where + ": datatype " + std::to_string(h.datatype) + " (" + info.name +
                            ") is not supported; expected an integer or real label type "
                            "(uint8, int8, uint16, int16, uint32, int32, uint64, int64, "
                            "float32, float64)");
        }
        if (h.bitpix != info.bitpix) {
            throw Error(ErrorCode::InvalidInput, where + ": bitpix " + std::to_string(h.bitpix) +
                                                     " does not match datatype " + info.name +
                                                     ", expected " + std::to_string(info.bitpix));
        }
        return info.type;
    }
    throw Error(ErrorCode::InvalidInput,
                where + ": unknown datatype code " + std::to_string(h.datatype));
}

/// Checks dim[]; returns width, height, depth.
std::array<std::uint64_t, 3> check_dims(const NiftiHeader& h, const std::string& where) {
    const std::int64_t rank = h.dim[0];
    if (rank < 2 || rank > 7) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": dim[0] = " + std::to_string(rank) + ", expected 2..7 dimensions");
    }
    for (int d = 1; d <= rank; ++d) {
        if (h.dim[d] < 0) {
            throw Error(ErrorCode::InvalidInput, where + ": dim[" + std::to_string(d) +
                                                     "] = " + std::to_string(h.dim[d]) +
                                                     ", expected a positive size");
        }
    }
    // note: saturating product so that absurd headers still give a number to print
    long double volumes = 1;
    for (int d = 4; d <= rank; ++d) {
        volumes *= static_cast<long double>(h.dim[d]);
    }
    if (volumes == 0) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": empty dimension: dim[4..7] has a 0, expected 1 (one volume)");
    }
    if (volumes > 1) {
        std::ostringstream s;
        s.precision(20);
        s << where << ": " << rank << "D NIfTI with " << volumes
          << " volumes; expected a single 3D label volume";
        throw Error(ErrorCode::Unsupported, s.str());
    }
    const auto axis = [&](int d) -> std::uint64_t {
        return d <= rank ? static_cast<std::uint64_t>(h.dim[d]) : 1;
    };
    return {axis(1), axis(2), axis(3)};
}

/// Voxel size in mm per axis from pixdim (checked for the axes in use) and xyzt_units.
Vec3 voxel_size(const NiftiHeader& h, double unit_mm, const std::string& where) {
    Vec3 size{1, 1, 1};
    const std::int64_t used = std::min<std::int64_t>(h.dim[0], 3);
    for (int d = 1; d <= 3; ++d) {
        const double value = h.pixdim[d];
        if (d <= used) {
            if (!std::isfinite(value) || value <= 0) {
                throw Error(ErrorCode::InvalidInput, where + ": pixdim[" + std::to_string(d) +
                                                         "] = " + format_number(value) +
                                                         " (voxel size along " + "ijk"[d - 1] +
                                                         "), expected a finite positive size");
            }
            size[d - 1] = value * unit_mm;
        } else if (std::isfinite(value) && value > 0) {
            size[d - 1] = value * unit_mm;  // 2D image: slice thickness if given
        }
    }
    return size;
}

double spatial_unit_mm(const NiftiHeader& h) {
    switch (h.xyzt_units & 0x07) {
        case 1:
            return 1000.0;  // metres
        case 3:
            return 0.001;  // micrometres
        default:
            return 1.0;  // mm, or unknown (mm by convention)
    }
}

Affine3 qform_affine(const NiftiHeader& h,
                     Vec3 voxel_mm,
                     double unit_mm,
                     const std::string& where) {
    const double b = h.quatern[0];
    const double c = h.quatern[1];
    const double d = h.quatern[2];
    for (double v : {b, c, d, h.qoffset[0], h.qoffset[1], h.qoffset[2]}) {
        if (!std::isfinite(v)) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": qform quaternion or offset has a non-finite value");
        }
    }
    const double bcd = b * b + c * c + d * d;
    if (bcd > 1.0 + 1e-4) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": qform quaternion (b,c,d) = (" + format_number(b) + "," +
                        format_number(c) + "," + format_number(d) +
                        ") has b^2+c^2+d^2 = " + format_number(bcd) + ", expected at most 1");
    }
    // note: as nifti_quatern_to_mat44, a tiny negative 1 - |bcd|^2 means a = 0 and (b,c,d) unit
    double a = 1.0 - bcd;
    double bn = b, cn = c, dn = d;
    if (a < 1e-7) {
        const double scale = 1.0 / std::sqrt(bcd);
        bn *= scale;
        cn *= scale;
        dn *= scale;
        a = 0;
    } else {
        a = std::sqrt(a);
    }
    const double qfac = h.pixdim[0] < 0 ? -1.0 : 1.0;
    const double r[3][3] = {
        {a * a + bn * bn - cn * cn - dn * dn, 2 * (bn * cn - a * dn), 2 * (bn * dn + a * cn)},
        {2 * (bn * cn + a * dn), a * a + cn * cn - bn * bn - dn * dn, 2 * (cn * dn - a * bn)},
        {2 * (bn * dn - a * cn), 2 * (cn * dn + a * bn), a * a + dn * dn - cn * cn - bn * bn},
    };
    Affine3 affine;
    for (int row = 0; row < 3; ++row) {
        affine.linear[row][0] = r[row][0] * voxel_mm.x;
        affine.linear[row][1] = r[row][1] * voxel_mm.y;
        affine.linear[row][2] = r[row][2] * voxel_mm.z * qfac;
        affine.translation[row] = h.qoffset[row] * unit_mm;
    }
    return affine;
}

Affine3 sform_affine(const NiftiHeader& h, double unit_mm, const std::string& where) {
    Affine3 affine;
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 4; ++col) {
            const double v = h.srow[row][col];
            if (!std::isfinite(v)) {
                throw Error(ErrorCode::InvalidInput, where + ": srow_" + "xyz"[row] + "[" +
                                                         std::to_string(col) + "] is not finite");
            }
            if (col < 3) {
                affine.linear[row][col] = v * unit_mm;
            } else {
                affine.translation[row] = v * unit_mm;
            }
        }
    }
    return affine;
}

/// Index -> world affine in the file's RAS frame ("RAS"), or diag(pixdim) ("none").
std::pair<Affine3, std::string> world_affine(const NiftiHeader& h, const std::string& where) {
    if (h.sform_code < 0 || h.qform_code < 0) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": negative " + (h.sform_code < 0 ? "sform_code " : "qform_code ") +
                        std::to_string(std::min(h.sform_code, h.qform_code)) +
                        ", expected 0 (unset) or a positive code");
    }
    const double unit_mm = spatial_unit_mm(h);
    const Vec3 voxel_mm = voxel_size(h, unit_mm, where);
    if (h.sform_code > 0) {
        return {sform_affine(h, unit_mm, where), "RAS"};
    }
    if (h.qform_code > 0) {
        return {qform_affine(h, voxel_mm, unit_mm, where), "RAS"};
    }
    Affine3 affine;
    for (int i = 0; i < 3; ++i) {
        affine.linear[i][i] = voxel_mm[i];
    }
    return {affine, "none"};
}

/// Checks vox_offset; returns it as a byte count.
std::uint64_t check_vox_offset(const NiftiHeader& h, const std::string& where) {
    const double offset = h.vox_offset;
    // note: the 4 bytes after the header are the extension flag; data starting among them would
    // be read shifted. Exactly the header size (no flag at all) is still read, as nifti1_io does.
    const double size = static_cast<double>(h.size);
    if (!std::isfinite(offset) || offset != std::floor(offset) || offset < size ||
        (offset > size && offset < size + 4) || offset > 0x1p62) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": vox_offset " + format_number(offset) +
                        ", expected a whole number of bytes, " + std::to_string(h.size) +
                        " (the header size) or at least " + std::to_string(h.size + 4) +
                        " (the header and its extension flag)");
    }
    return static_cast<std::uint64_t>(offset);
}

void check_scaling(const NiftiHeader& h, const std::string& where) {
    if (h.scl_slope != 0.0 && (!std::isfinite(h.scl_slope) || !std::isfinite(h.scl_inter))) {
        throw Error(ErrorCode::InvalidInput, where + ": scl_slope " + format_number(h.scl_slope) +
                                                 " / scl_inter " + format_number(h.scl_inter) +
                                                 " is not finite");
    }
}

// ---------------------------------------------------------------------------------------------
// Extensions: a Caret/CIFTI <LabelTable> (TotalSegmentator writes one, with ecode 0) gives label
// names and colours. Extensions are optional metadata: malformed ones are warned about, not fatal.

std::optional<std::string_view> xml_attribute(std::string_view tag, std::string_view name) {
    std::size_t at = 0;
    while ((at = tag.find(name, at)) != std::string_view::npos) {
        const std::size_t after = at + name.size();
        const bool is_word_start = at > 0 && std::isspace(static_cast<unsigned char>(tag[at - 1]));
        if (is_word_start && tag.substr(after, 2) == "=\"") {
            const std::size_t end = tag.find('"', after + 2);
            if (end == std::string_view::npos) {
                return std::nullopt;
            }
            return tag.substr(after + 2, end - after - 2);
        }
        at = after;
    }
    return std::nullopt;
}

std::string xml_text(std::string_view text) {
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) {
        text.remove_prefix(1);
    }
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) {
        text.remove_suffix(1);
    }
    if (text.starts_with("<![CDATA[") && text.ends_with("]]>")) {
        return std::string(text.substr(9, text.size() - 12));
    }
    static constexpr std::pair<std::string_view, char> kEntities[] = {
        {"&amp;", '&'}, {"&lt;", '<'}, {"&gt;", '>'}, {"&quot;", '"'}, {"&apos;", '\''}};
    std::string out;
    for (std::size_t n = 0; n < text.size(); ++n) {
        bool is_entity = false;
        for (const auto& [entity, ch] : kEntities) {
            if (text.substr(n, entity.size()) == entity) {
                out.push_back(ch);
                n += entity.size() - 1;
                is_entity = true;
                break;
            }
        }
        if (!is_entity) {
            out.push_back(text[n]);
        }
    }
    return out;
}

std::vector<LabelInfo> caret_labels(std::string_view xml,
                                    const std::string& where,
                                    Report& report) {
    std::vector<LabelInfo> table;
    std::size_t pos = 0;
    while ((pos = xml.find("<Label", pos)) != std::string_view::npos) {
        const std::size_t tag_end = xml.find('>', pos);
        if (tag_end == std::string_view::npos) {
            break;
        }
        const std::string_view tag = xml.substr(pos, tag_end - pos);
        if (tag.size() <= 6 || !std::isspace(static_cast<unsigned char>(tag[6]))) {
            pos = tag_end + 1;  // <LabelTable> or another element
            continue;
        }
        const std::size_t close = xml.find("</Label>", tag_end);
        if (close == std::string_view::npos) {
            break;
        }
        const std::string name = xml_text(xml.substr(tag_end + 1, close - tag_end - 1));
        pos = close + 8;
        const auto key_text = xml_attribute(tag, "Key");
        const auto key = key_text ? parse_number<double>(*key_text) : std::nullopt;
        if (!key || *key != std::floor(*key) || *key < 0 || *key > 65535) {
            report.warn("input", where,
                        "ignored a label of the NIfTI label-table extension with key \"" +
                            std::string(key_text.value_or("")) + "\", expected 0..65535");
            continue;
        }
        const auto value = static_cast<std::uint16_t>(*key);
        if (value == 0 || std::any_of(table.begin(), table.end(),
                                      [&](const LabelInfo& l) { return l.value == value; })) {
            continue;  // background, or a repeated key (first kept)
        }
        ColorSrgb8 color = palette_color(value);
        const std::optional<std::string_view> rgb[3] = {
            xml_attribute(tag, "Red"), xml_attribute(tag, "Green"), xml_attribute(tag, "Blue")};
        if (rgb[0] && rgb[1] && rgb[2]) {
            bool is_valid = true;
            ColorSrgb8 parsed{};
            for (int c = 0; c < 3; ++c) {
                const auto component = parse_number<double>(*rgb[c]);
                is_valid = is_valid && component && *component >= 0.0 && *component <= 1.0;
                if (is_valid) {
                    parsed[c] = static_cast<std::uint8_t>(std::lround(255.0 * *component));
                }
            }
            if (is_valid) {
                color = parsed;
            }
        }
        table.push_back({value, name.empty() ? "label " + std::to_string(value) : name, color});
    }
    std::sort(table.begin(), table.end(),
              [](const LabelInfo& a, const LabelInfo& b) { return a.value < b.value; });
    return table;
}

/// Label names and colours from the extensions between the header and vox_offset (`bytes`
/// starts with the 4-byte extender).
std::vector<LabelInfo> read_extension_labels(const std::string& bytes,
                                             bool swap,
                                             std::size_t header_size,
                                             const std::string& where,
                                             Report& report) {
    if (bytes.size() < 4 || bytes[0] == 0) {
        return {};
    }
    const auto* data = reinterpret_cast<const unsigned char*>(bytes.data());
    std::size_t pos = 4;
    while (pos + 8 <= bytes.size()) {
        const auto esize = load<std::int32_t>(data + pos, swap);
        if (esize < 8 || static_cast<std::uint64_t>(esize) > bytes.size() - pos) {
            report.warn("input", where,
                        "ignored a malformed NIfTI extension at byte " +
                            std::to_string(header_size + pos) + " (esize " + std::to_string(esize) +
                            ")");
            return {};
        }
        const std::string_view content(bytes.data() + pos + 8, static_cast<std::size_t>(esize) - 8);
        if (content.find("<CaretExtension") != std::string_view::npos) {
            return caret_labels(content, where, report);
        }
        pos += static_cast<std::size_t>(esize);
    }
    return {};
}

}  // namespace

namespace detail {

SliceStack read_nifti(const std::filesystem::path& file,
                      const ReadOptions& options,
                      Report& report) {
    const std::string where = file.filename().string();
    GzInput in(file, where);
    const NiftiHeader h = parse_header(in, where);

    const ScalarType type = check_datatype(h, where);
    const auto [width, height, depth] = check_dims(h, where);
    check_stack_dimensions(width, height, depth, where, options.max_bytes);
    check_scaling(h, where);
    const std::uint64_t vox_offset = check_vox_offset(h, where);
    auto [affine, frame] = world_affine(h, where);
    if (frame == "RAS") {
        affine = flip_ras_lps(affine);
    }
    const Vec3 spacing{norm(affine.column(0)), norm(affine.column(1)), norm(affine.column(2))};
    check_spacing(spacing, where + ": " +
                               (h.sform_code > 0   ? "sform"
                                : h.qform_code > 0 ? "qform"
                                                   : "pixdim"));
    if (std::abs(affine.determinant()) <= 1e-12 * spacing.x * spacing.y * spacing.z) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": the " + (h.sform_code > 0 ? "sform" : "qform") +
                        " matrix is singular (its axes are coplanar), expected an invertible "
                        "voxel-to-world transform");
    }

    // Extensions: only a Caret label table is used; larger gaps are skipped unread.
    const std::uint64_t gap = vox_offset - h.size;
    std::vector<LabelInfo> label_table;
    if (gap <= kMaxExtensionBytes) {
        std::string extensions(gap, '\0');
        const std::size_t got = in.read(extensions.data(), extensions.size());
        if (got < gap) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": truncated: file ends at byte " + std::to_string(h.size + got) +
                            ", before vox_offset " + std::to_string(vox_offset));
        }
        label_table = read_extension_labels(extensions, h.swap, h.size, where, report);
    } else {
        const std::uint64_t skipped = in.skip(gap);
        if (skipped < gap) {
            throw Error(ErrorCode::InvalidInput, where + ": truncated: file ends at byte " +
                                                     std::to_string(h.size + skipped) +
                                                     ", before vox_offset " +
                                                     std::to_string(vox_offset));
        }
    }

    SliceStack stack;
    stack.width = static_cast<std::uint32_t>(width);
    stack.height = static_cast<std::uint32_t>(height);
    stack.depth = static_cast<std::uint32_t>(depth);
    stack.index_to_world = affine;
    stack.source = file.string();
    stack.source_frame = frame;
    stack.label_table = std::move(label_table);

    // What the file can hold: its bytes after vox_offset, or (gzip) 1032 times its size.
    std::error_code ec;
    const std::uint64_t file_bytes = std::filesystem::file_size(file, ec);
    detail::DataBound bound;
    if (!ec) {
        bound.is_exact = !in.is_compressed();
        bound.max_bytes = bound.is_exact ? (file_bytes > vox_offset ? file_bytes - vox_offset : 0)
                                         : file_bytes * detail::kMaxDeflateRatio;
    }

    // note: scl_slope 0 means the values are not scaled
    const ValueScaling scaling =
        h.scl_slope != 0.0 ? ValueScaling{h.scl_slope, h.scl_inter} : ValueScaling{};
    LabelDecoder decoder(type, h.swap, stack, where, options.progress, scaling);
    decoder.decode_all([&](unsigned char* out, std::size_t size) { return in.read(out, size); },
                       " after vox_offset " + std::to_string(vox_offset), bound);
    in.check_trailer();
    return stack;
}

}  // namespace detail

}  // namespace strata

// NRRD label volumes (attached `.nrrd`, 3D Slicer `.seg.nrrd`, detached `.nhdr`), read with zlib
// only so that every header field is validated before it is used; the header's text is parsed in
// nrrd_header.cpp.
//
// Format: "Definition of NRRD File Format", Teem 1.9+ (http://teem.sourceforge.net/nrrd/
// format.html), magics NRRD0001..NRRD0005. Segmentation fields: 3D Slicer's
// vtkMRMLSegmentationStorageNode (SegmentN_Name/_Color/_LabelValue/_Layer key:=value pairs).

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>
#include <zlib.h>

#include "core/error.h"
#include "input/detail/nrrd_header.h"
#include "input/detail/readers.h"
#include "input/detail/text.h"
#include "input/detail/voxel_decode.h"

namespace strata::detail {

namespace {

using namespace nrrd;

// ---------------------------------------------------------------------------------------------
// Data streams

/// Inflates a gzip (or zlib) stream read from `in`.
class Inflater {
public:
    Inflater(std::istream& in, std::string where) : in_(in), where_(std::move(where)) {
        // note: windowBits 15 + 32: accept both gzip and zlib wrappers
        if (inflateInit2(&stream_, 15 + 32) != Z_OK) {
            throw Error(ErrorCode::Internal, where_ + ": zlib: inflateInit2 failed");
        }
    }
    ~Inflater() { inflateEnd(&stream_); }
    Inflater(const Inflater&) = delete;
    Inflater& operator=(const Inflater&) = delete;

    /// Inflates up to `size` bytes; fewer only if the compressed data ends early.
    std::size_t read(unsigned char* out, std::size_t size) {
        stream_.next_out = out;
        stream_.avail_out = static_cast<uInt>(size);
        while (stream_.avail_out > 0 && !is_done_) {
            if (stream_.avail_in == 0 && !refill()) {
                break;
            }
            const uInt before = stream_.avail_out;
            const int status = inflate(&stream_, Z_NO_FLUSH);
            if (stream_.avail_out != before) {
                at_member_end_ = false;
            }
            if (status == Z_STREAM_END) {
                at_member_end_ = true;
                // note: concatenated gzip members are one stream (as gunzip reads them)
                if (stream_.avail_in == 0 && !refill()) {
                    is_done_ = true;
                } else if (inflateReset(&stream_) != Z_OK) {
                    throw Error(ErrorCode::Internal, where_ + ": zlib: inflateReset failed");
                }
            } else if (status == Z_DATA_ERROR || status == Z_NEED_DICT) {
                throw Error(ErrorCode::InvalidInput,
                            where_ + ": corrupt gzip data: " +
                                (stream_.msg != nullptr ? stream_.msg : "invalid stream"));
            } else if (status == Z_MEM_ERROR) {
                throw Error(ErrorCode::Internal, where_ + ": zlib: out of memory");
            }
        }
        return size - stream_.avail_out;
    }

    /// After the voxel data: inflates to the end of the member so that zlib checks its CRC and
    /// length trailer. A wrong or missing trailer (a file cut short) is refused; data beyond
    /// what the header promised is inflated and ignored.
    void check_trailer() {
        std::vector<unsigned char> scratch(std::size_t(1) << 16);
        while (!is_done_ && !at_member_end_) {
            if (stream_.avail_in == 0 && !refill()) {
                throw Error(ErrorCode::InvalidInput,
                            where_ +
                                ": truncated gzip stream: it ends without its CRC/length "
                                "trailer, expected a complete gzip stream (cut short?)");
            }
            stream_.next_out = scratch.data();
            stream_.avail_out = static_cast<uInt>(scratch.size());
            const int status = inflate(&stream_, Z_NO_FLUSH);
            if (status == Z_STREAM_END) {
                return;
            }
            if (status == Z_DATA_ERROR || status == Z_NEED_DICT) {
                throw Error(ErrorCode::InvalidInput,
                            where_ + ": corrupt gzip data after the voxel data: " +
                                (stream_.msg != nullptr ? stream_.msg : "invalid stream"));
            }
            if (status == Z_MEM_ERROR) {
                throw Error(ErrorCode::Internal, where_ + ": zlib: out of memory");
            }
        }
    }

private:
    bool refill() {
        in_.read(reinterpret_cast<char*>(buffer_.data()), buffer_.size());
        const auto got = in_.gcount();
        if (in_.bad()) {
            throw Error(ErrorCode::Io, where_ + ": read error");
        }
        stream_.next_in = buffer_.data();
        stream_.avail_in = static_cast<uInt>(got);
        return got > 0;
    }

    std::istream& in_;
    std::string where_;
    z_stream stream_{};
    std::array<unsigned char, 1 << 16> buffer_{};
    bool is_done_ = false;
    bool at_member_end_ = false;  // the last inflate ended a member (its trailer checked)
};

std::size_t read_raw(std::istream& in,
                     unsigned char* out,
                     std::size_t size,
                     const std::string& where) {
    in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(size));
    if (in.bad()) {
        throw Error(ErrorCode::Io, where + ": read error");
    }
    return static_cast<std::size_t>(in.gcount());
}

void skip_lines(std::istream& in, std::int64_t count, const std::string& where) {
    std::streambuf* buffer = in.rdbuf();
    for (std::int64_t line = 0; line < count; ++line) {
        for (;;) {
            const int ch = buffer->sbumpc();
            if (ch == std::char_traits<char>::eof()) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": truncated: file ends after " + std::to_string(line) +
                                " of the " + std::to_string(count) + " lines of 'line skip'");
            }
            if (ch == '\n') {
                break;
            }
        }
    }
}

void decode_ascii(std::istream& in,
                  std::uint64_t expected_values,
                  LabelDecoder& decoder,
                  const std::string& where) {
    std::streambuf* buffer = in.rdbuf();
    std::string token;
    std::uint64_t found = 0;
    int ch = buffer->sbumpc();
    while (found < expected_values) {
        while (ch != std::char_traits<char>::eof() && (std::isspace(ch) != 0 || ch == ',')) {
            ch = buffer->sbumpc();
        }
        if (ch == std::char_traits<char>::eof()) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": truncated: expected " + std::to_string(expected_values) +
                            " ascii voxel values, found " + std::to_string(found));
        }
        token.clear();
        while (ch != std::char_traits<char>::eof() && std::isspace(ch) == 0 && ch != ',') {
            if (token.size() < 64) {
                token.push_back(static_cast<char>(ch));
            }
            ch = buffer->sbumpc();
        }
        const auto value = parse_double(token);
        if (!value) {
            throw Error(ErrorCode::InvalidInput, where + ": ascii voxel value " +
                                                     std::to_string(found) + " \"" + token +
                                                     "\" is not a number");
        }
        decoder.decode_value(*value);
        ++found;
    }
}

/// Refuses a detached data file that is not a regular file, or that lies outside the folder of
/// the header `file` (after resolving links: "../../etc/passwd", "/dev/urandom") unless it is
/// `allowed` (ReadOptions::allowed_data_file, the CLI's --allow-data-file).
void check_data_file(const std::filesystem::path& file,
                     const std::filesystem::path& data_path,
                     const std::filesystem::path& allowed,
                     const std::string& where) {
    namespace fs = std::filesystem;
    std::error_code ec;
    const fs::file_status status = fs::status(data_path, ec);
    if (ec && status.type() != fs::file_type::not_found) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": cannot resolve " + data_path.string() + ": " + ec.message());
    }
    if (status.type() == fs::file_type::not_found) {
        throw Error(ErrorCode::Io, where + ": cannot open " + data_path.string() +
                                       ": no such file, expected the header's data file");
    }
    if (status.type() != fs::file_type::regular) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": " + data_path.string() +
                        " is not a regular file (a FIFO, device or folder), expected a file of "
                        "voxel data");
    }
    const fs::path data = fs::canonical(data_path, ec);
    const fs::path folder = fs::canonical(fs::absolute(file).parent_path(), ec);
    if (!allowed.empty()) {
        std::error_code allowed_ec;
        const fs::path allowed_data = fs::canonical(allowed, allowed_ec);
        if (!allowed_ec && !ec && allowed_data == data) {
            return;
        }
    }
    const fs::path relative = data.lexically_relative(folder);
    if (ec || relative.empty() || *relative.begin() == "..") {
        throw Error(ErrorCode::InvalidInput,
                    where + ": the data file " + data.string() + " lies outside the folder of " +
                        file.filename().string() +
                        ", expected it beside the header (name it with --allow-data-file " +
                        data.string() + " to read it anyway)");
    }
}

/// Bytes from the read position of `in` to the end of `file` (0 when unknown).
std::uint64_t data_bytes_left(std::istream& in, const std::filesystem::path& file) {
    std::error_code ec;
    const std::uint64_t size = std::filesystem::file_size(file, ec);
    const std::streamoff at = in.tellg();
    if (ec || at < 0) {
        return UINT64_MAX / kMaxDeflateRatio;
    }
    return size > static_cast<std::uint64_t>(at) ? size - static_cast<std::uint64_t>(at) : 0;
}

// ---------------------------------------------------------------------------------------------
// The steps of read_nrrd, in the order it checks the header's fields (a header with several
// faults is refused for the first of them, always the same one).

enum class Encoding { Raw, Gzip, Ascii };

/// How the voxels are stored: the fields 'dimension', 'type', 'encoding', 'endian' and 'sizes'.
struct Storage {
    std::size_t dimension = 0;
    std::string type_name;
    ScalarType type{};
    std::size_t value_bytes = 0;
    std::string encoding_name;
    Encoding encoding = Encoding::Raw;
    bool swap = false;  ///< the file's byte order is not this machine's
    std::vector<std::uint64_t> sizes;
};

Storage parse_storage(const NrrdHeader& header, const std::string& where) {
    Storage storage;
    const auto dimension_value = parse_int(require_field(header, "dimension", where));
    if (!dimension_value || *dimension_value < 1 || *dimension_value > 16) {
        throw Error(ErrorCode::InvalidInput, where + ": header field 'dimension' is \"" +
                                                 require_field(header, "dimension", where) +
                                                 "\", expected 1..16");
    }
    storage.dimension = static_cast<std::size_t>(*dimension_value);

    storage.type_name = require_field(header, "type", where);
    const std::string& type_name = storage.type_name;
    if (type_name == "block") {
        throw Error(ErrorCode::Unsupported,
                    where + ": type 'block' is not supported, expected an integer or real type");
    }
    const std::optional<ScalarType> type = parse_type(type_name);
    if (!type) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": header field 'type' is \"" + type_name +
                        "\", expected a NRRD scalar type (uchar, short, ushort, int, uint, "
                        "longlong, ulonglong, float, double, ...)");
    }
    storage.type = *type;
    storage.value_bytes = scalar_bytes(*type);

    storage.encoding_name = require_field(header, "encoding", where);
    const std::string& encoding_name = storage.encoding_name;
    if (encoding_name == "raw") {
        storage.encoding = Encoding::Raw;
    } else if (encoding_name == "gzip" || encoding_name == "gz") {
        storage.encoding = Encoding::Gzip;
    } else if (encoding_name == "ascii" || encoding_name == "text" || encoding_name == "txt") {
        storage.encoding = Encoding::Ascii;
    } else if (encoding_name == "bzip2" || encoding_name == "bz2" || encoding_name == "hex" ||
               encoding_name == "zrl") {
        throw Error(ErrorCode::Unsupported, where + ": encoding '" + encoding_name +
                                                "' is not supported, expected raw, gzip or ascii");
    } else {
        throw Error(ErrorCode::InvalidInput, where + ": unknown encoding '" + encoding_name +
                                                 "', expected raw, gzip or ascii");
    }

    if (const std::string* endian = find_field(header, "endian")) {
        if (*endian != "little" && *endian != "big") {
            throw Error(ErrorCode::InvalidInput, where + ": header field 'endian' is \"" + *endian +
                                                     "\", expected little or big");
        }
        storage.swap = (*endian == "big") != (std::endian::native == std::endian::big);
    } else if (storage.value_bytes > 1 && storage.encoding != Encoding::Ascii) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": header field 'endian' is missing, expected it for type '" +
                        type_name + "' with encoding '" + encoding_name + "'");
    }

    const std::vector<std::string> size_words =
        axis_values(require_field(header, "sizes", where), "sizes", storage.dimension, where);
    for (std::size_t axis = 0; axis < storage.dimension; ++axis) {
        const auto size = parse_int(size_words[axis]);
        if (!size || *size < 0) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": header field 'sizes' has \"" + size_words[axis] + "\" on axis " +
                            std::to_string(axis) + ", expected a positive integer");
        }
        storage.sizes.push_back(static_cast<std::uint64_t>(*size));
    }
    return storage;
}

/// The world of the axes: 'space' or 'space dimension', then 'space directions' per axis.
struct WorldAxes {
    std::optional<Space> space;
    std::size_t space_dimension = 0;              ///< 0 without a world space, else 3
    bool has_directions = false;                  ///< 'space directions' is given
    std::vector<std::optional<Vec3>> directions;  ///< per axis; none for a non-spatial axis
};

WorldAxes parse_world_axes(const NrrdHeader& header,
                           std::size_t dimension,
                           const std::string& where) {
    WorldAxes world;
    if (const std::string* name = find_field(header, "space")) {
        world.space = parse_space(*name);
        if (!world.space) {
            if (name->find("time") != std::string::npos || *name == "RAST" || *name == "LAST" ||
                *name == "LPST") {
                throw Error(ErrorCode::Unsupported,
                            where + ": space '" + *name +
                                "' has a time axis; expected a 3D space (left-posterior-superior, "
                                "right-anterior-superior, left-anterior-superior)");
            }
            throw Error(ErrorCode::InvalidInput,
                        where + ": unknown space '" + *name +
                            "', expected left-posterior-superior (LPS), right-anterior-superior "
                            "(RAS), left-anterior-superior (LAS), scanner-xyz or 3D-*-handed");
        }
        world.space_dimension = 3;
        if (find_field(header, "space dimension") != nullptr) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": header fields 'space' and 'space dimension' are both given, "
                            "expected one of them");
        }
    } else if (const std::string* value = find_field(header, "space dimension")) {
        const auto n = parse_int(*value);
        if (!n || *n < 1) {
            throw Error(ErrorCode::InvalidInput, where + ": header field 'space dimension' is \"" +
                                                     *value + "\", expected a positive integer");
        }
        if (*n != 3) {
            throw Error(ErrorCode::Unsupported,
                        where + ": space dimension " + *value + ", expected 3 (a 3D world)");
        }
        world.space_dimension = 3;
        world.space = Space{"none", {1, 1, 1}, false};
    }

    world.directions.resize(dimension);
    const std::string* directions_field = find_field(header, "space directions");
    world.has_directions = directions_field != nullptr;
    if (directions_field != nullptr) {
        if (world.space_dimension == 0) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": header field 'space directions' without 'space' or 'space "
                            "dimension', expected one of them first");
        }
        const std::vector<std::string> words =
            axis_values(*directions_field, "space directions", dimension, where);
        for (std::size_t axis = 0; axis < dimension; ++axis) {
            if (words[axis] == "none") {
                continue;
            }
            const auto v = parse_vector(words[axis], world.space_dimension);
            if (!v) {
                throw Error(ErrorCode::InvalidInput,
                            where + ": header field 'space directions' has \"" + words[axis] +
                                "\" on axis " + std::to_string(axis) +
                                ", expected none or a vector (x,y,z) of finite numbers");
            }
            world.directions[axis] = Vec3{(*v)[0], (*v)[1], (*v)[2]};
        }
    }
    return world;
}

/// Refuses a non-spatial axis of more than one sample (a 4D volume, a layered segmentation),
/// then a volume of other than 2 or 3 spatial axes.
void check_axes(const Storage& storage,
                const std::vector<std::size_t>& spatial,
                const std::vector<std::string>& kinds,
                bool is_segmentation,
                const std::string& where) {
    const std::vector<std::uint64_t>& sizes = storage.sizes;
    for (std::size_t axis = 0; axis < storage.dimension; ++axis) {
        if (std::find(spatial.begin(), spatial.end(), axis) != spatial.end()) {
            continue;
        }
        if (sizes[axis] == 0) {
            throw Error(ErrorCode::InvalidInput, where + ": header field 'sizes' has 0 on axis " +
                                                     std::to_string(axis) +
                                                     ": empty dimension, expected at least 1");
        }
        if (sizes[axis] > 1) {
            const std::string kind = kinds.empty() ? "no kind" : "kind '" + kinds[axis] + "'";
            if (is_segmentation) {
                throw Error(ErrorCode::Unsupported,
                            where + ": segmentation with " + std::to_string(sizes[axis]) +
                                " layers (4D seg.nrrd, overlapping segments on axis " +
                                std::to_string(axis) +
                                "); expected a single layer (in 3D Slicer: Segmentations module, "
                                "'Collapse segments to as few layers as possible')");
            }
            throw Error(ErrorCode::Unsupported, where + ": non-spatial axis " +
                                                    std::to_string(axis) + " (" + kind + ") has " +
                                                    std::to_string(sizes[axis]) +
                                                    " samples; expected a single 3D label volume");
        }
    }
    if (spatial.size() < 2 || spatial.size() > 3) {
        throw Error(ErrorCode::Unsupported,
                    where + ": " + std::to_string(spatial.size()) +
                        " spatial axes, expected 2 (one slice) or 3 (a label volume)");
    }
}

/// Voxel index -> patient LPS mm of the `spatial` axes: the directions (or the spacings), the
/// unit and the origin, in the space's axes turned to LPS.
Affine3 index_to_lps(const NrrdHeader& header,
                     const Storage& storage,
                     const WorldAxes& world,
                     const std::vector<std::size_t>& spatial,
                     const std::string& where,
                     Report& report) {
    double unit_mm = 1.0;
    if (const std::string* value = find_field(header, "space units")) {
        for (const std::string& unit : split_axis_values(*value, "space units", where)) {
            const std::string bare =
                unit.size() >= 2 && unit.front() == '"' ? unit.substr(1, unit.size() - 2) : unit;
            const double scale = unit_to_mm(bare);
            if (scale == 0.0) {
                throw Error(ErrorCode::Unsupported,
                            where + ": space unit \"" + bare + "\", expected mm, cm, m or um");
            }
            unit_mm = scale;  // note: one unit for all world axes; mixed units are not seen
        }
    }
    Vec3 spacings{1, 1, 1};
    if (!world.has_directions) {
        if (const std::string* value = find_field(header, "spacings")) {
            const std::vector<std::string> words =
                axis_values(*value, "spacings", storage.dimension, where);
            for (std::size_t s = 0; s < spatial.size(); ++s) {
                const auto parsed = parse_double(words[spatial[s]]);
                if (!parsed) {
                    throw Error(ErrorCode::InvalidInput,
                                where + ": header field 'spacings' has \"" + words[spatial[s]] +
                                    "\" on axis " + std::to_string(spatial[s]) +
                                    ", expected a number");
                }
                spacings[static_cast<int>(s)] = *parsed;
            }
            check_spacing(spacings, where + ": spacings");
        } else {
            report.warn("input", where, "no space directions or spacings; using 1 mm voxels");
        }
    }
    Affine3 affine;
    for (std::size_t s = 0; s < spatial.size(); ++s) {
        Vec3 column{};
        if (world.has_directions) {
            column = *world.directions[spatial[s]];
        } else {
            column[static_cast<int>(s)] = spacings[static_cast<int>(s)];
        }
        for (int r = 0; r < 3; ++r) {
            affine.linear[r][s] = column[r] * unit_mm;
        }
    }
    if (spatial.size() == 2) {
        // note: one slice: the third axis is the unit normal (1 mm), right-handed
        const Vec3 normal = cross(affine.column(0), affine.column(1));
        const double length = norm(normal);
        for (int r = 0; r < 3; ++r) {
            affine.linear[r][2] = length > 0 ? normal[r] / length : (r == 2 ? 1.0 : 0.0);
        }
    }
    if (const std::string* value = find_field(header, "space origin")) {
        if (world.space_dimension == 0) {
            throw Error(ErrorCode::InvalidInput,
                        where +
                            ": header field 'space origin' without 'space' or 'space "
                            "dimension', expected one of them first");
        }
        const auto origin = parse_vector(*value, world.space_dimension);
        if (!origin) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": header field 'space origin' is \"" + *value +
                            "\", expected a vector (x,y,z) of finite numbers");
        }
        for (int r = 0; r < 3; ++r) {
            affine.translation[r] = (*origin)[r] * unit_mm;
        }
    }
    if (world.space) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) {
                affine.linear[r][c] *= world.space->to_lps[r];
            }
            affine.translation[r] *= world.space->to_lps[r];
        }
        if (!world.space->is_patient && world.space->frame != "none") {
            report.warn("input", where,
                        "space '" + world.space->frame +
                            "' is not patient-based; its axes are used as LPS");
        }
    }
    const Vec3 spacing{norm(affine.column(0)), norm(affine.column(1)), norm(affine.column(2))};
    check_spacing(spacing, where + ": " + (world.has_directions ? "space directions" : "spacings"));
    if (std::abs(affine.determinant()) <= 1e-12 * spacing.x * spacing.y * spacing.z) {
        throw Error(ErrorCode::InvalidInput,
                    where + ": space directions are coplanar, expected three independent axes");
    }
    return affine;
}

/// Where the voxels start in the data: 'line skip' lines, then 'byte skip' bytes (-1: the data
/// are the last bytes of a raw file).
struct Skips {
    std::int64_t lines = 0;
    std::int64_t bytes = 0;
};

Skips parse_skips(const NrrdHeader& header, const Storage& storage, const std::string& where) {
    Skips skips;
    if (const std::string* value = find_field(header, "line skip")) {
        const auto n = parse_int(*value);
        if (!n || *n < 0) {
            throw Error(ErrorCode::InvalidInput, where + ": header field 'line skip' is \"" +
                                                     *value + "\", expected 0 or more lines");
        }
        skips.lines = *n;
    }
    if (const std::string* value = find_field(header, "byte skip")) {
        const auto n = parse_int(*value);
        if (!n || *n < -1) {
            throw Error(ErrorCode::InvalidInput, where + ": header field 'byte skip' is \"" +
                                                     *value + "\", expected -1 or more bytes");
        }
        skips.bytes = *n;
        if (skips.bytes == -1 && storage.encoding != Encoding::Raw) {
            throw Error(ErrorCode::InvalidInput,
                        where + ": 'byte skip: -1' is only allowed with raw encoding, not '" +
                            storage.encoding_name + "'");
        }
    }
    return skips;
}

/// Decodes the `count` voxels from `data` (the rest of `data_file`, after the header or in the
/// detached file) into the decoder's stack.
void decode_voxels(std::istream& data,
                   const std::filesystem::path& data_file,
                   const Storage& storage,
                   const Skips& skips,
                   std::uint64_t count,
                   LabelDecoder& decoder,
                   const std::string& data_where) {
    const std::uint64_t expected = count * storage.value_bytes;
    const std::int64_t byte_skip = skips.bytes;
    skip_lines(data, skips.lines, data_where);
    if (storage.encoding == Encoding::Gzip) {
        Inflater inflater(data, data_where);
        if (byte_skip > 0) {
            std::vector<unsigned char> scratch(std::min<std::uint64_t>(byte_skip, kChunkBytes));
            std::uint64_t skipped = 0;
            while (skipped < static_cast<std::uint64_t>(byte_skip)) {
                const std::size_t ask =
                    std::min<std::uint64_t>(byte_skip - skipped, scratch.size());
                const std::size_t got = inflater.read(scratch.data(), ask);
                skipped += got;
                if (got < ask) {
                    throw Error(ErrorCode::InvalidInput,
                                data_where + ": truncated: data ends within the " +
                                    std::to_string(byte_skip) + " bytes of 'byte skip'");
                }
            }
        }
        decoder.decode_all(
            [&](unsigned char* out, std::size_t size) { return inflater.read(out, size); }, "",
            DataBound{data_bytes_left(data, data_file) * kMaxDeflateRatio, false});
        inflater.check_trailer();
        return;
    }
    if (byte_skip == -1) {
        // note: the data are the last `expected` bytes of the file
        data.seekg(0, std::ios::end);
        const auto end = static_cast<std::uint64_t>(data.tellg());
        if (end < expected) {
            throw Error(ErrorCode::InvalidInput,
                        data_where + ": truncated: expected " + std::to_string(expected) +
                            " bytes of voxel data at the end of the file ('byte skip: -1'), "
                            "found " +
                            std::to_string(end));
        }
        data.seekg(static_cast<std::streamoff>(end - expected));
    } else if (byte_skip > 0) {
        data.ignore(byte_skip);
        if (data.gcount() < byte_skip) {
            throw Error(ErrorCode::InvalidInput, data_where + ": truncated: file ends within the " +
                                                     std::to_string(byte_skip) +
                                                     " bytes of 'byte skip'");
        }
    }
    if (storage.encoding == Encoding::Ascii) {
        decode_ascii(data, count, decoder, data_where);
    } else {
        decoder.decode_all([&](unsigned char* out,
                               std::size_t size) { return read_raw(data, out, size, data_where); },
                           "", DataBound{data_bytes_left(data, data_file), true});
    }
}

}  // namespace

SliceStack read_nrrd(const std::filesystem::path& file,
                     const ReadOptions& options,
                     Report& report) {
    const std::string where = file.filename().string();
    std::ifstream in(file, std::ios::binary);
    if (!in) {
        throw Error(ErrorCode::Io,
                    where + ": cannot open " + file.string() + ": " + std::strerror(errno));
    }
    const NrrdHeader header = read_header(in, where, report);
    const Storage storage = parse_storage(header, where);
    const WorldAxes world = parse_world_axes(header, storage.dimension, where);

    // Spatial axes: those with a direction, else those of a spatial kind, else all.
    std::vector<std::string> kinds;
    if (const std::string* value = find_field(header, "kinds")) {
        kinds = axis_values(*value, "kinds", storage.dimension, where);
    }
    std::vector<std::size_t> spatial;
    for (std::size_t axis = 0; axis < storage.dimension; ++axis) {
        const bool is_spatial = world.has_directions ? world.directions[axis].has_value()
                                : !kinds.empty()     ? is_spatial_kind(kinds[axis])
                                                     : true;
        if (is_spatial) {
            spatial.push_back(axis);
        }
    }
    const std::map<int, Segment> segments = parse_segments(header, where);
    check_axes(storage, spatial, kinds, !segments.empty(), where);
    const std::uint64_t width = storage.sizes[spatial[0]];
    const std::uint64_t height = storage.sizes[spatial[1]];
    const std::uint64_t depth = spatial.size() == 3 ? storage.sizes[spatial[2]] : 1;
    check_stack_dimensions(width, height, depth, where, options.max_bytes);
    const Affine3 affine = index_to_lps(header, storage, world, spatial, where, report);

    // Where the data is.
    const Skips skips = parse_skips(header, storage, where);
    std::ifstream detached;
    std::istream* data = &in;
    std::filesystem::path data_file = file;
    std::string data_where = where;
    if (const std::string* value = find_field(header, "data file")) {
        if (*value == "LIST" || value->rfind("LIST ", 0) == 0 ||
            value->find('%') != std::string::npos) {
            throw Error(ErrorCode::Unsupported,
                        where + ": 'data file: " + *value +
                            "' names several data files; expected a single data file");
        }
        std::filesystem::path data_path(*value);
        if (data_path.is_relative()) {
            data_path = file.parent_path() / data_path;
        }
        data_where = where + ": data file " + *value;
        check_data_file(file, data_path, options.allowed_data_file, data_where);
        detached.open(data_path, std::ios::binary);
        if (!detached) {
            throw Error(ErrorCode::Io, data_where + ": cannot open " + data_path.string() + ": " +
                                           std::strerror(errno));
        }
        data = &detached;
        data_file = data_path;
    } else if (!header.has_blank_line) {
        throw Error(ErrorCode::InvalidInput,
                    where +
                        ": truncated: the header has no 'data file' and no blank line "
                        "followed by attached data");
    }

    SliceStack stack;
    stack.width = static_cast<std::uint32_t>(width);
    stack.height = static_cast<std::uint32_t>(height);
    stack.depth = static_cast<std::uint32_t>(depth);
    stack.index_to_world = affine;
    stack.source = file.string();
    stack.source_frame = world.space ? world.space->frame : "none";
    if (!segments.empty()) {
        stack.label_table = segment_label_table(segments, where, report);
    }
    LabelDecoder decoder(storage.type, storage.swap, stack, data_where, options.progress);
    decode_voxels(*data, data_file, storage, skips, width * height * depth, decoder, data_where);
    return stack;
}

}  // namespace strata::detail

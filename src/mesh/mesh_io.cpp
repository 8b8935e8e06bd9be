// Triangle mesh files: PLY (Turk, "The PLY polygon file format", 1994), Wavefront OBJ
// (Wavefront Technologies, "Object Files (.obj)", Advanced Visualizer manual, appendix B1) and
// STL (3D Systems, "StereoLithography Interface Specification", 1988).
//
// Readers load the whole file and parse it from memory, checking every count against the bytes
// that are actually there before allocating, so a lying header cannot cause a huge allocation.
// Writers build the file in memory and hand it to write_file_atomically.
#include "mesh/mesh_io.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <vector>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"

namespace strata {

namespace {

using Triangle = std::array<std::uint32_t, 3>;
constexpr std::uint64_t kMaxVertices = std::numeric_limits<std::uint32_t>::max();

// ---------------------------------------------------------------------------------------------
// Common helpers

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

std::string read_file(const std::filesystem::path& path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) {
        fail(ErrorCode::Io, path, "is a folder, expected a mesh file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        fail(ErrorCode::Io, path, std::string("cannot open for reading: ") + std::strerror(errno));
    }
    std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) {
        fail(ErrorCode::Io, path, "read error");
    }
    return data;
}

template <class T>
T load_le(const char* p) {
    static_assert(std::is_unsigned_v<T>);
    T value = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) {
        value =
            static_cast<T>(value | (static_cast<T>(static_cast<unsigned char>(p[i])) << (8 * i)));
    }
    return value;
}

template <class T>
void store_le(std::string& out, T value) {
    static_assert(std::is_unsigned_v<T>);
    for (std::size_t i = 0; i < sizeof(T); ++i) {
        out.push_back(static_cast<char>((value >> (8 * i)) & 0xFF));
    }
}

void store_f32(std::string& out, float value) {
    store_le(out, std::bit_cast<std::uint32_t>(value));
}

bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// Splits a line at blanks.
void split(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && is_space(line[i])) {
            ++i;
        }
        const std::size_t begin = i;
        while (i < line.size() && !is_space(line[i])) {
            ++i;
        }
        if (i > begin) {
            tokens.push_back(line.substr(begin, i - begin));
        }
    }
}

/// Reads a text file line by line, counting lines from 1.
class Lines {
public:
    explicit Lines(std::string_view text, std::size_t offset = 0, std::size_t first_line = 1)
        : text_(text), pos_(offset), next_number_(first_line) {}

    bool next(std::string_view& line) {
        if (pos_ >= text_.size()) {
            return false;
        }
        const std::size_t end = std::min(text_.find('\n', pos_), text_.size());
        line = text_.substr(pos_, end - pos_);
        if (!line.empty() && line.back() == '\r') {
            line.remove_suffix(1);
        }
        pos_ = end + 1;
        number_ = next_number_++;
        return true;
    }

    std::size_t number() const { return number_; }
    std::size_t offset() const { return std::min(pos_, text_.size()); }

private:
    std::string_view text_;
    std::size_t pos_ = 0;
    std::size_t next_number_ = 1;
    std::size_t number_ = 0;
};

std::string quote_token(std::string_view token) {
    constexpr std::size_t kMax = 40;
    std::string out = "'";
    for (char c : token.substr(0, kMax)) {
        out += (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) ? '?'
                                                                                              : c;
    }
    return out + (token.size() > kMax ? "...'" : "'");
}

std::optional<double> parse_double(std::string_view token) {
    if (!token.empty() && token.front() == '+') {
        token.remove_prefix(1);
    }
    double value = 0.0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size() || token.empty()) {
        return std::nullopt;
    }
    return value;
}

std::optional<std::int64_t> parse_int(std::string_view token) {
    if (!token.empty() && token.front() == '+') {
        token.remove_prefix(1);
    }
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size() || token.empty()) {
        return std::nullopt;
    }
    return value;
}

bool is_finite(const Vec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// Welds corners with exactly equal coordinates (0 and -0 are equal), first appearance first.
class Welder {
public:
    explicit Welder(TriMesh& mesh) : mesh_(mesh) {}

    std::uint32_t add(Vec3 p) {
        // note: + 0.0 turns -0.0 into +0.0 so both hash alike.
        const Key key{std::bit_cast<std::uint64_t>(p.x + 0.0),
                      std::bit_cast<std::uint64_t>(p.y + 0.0),
                      std::bit_cast<std::uint64_t>(p.z + 0.0)};
        const auto [it, inserted] =
            index_.try_emplace(key, static_cast<std::uint32_t>(mesh_.positions.size()));
        if (inserted) {
            mesh_.positions.push_back(p);
        }
        return it->second;
    }

private:
    using Key = std::array<std::uint64_t, 3>;
    struct Hash {
        std::size_t operator()(const Key& k) const {
            std::uint64_t h = 0x9E3779B97F4A7C15ull;
            for (std::uint64_t v : k) {
                h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
            }
            return static_cast<std::size_t>(h);
        }
    };
    TriMesh& mesh_;
    std::unordered_map<Key, std::uint32_t, Hash> index_;
};

// ---------------------------------------------------------------------------------------------
// Writing

/// Positions as float32, checked: indices in range, labels sized right, coordinates finite.
std::vector<std::array<float, 3>> checked_float_positions(const TriMesh& mesh,
                                                          const std::filesystem::path& path) {
    const std::size_t n = mesh.positions.size();
    if (n > kMaxVertices) {
        fail(ErrorCode::InvalidInput, path,
             "cannot write " + std::to_string(n) + " vertices, at most " +
                 std::to_string(kMaxVertices) + " can be indexed");
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (std::uint32_t v : mesh.triangles[t]) {
            if (v >= n) {
                fail(ErrorCode::InvalidInput, path,
                     "cannot write triangle " + std::to_string(t) + ": vertex index " +
                         std::to_string(v) + " out of range, expected < " + std::to_string(n) +
                         " (the vertex count)");
            }
        }
    }
    if (!mesh.labels.empty() && mesh.labels.size() != mesh.triangles.size()) {
        fail(ErrorCode::InvalidInput, path,
             "cannot write " + std::to_string(mesh.labels.size()) + " labels for " +
                 std::to_string(mesh.triangles.size()) + " triangles, expected one per triangle");
    }
    std::vector<std::array<float, 3>> out(n);
    constexpr double kMaxFloat = std::numeric_limits<float>::max();
    for (std::size_t v = 0; v < n; ++v) {
        for (int k = 0; k < 3; ++k) {
            const double x = mesh.positions[v][k];
            if (!(std::abs(x) <= kMaxFloat)) {
                fail(ErrorCode::InvalidInput, path,
                     "cannot write vertex " + std::to_string(v) + ": coordinate " +
                         std::to_string(x) + " is not a finite float32");
            }
            out[v][k] = static_cast<float>(x);
        }
    }
    return out;
}

/// Normals as float32, checked: one per vertex (or none), finite.
std::vector<std::array<float, 3>> checked_float_normals(const TriMesh& mesh,
                                                        const std::vector<Vec3>& normals,
                                                        const std::filesystem::path& path) {
    if (!normals.empty() && normals.size() != mesh.positions.size()) {
        fail(ErrorCode::InvalidInput, path,
             "cannot write " + std::to_string(normals.size()) + " normals for " +
                 std::to_string(mesh.positions.size()) + " vertices, expected one per vertex");
    }
    std::vector<std::array<float, 3>> out(normals.size());
    for (std::size_t v = 0; v < normals.size(); ++v) {
        for (int k = 0; k < 3; ++k) {
            const double x = normals[v][k];
            if (!(std::abs(x) <= 1.0 + 1e-6)) {
                fail(ErrorCode::InvalidInput, path,
                     "cannot write the normal of vertex " + std::to_string(v) + ": component " +
                         std::to_string(x) + ", expected a unit vector");
            }
            out[v][k] = static_cast<float>(x);
        }
    }
    return out;
}

std::string encode_ply(const TriMesh& mesh,
                       const std::vector<std::array<float, 3>>& positions,
                       const std::vector<std::array<float, 3>>& normals) {
    const bool labelled = !mesh.labels.empty();
    std::string out =
        "ply\nformat binary_little_endian 1.0\ncomment written by strata\nelement vertex " +
        std::to_string(positions.size()) +
        "\nproperty float x\nproperty float y\nproperty float z" +
        (normals.empty() ? "" : "\nproperty float nx\nproperty float ny\nproperty float nz") +
        "\nelement face " + std::to_string(mesh.triangles.size()) +
        "\nproperty list uchar uint vertex_indices\n" +
        (labelled ? "property ushort label\n" : "") + "end_header\n";
    out.reserve(out.size() + 12 * positions.size() + (labelled ? 15 : 13) * mesh.triangles.size());
    for (std::size_t v = 0; v < positions.size(); ++v) {
        for (int k = 0; k < 3; ++k) {
            store_f32(out, positions[v][std::size_t(k)]);
        }
        if (!normals.empty()) {
            for (int k = 0; k < 3; ++k) {
                store_f32(out, normals[v][std::size_t(k)]);
            }
        }
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        out.push_back(3);
        for (std::uint32_t v : mesh.triangles[t]) {
            store_le(out, v);
        }
        if (labelled) {
            store_le(out, mesh.labels[t]);
        }
    }
    return out;
}

void append_float(std::string& out, float value) {
    char buffer[32];
    const auto [end, ec] = std::to_chars(buffer, buffer + sizeof(buffer), value);
    out.append(buffer, end);
}

std::string encode_obj(const TriMesh& mesh,
                       const std::vector<std::array<float, 3>>& positions,
                       const std::vector<std::array<float, 3>>& normals) {
    std::string out = "# written by strata: " + std::to_string(positions.size()) + " vertices, " +
                      std::to_string(mesh.triangles.size()) + " triangles\n";
    out.reserve(out.size() + 36 * positions.size() + 24 * mesh.triangles.size());
    auto append_rows = [&](const char* keyword, const std::vector<std::array<float, 3>>& rows) {
        for (const auto& p : rows) {
            out += keyword;
            append_float(out, p[0]);
            out += ' ';
            append_float(out, p[1]);
            out += ' ';
            append_float(out, p[2]);
            out += '\n';
        }
    };
    append_rows("v ", positions);
    append_rows("vn ", normals);
    for (const Triangle& t : mesh.triangles) {
        out += 'f';
        for (const std::uint32_t v : t) {
            const std::string index = std::to_string(std::uint64_t{v} + 1);
            out += ' ' + index + (normals.empty() ? "" : "//" + index);
        }
        out += '\n';
    }
    return out;
}

std::string encode_stl(const TriMesh& mesh, const std::vector<std::array<float, 3>>& positions) {
    if (mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max()) {
        throw Error(ErrorCode::InvalidInput, "binary STL holds at most 2^32 - 1 triangles");
    }
    // note: the header must not start with "solid", or readers take the file for ASCII STL.
    std::string out = "binary STL written by strata";
    out.resize(80, ' ');
    out.reserve(84 + 50 * mesh.triangles.size());
    store_le(out, static_cast<std::uint32_t>(mesh.triangles.size()));
    for (const Triangle& t : mesh.triangles) {
        Vec3 corner[3];
        for (int k = 0; k < 3; ++k) {
            const auto& p = positions[t[k]];
            corner[k] = {p[0], p[1], p[2]};
        }
        Vec3 normal = cross(corner[1] - corner[0], corner[2] - corner[0]);
        const double length = norm(normal);
        normal = length > 0.0 ? (1.0 / length) * normal : Vec3{};
        for (int k = 0; k < 3; ++k) {
            store_f32(out, static_cast<float>(normal[k]));
        }
        for (int c = 0; c < 3; ++c) {
            for (int k = 0; k < 3; ++k) {
                store_f32(out, positions[t[c]][k]);
            }
        }
        store_le(out, std::uint16_t{0});
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// PLY reading

enum class PlyType { Int8, Uint8, Int16, Uint16, Int32, Uint32, Float32, Float64 };

std::optional<PlyType> ply_type(std::string_view name) {
    static constexpr std::pair<std::string_view, PlyType> kNames[] = {
        {"char", PlyType::Int8},       {"int8", PlyType::Int8},       {"uchar", PlyType::Uint8},
        {"uint8", PlyType::Uint8},     {"short", PlyType::Int16},     {"int16", PlyType::Int16},
        {"ushort", PlyType::Uint16},   {"uint16", PlyType::Uint16},   {"int", PlyType::Int32},
        {"int32", PlyType::Int32},     {"uint", PlyType::Uint32},     {"uint32", PlyType::Uint32},
        {"float", PlyType::Float32},   {"float32", PlyType::Float32}, {"double", PlyType::Float64},
        {"float64", PlyType::Float64},
    };
    for (const auto& [n, type] : kNames) {
        if (n == name) {
            return type;
        }
    }
    return std::nullopt;
}

std::size_t ply_size(PlyType type) {
    switch (type) {
        case PlyType::Int8:
        case PlyType::Uint8:
            return 1;
        case PlyType::Int16:
        case PlyType::Uint16:
            return 2;
        case PlyType::Int32:
        case PlyType::Uint32:
        case PlyType::Float32:
            return 4;
        case PlyType::Float64:
            return 8;
    }
    return 0;
}

bool is_integer(PlyType type) {
    return type != PlyType::Float32 && type != PlyType::Float64;
}

std::pair<std::int64_t, std::int64_t> integer_range(PlyType type) {
    switch (type) {
        case PlyType::Int8:
            return {-128, 127};
        case PlyType::Uint8:
            return {0, 255};
        case PlyType::Int16:
            return {-32768, 32767};
        case PlyType::Uint16:
            return {0, 65535};
        case PlyType::Int32:
            return {std::numeric_limits<std::int32_t>::min(),
                    std::numeric_limits<std::int32_t>::max()};
        default:
            return {0, std::numeric_limits<std::uint32_t>::max()};
    }
}

struct PlyProperty {
    std::string name;
    PlyType type = PlyType::Float32;  ///< the value type (of the items, for lists)
    bool is_list = false;
    PlyType count_type = PlyType::Uint8;
};

struct PlyElement {
    std::string name;
    std::uint64_t count = 0;
    std::vector<PlyProperty> properties;

    /// Bytes of one row in binary, or nullopt when it has lists.
    std::optional<std::size_t> fixed_row_size() const {
        std::size_t size = 0;
        for (const auto& p : properties) {
            if (p.is_list) {
                return std::nullopt;
            }
            size += ply_size(p.type);
        }
        return size;
    }
    /// Fewest bytes of one row in binary (every list empty).
    std::size_t min_row_size() const {
        std::size_t size = 0;
        for (const auto& p : properties) {
            size += p.is_list ? ply_size(p.count_type) : ply_size(p.type);
        }
        return std::max<std::size_t>(size, 1);
    }
    int find(std::string_view property) const {
        for (std::size_t i = 0; i < properties.size(); ++i) {
            if (properties[i].name == property) {
                return static_cast<int>(i);
            }
        }
        return -1;
    }
};

struct PlyHeader {
    bool binary = false;
    std::vector<PlyElement> elements;
    std::size_t body_offset = 0;  ///< first byte after "end_header\n"
    std::size_t body_line = 0;    ///< line number of the first body line (ASCII)
};

PlyHeader parse_ply_header(std::string_view data, const std::filesystem::path& path) {
    Lines lines(data);
    std::string_view line;
    if (!lines.next(line) || line != "ply") {
        fail(ErrorCode::InvalidInput, path,
             "not a PLY file: first line is " + quote_token(line.substr(0, 20)) +
                 ", expected 'ply'");
    }
    PlyHeader header;
    bool have_format = false;
    bool ended = false;
    std::vector<std::string_view> tokens;
    while (lines.next(line)) {
        split(line, tokens);
        auto bad = [&](const std::string& what) {
            return Error(ErrorCode::InvalidInput, path.string() + ": PLY header line " +
                                                      std::to_string(lines.number()) + ": " + what);
        };
        if (tokens.empty() || tokens[0] == "comment" || tokens[0] == "obj_info") {
            continue;
        }
        if (tokens[0] == "end_header") {
            ended = true;
            break;
        }
        if (tokens[0] == "format") {
            if (tokens.size() != 3 || tokens[2] != "1.0") {
                throw bad("expected 'format <ascii|binary_little_endian> 1.0'");
            }
            if (tokens[1] == "ascii") {
                header.binary = false;
            } else if (tokens[1] == "binary_little_endian") {
                header.binary = true;
            } else if (tokens[1] == "binary_big_endian") {
                fail(ErrorCode::Unsupported, path,
                     "PLY format binary_big_endian is not supported, expected ascii or "
                     "binary_little_endian");
            } else {
                throw bad("unknown format " + quote_token(tokens[1]) +
                          ", expected ascii or binary_little_endian");
            }
            have_format = true;
        } else if (tokens[0] == "element") {
            const auto count = tokens.size() == 3 ? parse_int(tokens[2]) : std::nullopt;
            if (!count || *count < 0) {
                throw bad("expected 'element <name> <count>' with a count >= 0");
            }
            for (const auto& e : header.elements) {
                if (e.name == tokens[1]) {
                    throw bad("element " + quote_token(tokens[1]) + " declared twice");
                }
            }
            header.elements.push_back({std::string(tokens[1]), std::uint64_t(*count), {}});
        } else if (tokens[0] == "property") {
            if (header.elements.empty()) {
                throw bad("property before any element");
            }
            PlyProperty property;
            if (tokens.size() == 5 && tokens[1] == "list") {
                const auto count_type = ply_type(tokens[2]);
                const auto item_type = ply_type(tokens[3]);
                if (!count_type || !item_type) {
                    throw bad("unknown type in " + quote_token(line) +
                              ", expected char, uchar, short, ushort, int, uint, float or double");
                }
                if (!is_integer(*count_type)) {
                    throw bad("list count type " + quote_token(tokens[2]) +
                              " must be an integer type");
                }
                property = {std::string(tokens[4]), *item_type, true, *count_type};
            } else if (tokens.size() == 3 && tokens[1] != "list") {
                const auto type = ply_type(tokens[1]);
                if (!type) {
                    throw bad("unknown property type " + quote_token(tokens[1]) +
                              ", expected char, uchar, short, ushort, int, uint, float or double");
                }
                property = {std::string(tokens[2]), *type, false, PlyType::Uint8};
            } else {
                throw bad(
                    "expected 'property <type> <name>' or 'property list <count type> <type> "
                    "<name>'");
            }
            header.elements.back().properties.push_back(std::move(property));
        } else {
            throw bad("unknown keyword " + quote_token(tokens[0]) +
                      ", expected format, element, property, comment or end_header");
        }
    }
    if (!ended) {
        fail(ErrorCode::InvalidInput, path, "PLY header has no end_header line");
    }
    if (!have_format) {
        fail(ErrorCode::InvalidInput, path, "PLY header has no format line");
    }
    header.body_offset = lines.offset();
    header.body_line = lines.number() + 1;
    return header;
}

/// Thrown by the row readers; the element loop adds the context.
struct RowError {
    std::string message;
    bool truncated = false;
};

class BinaryRows {
public:
    BinaryRows(std::string_view data, std::size_t offset) : data_(data), pos_(offset) {}

    void begin_row() {}
    void end_row() {}

    double scalar(PlyType type) {
        const std::size_t size = ply_size(type);
        if (data_.size() - pos_ < size) {
            throw RowError{"needs " + std::to_string(size) + " more bytes at byte " +
                               std::to_string(pos_) + ", only " +
                               std::to_string(data_.size() - pos_) + " left",
                           true};
        }
        const char* p = data_.data() + pos_;
        pos_ += size;
        switch (type) {
            case PlyType::Int8:
                return static_cast<std::int8_t>(load_le<std::uint8_t>(p));
            case PlyType::Uint8:
                return load_le<std::uint8_t>(p);
            case PlyType::Int16:
                return static_cast<std::int16_t>(load_le<std::uint16_t>(p));
            case PlyType::Uint16:
                return load_le<std::uint16_t>(p);
            case PlyType::Int32:
                return static_cast<std::int32_t>(load_le<std::uint32_t>(p));
            case PlyType::Uint32:
                return load_le<std::uint32_t>(p);
            case PlyType::Float32:
                return std::bit_cast<float>(load_le<std::uint32_t>(p));
            case PlyType::Float64:
                return std::bit_cast<double>(load_le<std::uint64_t>(p));
        }
        return 0.0;
    }

    /// Rows the remaining bytes can hold at most.
    std::uint64_t capacity(const PlyElement& element) const {
        return (data_.size() - pos_) / element.min_row_size();
    }

    /// Throws unless the element's rows fit in the remaining bytes.
    void check_fits(const PlyElement& element, const std::filesystem::path& path) const {
        const std::uint64_t left = data_.size() - pos_;
        const auto fixed = element.fixed_row_size();
        const std::uint64_t row = fixed ? *fixed : element.min_row_size();
        if (row != 0 && element.count > left / row) {
            fail(ErrorCode::InvalidInput, path,
                 "truncated: element '" + element.name + "' has " + std::to_string(element.count) +
                     " rows of " + (fixed ? "" : "at least ") + std::to_string(row) +
                     " bytes, but only " + std::to_string(left) + " bytes follow byte " +
                     std::to_string(pos_));
        }
    }

    std::string where() const { return "byte " + std::to_string(pos_); }

    void finish(const std::filesystem::path& path) const {
        if (pos_ != data_.size()) {
            fail(ErrorCode::InvalidInput, path,
                 std::to_string(data_.size() - pos_) +
                     " unexpected bytes after the last element (from byte " + std::to_string(pos_) +
                     "), expected the file to end there");
        }
    }

private:
    std::string_view data_;
    std::size_t pos_;
};

class AsciiRows {
public:
    AsciiRows(std::string_view data, std::size_t offset, std::size_t first_line)
        : lines_(data, offset, first_line), bytes_left_(data.size() - offset) {}

    void begin_row() {
        std::string_view line;
        do {
            if (!lines_.next(line)) {
                throw RowError{"unexpected end of file", true};
            }
            split(line, tokens_);
        } while (tokens_.empty());
        next_ = 0;
    }

    void end_row() {
        if (next_ != tokens_.size()) {
            throw RowError{"line " + std::to_string(lines_.number()) + " has " +
                           std::to_string(tokens_.size()) + " values, expected " +
                           std::to_string(next_)};
        }
    }

    double scalar(PlyType type) {
        if (next_ >= tokens_.size()) {
            throw RowError{"line " + std::to_string(lines_.number()) + " has too few values (" +
                           std::to_string(tokens_.size()) + ")"};
        }
        const std::string_view token = tokens_[next_++];
        if (is_integer(type)) {
            const auto value = parse_int(token);
            const auto [lo, hi] = integer_range(type);
            if (!value || *value < lo || *value > hi) {
                throw RowError{"line " + std::to_string(lines_.number()) + ": " +
                               quote_token(token) + " is not an integer in [" + std::to_string(lo) +
                               ", " + std::to_string(hi) + "]"};
            }
            return static_cast<double>(*value);
        }
        const auto value = parse_double(token);
        if (!value) {
            throw RowError{"line " + std::to_string(lines_.number()) + ": " + quote_token(token) +
                           " is not a number"};
        }
        return *value;
    }

    std::uint64_t capacity(const PlyElement&) const { return bytes_left_ / 2 + 1; }
    void check_fits(const PlyElement&, const std::filesystem::path&) const {}
    std::string where() const { return "line " + std::to_string(lines_.number()); }

    void finish(const std::filesystem::path& path) {
        std::string_view line;
        while (lines_.next(line)) {
            split(line, tokens_);
            if (!tokens_.empty()) {
                fail(ErrorCode::InvalidInput, path,
                     "unexpected data after the last element at line " +
                         std::to_string(lines_.number()) + ": " + quote_token(line));
            }
        }
    }

private:
    Lines lines_;
    std::size_t bytes_left_;
    std::vector<std::string_view> tokens_;
    std::size_t next_ = 0;
};

/// The properties of an element that read_ply_body uses (-1: none): the vertex coordinates, the
/// face's corner list and label.
struct PlyColumns {
    int x = -1;
    int y = -1;
    int z = -1;
    int corners = -1;
    int label = -1;
};

PlyColumns ply_columns(const PlyElement& element,
                       bool is_vertex,
                       bool is_face,
                       const std::filesystem::path& path) {
    PlyColumns columns;
    int& x = columns.x;
    int& y = columns.y;
    int& z = columns.z;
    int& corners = columns.corners;
    int& label = columns.label;
    if (is_vertex) {
        x = element.find("x");
        y = element.find("y");
        z = element.find("z");
        if (x < 0 || y < 0 || z < 0 || element.properties[x].is_list ||
            element.properties[y].is_list || element.properties[z].is_list) {
            fail(ErrorCode::InvalidInput, path,
                 "PLY element 'vertex' needs scalar properties x, y and z");
        }
    }
    if (is_face) {
        corners = element.find("vertex_indices");
        if (corners < 0) {
            corners = element.find("vertex_index");
        }
        if (corners < 0 || !element.properties[corners].is_list ||
            !is_integer(element.properties[corners].type)) {
            fail(ErrorCode::InvalidInput, path,
                 "PLY element 'face' needs an integer list property vertex_indices");
        }
        label = element.find("label");
        if (label >= 0 &&
            (element.properties[label].is_list || !is_integer(element.properties[label].type))) {
            fail(ErrorCode::InvalidInput, path,
                 "PLY face property 'label' must be a scalar integer");
        }
    }
    return columns;
}

/// The rows of one element: vertices to positions, faces fanned into triangles (and labels).
template <class Rows>
void read_ply_rows(Rows& rows,
                   const PlyElement& element,
                   bool is_vertex,
                   bool is_face,
                   const PlyColumns& columns,
                   std::uint64_t vertex_count,
                   TriMesh& mesh,
                   const std::filesystem::path& path) {
    const auto [x, y, z, corners, label] = columns;
    std::vector<double> values;
    std::uint64_t row = 0;
    auto context = [&] {
        return element.name + " " + std::to_string(row) + " of " + std::to_string(element.count) +
               " (" + rows.where() + ")";
    };
    try {
        for (; row < element.count; ++row) {
            rows.begin_row();
            Vec3 position;
            std::uint16_t row_label = 0;
            for (std::size_t p = 0; p < element.properties.size(); ++p) {
                const PlyProperty& property = element.properties[p];
                if (!property.is_list) {
                    const double value = rows.scalar(property.type);
                    const int index = static_cast<int>(p);
                    if (index == x || index == y || index == z) {
                        if (!std::isfinite(value)) {
                            throw RowError{"non-finite coordinate " + property.name};
                        }
                        position[index == x ? 0 : (index == y ? 1 : 2)] = value;
                    } else if (index == label) {
                        if (value < 0 || value > 65535) {
                            throw RowError{"label " + std::to_string(std::int64_t(value)) +
                                           " out of range, expected 0 to 65535"};
                        }
                        row_label = static_cast<std::uint16_t>(value);
                    }
                    continue;
                }
                const double count = rows.scalar(property.count_type);
                if (count < 0) {
                    throw RowError{"negative list length " + std::to_string(std::int64_t(count))};
                }
                const bool is_corners = static_cast<int>(p) == corners;
                if (is_corners && count < 3) {
                    throw RowError{std::to_string(std::int64_t(count)) +
                                   " corners, expected at least 3"};
                }
                values.clear();
                for (std::uint64_t i = 0; i < static_cast<std::uint64_t>(count); ++i) {
                    const double value = rows.scalar(property.type);
                    if (is_corners) {
                        if (value < 0 || value >= static_cast<double>(vertex_count)) {
                            throw RowError{"vertex index " + std::to_string(std::int64_t(value)) +
                                           " out of range, expected 0 to " +
                                           std::to_string(std::int64_t(vertex_count) - 1) + " (" +
                                           std::to_string(vertex_count) + " vertices)"};
                        }
                        values.push_back(value);
                    }
                }
                for (std::size_t i = 1; is_corners && i + 1 < values.size(); ++i) {
                    mesh.triangles.push_back({static_cast<std::uint32_t>(values[0]),
                                              static_cast<std::uint32_t>(values[i]),
                                              static_cast<std::uint32_t>(values[i + 1])});
                }
            }
            rows.end_row();
            if (is_vertex) {
                mesh.positions.push_back(position);
            }
            if (is_face && label >= 0) {
                mesh.labels.resize(mesh.triangles.size(), row_label);
            }
        }
    } catch (const RowError& e) {
        fail(ErrorCode::InvalidInput, path,
             std::string(e.truncated ? "truncated: " : "") + context() + ": " + e.message);
    }
}

template <class Rows>
void read_ply_body(Rows& rows,
                   const PlyHeader& header,
                   TriMesh& mesh,
                   const std::filesystem::path& path) {
    const PlyElement* vertices = nullptr;
    for (const auto& e : header.elements) {
        if (e.name == "vertex") {
            vertices = &e;
        }
    }
    if (vertices == nullptr) {
        fail(ErrorCode::InvalidInput, path, "PLY header has no 'vertex' element");
    }
    if (vertices->count > kMaxVertices) {
        fail(ErrorCode::InvalidInput, path,
             std::to_string(vertices->count) + " vertices, at most " +
                 std::to_string(kMaxVertices) + " are supported");
    }
    const std::uint64_t vertex_count = vertices->count;

    for (const PlyElement& element : header.elements) {
        rows.check_fits(element, path);
        const bool is_vertex = &element == vertices;
        const bool is_face = element.name == "face";
        const PlyColumns columns = ply_columns(element, is_vertex, is_face, path);
        if (is_vertex) {
            mesh.positions.reserve(std::min(element.count, rows.capacity(element)));
        }
        if (is_face) {
            mesh.triangles.reserve(std::min(element.count, rows.capacity(element)));
            if (columns.label >= 0) {
                mesh.labels.reserve(mesh.triangles.capacity());
            }
        }
        read_ply_rows(rows, element, is_vertex, is_face, columns, vertex_count, mesh, path);
    }
    rows.finish(path);
}

TriMesh read_ply(std::string_view data, const std::filesystem::path& path) {
    const PlyHeader header = parse_ply_header(data, path);
    TriMesh mesh;
    if (header.binary) {
        BinaryRows rows(data, header.body_offset);
        read_ply_body(rows, header, mesh, path);
    } else {
        AsciiRows rows(data, header.body_offset, header.body_line);
        read_ply_body(rows, header, mesh, path);
    }
    return mesh;
}

// ---------------------------------------------------------------------------------------------
// OBJ reading

bool is_ignored_obj_statement(std::string_view keyword) {
    static constexpr std::string_view kIgnored[] = {
        "vt",     "vn",     "vp",       "o",        "g",    "s",          "mg",        "usemtl",
        "mtllib", "l",      "p",        "cstype",   "deg",  "bmat",       "step",      "curv",
        "curv2",  "surf",   "parm",     "trim",     "hole", "scrv",       "sp",        "end",
        "con",    "bevel",  "c_interp", "d_interp", "lod",  "shadow_obj", "trace_obj", "ctech",
        "stech",  "maplib", "usemap",   "call",     "csh",
    };
    return std::find(std::begin(kIgnored), std::end(kIgnored), keyword) != std::end(kIgnored);
}

/// A line of an OBJ file, for its errors.
struct ObjLine {
    const std::filesystem::path& path;
    std::size_t number;

    Error bad(const std::string& what) const {
        return Error(ErrorCode::InvalidInput,
                     path.string() + ": line " + std::to_string(number) + ": " + what);
    }
};

/// The position of a 'v' statement (`tokens` after the keyword's split); `count` vertices came
/// before it.
Vec3 obj_vertex(const std::vector<std::string_view>& tokens, std::size_t count, const ObjLine& at) {
    auto bad = [&](const std::string& what) { return at.bad(what); };
    if (tokens.size() < 4 || tokens.size() > 8) {
        throw bad("'v' needs 3 coordinates (optionally w or a colour), found " +
                  std::to_string(tokens.size() - 1) + " values");
    }
    Vec3 p;
    for (std::size_t k = 1; k < tokens.size(); ++k) {
        const auto value = parse_double(tokens[k]);
        if (!value) {
            throw bad("vertex coordinate " + quote_token(tokens[k]) + " is not a number");
        }
        if (k <= 3) {
            if (!std::isfinite(*value)) {
                throw bad("vertex " + std::to_string(count + 1) + " has a non-finite coordinate " +
                          quote_token(tokens[k]));
            }
            p[static_cast<int>(k - 1)] = *value;
        }
    }
    if (count >= kMaxVertices) {
        throw bad("more than " + std::to_string(kMaxVertices) + " vertices");
    }
    return p;
}

/// The corners of an 'f' statement (0-based vertex indices; relative ones resolved against the
/// `so_far` vertices read); the largest positive index and its line go to `max_index`.
void obj_face(const std::vector<std::string_view>& tokens,
              std::int64_t so_far,
              const ObjLine& at,
              std::vector<std::uint32_t>& corners,
              std::uint64_t& max_index,
              std::size_t& max_index_line) {
    auto bad = [&](const std::string& what) { return at.bad(what); };
    const std::size_t line_number = at.number;
    if (tokens.size() < 4) {
        throw bad("face with " + std::to_string(tokens.size() - 1) +
                  " corners, expected at least 3");
    }
    corners.clear();
    for (std::size_t k = 1; k < tokens.size(); ++k) {
        const std::string_view corner = tokens[k];
        // v, v/vt, v//vn or v/vt/vn: only v is used, the others must be well formed.
        std::string_view parts[3];
        std::size_t part_count = 0;
        std::size_t begin = 0;
        while (true) {
            const std::size_t slash = corner.find('/', begin);
            if (part_count == 3) {
                throw bad("face corner " + quote_token(corner) +
                          ": expected v, v/vt, v//vn or v/vt/vn");
            }
            parts[part_count++] = corner.substr(begin, slash - begin);
            if (slash == std::string_view::npos) {
                break;
            }
            begin = slash + 1;
        }
        for (std::size_t i = 1; i < part_count; ++i) {
            const bool may_be_empty = i == 1 && part_count == 3;
            if (parts[i].empty() && may_be_empty) {
                continue;
            }
            const auto index = parse_int(parts[i]);
            if (!index || *index == 0) {
                throw bad("face corner " + quote_token(corner) +
                          ": expected v, v/vt, v//vn or v/vt/vn with non-zero integers");
            }
        }
        const auto index = parse_int(parts[0]);
        if (!index) {
            throw bad("face corner " + quote_token(corner) + ": vertex index is not an integer");
        }
        if (*index == 0) {
            throw bad("face vertex index 0 is invalid, OBJ indices start at 1");
        } else if (*index < 0) {
            if (*index < -so_far) {
                throw bad("relative face vertex index " + std::to_string(*index) +
                          " points before the first vertex, only " + std::to_string(so_far) +
                          " vertices so far");
            }
            corners.push_back(static_cast<std::uint32_t>(so_far + *index));
        } else {
            if (static_cast<std::uint64_t>(*index) > kMaxVertices) {
                throw bad("face vertex index " + std::to_string(*index) + " is too large");
            }
            if (static_cast<std::uint64_t>(*index) > max_index) {
                max_index = static_cast<std::uint64_t>(*index);
                max_index_line = line_number;
            }
            corners.push_back(static_cast<std::uint32_t>(*index - 1));
        }
    }
}

TriMesh read_obj(std::string_view data, const std::filesystem::path& path) {
    TriMesh mesh;
    Lines lines(data);
    std::string_view physical;
    std::string logical;
    std::vector<std::string_view> tokens;
    std::vector<std::uint32_t> corners;
    // Positive indices may point forward; the largest one is checked at the end.
    std::uint64_t max_index = 0;
    std::size_t max_index_line = 0;

    while (lines.next(physical)) {
        const std::size_t line_number = lines.number();
        const ObjLine at{path, line_number};
        // Join continuation lines ending in a backslash.
        logical.assign(physical);
        while (!logical.empty() && logical.back() == '\\') {
            logical.back() = ' ';
            if (!lines.next(physical)) {
                break;
            }
            logical.append(physical);
        }
        std::string_view line = logical;
        if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
            line = line.substr(0, hash);
        }
        split(line, tokens);
        if (tokens.empty()) {
            continue;
        }
        const std::string_view keyword = tokens[0];
        if (keyword == "v") {
            mesh.positions.push_back(obj_vertex(tokens, mesh.positions.size(), at));
        } else if (keyword == "f") {
            obj_face(tokens, static_cast<std::int64_t>(mesh.positions.size()), at, corners,
                     max_index, max_index_line);
            for (std::size_t i = 1; i + 1 < corners.size(); ++i) {
                mesh.triangles.push_back({corners[0], corners[i], corners[i + 1]});
            }
        } else if (!is_ignored_obj_statement(keyword)) {
            throw at.bad("unknown statement " + quote_token(keyword) +
                         ", expected v, f or another OBJ keyword");
        }
    }
    if (max_index > mesh.positions.size()) {
        fail(ErrorCode::InvalidInput, path,
             "line " + std::to_string(max_index_line) + ": face vertex index " +
                 std::to_string(max_index) + " out of range, the file has " +
                 std::to_string(mesh.positions.size()) + " vertices (indices 1 to " +
                 std::to_string(mesh.positions.size()) + ")");
    }
    return mesh;
}

// ---------------------------------------------------------------------------------------------
// STL reading

TriMesh read_binary_stl(std::string_view data, const std::filesystem::path& path) {
    if (data.size() < 84) {
        fail(ErrorCode::InvalidInput, path,
             "truncated: " + std::to_string(data.size()) +
                 " bytes, a binary STL has at least 84 (80-byte header and triangle count)");
    }
    const std::uint64_t count = load_le<std::uint32_t>(data.data() + 80);
    const std::uint64_t expected = 84 + 50 * count;
    if (data.size() != expected) {
        fail(ErrorCode::InvalidInput, path,
             "size mismatch: the header says " + std::to_string(count) +
                 " triangles, which take 84 + 50 * " + std::to_string(count) + " = " +
                 std::to_string(expected) + " bytes, but the file has " +
                 std::to_string(data.size()) + " bytes");
    }
    TriMesh mesh;
    mesh.triangles.reserve(count);
    Welder welder(mesh);
    for (std::uint64_t t = 0; t < count; ++t) {
        const char* record = data.data() + 84 + 50 * t + 12;  // skip the normal
        Triangle triangle{};
        for (int c = 0; c < 3; ++c) {
            Vec3 p;
            for (int k = 0; k < 3; ++k) {
                p[k] = std::bit_cast<float>(load_le<std::uint32_t>(record + 12 * c + 4 * k));
            }
            if (!is_finite(p)) {
                fail(ErrorCode::InvalidInput, path,
                     "triangle " + std::to_string(t) + " of " + std::to_string(count) +
                         ": corner " + std::to_string(c) + " has a non-finite coordinate");
            }
            triangle[c] = welder.add(p);
        }
        mesh.triangles.push_back(triangle);
    }
    return mesh;
}

TriMesh read_ascii_stl(std::string_view data, const std::filesystem::path& path) {
    TriMesh mesh;
    Welder welder(mesh);
    Lines lines(data);
    std::string_view line;
    std::vector<std::string_view> tokens;
    auto bad = [&](const std::string& what) {
        return Error(ErrorCode::InvalidInput, path.string() + ": ASCII STL line " +
                                                  std::to_string(lines.number()) + ": " + what);
    };
    // Next non-blank line, split; false at the end of the file.
    auto next = [&] {
        while (lines.next(line)) {
            split(line, tokens);
            if (!tokens.empty()) {
                return true;
            }
        }
        return false;
    };
    // Next line: `words`, then `values` more tokens (checked by the caller).
    auto expect = [&](std::initializer_list<std::string_view> words, std::size_t values,
                      std::string_view expected) {
        if (!next()) {
            fail(ErrorCode::InvalidInput, path,
                 "truncated: ASCII STL ends after line " + std::to_string(lines.number()) +
                     ", expected '" + std::string(expected) + "'");
        }
        const bool match = tokens.size() == words.size() + values &&
                           std::equal(words.begin(), words.end(), tokens.begin());
        if (!match) {
            throw bad("found " + quote_token(line) + ", expected '" + std::string(expected) + "'");
        }
    };

    bool any_solid = false;
    while (next()) {
        if (tokens[0] != "solid") {
            throw bad("found " + quote_token(line) + ", expected 'solid' or the end of the file");
        }
        any_solid = true;
        while (true) {
            if (!next()) {
                fail(ErrorCode::InvalidInput, path,
                     "truncated: ASCII STL ends after line " + std::to_string(lines.number()) +
                         ", expected 'facet' or 'endsolid'");
            }
            if (tokens[0] == "endsolid") {
                break;
            }
            if (tokens[0] != "facet" || tokens.size() != 5 || tokens[1] != "normal") {
                throw bad("found " + quote_token(line) +
                          ", expected 'facet normal <x> <y> <z>' or 'endsolid'");
            }
            for (int k = 2; k < 5; ++k) {
                if (!parse_double(tokens[k])) {
                    throw bad("normal component " + quote_token(tokens[k]) + " is not a number");
                }
            }
            expect({"outer", "loop"}, 0, "outer loop");
            Triangle triangle{};
            for (int c = 0; c < 3; ++c) {
                expect({"vertex"}, 3, "vertex <x> <y> <z>");
                Vec3 p;
                for (int k = 0; k < 3; ++k) {
                    const auto value = parse_double(tokens[1 + k]);
                    if (!value) {
                        throw bad("vertex coordinate " + quote_token(tokens[1 + k]) +
                                  " is not a number");
                    }
                    if (!std::isfinite(*value)) {
                        throw bad("non-finite vertex coordinate " + quote_token(tokens[1 + k]));
                    }
                    p[k] = *value;
                }
                triangle[c] = welder.add(p);
            }
            expect({"endloop"}, 0, "endloop");
            expect({"endfacet"}, 0, "endfacet");
            if (mesh.positions.size() > kMaxVertices) {
                throw bad("more than " + std::to_string(kMaxVertices) + " distinct vertices");
            }
            mesh.triangles.push_back(triangle);
        }
    }
    if (!any_solid) {
        fail(ErrorCode::InvalidInput, path, "ASCII STL has no 'solid'");
    }
    return mesh;
}

TriMesh read_stl(std::string_view data, const std::filesystem::path& path) {
    // note: binary headers may start with "solid" too; an exact binary size or any NUL byte
    // decides for binary.
    std::size_t first = 0;
    while (first < data.size() && (is_space(data[first]) || data[first] == '\n')) {
        ++first;
    }
    const bool says_solid = data.substr(first, 5) == "solid";
    const bool binary_size =
        data.size() >= 84 &&
        data.size() == 84 + 50 * std::uint64_t{load_le<std::uint32_t>(data.data() + 80)};
    if (says_solid && !binary_size && data.find('\0') == std::string_view::npos) {
        return read_ascii_stl(data, path);
    }
    return read_binary_stl(data, path);
}

}  // namespace

void write_mesh(const TriMesh& mesh,
                const std::filesystem::path& path,
                const std::vector<Vec3>& normals) {
    const std::string ext = lowercase_extension(path);
    if (ext != ".ply" && ext != ".obj" && ext != ".stl") {
        fail(ErrorCode::Unsupported, path,
             "cannot write a mesh with extension " + quote_token(ext) +
                 ", expected .ply, .obj or .stl");
    }
    const auto positions = checked_float_positions(mesh, path);
    const auto float_normals = checked_float_normals(mesh, normals, path);
    std::string bytes;
    try {
        bytes = ext == ".ply"   ? encode_ply(mesh, positions, float_normals)
                : ext == ".obj" ? encode_obj(mesh, positions, float_normals)
                                : encode_stl(mesh, positions);
    } catch (const Error& e) {
        fail(e.code(), path, e.what());
    }
    write_file_atomically(path, bytes);
}

TriMesh read_mesh(const std::filesystem::path& path) {
    const std::string ext = lowercase_extension(path);
    if (ext != ".ply" && ext != ".obj" && ext != ".stl") {
        fail(ErrorCode::Unsupported, path,
             "cannot read a mesh with extension " + quote_token(ext) +
                 ", expected .ply, .obj or .stl");
    }
    const std::string data = read_file(path);
    if (ext == ".ply") {
        return read_ply(data, path);
    }
    if (ext == ".obj") {
        return read_obj(data, path);
    }
    return read_stl(data, path);
}

}  // namespace strata

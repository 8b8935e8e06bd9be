// PLY reading (Turk, "The PLY polygon file format", 1994): the header, then the body row by row
// from ASCII or binary rows, every count checked against the bytes that are there before
// anything is allocated.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "mesh/detail/mesh_files.h"
#include "mesh/mesh_io.h"

namespace strata::mesh_detail {

namespace {

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

}  // namespace

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

}  // namespace strata::mesh_detail

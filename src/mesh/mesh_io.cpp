// Triangle mesh files: PLY (Turk, "The PLY polygon file format", 1994), Wavefront OBJ
// (Wavefront Technologies, "Object Files (.obj)", Advanced Visualizer manual, appendix B1) and
// STL (3D Systems, "StereoLithography Interface Specification", 1988).
//
// PLY is read in read_ply.cpp. Readers load the whole file and parse it from memory, checking every
// count against the bytes that are actually there before allocating, so a lying header cannot cause
// a huge allocation. Writers build the file in memory and hand it to write_file_atomically.
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
#include "mesh/detail/mesh_files.h"

namespace strata {

namespace {

using namespace mesh_detail;

// ---------------------------------------------------------------------------------------------
// Reading a file

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

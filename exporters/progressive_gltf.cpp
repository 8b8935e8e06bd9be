// Progressive glTF 2.0 (../shared/DESIGN.md section 4; the extension is specified in
// schema/README.md): the base mesh as plain primitives, every other cluster a Draco-compressed
// primitive (KHR_draco_mesh_compression, Khronos 2019), the DAG in STRATA_progressive_mesh.
//
// The JSON is written with nlohmann_json and the GLB container by hand (glTF 2.0 specification
// section 4.4): tinygltf cannot write Draco primitives. Draco encodes each chunk with explicit
// quantization on the model's own dyadic grid: origin and range multiples of the grid step, so
// Draco's float quantize/dequantize steps are exact and decoded positions equal ours bit for bit.
#include "exporters/progressive_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <string>
#include <system_error>
#include <unordered_map>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/parallel.h"
#include "exporters/detail/draco_chunk.h"
#include "exporters/detail/gltf_common.h"

namespace strata {

namespace {

using Json = nlohmann::ordered_json;
using detail::to_float;

constexpr int kFloat = 5126;
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr double kRoughness = 0.6;
constexpr std::size_t kMaxShortVertices = 65535;  // index 65535 is the primitive restart value
constexpr const char* kExtension = "STRATA_progressive_mesh";
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kCoarse = "_COARSE_POSITION";

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

std::string object_name(const ProgressiveObject& object) {
    return object.name.empty() ? "label " + std::to_string(object.label) : object.name;
}

/// Storage frame of one object: grid coordinates (x px, y px, z in slices, x negated when the
/// slice frame mirrors) and the maps out of it.
struct StorageFrame {
    double flip_x = 1.0;             ///< -1 when the slice frame mirrors
    std::array<double, 16> matrix;   ///< storage -> LPS mm, column-major (glTF node matrix)
    std::array<double, 9> to_scene;  ///< slice-space px -> scene metres (linear part), row-major
    std::array<double, 3> scene_origin;
    double scene_scale = 0.0;  ///< largest stretch of slice space -> scene (metres per px)
    double error_m_per_px = 0.0;
};

double column_norm(const std::array<double, 9>& m, int c) {
    return std::sqrt(m[c] * m[c] + m[3 + c] * m[3 + c] + m[6 + c] * m[6 + c]);
}

StorageFrame storage_frame(const std::filesystem::path& path, const SliceFrame& frame) {
    const auto& l = frame.linear;
    for (double v : l) {
        if (!std::isfinite(v)) {
            fail(ErrorCode::InvalidInput, path, "the slice frame has a non-finite entry");
        }
    }
    for (int a = 0; a < 3; ++a) {
        if (!(column_norm(l, a) > 0.0)) {
            fail(ErrorCode::InvalidInput, path,
                 "the slice frame's column " + std::to_string(a) + " is zero");
        }
        for (int b = a + 1; b < 3; ++b) {
            const double dot = l[a] * l[b] + l[3 + a] * l[3 + b] + l[6 + a] * l[6 + b];
            if (std::abs(dot) > 1e-6 * column_norm(l, a) * column_norm(l, b)) {
                fail(ErrorCode::InvalidInput, path,
                     "the voxel grid is sheared (columns " + std::to_string(a) + " and " +
                         std::to_string(b) +
                         " of the affine are not orthogonal): a glTF node cannot hold the "
                         "transform; resample the volume to an orthogonal grid");
            }
        }
    }
    const double det = l[0] * (l[4] * l[8] - l[5] * l[7]) - l[1] * (l[3] * l[8] - l[5] * l[6]) +
                       l[2] * (l[3] * l[7] - l[4] * l[6]);
    StorageFrame s;
    s.flip_x = det < 0.0 ? -1.0 : 1.0;
    const double d = frame.slice_spacing_px;
    const std::array<double, 3> scale{s.flip_x, 1.0, d};
    for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) {
            s.matrix[4 * c + r] = l[3 * r + c] * scale[c];
        }
        s.matrix[4 * c + 3] = 0.0;
    }
    s.matrix[12] = frame.origin[0];
    s.matrix[13] = frame.origin[1];
    s.matrix[14] = frame.origin[2];
    s.matrix[15] = 1.0;
    // scene = P * (L p + o), P the patient -> glTF matrix (column-major 4 x 4)
    const auto& p = detail::kPatientToGltf;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            double sum = 0.0;
            for (int k = 0; k < 3; ++k) {
                sum += p[4 * k + r] * l[3 * k + c];
            }
            s.to_scene[3 * r + c] = sum;
        }
        double o = p[12 + r];
        for (int k = 0; k < 3; ++k) {
            o += p[4 * k + r] * frame.origin[k];
        }
        s.scene_origin[r] = o;
    }
    // orthogonal columns: the largest column norm is the largest stretch
    s.scene_scale = std::max({column_norm(s.to_scene, 0), column_norm(s.to_scene, 1),
                              column_norm(s.to_scene, 2)}) *
                    (1.0 + 1e-9);
    s.error_m_per_px = frame.error_mm_per_px * 0.001;
    return s;
}

/// The double a JSON reader parses from `x` printed with `decimals` decimals (nlohmann prints it
/// back as that short decimal). Keeps the JSON small: spheres need micrometres, not 17 digits.
double short_decimal(double x, int decimals) {
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, x);
    return std::strtod(text, nullptr);
}

/// The smallest 7-significant-digit decimal (as parsed) >= x: for bounds, which may only grow.
double short_bound(double x) {
    char text[64];
    for (double up = x;;
         up = std::nextafter(up + std::abs(up) * 1e-7, std::numeric_limits<double>::infinity())) {
        std::snprintf(text, sizeof text, "%.7g", up);
        const double r = std::strtod(text, nullptr);
        if (r >= x || !std::isfinite(r)) {
            return r >= x ? r : x;
        }
    }
}

constexpr int kSphereDecimals = 6;  ///< metres: 1 micrometre, 1/50 of a 0.05 mm grid step

/// A sphere in the scene frame (metres) as written: centre at kSphereDecimals decimals, radius
/// rounded up so that it still contains the exact sphere and every sphere in `inside` (already
/// written ones: nesting survives the rounding).
struct SceneSphere {
    std::array<double, 4> v{};  ///< x, y, z, r as parsed back from the JSON
    Json json() const { return Json::array({v[0], v[1], v[2], v[3]}); }
};

SceneSphere scene_sphere(const StorageFrame& s,
                         const Sphere& sphere,
                         const std::vector<const SceneSphere*>& inside = {}) {
    const Vec3 c = sphere.center;
    std::array<double, 3> exact{};
    SceneSphere out;
    for (int r = 0; r < 3; ++r) {
        exact[r] = s.scene_origin[r] + s.to_scene[3 * r] * c.x + s.to_scene[3 * r + 1] * c.y +
                   s.to_scene[3 * r + 2] * c.z;
        out.v[r] = short_decimal(exact[r], kSphereDecimals);
    }
    const auto distance = [&](const std::array<double, 4>& to) {
        return std::hypot(out.v[0] - to[0], out.v[1] - to[1], out.v[2] - to[2]);
    };
    double radius = sphere.radius * s.scene_scale + distance({exact[0], exact[1], exact[2], 0.0});
    for (const SceneSphere* other : inside) {
        radius = std::max(radius, distance(other->v) + other->v[3]);
    }
    radius += 1e-12 * (1.0 + std::abs(out.v[0]) + std::abs(out.v[1]) + std::abs(out.v[2]));
    const double step = std::pow(10.0, -kSphereDecimals);
    out.v[3] = short_decimal(std::ceil(radius / step) * step, kSphereDecimals);
    while (out.v[3] < radius) {
        out.v[3] = short_decimal(out.v[3] + step, kSphereDecimals);
    }
    return out;
}

/// Grid coordinates of one slice-space position as floats (exact: multiples of the grid step).
struct GridPoint {
    std::array<float, 3> v;
};

GridPoint grid_point(const Vec3& p, double step, double d, double flip_x) {
    const double z = std::nearbyint(p.z / d / step) * step;
    return {{to_float(flip_x * p.x), to_float(p.y), to_float(z)}};
}

}  // namespace

std::vector<std::vector<std::array<float, 3>>> progressive_cluster_normals(
    const MultiresMesh& model, const std::vector<std::array<float, 3>>& points, bool reverse) {
    std::vector<std::vector<std::array<float, 3>>> normals(model.clusters.size());
    std::vector<Vec3> sum(points.size());
    const auto at = [&](std::uint32_t v) { return Vec3{points[v][0], points[v][1], points[v][2]}; };
    for (std::uint32_t level = 0; level < level_count(model); ++level) {
        const MultiresCut cut = select_cut_at_level(model, level);
        for (const std::uint32_t c : cut.clusters) {
            const MultiresCluster& cluster = model.clusters[c];
            for (const auto& t : cluster.triangles) {
                std::array<std::uint32_t, 3> ids{cluster.vertices[t[0]], cluster.vertices[t[1]],
                                                 cluster.vertices[t[2]]};
                if (reverse) {
                    std::swap(ids[1], ids[2]);
                }
                const Vec3 a = at(ids[0]);
                const Vec3 n = cross(at(ids[1]) - a, at(ids[2]) - a);
                for (const std::uint32_t v : ids) {
                    sum[v] = sum[v] + n;
                }
            }
        }
        for (const std::uint32_t c : cut.clusters) {
            const MultiresCluster& cluster = model.clusters[c];
            if (cluster.level != level) {
                continue;
            }
            std::vector<std::array<float, 3>>& out = normals[c];
            out.reserve(cluster.vertices.size());
            for (const std::uint32_t v : cluster.vertices) {
                const double length = norm(sum[v]);
                const Vec3 n = (length > 0.0 && std::isfinite(length)) ? (1.0 / length) * sum[v]
                                                                       : Vec3{0, 0, 1};
                out.push_back({to_float(n.x), to_float(n.y), to_float(n.z)});
            }
        }
        for (const std::uint32_t c : cut.clusters) {
            for (const std::uint32_t v : model.clusters[c].vertices) {
                sum[v] = Vec3{};
            }
        }
    }
    return normals;
}

namespace {

/// One encoded chunk and what its accessors need.
struct Chunk {
    std::string bytes;
    std::uint32_t points = 0;
    std::uint32_t faces = 0;
    std::array<float, 3> min{}, max{};
    int position_id = 0, normal_id = 0, coarse_id = 0;
};

/// Encodes one cluster with Draco (detail::encode_draco_chunk) and checks the decoded mesh
/// against it.
Chunk encode_chunk(const std::filesystem::path& path,
                   const std::string& where,
                   const MultiresCluster& cluster,
                   const std::vector<GridPoint>& points,
                   const std::vector<std::array<float, 3>>& normals,  // per cluster vertex
                   bool reverse,
                   double step,
                   const ProgressiveOptions& options) {
    const std::size_t n = cluster.vertices.size();
    detail::DracoChunkInput input;
    input.step = step;
    input.normals = normals;
    for (std::size_t i = 0; i < n; ++i) {
        input.positions.push_back(points[cluster.vertices[i]].v);
        input.coarse.push_back(points[cluster.coarse_vertices[i]].v);
    }
    for (const auto& t : cluster.triangles) {
        input.triangles.push_back({t[0], reverse ? t[2] : t[1], reverse ? t[1] : t[2]});
    }
    detail::DracoChunkBytes encoded;
    try {
        encoded = detail::encode_draco_chunk(input, options.compression_level, options.normal_bits);
    } catch (const Error& e) {
        fail(e.code(), path, where + ": " + e.what());
    }
    Chunk chunk;
    chunk.bytes = std::move(encoded.bytes);
    chunk.position_id = encoded.position_id;
    chunk.normal_id = encoded.normal_id;
    chunk.coarse_id = encoded.coarse_id;

    // Decode and compare: every decoded triangle is one of the cluster's, same orientation, and
    // every point carries its vertex's coarse position.
    draco::DecoderBuffer in;
    in.Init(chunk.bytes.data(), chunk.bytes.size());
    draco::Decoder decoder;
    auto decoded_or = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded_or.ok()) {
        fail(ErrorCode::Internal, path,
             where + ": Draco cannot decode its own output: " + decoded_or.status().error_msg());
    }
    const std::unique_ptr<draco::Mesh> decoded = std::move(decoded_or).value();
    const draco::PointAttribute* dp = decoded->GetAttributeByUniqueId(chunk.position_id);
    const draco::PointAttribute* dc = decoded->GetAttributeByUniqueId(chunk.coarse_id);
    if (dp == nullptr || dc == nullptr || decoded->num_faces() != cluster.triangles.size()) {
        fail(ErrorCode::Internal, path, where + ": Draco round trip lost attributes or faces");
    }
    std::map<std::array<float, 3>, std::uint32_t> local;
    for (std::size_t i = 0; i < n; ++i) {
        local.emplace(points[cluster.vertices[i]].v, static_cast<std::uint32_t>(i));
    }
    chunk.points = decoded->num_points();
    chunk.faces = decoded->num_faces();
    chunk.min.fill(std::numeric_limits<float>::infinity());
    chunk.max.fill(-std::numeric_limits<float>::infinity());
    std::vector<std::uint32_t> vertex_of(chunk.points);
    for (std::uint32_t i = 0; i < chunk.points; ++i) {
        std::array<float, 3> p{}, c{};
        dp->ConvertValue<float, 3>(dp->mapped_index(draco::PointIndex(i)), p.data());
        dc->ConvertValue<float, 3>(dc->mapped_index(draco::PointIndex(i)), c.data());
        const auto it = local.find(p);
        if (it == local.end() || points[cluster.coarse_vertices[it->second]].v != c) {
            fail(ErrorCode::Internal, path,
                 where + ": Draco moved a position off the grid (decoded point " +
                     std::to_string(i) + ")");
        }
        vertex_of[i] = it->second;
        for (int k = 0; k < 3; ++k) {
            chunk.min[k] = std::min(chunk.min[k], p[k]);
            chunk.max[k] = std::max(chunk.max[k], p[k]);
        }
    }
    const auto canonical = [](std::array<std::uint32_t, 3> t) {
        std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
        return t;
    };
    std::vector<std::array<std::uint32_t, 3>> expected, got;
    for (const auto& t : cluster.triangles) {
        expected.push_back(canonical(reverse ? std::array{t[0], t[2], t[1]} : t));
    }
    for (draco::FaceIndex f(0); f < decoded->num_faces(); ++f) {
        const auto& face = decoded->face(f);
        got.push_back(canonical(
            {vertex_of[face[0].value()], vertex_of[face[1].value()], vertex_of[face[2].value()]}));
    }
    std::sort(expected.begin(), expected.end());
    std::sort(got.begin(), got.end());
    if (expected != got) {
        fail(ErrorCode::Internal, path, where + ": Draco round trip changed the triangles");
    }
    return chunk;
}

/// The binary buffers: buffer 0 holds the base meshes, buffer 1 + L the chunks of level L
/// (`.gltf`); for `.glb` everything is appended to buffer 0.
class Buffers {
public:
    explicit Buffers(Json& json) : json_(json), data_(1) {}

    /// Appends `bytes` to `buffer` (4-byte aligned) as a new buffer view; returns its index.
    int add_view(std::size_t buffer, const void* bytes, std::size_t size, int target) {
        if (data_.size() <= buffer) {
            data_.resize(buffer + 1);
        }
        std::string& data = data_[buffer];
        Json view = {{"buffer", buffer}, {"byteOffset", data.size()}, {"byteLength", size}};
        if (target != 0) {
            view["target"] = target;
        }
        data.append(static_cast<const char*>(bytes), size);
        data.resize((data.size() + 3) / 4 * 4, '\0');
        json_["bufferViews"].push_back(std::move(view));
        return static_cast<int>(json_["bufferViews"].size() - 1);
    }

    std::vector<std::string>& data() { return data_; }

    /// For a .glb: every buffer appended to buffer 0, the coarsest level first, the views moved
    /// with their data. The base meshes stay together at the start of the BIN chunk (one range
    /// request for a first frame) and a prefix of the file holds the coarse levels.
    void merge_into_first() {
        std::vector<std::size_t> start(data_.size(), 0);
        for (std::size_t b = data_.size(); b-- > 1;) {
            start[b] = data_[0].size();
            data_[0] += data_[b];
            data_[b].clear();
        }
        data_.resize(1);
        for (Json& view : json_["bufferViews"]) {
            const std::size_t b = view["buffer"].get<std::size_t>();
            view["byteOffset"] = start[b] + view["byteOffset"].get<std::size_t>();
            view["buffer"] = 0;
        }
    }

private:
    Json& json_;
    std::vector<std::string> data_;
};

int add_accessor(Json& json, Json accessor) {
    json["accessors"].push_back(std::move(accessor));
    return static_cast<int>(json["accessors"].size() - 1);
}

/// One plain primitive (a root cluster of the base mesh).
Json base_primitive(Json& json,
                    Buffers& buffers,
                    const MultiresCluster& cluster,
                    const std::vector<GridPoint>& points,
                    const std::vector<std::array<float, 3>>& normals,  // per cluster vertex
                    bool reverse,
                    int material) {
    const std::size_t n = cluster.vertices.size();
    std::vector<float> positions, normal_data;
    positions.reserve(3 * n);
    normal_data.reserve(3 * n);
    Json min = Json::array(), max = Json::array();
    std::array<float, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<float>::infinity());
    hi.fill(-std::numeric_limits<float>::infinity());
    for (std::size_t i = 0; i < n; ++i) {
        const std::uint32_t v = cluster.vertices[i];
        for (int k = 0; k < 3; ++k) {
            positions.push_back(points[v].v[k]);
            normal_data.push_back(normals[i][k]);
            lo[k] = std::min(lo[k], points[v].v[k]);
            hi[k] = std::max(hi[k], points[v].v[k]);
        }
    }
    for (int k = 0; k < 3; ++k) {
        min.push_back(lo[k]);
        max.push_back(hi[k]);
    }
    Json primitive;
    Json attributes;
    int view =
        buffers.add_view(0, positions.data(), positions.size() * sizeof(float), kArrayBuffer);
    attributes["POSITION"] = add_accessor(json, {{"bufferView", view},
                                                 {"componentType", kFloat},
                                                 {"count", n},
                                                 {"type", "VEC3"},
                                                 {"min", min},
                                                 {"max", max}});
    view =
        buffers.add_view(0, normal_data.data(), normal_data.size() * sizeof(float), kArrayBuffer);
    attributes["NORMAL"] = add_accessor(
        json, {{"bufferView", view}, {"componentType", kFloat}, {"count", n}, {"type", "VEC3"}});
    primitive["attributes"] = attributes;
    std::vector<std::uint32_t> indices;
    for (const auto& t : cluster.triangles) {
        indices.push_back(t[0]);
        indices.push_back(reverse ? t[2] : t[1]);
        indices.push_back(reverse ? t[1] : t[2]);
    }
    if (n <= kMaxShortVertices) {
        std::vector<std::uint16_t> shorts(indices.begin(), indices.end());
        view = buffers.add_view(0, shorts.data(), shorts.size() * 2, kElementArrayBuffer);
        primitive["indices"] = add_accessor(json, {{"bufferView", view},
                                                   {"componentType", kUnsignedShort},
                                                   {"count", shorts.size()},
                                                   {"type", "SCALAR"}});
    } else {
        view = buffers.add_view(0, indices.data(), indices.size() * 4, kElementArrayBuffer);
        primitive["indices"] = add_accessor(json, {{"bufferView", view},
                                                   {"componentType", kUnsignedInt},
                                                   {"count", indices.size()},
                                                   {"type", "SCALAR"}});
    }
    primitive["material"] = material;
    primitive["mode"] = 4;
    return primitive;
}

/// Draco primitive of one chunk.
Json draco_primitive(
    Json& json, Buffers& buffers, std::size_t buffer, const Chunk& chunk, int material) {
    const int view = buffers.add_view(buffer, chunk.bytes.data(), chunk.bytes.size(), 0);
    Json min = Json::array(), max = Json::array();
    for (int k = 0; k < 3; ++k) {
        min.push_back(chunk.min[k]);
        max.push_back(chunk.max[k]);
    }
    Json attributes;
    attributes["POSITION"] = add_accessor(json, {{"componentType", kFloat},
                                                 {"count", chunk.points},
                                                 {"type", "VEC3"},
                                                 {"min", min},
                                                 {"max", max}});
    attributes["NORMAL"] =
        add_accessor(json, {{"componentType", kFloat}, {"count", chunk.points}, {"type", "VEC3"}});
    attributes[kCoarse] =
        add_accessor(json, {{"componentType", kFloat}, {"count", chunk.points}, {"type", "VEC3"}});
    Json primitive;
    primitive["attributes"] = attributes;
    primitive["indices"] = add_accessor(
        json, {{"componentType", chunk.points <= kMaxShortVertices ? kUnsignedShort : kUnsignedInt},
               {"count", 3 * std::size_t{chunk.faces}},
               {"type", "SCALAR"}});
    primitive["material"] = material;  // mode: TRIANGLES, the default, left out (JSON bytes)
    primitive["extensions"][kDraco] = {{"bufferView", view},
                                       {"attributes",
                                        {{"POSITION", chunk.position_id},
                                         {"NORMAL", chunk.normal_id},
                                         {kCoarse, chunk.coarse_id}}}};
    return primitive;
}

void check_object(const std::filesystem::path& path,
                  const ProgressiveObject& object,
                  std::size_t index) {
    const std::string what = "object " + std::to_string(index) + " '" + object_name(object) + "'";
    if (object.model == nullptr) {
        fail(ErrorCode::InvalidInput, path, what + " has no model");
    }
    const MultiresMesh& model = *object.model;
    if (!(model.grid_step > 0.0)) {
        fail(ErrorCode::InvalidInput, path,
             what +
                 ": its positions are not on a grid (grid_step 0); the progressive format "
                 "stores snapped surfaces only");
    }
    for (double c : object.srgb) {
        if (!(c >= 0.0 && c <= 1.0)) {
            fail(ErrorCode::InvalidInput, path,
                 what + ": colour channel " + std::to_string(c) + ", expected sRGB in [0, 1]");
        }
    }
    const std::size_t n = model.positions.size();
    for (std::size_t c = 0; c < model.clusters.size(); ++c) {
        const MultiresCluster& cluster = model.clusters[c];
        const bool root = cluster.consumer < 0;
        if (!root && cluster.coarse_vertices.size() != cluster.vertices.size()) {
            fail(ErrorCode::InvalidInput, path,
                 what + ": cluster " + std::to_string(c) + " lacks its coarse vertices");
        }
        for (std::uint32_t v : cluster.vertices) {
            if (v >= n) {
                fail(ErrorCode::InvalidInput, path,
                     what + ": cluster " + std::to_string(c) + " uses vertex " + std::to_string(v) +
                         ", expected < " + std::to_string(n));
            }
        }
        for (std::uint32_t v : cluster.coarse_vertices) {
            if (v >= n) {
                fail(ErrorCode::InvalidInput, path,
                     what + ": cluster " + std::to_string(c) + " collapses to vertex " +
                         std::to_string(v) + ", expected < " + std::to_string(n));
            }
        }
        for (const auto& t : cluster.triangles) {
            for (std::uint32_t v : t) {
                if (v >= cluster.vertices.size()) {
                    fail(ErrorCode::InvalidInput, path,
                         what + ": cluster " + std::to_string(c) + " has a triangle index " +
                             std::to_string(v) + ", expected < " +
                             std::to_string(cluster.vertices.size()));
                }
            }
        }
    }
}

/// GLB container (glTF 2.0 section 4.4): header, JSON chunk (space padded), BIN chunk.
std::string glb_bytes(const std::filesystem::path& path,
                      const std::string& json,
                      const std::string& bin) {
    std::string padded_json = json;
    padded_json.resize((padded_json.size() + 3) / 4 * 4, ' ');
    const std::uint64_t total = 12 + 8 + padded_json.size() + (bin.empty() ? 0 : 8 + bin.size());
    if (total > std::numeric_limits<std::uint32_t>::max()) {
        fail(ErrorCode::Unsupported, path,
             "the scene needs " + std::to_string(total) +
                 " bytes, more than a .glb holds (4 GiB); write .gltf instead");
    }
    std::string out;
    out.reserve(total);
    const auto u32 = [&](std::uint32_t v) {
        for (int i = 0; i < 4; ++i) {
            out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
        }
    };
    u32(0x46546C67);  // "glTF"
    u32(2);
    u32(static_cast<std::uint32_t>(total));
    u32(static_cast<std::uint32_t>(padded_json.size()));
    u32(0x4E4F534A);  // "JSON"
    out += padded_json;
    if (!bin.empty()) {
        u32(static_cast<std::uint32_t>(bin.size()));
        u32(0x004E4942);  // "BIN\0"
        out += bin;
    }
    return out;
}

}  // namespace

ProgressiveStats write_progressive_gltf(const std::filesystem::path& path,
                                        const std::vector<ProgressiveObject>& objects,
                                        const SliceFrame& frame,
                                        const SceneInfo& info,
                                        const ProgressiveOptions& options) {
    detail::require_gltf_extension(path);
    const std::string ext = lowercase_extension(path);
    if (objects.empty()) {
        fail(ErrorCode::InvalidInput, path, "no objects to write, expected at least one");
    }
    if (!(frame.slice_spacing_px > 0.0) || !(frame.error_mm_per_px > 0.0)) {
        fail(ErrorCode::InvalidInput, path, "slice spacing and error scale must be positive");
    }
    for (std::size_t i = 0; i < objects.size(); ++i) {
        check_object(path, objects[i], i);
    }
    const StorageFrame storage = storage_frame(path, frame);
    const bool reverse = storage.flip_x < 0.0;
    const bool single = ext == ".glb";

    Json json;
    json["asset"] = {{"generator", info.generator}, {"version", "2.0"}};
    json["extensionsUsed"] = {kDraco, kExtension};
    json["extensionsRequired"] = {kDraco};
    json["scene"] = 0;
    json["scenes"] = Json::array();
    json["scenes"].push_back(Json{{"nodes", Json::array({0})}});
    json["nodes"] = Json::array();
    json["meshes"] = Json::array();
    json["materials"] = Json::array();
    json["accessors"] = Json::array();
    json["bufferViews"] = Json::array();
    json["nodes"].push_back(
        {{"name", "patient"}, {"matrix", detail::kPatientToGltf}, {"children", Json::array()}});
    Buffers buffers(json);
    ProgressiveStats stats;

    for (const ProgressiveObject& object : objects) {
        const MultiresMesh& model = *object.model;
        if (model.clusters.empty()) {
            continue;
        }
        const std::string name = object_name(object);
        const double step = model.grid_step;
        std::vector<GridPoint> points(model.positions.size());
        for (std::size_t v = 0; v < points.size(); ++v) {
            points[v] =
                grid_point(model.positions[v], step, frame.slice_spacing_px, storage.flip_x);
        }
        std::vector<std::array<float, 3>> storage_points(points.size());
        std::transform(points.begin(), points.end(), storage_points.begin(),
                       [](const GridPoint& p) { return p.v; });
        const auto normals = progressive_cluster_normals(model, storage_points, reverse);

        json["materials"].push_back(
            {{"name", name},
             {"pbrMetallicRoughness",
              {{"baseColorFactor",
                {detail::srgb_to_linear(object.srgb[0]), detail::srgb_to_linear(object.srgb[1]),
                 detail::srgb_to_linear(object.srgb[2]), 1.0}},
               {"metallicFactor", 0.0},
               {"roughnessFactor", kRoughness}}}});
        const int material = static_cast<int>(json["materials"].size() - 1);

        // Chunks, encoded in parallel (each independent; written in cluster order).
        std::vector<std::uint32_t> chunk_clusters;
        for (std::uint32_t c = 0; c < model.clusters.size(); ++c) {
            if (model.clusters[c].consumer >= 0) {
                chunk_clusters.push_back(c);
            }
        }
        std::vector<Chunk> chunks(chunk_clusters.size());
        parallel_for(chunk_clusters.size(), options.threads, [&](std::size_t i) {
            const std::uint32_t c = chunk_clusters[i];
            chunks[i] = encode_chunk(path, "'" + name + "' cluster " + std::to_string(c),
                                     model.clusters[c], points, normals[c], reverse, step, options);
        });

        Json base;
        base["name"] = name;
        base["primitives"] = Json::array();
        Json clusters = Json::array();
        const int base_mesh = static_cast<int>(json["meshes"].size());
        json["meshes"].push_back(Json());  // placeholder, filled after the chunks
        std::size_t next_chunk = 0;
        std::vector<SceneSphere> cluster_spheres(model.clusters.size());
        for (std::uint32_t c = 0; c < model.clusters.size(); ++c) {
            const MultiresCluster& cluster = model.clusters[c];
            Json entry;
            if (cluster.consumer < 0) {
                entry["mesh"] = base_mesh;
                entry["primitive"] = base["primitives"].size();
                base["primitives"].push_back(
                    base_primitive(json, buffers, cluster, points, normals[c], reverse, material));
            } else {
                const Chunk& chunk = chunks[next_chunk++];
                entry["mesh"] = json["meshes"].size();
                // unnamed: the extension's cluster entry names it (JSON bytes)
                json["meshes"].push_back(
                    {{"primitives", Json::array({draco_primitive(json, buffers, 1 + cluster.level,
                                                                 chunk, material)})}});
                stats.chunk_bytes += chunk.bytes.size();
                ++stats.chunks;
            }
            entry["level"] = cluster.level;
            if (cluster.producer >= 0) {
                entry["producer"] = cluster.producer;
            }
            if (cluster.consumer >= 0) {
                entry["consumer"] = cluster.consumer;
            }
            cluster_spheres[c] = scene_sphere(storage, cluster.bounds);
            entry["sphere"] = cluster_spheres[c].json();
            clusters.push_back(std::move(entry));
        }
        json["meshes"][base_mesh] = std::move(base);

        // groups come after the groups below them: their written spheres nest in the written
        // spheres of their clusters and of the groups below
        Json groups = Json::array();
        std::vector<SceneSphere> group_spheres(model.groups.size());
        for (std::size_t g = 0; g < model.groups.size(); ++g) {
            const MultiresGroup& group = model.groups[g];
            std::vector<const SceneSphere*> inside;
            for (const std::uint32_t c : group.produced) {
                inside.push_back(&cluster_spheres[c]);
            }
            for (const std::uint32_t c : group.consumed) {
                inside.push_back(&cluster_spheres[c]);
                const std::int32_t below = model.clusters[c].producer;
                if (below >= 0) {
                    inside.push_back(&group_spheres[std::size_t(below)]);
                }
            }
            group_spheres[g] = scene_sphere(storage, group.bounds, inside);
            groups.push_back({{"level", group.level},
                              {"error", short_bound(group.error_px * storage.error_m_per_px)},
                              {"sphere", group_spheres[g].json()},
                              {"consumed", group.consumed},
                              {"produced", group.produced}});
        }
        Json node;
        node["name"] = name;
        node["mesh"] = base_mesh;
        node["matrix"] = storage.matrix;
        node["extensions"][kExtension] = {
            {"clusters", std::move(clusters)},
            {"groups", std::move(groups)},
            {"fullResolutionError",
             short_bound(model.full_resolution_error_px * storage.error_m_per_px)},
            {"gridStep", step}};
        node["extras"] = {{"label", object.label},
                          {"source", info.source},
                          {"spacing_mm", info.spacing_mm},
                          {"volume_ml", object.volume_ml},
                          {"error_unit", "m"}};
        json["nodes"].push_back(std::move(node));
        json["nodes"][0]["children"].push_back(json["nodes"].size() - 1);
    }
    if (json["nodes"][0]["children"].empty()) {
        fail(ErrorCode::InvalidInput, path,
             std::to_string(objects.size()) +
                 " objects, none with a triangle: nothing to write, expected at least one "
                 "non-empty object");
    }

    // Buffers: .glb one (the BIN chunk); .gltf buffer 0 = <stem>.bin, others <stem>.level<L>.bin,
    // renumbered so that levels without chunks leave no empty buffer.
    if (single) {
        buffers.merge_into_first();
    }
    std::vector<std::string>& data = buffers.data();
    std::vector<int> renumber(data.size(), -1);
    json["buffers"] = Json::array();
    std::vector<std::pair<std::filesystem::path, const std::string*>> files;
    const std::string stem = path.stem().string();
    for (std::size_t b = 0; b < data.size(); ++b) {
        if (b > 0 && data[b].empty()) {
            continue;
        }
        renumber[b] = static_cast<int>(json["buffers"].size());
        Json buffer = {{"byteLength", data[b].size()}};
        if (!single) {
            const std::string file =
                b == 0 ? stem + ".bin" : stem + ".level" + std::to_string(b - 1) + ".bin";
            buffer["uri"] = detail::uri_encode(file);
            files.emplace_back(path.parent_path() / file, &data[b]);
        }
        json["buffers"].push_back(std::move(buffer));
    }
    for (Json& view : json["bufferViews"]) {
        view["buffer"] = renumber[view["buffer"].get<std::size_t>()];
    }
    const std::string text = json.dump();  // compact: the JSON is most of a first frame's bytes
    if (single) {
        const std::string bytes = glb_bytes(path, text, data[0]);
        write_file_atomically(path, bytes);
        stats.total_bytes = bytes.size();
    } else {
        stats.total_bytes = text.size() + 1;
        for (const auto& [file, bytes] : files) {
            write_file_atomically(file, *bytes);
            stats.files.push_back(file);
            stats.total_bytes += bytes->size();
        }
        write_file_atomically(path, text + "\n");
    }
    stats.base_bytes = stats.total_bytes - stats.chunk_bytes;
    stats.files.push_back(path);
    return stats;
}

}  // namespace strata

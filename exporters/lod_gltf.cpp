// Discrete LOD glTF 2.0 for asset pipelines: MSFT_lod (Microsoft vendor extension: a node names
// its coarser stand-ins, `extras.MSFT_screencoverage` says when each is shown), `_LOD<i>` node
// names (the Unity and Unreal importers' convention) and either KHR_draco_mesh_compression or
// EXT_meshopt_compression (with KHR_mesh_quantization) on every level. Each level is a cut of the
// multiresolution model, so it is closed, crack-free and within its declared bound.
//
// The JSON is written with nlohmann_json and the GLB container by hand (tinygltf cannot write
// compressed primitives).
#include "exporters/lod_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <numbers>
#include <string>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "exporters/detail/draco_chunk.h"
#include "exporters/detail/glb_container.h"
#include "exporters/detail/gltf_assembly.h"
#include "exporters/detail/gltf_common.h"
#include "exporters/detail/meshopt_streams.h"
#include "exporters/detail/storage_frame.h"

namespace strata {

namespace {

using Json = nlohmann::ordered_json;
using detail::to_float;

constexpr int kFloat = 5126;
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;
constexpr double kRoughness = 0.6;
constexpr std::size_t kMaxShortVertices = 65535;  // index 65535 is the primitive restart value
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kMeshopt = "EXT_meshopt_compression";
constexpr const char* kQuantization = "KHR_mesh_quantization";
constexpr const char* kLod = "MSFT_lod";

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

std::string object_name(const LodObject& object) {
    return object.name.empty() ? "label " + std::to_string(object.label) : object.name;
}

void check_options(const std::filesystem::path& path, const LodOptions& options) {
    for (std::size_t i = 0; i < options.error_mm.size(); ++i) {
        const double e = options.error_mm[i];
        if (!std::isfinite(e) || e < 0.0 || (i > 0 && !(e > options.error_mm[i - 1]))) {
            fail(ErrorCode::InvalidInput, path,
                 "LOD error bound " + std::to_string(i) + " is " + std::to_string(e) +
                     " mm, expected finite, non-negative and increasing bounds");
        }
    }
    if (options.error_mm.empty() && options.level_count == 0) {
        fail(ErrorCode::InvalidInput, path, "0 LOD levels requested, expected at least one");
    }
    if (!(options.screen_error_px > 0.0) || !(options.viewport_height_px > 0.0) ||
        !(options.aspect > 0.0) || !std::isfinite(options.screen_error_px) ||
        !std::isfinite(options.viewport_height_px) || !std::isfinite(options.aspect)) {
        fail(ErrorCode::InvalidInput, path,
             "screen error, viewport height and aspect must be positive and finite");
    }
}

/// Column-major 4 x 4 product a * b.
std::array<double, 16> multiply(const std::array<double, 16>& a, const std::array<double, 16>& b) {
    std::array<double, 16> m{};
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            for (int k = 0; k < 4; ++k) {
                m[4 * c + r] += a[4 * k + r] * b[4 * c + k];
            }
        }
    }
    return m;
}

Vec3 transform(const std::array<double, 16>& m, const std::array<double, 3>& p) {
    Vec3 out;
    for (int r = 0; r < 3; ++r) {
        out[r] = m[12 + r] + m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2];
    }
    return out;
}

/// One level ready to be placed in the buffer.
struct EncodedLevel {
    MultiresCut cut;
    std::size_t triangles = 0;
    std::size_t vertices = 0;
    std::uint32_t model_level = 0;
    // Draco
    std::string draco;
    std::uint32_t points = 0;
    int position_id = -1, normal_id = -1;
    std::array<float, 3> min{}, max{};
    // meshopt
    detail::MeshoptMesh meshopt;
};

/// The cut's mesh in storage coordinates (triangles reversed when the frame mirrors).
struct StorageMesh {
    std::vector<std::array<float, 3>> points;
    std::vector<std::array<std::uint32_t, 3>> triangles;
};

StorageMesh storage_mesh(const TriMesh& cut, const detail::StorageFrame& s, double step) {
    StorageMesh m;
    m.points.reserve(cut.positions.size());
    for (const Vec3& p : cut.positions) {
        const double z = std::nearbyint(p.z / s.slice_spacing_px / step) * step;
        m.points.push_back({to_float(s.flip_x * p.x), to_float(p.y), to_float(z)});
    }
    m.triangles = cut.triangles;
    if (s.flip_x < 0.0) {
        for (auto& t : m.triangles) {
            std::swap(t[1], t[2]);
        }
    }
    return m;
}

/// Area-weighted unit vertex normals in storage coordinates (+z where undefined).
std::vector<std::array<float, 3>> storage_normals(const StorageMesh& m) {
    std::vector<Vec3> sum(m.points.size());
    const auto at = [&](std::uint32_t v) {
        return Vec3{m.points[v][0], m.points[v][1], m.points[v][2]};
    };
    for (const auto& t : m.triangles) {
        const Vec3 a = at(t[0]);
        const Vec3 n = cross(at(t[1]) - a, at(t[2]) - a);
        for (const std::uint32_t v : t) {
            sum[v] = sum[v] + n;
        }
    }
    std::vector<std::array<float, 3>> out;
    out.reserve(sum.size());
    for (const Vec3& n : sum) {
        const double length = norm(n);
        const Vec3 u = (length > 0.0 && std::isfinite(length)) ? (1.0 / length) * n : Vec3{0, 0, 1};
        out.push_back({to_float(u.x), to_float(u.y), to_float(u.z)});
    }
    return out;
}

/// Triangles as position triples rotated to start at their smallest point, sorted: equal for two
/// meshes with the same oriented triangles whatever their vertex order.
std::vector<std::array<std::array<float, 3>, 3>> canonical_triangles(
    const std::vector<std::array<float, 3>>& points,
    const std::vector<std::array<std::uint32_t, 3>>& triangles) {
    std::vector<std::array<std::array<float, 3>, 3>> out;
    out.reserve(triangles.size());
    for (const auto& t : triangles) {
        std::array<std::array<float, 3>, 3> p{points[t[0]], points[t[1]], points[t[2]]};
        const auto first = std::min_element(p.begin(), p.end()) - p.begin();
        std::rotate(p.begin(), p.begin() + first, p.end());
        out.push_back(p);
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// Encodes one level with Draco, lossless on the grid, and checks the decoded mesh: the same
/// oriented triangles on the same positions.
void encode_draco(const std::filesystem::path& path,
                  const std::string& where,
                  const StorageMesh& m,
                  const std::vector<std::array<float, 3>>& normals,
                  double step,
                  const LodOptions& options,
                  EncodedLevel& level) {
    detail::DracoChunkInput input;
    input.positions = m.points;
    input.normals = normals;
    input.triangles = m.triangles;
    input.step = step;
    detail::DracoChunkBytes encoded;
    try {
        encoded = detail::encode_draco_chunk(input, options.compression_level, options.normal_bits);
    } catch (const Error& e) {
        fail(e.code(), path, where + ": " + e.what());
    }
    draco::DecoderBuffer in;
    in.Init(encoded.bytes.data(), encoded.bytes.size());
    draco::Decoder decoder;
    auto decoded_or = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded_or.ok()) {
        fail(ErrorCode::Internal, path,
             where + ": Draco cannot decode its own output: " + decoded_or.status().error_msg());
    }
    const std::unique_ptr<draco::Mesh> decoded = std::move(decoded_or).value();
    const draco::PointAttribute* dp = decoded->GetAttributeByUniqueId(encoded.position_id);
    if (dp == nullptr || decoded->num_faces() != m.triangles.size()) {
        fail(ErrorCode::Internal, path, where + ": Draco round trip lost positions or faces");
    }
    std::vector<std::array<float, 3>> points(decoded->num_points());
    level.min.fill(std::numeric_limits<float>::infinity());
    level.max.fill(-std::numeric_limits<float>::infinity());
    for (std::uint32_t i = 0; i < points.size(); ++i) {
        dp->ConvertValue<float, 3>(dp->mapped_index(draco::PointIndex(i)), points[i].data());
        for (int k = 0; k < 3; ++k) {
            level.min[k] = std::min(level.min[k], points[i][k]);
            level.max[k] = std::max(level.max[k], points[i][k]);
        }
    }
    std::vector<std::array<std::uint32_t, 3>> faces;
    faces.reserve(decoded->num_faces());
    for (draco::FaceIndex f(0); f < decoded->num_faces(); ++f) {
        const auto& face = decoded->face(f);
        faces.push_back({face[0].value(), face[1].value(), face[2].value()});
    }
    if (canonical_triangles(points, faces) != canonical_triangles(m.points, m.triangles)) {
        fail(ErrorCode::Internal, path,
             where + ": Draco changed the triangles or moved a position off the grid");
    }
    level.draco = std::move(encoded.bytes);
    level.points = decoded->num_points();
    level.position_id = encoded.position_id;
    level.normal_id = encoded.normal_id;
}

/// The per-object grid for meshopt: positions as uint16 steps from `origin` when the model's
/// extent fits 65535 steps, else float storage coordinates.
struct MeshoptGrid {
    bool fits = false;
    std::array<double, 3> origin{};
    double step = 0.0;
};

MeshoptGrid meshopt_grid(const MultiresMesh& model, const detail::StorageFrame& s) {
    MeshoptGrid g;
    g.step = model.grid_step;
    TriMesh all;
    all.positions = model.positions;
    const StorageMesh m = storage_mesh(all, s, g.step);
    std::array<double, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (const auto& p : m.points) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(p[k]));
            hi[k] = std::max(hi[k], double(p[k]));
        }
    }
    g.origin = lo;
    g.fits = !m.points.empty();
    for (int k = 0; k < 3; ++k) {
        g.fits = g.fits && (hi[k] - lo[k]) / g.step <= 65535.0;
    }
    for (const auto& p : m.points) {
        for (int k = 0; k < 3 && g.fits; ++k) {
            const double q = std::nearbyint((p[k] - lo[k]) / g.step);
            g.fits = lo[k] + q * g.step == double(p[k]);
        }
    }
    return g;
}

void encode_meshopt(const std::filesystem::path& path,
                    const std::string& where,
                    const StorageMesh& m,
                    const std::vector<std::array<float, 3>>& normals,
                    const MeshoptGrid& grid,
                    EncodedLevel& level) {
    detail::MeshoptInput input;
    input.normals = normals;
    input.triangles = m.triangles;
    if (grid.fits) {
        input.grid_positions.reserve(m.points.size());
        for (const auto& p : m.points) {
            std::array<std::uint16_t, 3> q{};
            for (int k = 0; k < 3; ++k) {
                q[k] =
                    static_cast<std::uint16_t>(std::nearbyint((p[k] - grid.origin[k]) / grid.step));
            }
            input.grid_positions.push_back(q);
        }
    } else {
        input.float_positions = m.points;
    }
    try {
        level.meshopt = detail::encode_meshopt_mesh(input);
    } catch (const Error& e) {
        fail(e.code(), path, where + ": " + e.what());
    }
}

Json json_array(const auto& values) {
    Json a = Json::array();
    for (const auto v : values) {
        a.push_back(v);
    }
    return a;
}

/// The mesh of one level: one primitive, its accessors and views.
Json level_primitive(detail::GltfAssembly& a, const EncodedLevel& level, bool draco, int material) {
    Json primitive;
    if (draco) {
        const int view = a.add_view(level.draco);
        const int position = a.add_accessor({{"componentType", kFloat},
                                             {"count", level.points},
                                             {"type", "VEC3"},
                                             {"min", json_array(level.min)},
                                             {"max", json_array(level.max)}});
        const int normal =
            a.add_accessor({{"componentType", kFloat}, {"count", level.points}, {"type", "VEC3"}});
        const int indices = a.add_accessor(
            {{"componentType", level.points <= kMaxShortVertices ? kUnsignedShort : kUnsignedInt},
             {"count", 3 * level.triangles},
             {"type", "SCALAR"}});
        primitive["attributes"] = {{"POSITION", position}, {"NORMAL", normal}};
        primitive["indices"] = indices;
        primitive["extensions"][kDraco] = {
            {"bufferView", view},
            {"attributes", {{"POSITION", level.position_id}, {"NORMAL", level.normal_id}}}};
        primitive["material"] = material;
        return primitive;
    }
    return a.add_meshopt_primitive(level.meshopt, material);
}

/// The smallest 7-significant-digit decimal (as parsed back) >= x.
double short_up(double x) {
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

/// A short decimal <= x (screen coverage thresholds may only shrink: a smaller threshold keeps
/// the finer level longer).
double short_down(double x) {
    return -short_up(-x);
}

}  // namespace

std::vector<MultiresCut> lod_cuts(const MultiresMesh& model,
                                  double mm_per_px,
                                  const LodOptions& options) {
    std::vector<MultiresCut> candidates;
    if (!options.error_mm.empty()) {
        for (const double e : options.error_mm) {
            candidates.push_back(select_cut_by_error(model, e / mm_per_px));
        }
    } else {
        const std::uint32_t levels = level_count(model);
        const std::uint32_t n = std::min<std::uint32_t>(options.level_count, levels);
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t level =
                n == 1
                    ? 0
                    : static_cast<std::uint32_t>(std::lround(double(i) * (levels - 1) / (n - 1)));
            candidates.push_back(select_cut_at_level(model, level));
        }
    }
    // Keep cuts that are coarser and declare a larger bound than the previous one; a coarser cut
    // with the same bound replaces it (the finer one would never be worth its triangles).
    std::vector<MultiresCut> cuts;
    for (MultiresCut& cut : candidates) {
        if (!cuts.empty() && cut.clusters == cuts.back().clusters) {
            continue;
        }
        if (!cuts.empty() && !(cut.error_px > cuts.back().error_px)) {
            cuts.back() = std::move(cut);
            continue;
        }
        cuts.push_back(std::move(cut));
    }
    return cuts;
}

namespace {

/// Refuses objects without a quantized model or with a colour outside sRGB [0, 1].
void check_objects(const std::filesystem::path& path, const std::vector<LodObject>& objects) {
    for (std::size_t i = 0; i < objects.size(); ++i) {
        const LodObject& o = objects[i];
        const std::string what = "object " + std::to_string(i) + " '" + object_name(o) + "'";
        if (o.model == nullptr || o.model->clusters.empty()) {
            fail(ErrorCode::InvalidInput, path, what + " has no model");
        }
        if (!(o.model->grid_step > 0.0)) {
            fail(ErrorCode::InvalidInput, path,
                 what + ": its model is not on a grid (grid_step 0), expected a quantized model");
        }
        for (const double c : o.srgb) {
            if (!(c >= 0.0 && c <= 1.0)) {
                fail(ErrorCode::InvalidInput, path,
                     what + ": colour channel " + std::to_string(c) + ", expected sRGB in [0, 1]");
            }
        }
    }
}

/// Radius of the bounding sphere of `m` in the patient frame: its box's half diagonal (the
/// patient -> glTF map is a rotation and scale, so boxes stay boxes).
double bounding_radius_mm(const StorageMesh& m, const detail::StorageFrame& storage) {
    Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
            std::numeric_limits<double>::infinity()};
    Vec3 hi = -1.0 * lo;
    for (const auto& p : m.points) {
        const Vec3 w = transform(storage.matrix, {p[0], p[1], p[2]});
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], w[k]);
            hi[k] = std::max(hi[k], w[k]);
        }
    }
    return 0.5 * norm(hi - lo);
}

/// The glTF document's asset, extensions, scene and the patient root node.
void start_document(Json& json, const SceneInfo& info, bool draco) {
    json["asset"] = {{"version", "2.0"}, {"generator", info.generator}};
    json["extensionsUsed"] = Json::array();
    json["extensionsRequired"] = Json::array();
    json["extensionsUsed"].push_back(kLod);
    if (draco) {
        json["extensionsUsed"].push_back(kDraco);
        json["extensionsRequired"].push_back(kDraco);
    } else {
        json["extensionsUsed"].push_back(kMeshopt);
        json["extensionsUsed"].push_back(kQuantization);
        json["extensionsRequired"].push_back(kMeshopt);
        json["extensionsRequired"].push_back(kQuantization);
    }
    json["scene"] = 0;
    json["scenes"] = Json::array({{{"nodes", Json::array({0})}}});
    json["nodes"] = Json::array();
    json["meshes"] = Json::array();
    json["materials"] = Json::array();
    json["accessors"] = Json::array();
    json["bufferViews"] = Json::array();
    json["nodes"].push_back({{"name", detail::kRootNodeName},
                             {"matrix", json_array(detail::kPatientToGltf)},
                             {"children", Json::array()}});
}

/// The nodes of one object: LOD0 under the root, naming the coarser ones (after it, outside the
/// hierarchy) in MSFT_lod, with their bounds and screen coverages in the extras.
void add_object_nodes(Json& json,
                      const LodObject& object,
                      const std::vector<EncodedLevel>& levels,
                      const std::vector<LodLevelStats>& stats,
                      const std::vector<int>& mesh_of,
                      const std::array<double, 16>& matrix,
                      double radius_mm,
                      const SceneInfo& info,
                      const LodOptions& options) {
    const std::size_t n = levels.size();
    const int first = static_cast<int>(json["nodes"].size());
    // Bounds as written (7 digits, rounded up); the coverage is computed from them.
    std::vector<double> written(n);
    for (std::size_t i = 0; i < n; ++i) {
        written[i] = short_up(stats[i].error_mm);
    }
    const Json errors = json_array(written);
    Json coverage = Json::array();
    for (std::size_t i = 0; i + 1 < n; ++i) {
        // Level i + 1 projects its bound to at most screen_error_px while the sphere's
        // projected radius R (px) <= screen_error_px * r / e_{i+1}; coverage =
        // pi (R / H)^2 / aspect, rounded down (a smaller threshold keeps level i longer).
        const double r_px = options.screen_error_px * radius_mm / written[i + 1];
        const double c =
            std::numbers::pi * std::pow(r_px / options.viewport_height_px, 2) / options.aspect;
        coverage.push_back(std::clamp(short_down(c), 0.0, 1.0));
    }
    coverage.push_back(0.0);  // the coarsest is never culled
    for (std::size_t i = 0; i < n; ++i) {
        Json node;
        node["name"] = object_name(object) + "_LOD" + std::to_string(i);
        node["mesh"] = mesh_of[i];
        node["matrix"] = json_array(matrix);
        Json extras = {{"lod", i},
                       {"error_mm", errors[i]},
                       {"triangles", levels[i].triangles},
                       {"label", object.label},
                       {"source", info.source},
                       {"spacing_mm", json_array(info.spacing_mm)},
                       {"units", "mm"}};
        if (i == 0) {
            if (n > 1) {
                Json ids = Json::array();
                for (std::size_t k = 1; k < n; ++k) {
                    ids.push_back(first + static_cast<int>(k));
                }
                node["extensions"][kLod] = {{"ids", ids}};
            }
            extras["MSFT_screencoverage"] = coverage;
            extras["lod_error_mm"] = errors;
            extras["screen_error_px"] = options.screen_error_px;
            extras["viewport_height_px"] = options.viewport_height_px;
            extras["aspect"] = options.aspect;
            extras["bounding_radius_mm"] = short_up(radius_mm);
            json["nodes"][0]["children"].push_back(first);
        }
        node["extras"] = extras;
        json["nodes"].push_back(node);
    }
}

/// Every level of one object (its cuts at the options' bounds), encoded; `radius_mm` gets the
/// bounding radius of its finest level.
std::vector<EncodedLevel> encode_levels(const std::filesystem::path& path,
                                        const LodObject& object,
                                        const detail::StorageFrame& storage,
                                        const MeshoptGrid& grid,
                                        double error_mm_per_px,
                                        const LodOptions& options,
                                        double& radius_mm) {
    const MultiresMesh& model = *object.model;
    const bool draco = options.compression == LodCompression::Draco;
    std::vector<EncodedLevel> levels;
    const std::vector<MultiresCut> cuts = lod_cuts(model, error_mm_per_px, options);
    for (std::size_t i = 0; i < cuts.size(); ++i) {
        const std::string where = "object '" + object_name(object) + "' LOD" + std::to_string(i);
        EncodedLevel level;
        level.cut = cuts[i];
        const TriMesh mesh = cut_mesh(model, level.cut);
        level.triangles = mesh.triangles.size();
        level.vertices = mesh.positions.size();
        level.model_level = 0;
        for (const std::uint32_t c : level.cut.clusters) {
            level.model_level = std::max(level.model_level, model.clusters[c].level);
        }
        const StorageMesh m = storage_mesh(mesh, storage, model.grid_step);
        const auto normals = storage_normals(m);
        if (i == 0) {
            radius_mm = bounding_radius_mm(m, storage);
        }
        if (draco) {
            encode_draco(path, where, m, normals, model.grid_step, options, level);
        } else {
            encode_meshopt(path, where, m, normals, grid, level);
        }
        levels.push_back(std::move(level));
    }
    return levels;
}

}  // namespace

LodStats write_lod_gltf(const std::filesystem::path& path,
                        const std::vector<LodObject>& objects,
                        const SliceFrame& frame,
                        const SceneInfo& info,
                        const LodOptions& options) {
    if (lowercase_extension(path) != ".glb") {
        fail(ErrorCode::Unsupported, path,
             "unsupported extension '" + path.extension().string() + "', expected .glb");
    }
    check_options(path, options);
    if (objects.empty()) {
        fail(ErrorCode::InvalidInput, path, "no objects to write, expected at least one");
    }
    check_objects(path, objects);
    const detail::StorageFrame storage = detail::storage_frame(path, frame);
    const bool draco = options.compression == LodCompression::Draco;

    // Encode every level of every object.
    std::vector<std::vector<EncodedLevel>> levels(objects.size());
    std::vector<MeshoptGrid> grids(objects.size());
    std::vector<double> radius_mm(objects.size(), 0.0);
    for (std::size_t o = 0; o < objects.size(); ++o) {
        const MultiresMesh& model = *objects[o].model;
        if (!draco) {
            grids[o] = meshopt_grid(model, storage);
        }
        levels[o] = encode_levels(path, objects[o], storage, grids[o], frame.error_mm_per_px,
                                  options, radius_mm[o]);
    }

    detail::GltfAssembly a;
    Json& json = a.json;
    start_document(json, info, draco);

    // Materials, meshes coarse-first in the buffer (every object's coarsest level, then the next).
    std::vector<std::vector<int>> mesh_of(objects.size());
    for (std::size_t o = 0; o < objects.size(); ++o) {
        const LodObject& object = objects[o];
        json["materials"].push_back(
            {{"name", object_name(object)},
             {"pbrMetallicRoughness",
              {{"baseColorFactor",
                {detail::srgb_to_linear(object.srgb[0]), detail::srgb_to_linear(object.srgb[1]),
                 detail::srgb_to_linear(object.srgb[2]), 1.0}},
               {"metallicFactor", 0.0},
               {"roughnessFactor", kRoughness}}}});
        mesh_of[o].assign(levels[o].size(), -1);
    }
    std::size_t most_levels = 0;
    for (const auto& l : levels) {
        most_levels = std::max(most_levels, l.size());
    }
    LodStats stats;
    stats.objects.resize(objects.size());
    for (std::size_t o = 0; o < objects.size(); ++o) {
        stats.objects[o].resize(levels[o].size());
    }
    for (std::size_t rank = 0; rank < most_levels; ++rank) {  // rank 0: coarsest
        for (std::size_t o = 0; o < objects.size(); ++o) {
            if (rank >= levels[o].size()) {
                continue;
            }
            const std::size_t i = levels[o].size() - 1 - rank;
            const std::size_t before = a.bin.size();
            Json primitive = level_primitive(a, levels[o][i], draco, static_cast<int>(o));
            json["meshes"].push_back(
                {{"name", object_name(objects[o]) + "_LOD" + std::to_string(i)},
                 {"primitives", Json::array({primitive})}});
            mesh_of[o][i] = static_cast<int>(json["meshes"].size() - 1);
            LodLevelStats& s = stats.objects[o][i];
            s.bytes = a.bin.size() - before;
            s.triangles = levels[o][i].triangles;
            s.vertices = levels[o][i].vertices;
            s.model_level = levels[o][i].model_level;
            s.error_mm = levels[o][i].cut.error_px * frame.error_mm_per_px;
        }
    }

    // Nodes: per object LOD0 under the root, the coarser ones after it (outside the hierarchy).
    for (std::size_t o = 0; o < objects.size(); ++o) {
        const LodObject& object = objects[o];
        std::array<double, 16> matrix = storage.matrix;
        if (!draco && grids[o].fits) {
            const double q = grids[o].step;
            const std::array<double, 16> dequantize{q,
                                                    0,
                                                    0,
                                                    0,
                                                    0,
                                                    q,
                                                    0,
                                                    0,
                                                    0,
                                                    0,
                                                    q,
                                                    0,
                                                    grids[o].origin[0],
                                                    grids[o].origin[1],
                                                    grids[o].origin[2],
                                                    1};
            matrix = multiply(storage.matrix, dequantize);
        }
        add_object_nodes(json, object, levels[o], stats.objects[o], mesh_of[o], matrix,
                         radius_mm[o], info, options);
    }
    a.finish_buffers();
    const std::string bytes = detail::glb_container(path, json.dump(), a.bin);
    write_file_atomically(path, bytes);
    stats.total_bytes = bytes.size();
    return stats;
}

}  // namespace strata

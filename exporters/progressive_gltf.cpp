// Progressive glTF 2.0, STRATA_progressive_mesh version 3 (schema/README.md; docs/format.md has
// the measurements behind it): the base mesh as one Draco primitive (KHR_draco_mesh_compression),
// one raw Draco chunk per group, the DAG as a binary table, one error per group in the JSON.
//
// The JSON is written with nlohmann_json and the GLB container by hand (glTF 2.0 specification
// section 4.4): tinygltf cannot write Draco primitives. Draco encodes with explicit quantization
// on the model's own dyadic grid: origin and range multiples of the grid step, so Draco's float
// quantize/dequantize steps are exact and decoded positions equal ours bit for bit.
#include "exporters/progressive_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <string>
#include <system_error>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/parallel.h"
#include "exporters/detail/draco_chunk.h"
#include "exporters/detail/glb_container.h"
#include "exporters/detail/gltf_common.h"
#include "exporters/detail/storage_frame.h"
#include "exporters/progressive_format.h"
#include "mesh/shading_normals.h"

namespace strata {

namespace {

using Json = nlohmann::ordered_json;
using detail::to_float;

constexpr double kRoughness = 0.6;
constexpr std::size_t kMaxShortVertices = 65535;  // index 65535 is the primitive restart value
constexpr int kErrorDigits = 3;     ///< errors rounded up to 3 significant digits (JSON bytes)
constexpr int kColorDecimals = 5;   ///< linear colour channels (from 8-bit sRGB: 1/255)
constexpr int kVolumeDecimals = 3;  ///< mL
constexpr int kStorageNode = 1;     ///< node index of the storage frame, the objects' parent

/// The double a JSON reader parses from `x` printed with `decimals` decimals (nlohmann prints it
/// back as that short decimal).
double short_decimal(double x, int decimals) {
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, x);
    return std::strtod(text, nullptr);
}

std::string key(std::string_view name) {
    return std::string(name);
}

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

std::string object_name(const ProgressiveObject& object) {
    return object.name.empty() ? "label " + std::to_string(object.label) : object.name;
}

/// The double parsed from the shortest decimal that gives `x`'s float back.
double short_float_decimal(double x) {
    const float f = to_float(x);
    char text[64];
    for (int digits = 1; digits <= 9; ++digits) {
        std::snprintf(text, sizeof text, "%.*g", digits, double(f));
        const double back = std::strtod(text, nullptr);
        if (to_float(back) == f) {
            return back;
        }
    }
    return double(f);
}

/// A JSON number: an integer when `x` is one (prints without ".0"), else `x`.
Json json_number(double x) {
    if (x == std::nearbyint(x) && std::abs(x) < 9.0e15) {
        return static_cast<std::int64_t>(x);
    }
    return x;
}

/// JSON numbers, integers without ".0" (JSON bytes).
template <class T, std::size_t N>
Json json_numbers(const std::array<T, N>& values) {
    Json out = Json::array();
    for (const T v : values) {
        out.push_back(json_number(double(v)));
    }
    return out;
}

/// The storage frame of one object (detail/storage_frame.h) with the written matrix and the maps
/// from slice space into the scene.
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
    const detail::StorageFrame stored = detail::storage_frame(path, frame);
    StorageFrame s;
    s.flip_x = stored.flip_x;
    s.matrix = stored.matrix;
    const std::array<double, 3> scale{s.flip_x, 1.0, stored.slice_spacing_px};
    // The matrix as written: each entry the shortest decimal of its float (JSON bytes: about 80
    // per object; the frame moves by float rounding, < 1e-7 relative, far below the grid step);
    // everything below is computed from the written matrix.
    for (double& m : s.matrix) {
        m = short_float_decimal(m);
    }
    // scene = P * (M q + t), q = (flip x, y, z / d) the storage coordinates of slice-space p
    const auto& p = detail::kPatientToGltf;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
            double sum = 0.0;
            for (int k = 0; k < 3; ++k) {
                sum += p[4 * k + r] * s.matrix[4 * c + k];
            }
            s.to_scene[3 * r + c] = sum / scale[c];
        }
        double o = p[12 + r];
        for (int k = 0; k < 3; ++k) {
            o += p[4 * k + r] * s.matrix[12 + k];
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

/// Grid coordinates of one slice-space position as floats (exact: multiples of the grid step).
struct GridPoint {
    std::array<float, 3> v;
};

GridPoint grid_point(const Vec3& p, double step, double d, double flip_x) {
    const double z = std::nearbyint(p.z / d / step) * step;
    return {{to_float(flip_x * p.x), to_float(p.y), to_float(z)}};
}

/// A sphere in the scene frame as float32 (the DAG table): the centre rounded to float, the
/// radius rounded up so that it contains the exact sphere and every sphere in `inside`.
std::array<float, 4> scene_sphere(const StorageFrame& s,
                                  const Sphere& sphere,
                                  const std::vector<const std::array<float, 4>*>& inside) {
    const Vec3 c = sphere.center;
    std::array<double, 3> exact{};
    std::array<float, 4> out{};
    for (int r = 0; r < 3; ++r) {
        exact[r] = s.scene_origin[r] + s.to_scene[3 * r] * c.x + s.to_scene[3 * r + 1] * c.y +
                   s.to_scene[3 * r + 2] * c.z;
        out[r] = to_float(exact[r]);
    }
    const auto distance = [&](const std::array<double, 3>& to) {
        return std::hypot(double(out[0]) - to[0], double(out[1]) - to[1], double(out[2]) - to[2]);
    };
    double radius = sphere.radius * s.scene_scale + distance(exact);
    for (const std::array<float, 4>* other : inside) {
        radius = std::max(radius, distance({(*other)[0], (*other)[1], (*other)[2]}) + (*other)[3]);
    }
    radius *= 1.0 + 1e-7;
    float r = to_float(radius);
    while (double(r) < radius) {
        r = std::nextafter(r, std::numeric_limits<float>::infinity());
    }
    out[3] = r;
    return out;
}

std::array<std::uint32_t, 3> canonical(std::array<std::uint32_t, 3> t) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
}

/// One object's geometry on its grid, in the file's frame and orientation.
struct ObjectGrid {
    const MultiresMesh* model = nullptr;
    bool reverse = false;  ///< triangles reversed (mirroring frame)
    double step = 0.0;
    double slice_spacing_px = 1.0;
    double flip_x = 1.0;
    /// Model vertex `v` on the grid (computed where a mesh reads it: no array per object).
    std::array<float, 3> point(std::uint32_t v) const {
        return grid_point(model->positions[v], step, slice_spacing_px, flip_x).v;
    }
};

ObjectGrid object_grid(const MultiresMesh& model,
                       const StorageFrame& storage,
                       const SliceFrame& frame) {
    ObjectGrid grid;
    grid.model = &model;
    grid.step = model.grid_step;
    grid.reverse = storage.flip_x < 0.0;
    grid.slice_spacing_px = frame.slice_spacing_px;
    grid.flip_x = storage.flip_x;
    return grid;
}

/// A Draco mesh over some clusters of a model, as encoded, with what its accessors need.
struct EncodedMesh {
    std::string bytes;
    std::uint32_t points = 0;
    std::uint32_t faces = 0;
    std::array<float, 3> min{}, max{};
    detail::DracoChunkBytes ids;
};

/// The welded input of `clusters` (each one `_CLUSTER` value, in this order): local vertices
/// in increasing model id, and for each the model vertex.
detail::DracoChunkInput mesh_input(const ObjectGrid& grid,
                                   const std::vector<std::uint32_t>& clusters,
                                   std::vector<std::uint32_t>& vertices) {
    const MultiresMesh& model = *grid.model;
    vertices.clear();
    for (const std::uint32_t c : clusters) {
        vertices.insert(vertices.end(), model.clusters[c].vertices.begin(),
                        model.clusters[c].vertices.end());
    }
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    const auto local = [&](std::uint32_t v) {
        return static_cast<std::uint32_t>(std::lower_bound(vertices.begin(), vertices.end(), v) -
                                          vertices.begin());
    };
    detail::DracoChunkInput in;
    in.step = grid.step;
    in.positions.reserve(vertices.size());
    for (const std::uint32_t v : vertices) {
        in.positions.push_back(grid.point(v));
    }
    std::vector<std::uint32_t> cluster_local;  // per vertex of a cluster: its local vertex
    for (std::uint32_t k = 0; k < clusters.size(); ++k) {
        const MultiresCluster& cluster = model.clusters[clusters[k]];
        cluster_local.resize(cluster.vertices.size());
        for (std::size_t i = 0; i < cluster.vertices.size(); ++i) {
            cluster_local[i] = local(cluster.vertices[i]);
        }
        for (const auto& t : cluster.triangles) {
            const std::uint32_t a = cluster_local[t[0]];
            const std::uint32_t b = cluster_local[t[1]];
            const std::uint32_t c = cluster_local[t[2]];
            in.triangles.push_back(grid.reverse ? std::array{a, c, b} : std::array{a, b, c});
            in.triangle_cluster.push_back(k);
        }
    }
    return in;
}

/// Where every local vertex of a group's chunk collapses (a local vertex; itself: survives).
std::vector<std::uint32_t> local_coarse(const MultiresMesh& model,
                                        const MultiresGroup& group,
                                        const std::vector<std::uint32_t>& vertices,
                                        const std::string& where) {
    constexpr std::uint32_t kUnset = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> coarse(vertices.size(), kUnset);
    const auto local = [&](std::uint32_t v) {
        const auto it = std::lower_bound(vertices.begin(), vertices.end(), v);
        if (it == vertices.end() || *it != v) {
            throw Error(ErrorCode::Internal, where + ": a vertex collapses outside its group");
        }
        return static_cast<std::uint32_t>(it - vertices.begin());
    };
    for (const std::uint32_t c : group.consumed) {
        const MultiresCluster& cluster = model.clusters[c];
        for (std::size_t i = 0; i < cluster.vertices.size(); ++i) {
            std::uint32_t& target = coarse[local(cluster.vertices[i])];
            const std::uint32_t to = local(cluster.coarse_vertices[i]);
            if (target != kUnset && target != to) {
                throw Error(ErrorCode::Internal,
                            where + ": clusters disagree on where a vertex collapses");
            }
            target = to;
        }
    }
    return coarse;
}

/// Decodes `mesh` again and checks it against its input: every triangle of every `_CLUSTER`
/// value, same orientation, and (with slots) every vertex's coarse vertex. Returns the decoded
/// chunk.
detail::DecodedChunk check_decoded(const EncodedMesh& mesh,
                                   const detail::DracoChunkInput& in,
                                   const std::vector<std::uint32_t>& coarse,
                                   std::uint32_t clusters,
                                   const std::string& where) {
    detail::DecodedChunk d;
    try {
        d = detail::decode_draco_chunk(
            mesh.bytes,
            {mesh.ids.position_id, mesh.ids.cluster_id, mesh.ids.slot_id, mesh.ids.normal_id},
            clusters, std::numeric_limits<std::size_t>::max());
    } catch (const Error& e) {
        throw Error(ErrorCode::Internal,
                    where + ": Draco cannot decode its own output: " + e.what());
    }
    // the input vertices by position (the first of equal positions: the stable sort keeps the
    // lowest vertex first), found by binary search
    using Indexed = std::pair<std::array<float, 3>, std::uint32_t>;
    std::vector<Indexed> input_vertex(in.positions.size());
    for (std::uint32_t v = 0; v < in.positions.size(); ++v) {
        input_vertex[v] = {in.positions[v], v};
    }
    const auto by_position = [](const Indexed& a, const Indexed& b) { return a.first < b.first; };
    std::stable_sort(input_vertex.begin(), input_vertex.end(), by_position);
    std::vector<std::uint32_t> vertex_of(d.positions.size());
    for (std::size_t v = 0; v < d.positions.size(); ++v) {
        const Indexed wanted{d.positions[v], 0};
        const auto it =
            std::lower_bound(input_vertex.begin(), input_vertex.end(), wanted, by_position);
        if (it == input_vertex.end() || by_position(wanted, *it)) {
            throw Error(ErrorCode::Internal, where + ": Draco moved a position off the grid");
        }
        vertex_of[v] = it->second;
    }
    using Tagged = std::pair<std::uint32_t, std::array<std::uint32_t, 3>>;
    std::vector<Tagged> expected, got;
    for (std::size_t t = 0; t < in.triangles.size(); ++t) {
        expected.push_back(
            {in.triangle_cluster.empty() ? 0 : in.triangle_cluster[t], canonical(in.triangles[t])});
    }
    for (std::size_t t = 0; t < d.triangles.size(); ++t) {
        const auto& tri = d.triangles[t];
        got.push_back({d.triangle_cluster.empty() ? 0 : d.triangle_cluster[t],
                       canonical({vertex_of[tri[0]], vertex_of[tri[1]], vertex_of[tri[2]]})});
    }
    std::sort(expected.begin(), expected.end());
    std::sort(got.begin(), got.end());
    if (expected != got) {
        throw Error(ErrorCode::Internal, where + ": Draco round trip changed the triangles");
    }
    if (!coarse.empty()) {
        const std::vector<std::uint32_t> resolved =
            detail::resolve_slots(d.positions, d.triangles, d.slots);
        for (std::size_t v = 0; v < resolved.size(); ++v) {
            if (vertex_of[resolved[v]] != coarse[vertex_of[v]]) {
                throw Error(ErrorCode::Internal,
                            where + ": the slots do not decode to the coarse vertices");
            }
        }
    }
    return d;
}

EncodedMesh encode_checked(const detail::DracoChunkInput& in,
                           const std::vector<std::uint32_t>& coarse,
                           std::uint32_t clusters,
                           const ProgressiveOptions& options,
                           const std::string& where) {
    EncodedMesh out;
    try {
        out.ids = detail::encode_draco_chunk(in, options.compression_level, options.normal_bits);
    } catch (const Error& e) {
        throw Error(e.code(), where + ": " + e.what());
    }
    out.bytes = std::move(out.ids.bytes);
    // note: points, faces and positions do not depend on the attributes read
    const detail::DecodedChunk d = check_decoded(out, in, coarse, clusters, where);
    out.points = static_cast<std::uint32_t>(d.points);
    out.faces = static_cast<std::uint32_t>(d.triangles.size());
    out.min.fill(std::numeric_limits<float>::infinity());
    out.max.fill(-std::numeric_limits<float>::infinity());
    for (const auto& p : d.positions) {
        for (int k = 0; k < 3; ++k) {
            out.min[k] = std::min(out.min[k], p[k]);
            out.max[k] = std::max(out.max[k], p[k]);
        }
    }
    return out;
}

/// The chunk of group `g`: its consumed clusters welded, `_CLUSTER` k = consumed[k], `_SLOT`.
EncodedMesh group_chunk(const ObjectGrid& grid,
                        std::size_t g,
                        const ProgressiveOptions& options,
                        const std::string& where) {
    const MultiresGroup& group = grid.model->groups[g];
    std::vector<std::uint32_t> vertices;
    detail::DracoChunkInput in = mesh_input(grid, group.consumed, vertices);
    const std::vector<std::uint32_t> coarse = local_coarse(*grid.model, group, vertices, where);
    try {
        in.slots = detail::encode_slots(in.positions, in.triangles, coarse);
    } catch (const Error& e) {
        throw Error(e.code(), where + ": " + e.what());
    }
    return encode_checked(in, coarse, static_cast<std::uint32_t>(group.consumed.size()), options,
                          where);
}

/// The base mesh: every root cluster (`_CLUSTER` k = k-th root), with the shading normals of the
/// base surface (mesh/shading_normals.h, computed in patient millimetres through the node matrix,
/// as the viewer computes them over a drawn cut), brought back to the storage frame.
EncodedMesh base_mesh(const ObjectGrid& grid,
                      const std::array<double, 16>& matrix,
                      const std::vector<std::uint32_t>& roots,
                      const ProgressiveOptions& options,
                      const std::string& where) {
    std::vector<std::uint32_t> vertices;
    detail::DracoChunkInput in = mesh_input(grid, roots, vertices);
    TriMesh patient;
    for (const auto& q : in.positions) {
        Vec3 p;
        for (int r = 0; r < 3; ++r) {
            p[r] = matrix[12 + r] + matrix[r] * q[0] + matrix[4 + r] * q[1] + matrix[8 + r] * q[2];
        }
        patient.positions.push_back(p);
    }
    patient.triangles = in.triangles;  // the matrix does not mirror: outward stays outward
    for (const Vec3& n : shading_normals(patient)) {
        // normals map by the inverse transpose; for M = rotation x positive scales that is
        // M^T up to a positive scale per axis, which the normalization removes
        Vec3 m;
        for (int c = 0; c < 3; ++c) {
            m[c] = matrix[4 * c] * n.x + matrix[4 * c + 1] * n.y + matrix[4 * c + 2] * n.z;
        }
        const double length = norm(m);
        const Vec3 u = (length > 0.0 && std::isfinite(length)) ? (1.0 / length) * m : Vec3{0, 0, 1};
        in.normals.push_back({to_float(u.x), to_float(u.y), to_float(u.z)});
    }
    if (roots.size() == 1) {
        in.triangle_cluster.clear();  // no _CLUSTER: every triangle is the one root's
    }
    return encode_checked(in, {}, static_cast<std::uint32_t>(roots.size()), options, where);
}

/// The buffer being written: a prefix (tables and bases, a first frame's bytes) and the chunks.
struct BufferParts {
    std::string prefix;
    std::string chunks;
    struct View {
        bool in_chunks;
        std::size_t offset, length;
    };
    std::vector<View> views;  ///< in JSON buffer view order

    int add(bool in_chunks, const std::string& bytes) {
        std::string& part = in_chunks ? chunks : prefix;
        views.push_back({in_chunks, part.size(), bytes.size()});
        part += bytes;
        part.resize((part.size() + 3) / 4 * 4, '\0');
        return static_cast<int>(views.size() - 1);
    }
};

int add_accessor(Json& json, Json accessor) {
    json["accessors"].push_back(std::move(accessor));
    return static_cast<int>(json["accessors"].size() - 1);
}

/// The base mesh's JSON (one Draco primitive) and its accessors.
Json base_mesh_json(
    Json& json, const EncodedMesh& base, int view, std::size_t roots, int material) {
    Json attributes;
    attributes[key(format::kPosition)] = add_accessor(json, {{"componentType", format::kFloat},
                                                             {"count", base.points},
                                                             {"type", "VEC3"},
                                                             {"min", json_numbers(base.min)},
                                                             {"max", json_numbers(base.max)}});
    attributes[key(format::kNormal)] = add_accessor(
        json, {{"componentType", format::kFloat}, {"count", base.points}, {"type", "VEC3"}});
    if (base.ids.cluster_id >= 0) {  // absent when there is one root
        attributes[key(format::kCluster)] = add_accessor(
            json, {{"componentType", roots > 256 ? format::kUnsignedShort : format::kUnsignedByte},
                   {"count", base.points},
                   {"type", "SCALAR"}});
    }
    Json primitive;
    primitive["attributes"] = attributes;
    primitive["indices"] = add_accessor(
        json, {{"componentType",
                base.points <= kMaxShortVertices ? format::kUnsignedShort : format::kUnsignedInt},
               {"count", 3 * std::size_t{base.faces}},
               {"type", "SCALAR"}});
    primitive["material"] = material;  // mode: TRIANGLES, the default, left out (JSON bytes)
    primitive["extensions"][key(format::kDraco)] = {
        {"bufferView", view},
        {"attributes",
         {{key(format::kPosition), base.ids.position_id},
          {key(format::kNormal), base.ids.normal_id}}}};
    if (base.ids.cluster_id >= 0) {
        primitive["extensions"][key(format::kDraco)]["attributes"][key(format::kCluster)] =
            base.ids.cluster_id;
    }
    // unnamed: the node carries the object's name (JSON bytes)
    return {{"primitives", Json::array({std::move(primitive)})}};
}

/// The DAG table of one model: spheres nested as written, chunk ranges from `chunk_offsets`.
format::DagTable dag_table(const MultiresMesh& model,
                           const StorageFrame& storage,
                           const std::vector<double>& errors,
                           const std::vector<std::uint32_t>& chunk_offsets,
                           const std::vector<EncodedMesh>& chunks) {
    format::DagTable table;
    table.clusters = static_cast<std::uint32_t>(model.clusters.size());
    std::vector<std::array<float, 4>> spheres(model.groups.size());
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        const MultiresGroup& group = model.groups[g];
        std::vector<const std::array<float, 4>*> inside;
        for (const std::uint32_t c : group.consumed) {
            const std::int32_t below = model.clusters[c].producer;
            if (below >= 0) {
                inside.push_back(&spheres[std::size_t(below)]);
            }
        }
        spheres[g] = scene_sphere(storage, group.bounds, inside);
        format::DagGroup out;
        out.sphere = spheres[g];
        out.chunk_offset = chunk_offsets[g];
        out.chunk_length = static_cast<std::uint32_t>(chunks[g].bytes.size());
        out.level = static_cast<std::uint16_t>(group.level);
        // the bound against the finest level as written (a fraction of the written error), made
        // monotone again after the rounding: at least that of every group below
        double fine = group.fine_error_px * storage.error_m_per_px;
        for (const std::uint32_t c : group.consumed) {
            const std::int32_t below = model.clusters[c].producer;
            if (below >= 0) {
                fine = std::max(fine, format::fine_error(errors[std::size_t(below)],
                                                         table.groups[std::size_t(below)].fine));
            }
        }
        out.fine = format::encode_fine(fine, errors[g]);
        out.consumed = group.consumed;
        out.produced = group.produced;
        table.groups.push_back(std::move(out));
    }
    return table;
}

/// An object whose chunks and DAG table wait for the file's chunk order (place_chunks).
struct PendingObject {
    const MultiresMesh* model = nullptr;
    std::vector<double> error_m;      ///< per group, as written in the JSON
    std::vector<EncodedMesh> chunks;  ///< per group
    std::size_t node = 0;             ///< its node in the JSON
};

/// The file's shared buffer views: every object's DAG table, every object's chunks.
struct SharedViews {
    std::string tables;
    std::string chunks;
    std::vector<PendingObject> objects;
};

/// The Draco meshes of one object: its group chunks and its base mesh.
struct EncodedObject {
    std::vector<EncodedMesh> chunks;  ///< per group
    EncodedMesh base;
};

/// Every object's chunks and base mesh (the objects without clusters: none), encoded over the
/// threads all together: the encodings depend on their own group or base alone, so the bytes
/// are those of a plain loop.
std::vector<EncodedObject> encode_objects(const std::vector<ProgressiveObject>& objects,
                                          const StorageFrame& storage,
                                          const SliceFrame& frame,
                                          const ProgressiveOptions& options) {
    std::vector<EncodedObject> encoded(objects.size());
    struct Task {
        std::size_t object;
        std::size_t group;  ///< the object's group count: its base mesh
    };
    std::vector<Task> tasks;
    for (std::size_t o = 0; o < objects.size(); ++o) {
        const MultiresMesh& model = *objects[o].model;
        if (model.clusters.empty()) {
            continue;
        }
        encoded[o].chunks.resize(model.groups.size());
        for (std::size_t g = 0; g <= model.groups.size(); ++g) {
            tasks.push_back({o, g});
        }
    }
    parallel_for(tasks.size(), options.threads, [&](std::size_t t) {
        const Task task = tasks[t];
        const ProgressiveObject& object = objects[task.object];
        const MultiresMesh& model = *object.model;
        const ObjectGrid grid = object_grid(model, storage, frame);
        const std::string name = object_name(object);
        if (task.group < model.groups.size()) {
            encoded[task.object].chunks[task.group] = group_chunk(
                grid, task.group, options, "'" + name + "' group " + std::to_string(task.group));
        } else {
            encoded[task.object].base =
                base_mesh(grid, storage.matrix, model.roots(), options, "'" + name + "' base mesh");
        }
    });
    return encoded;
}

/// One object, encoded: its base into `buffer`, its table and chunks into `shared`, its node,
/// mesh, material into `json`.
void write_object(Json& json,
                  BufferParts& buffer,
                  SharedViews& shared,
                  ProgressiveStats& stats,
                  const ProgressiveObject& object,
                  EncodedObject&& encoded,
                  const StorageFrame& storage) {
    const MultiresMesh& model = *object.model;
    const std::string name = object_name(object);
    std::vector<EncodedMesh> chunks = std::move(encoded.chunks);
    const EncodedMesh base = std::move(encoded.base);

    std::vector<double> error_m;
    for (const MultiresGroup& group : model.groups) {
        error_m.push_back(
            format::round_up_decimal(group.error_px * storage.error_m_per_px, kErrorDigits));
    }
    const int base_view = buffer.add(false, base.bytes);

    // unnamed, as the mesh: the node carries the object's name (JSON bytes)
    json["materials"].push_back(
        {{"pbrMetallicRoughness",
          {{"baseColorFactor",
            {short_decimal(detail::srgb_to_linear(object.srgb[0]), kColorDecimals),
             short_decimal(detail::srgb_to_linear(object.srgb[1]), kColorDecimals),
             short_decimal(detail::srgb_to_linear(object.srgb[2]), kColorDecimals), 1}},
           {"metallicFactor", 0},
           {"roughnessFactor", kRoughness}}}});
    const int material = static_cast<int>(json["materials"].size() - 1);
    json["meshes"].push_back(base_mesh_json(json, base, base_view, model.roots().size(), material));
    Json errors = Json::array();
    for (const double e : error_m) {
        errors.push_back(e);
    }
    Json node;
    node["name"] = name;
    node["mesh"] = json["meshes"].size() - 1;
    // no matrix: the storage node above every object carries it (JSON bytes)
    Json ext = {{"dag", 0}};  // the table's offset: set by place_chunks
    ext["errors"] = std::move(errors);
    ext["fullResolutionError"] = format::round_up_decimal(
        model.full_resolution_error_px * storage.error_m_per_px, kErrorDigits);
    ext["gridStep"] = model.grid_step;
    node["extensions"][key(format::kExtension)] = std::move(ext);
    node["extras"] = {{"label", object.label},
                      {"volume_ml", short_decimal(object.volume_ml, kVolumeDecimals)}};
    json["nodes"].push_back(std::move(node));
    json["nodes"][kStorageNode]["children"].push_back(json["nodes"].size() - 1);
    ++stats.objects;
    shared.objects.push_back(
        {&model, std::move(error_m), std::move(chunks), json["nodes"].size() - 1});
}

/// Lays out every object's chunks in the file's chunks view, each 4-byte aligned, in the order a
/// viewer of the whole scene wants them: by decreasing error bound (metres), over all objects
/// together (so the chunks a view wants at some tau are, for a view of the whole model, about one
/// prefix of the view: few, long range requests), ties by object, then parents before children;
/// then writes each object's DAG table with its chunk ranges.
void place_chunks(Json& json,
                  SharedViews& shared,
                  ProgressiveStats& stats,
                  const StorageFrame& storage) {
    struct Slot {
        double error;
        std::size_t object, group;
    };
    std::vector<Slot> order;
    for (std::size_t o = 0; o < shared.objects.size(); ++o) {
        for (std::size_t g = 0; g < shared.objects[o].chunks.size(); ++g) {
            order.push_back({shared.objects[o].error_m[g], o, g});
        }
    }
    std::sort(order.begin(), order.end(), [](const Slot& a, const Slot& b) {
        if (a.error != b.error) {
            return a.error > b.error;
        }
        if (a.object != b.object) {
            return a.object < b.object;
        }
        return a.group > b.group;  // groups are listed children first
    });
    std::vector<std::vector<std::uint32_t>> offsets(shared.objects.size());
    for (std::size_t o = 0; o < shared.objects.size(); ++o) {
        offsets[o].resize(shared.objects[o].chunks.size());
    }
    std::string& chunk_bytes = shared.chunks;
    for (const Slot& slot : order) {
        const std::string& bytes = shared.objects[slot.object].chunks[slot.group].bytes;
        if (chunk_bytes.size() + bytes.size() > std::numeric_limits<std::uint32_t>::max()) {
            throw Error(ErrorCode::Unsupported,
                        "the chunks exceed 4 GiB (the DAG table's uint32 offsets)");
        }
        offsets[slot.object][slot.group] = static_cast<std::uint32_t>(chunk_bytes.size());
        chunk_bytes += bytes;
        chunk_bytes.resize((chunk_bytes.size() + 3) / 4 * 4, '\0');
        stats.chunk_bytes += bytes.size();
        ++stats.chunks;
    }
    for (std::size_t o = 0; o < shared.objects.size(); ++o) {
        const PendingObject& object = shared.objects[o];
        const std::string table = format::encode_dag_table(
            dag_table(*object.model, storage, object.error_m, offsets[o], object.chunks));
        stats.dag_bytes += table.size();
        stats.groups += object.model->groups.size();
        json["nodes"][object.node]["extensions"][key(format::kExtension)]["dag"] =
            shared.tables.size();
        shared.tables += table;  // a multiple of 4 bytes
    }
    shared.objects.clear();
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

}  // namespace

ProgressiveStats write_progressive_gltf(const std::filesystem::path& path,
                                        const std::vector<ProgressiveObject>& objects,
                                        const SliceFrame& frame,
                                        const SceneInfo& info,
                                        const ProgressiveOptions& options) {
    detail::require_gltf_extension(path);
    const bool single = lowercase_extension(path) == ".glb";
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

    Json json;
    json["asset"] = {{"generator", info.generator}, {"version", "2.0"}};
    json["extensionsUsed"] = {key(format::kDraco), key(format::kExtension)};
    json["extensionsRequired"] = {key(format::kDraco)};
    json["extensions"][key(format::kExtension)] = {{"version", format::kVersion}};
    json["scene"] = 0;
    json["scenes"] = Json::array();
    json["scenes"].push_back(Json{{"nodes", Json::array({0})}});
    json["nodes"] = Json::array();
    json["meshes"] = Json::array();
    json["materials"] = Json::array();
    json["accessors"] = Json::array();
    // what all objects share is said once, on the root node (JSON bytes)
    json["nodes"].push_back(
        {{"name", std::string(format::kPatientNodeName)},
         {"matrix", json_numbers(detail::kPatientToGltf)},
         {"children", Json::array({kStorageNode})},
         // errors and spheres are in metres of the scene frame (the spec; JSON bytes)
         {"extras", {{"source", info.source}, {"spacing_mm", json_numbers(info.spacing_mm)}}}});
    // every object shares one storage frame: its matrix is said once, on the node above them
    json["nodes"].push_back({{"name", std::string(format::kStorageNodeName)},
                             {"matrix", json_numbers(storage.matrix)},
                             {"children", Json::array()}});
    BufferParts buffer;
    SharedViews shared;
    ProgressiveStats stats;
    std::vector<EncodedObject> encoded;
    try {
        encoded = encode_objects(objects, storage, frame, options);
    } catch (const Error& e) {
        fail(e.code(), path, e.what());
    }
    for (std::size_t o = 0; o < objects.size(); ++o) {
        if (!objects[o].model->clusters.empty()) {
            write_object(json, buffer, shared, stats, objects[o], std::move(encoded[o]), storage);
        }
    }
    try {
        place_chunks(json, shared, stats, storage);
    } catch (const Error& e) {
        fail(e.code(), path, e.what());
    }
    Json& ext = json["extensions"][key(format::kExtension)];
    ext["dag"] = buffer.add(false, shared.tables);
    // note: no chunks buffer view when no object has a group (glTF: byteLength >= 1)
    if (!shared.chunks.empty()) {
        ext["chunks"] = buffer.add(true, shared.chunks);
    }
    if (json["nodes"][kStorageNode]["children"].empty()) {
        fail(ErrorCode::InvalidInput, path,
             std::to_string(objects.size()) +
                 " objects, none with a triangle: nothing to write, expected at least one "
                 "non-empty object");
    }
    json["bufferViews"] = Json::array();
    for (const BufferParts::View& view : buffer.views) {
        Json v = {{"buffer", 0}};
        const std::size_t offset = (view.in_chunks ? buffer.prefix.size() : 0) + view.offset;
        if (offset != 0) {  // 0 is the default (JSON bytes)
            v["byteOffset"] = offset;
        }
        v["byteLength"] = view.length;
        json["bufferViews"].push_back(std::move(v));
    }
    const std::string data = buffer.prefix + buffer.chunks;
    Json b = {{"byteLength", data.size()}};
    const std::filesystem::path bin = path.parent_path() / (path.stem().string() + ".bin");
    if (!single) {
        b["uri"] = detail::uri_encode(bin.filename().string());
    }
    json["buffers"] = Json::array({std::move(b)});
    const std::string text = json.dump();  // compact: the JSON is part of a first frame's bytes
    stats.json_bytes = text.size();
    if (single) {
        const std::string bytes = detail::glb_container(path, text, data);
        write_file_atomically(path, bytes);
        stats.total_bytes = bytes.size();
        stats.base_bytes = 12 + 8 + (text.size() + 3) / 4 * 4 + 8 + buffer.prefix.size();
    } else {
        write_file_atomically(bin, data);
        stats.files.push_back(bin);
        write_file_atomically(path, text + "\n");
        stats.total_bytes = text.size() + 1 + data.size();
        stats.base_bytes = text.size() + 1 + buffer.prefix.size();
    }
    stats.files.push_back(path);
    return stats;
}

}  // namespace strata

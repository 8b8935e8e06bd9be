#include "exporters/detail/draco_chunk.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <unordered_map>

#include <draco/compression/decode.h>
#include <draco/compression/expert_encode.h>
#include <draco/core/options.h>
#include <draco/mesh/mesh.h>

#include "core/error.h"

namespace strata::detail {

namespace {

int bits_for(double extent_steps) {
    int bits = 1;
    while (bits < 24 && std::ldexp(1.0, bits) - 1.0 < extent_steps) {
        ++bits;
    }
    return bits;
}

// Draco keeps the quantization origin and range as decimal text with six decimals
// (draco::Options, std::to_string), so an origin of 7.8359375 comes back as 7.835938 and the
// decoded positions leave the grid. These read values back the way the encoder will.
bool survives_options(const float (&origin)[3]) {
    draco::Options options;
    options.SetVector("v", origin, 3);
    float back[3] = {};
    options.GetVector("v", 3, back);
    return back[0] == origin[0] && back[1] == origin[1] && back[2] == origin[2];
}

bool survives_options(float range) {
    draco::Options options;
    options.SetFloat("v", range);
    return options.GetFloat("v") == range;
}

/// Exact key of a float position (-0 as +0): hashes of one vertex's points agree.
struct PositionKey {
    std::array<float, 3> v;
    bool operator==(const PositionKey& o) const { return v == o.v; }
};

struct PositionHash {
    std::size_t operator()(const PositionKey& k) const {
        std::uint64_t h = 1469598103934665603ULL;
        for (const float x : k.v) {
            std::uint32_t bits = 0;
            const float y = x + 0.0f;
            std::memcpy(&bits, &y, 4);
            h = (h ^ bits) * 1099511628211ULL;
        }
        return static_cast<std::size_t>(h);
    }
};

PositionKey key_of(const std::array<float, 3>& p) {
    return {{p[0] + 0.0f, p[1] + 0.0f, p[2] + 0.0f}};
}

[[noreturn]] void reject(const std::string& what) {
    throw Error(ErrorCode::InvalidInput, what);
}

/// Explicit quantization of positions on the grid: origin and bits.
struct GridQuantization {
    float origin[3] = {};
    int bits = 0;
    float range = 0.0f;
};

GridQuantization grid_quantization(const DracoChunkInput& in) {
    std::array<double, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (const std::array<float, 3>& p : in.positions) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(p[k]));
            hi[k] = std::max(hi[k], double(p[k]));
        }
    }
    // The origin: the lowest grid point, moved down to a multiple of 1/64 when the grid is finer
    // (six decimals hold it exactly). The range: step * (2^bits - 1), with more bits where
    // Draco's text would round it.
    const double exact_step = std::max(in.step, 1.0 / 64.0);
    GridQuantization q;
    double extent = 0.0;
    for (int k = 0; k < 3; ++k) {
        q.origin[k] = static_cast<float>(std::floor(lo[k] / exact_step) * exact_step);
        extent = std::max(extent, (hi[k] - q.origin[k]) / in.step);
    }
    q.bits = bits_for(extent);
    const auto range_of = [&](int b) {
        return static_cast<float>(in.step * (std::ldexp(1.0, b) - 1.0));
    };
    while (q.bits < 24 && !survives_options(range_of(q.bits))) {
        ++q.bits;
    }
    if (std::ldexp(1.0, q.bits) - 1.0 < extent) {
        throw Error(ErrorCode::InvalidInput,
                    "spans " + std::to_string(extent) +
                        " grid steps, more than 2^24 (float positions would lose the grid)");
    }
    q.range = range_of(q.bits);
    if (!survives_options(q.origin) || !survives_options(q.range)) {
        throw Error(ErrorCode::Unsupported,
                    "the quantization origin (" + std::to_string(q.origin[0]) + ", " +
                        std::to_string(q.origin[1]) + ", " + std::to_string(q.origin[2]) +
                        ") or range " + std::to_string(q.range) +
                        " does not survive Draco's six-decimal options text (grid step " +
                        std::to_string(in.step) + ")");
    }
    return q;
}

/// The Draco mesh of `in`: one point per (vertex, cluster) pair the triangles use.
std::unique_ptr<draco::Mesh> draco_mesh(const DracoChunkInput& in, DracoChunkBytes& ids) {
    const bool clustered = !in.triangle_cluster.empty();
    std::unordered_map<std::uint64_t, std::uint32_t> point_of;
    std::vector<std::uint32_t> point_vertex, point_cluster;
    std::vector<std::array<std::uint32_t, 3>> faces;
    std::uint32_t clusters = 1;
    for (std::size_t t = 0; t < in.triangles.size(); ++t) {
        const std::uint32_t k = clustered ? in.triangle_cluster[t] : 0;
        clusters = std::max(clusters, k + 1);
        std::array<std::uint32_t, 3> face{};
        for (int i = 0; i < 3; ++i) {
            const std::uint32_t v = in.triangles[t][i];
            const auto [it, added] = point_of.emplace(
                (std::uint64_t{v} << 32) | k, static_cast<std::uint32_t>(point_vertex.size()));
            if (added) {
                point_vertex.push_back(v);
                point_cluster.push_back(k);
            }
            face[i] = it->second;
        }
        faces.push_back(face);
    }
    auto mesh = std::make_unique<draco::Mesh>();
    mesh->set_num_points(static_cast<std::uint32_t>(point_vertex.size()));
    const auto add = [&](draco::GeometryAttribute::Type type, draco::DataType data_type,
                         int components, std::size_t values, const std::vector<std::uint32_t>& map,
                         const auto& value_of) {
        draco::GeometryAttribute attribute;
        const int size = static_cast<int>(draco::DataTypeLength(data_type)) * components;
        attribute.Init(type, nullptr, static_cast<std::uint8_t>(components), data_type, false, size,
                       0);
        const int id = mesh->AddAttribute(attribute, false, static_cast<std::uint32_t>(values));
        draco::PointAttribute* a = mesh->attribute(id);
        for (std::size_t i = 0; i < values; ++i) {
            a->SetAttributeValue(draco::AttributeValueIndex(static_cast<std::uint32_t>(i)),
                                 value_of(i));
        }
        for (std::size_t p = 0; p < map.size(); ++p) {
            a->SetPointMapEntry(draco::PointIndex(static_cast<std::uint32_t>(p)),
                                draco::AttributeValueIndex(map[p]));
        }
        return id;
    };
    const std::size_t nv = in.positions.size();
    ids.position_id = add(draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, 3, nv,
                          point_vertex, [&](std::size_t i) { return in.positions[i].data(); });
    std::vector<std::uint8_t> cluster8(clusters);
    std::vector<std::uint16_t> cluster16(clusters);
    for (std::uint32_t k = 0; k < clusters; ++k) {
        cluster8[k] = static_cast<std::uint8_t>(k);
        cluster16[k] = static_cast<std::uint16_t>(k);
    }
    if (clustered) {
        const bool wide = clusters > 256;
        ids.cluster_id =
            add(draco::GeometryAttribute::GENERIC, wide ? draco::DT_UINT16 : draco::DT_UINT8, 1,
                clusters, point_cluster, [&](std::size_t k) -> const void* {
                    return wide ? static_cast<const void*>(&cluster16[k])
                                : static_cast<const void*>(&cluster8[k]);
                });
    }
    if (!in.slots.empty()) {
        ids.slot_id = add(draco::GeometryAttribute::GENERIC, draco::DT_UINT8, 1, nv, point_vertex,
                          [&](std::size_t i) { return &in.slots[i]; });
    }
    if (!in.normals.empty()) {
        ids.normal_id = add(draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, 3, nv,
                            point_vertex, [&](std::size_t i) { return in.normals[i].data(); });
    }
    for (const auto& f : faces) {
        mesh->AddFace({draco::PointIndex(f[0]), draco::PointIndex(f[1]), draco::PointIndex(f[2])});
    }
    return mesh;
}

}  // namespace

DracoChunkBytes encode_draco_chunk(const DracoChunkInput& in,
                                   int compression_level,
                                   int normal_bits) {
    const GridQuantization q = grid_quantization(in);
    DracoChunkBytes out;
    const std::unique_ptr<draco::Mesh> mesh = draco_mesh(in, out);
    draco::ExpertEncoder encoder(*mesh);
    encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    const int speed = 10 - std::clamp(compression_level, 0, 10);
    encoder.SetSpeedOptions(speed, speed);
    encoder.SetAttributeExplicitQuantization(out.position_id, q.bits, 3, q.origin, q.range);
    encoder.SetAttributePredictionScheme(out.position_id,
                                         draco::MESH_PREDICTION_CONSTRAINED_MULTI_PARALLELOGRAM);
    // measured on the torus phantom (bench-size breakdown): _CLUSTER 1.2 kB without prediction,
    // 0.3 kB with difference prediction (neighbours in the traversal share the cluster);
    // _SLOT 1.8 kB without prediction, 2.3 kB with it
    if (out.cluster_id >= 0) {
        encoder.SetAttributePredictionScheme(out.cluster_id, draco::PREDICTION_DIFFERENCE);
    }
    if (out.slot_id >= 0) {
        encoder.SetAttributePredictionScheme(out.slot_id, draco::PREDICTION_NONE);
    }
    if (out.normal_id >= 0) {
        encoder.SetAttributeQuantization(out.normal_id, normal_bits);
    }
    draco::EncoderBuffer buffer;
    const draco::Status status = encoder.EncodeToBuffer(&buffer);
    if (!status.ok()) {
        throw Error(ErrorCode::Internal, "Draco encoding failed: " + status.error_msg_string());
    }
    out.bytes.assign(buffer.data(), buffer.size());
    for (int* id : {&out.position_id, &out.cluster_id, &out.slot_id, &out.normal_id}) {
        if (*id >= 0) {
            *id = static_cast<int>(mesh->attribute(*id)->unique_id());
        }
    }
    return out;
}

std::size_t draco_declared_triangles(std::string_view bytes) {
    // header (Draco bitstream 2.2): "DRACO", major, minor, encoder type (1: mesh), method
    // (1: Edgebreaker), flags (uint16, 0: no metadata); the traversal type (uint8); then
    // varints: encoded vertices, faces
    if (bytes.size() < 14 || bytes.substr(0, 5) != "DRACO") {
        reject("not a Draco bitstream (no \"DRACO\" header)");
    }
    const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(bytes[i]); };
    if (byte(5) != 2 || byte(6) != 2 || byte(7) != 1 || byte(8) != 1 || byte(9) != 0 ||
        byte(10) != 0) {
        reject("Draco header " + std::to_string(byte(5)) + "." + std::to_string(byte(6)) +
               " type " + std::to_string(byte(7)) + " method " + std::to_string(byte(8)) +
               " flags " + std::to_string(byte(9) | (byte(10) << 8)) +
               ", expected a version 2.2 Edgebreaker mesh without metadata");
    }
    std::size_t at = 12;
    std::uint64_t value = 0;
    for (int field = 0; field < 2; ++field) {
        value = 0;
        for (int shift = 0;; shift += 7) {
            if (at >= bytes.size() || shift > 35) {
                reject("Draco header: a count is truncated or too long");
            }
            const unsigned char b = byte(at++);
            value |= std::uint64_t{b & 0x7Fu} << shift;
            if ((b & 0x80u) == 0) {
                break;
            }
        }
    }
    return static_cast<std::size_t>(value);
}

DecodedChunk decode_draco_chunk(std::string_view bytes,
                                const DracoAttributeIds& ids,
                                std::uint32_t cluster_count,
                                std::size_t max_triangles) {
    const std::size_t declared = draco_declared_triangles(bytes);
    if (declared > max_triangles || declared > kMaxTrianglesPerByte * bytes.size()) {
        reject("Draco declares " + std::to_string(declared) + " triangles in " +
               std::to_string(bytes.size()) + " bytes, expected at most " +
               std::to_string(std::min(max_triangles, kMaxTrianglesPerByte * bytes.size())));
    }
    draco::DecoderBuffer in;
    in.Init(bytes.data(), bytes.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded.ok()) {
        reject("Draco cannot decode it: " + decoded.status().error_msg_string());
    }
    const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    const std::size_t points = mesh->num_points();
    const std::size_t faces = mesh->num_faces();
    if (faces == 0 || faces > declared || points > 3 * faces) {
        reject(std::to_string(points) + " points and " + std::to_string(faces) +
               " triangles, expected 1 to " + std::to_string(declared) +
               " triangles and at most 3 points each");
    }
    const auto attribute = [&](int id, int components, const char* name) {
        const draco::PointAttribute* a =
            id < 0 ? nullptr : mesh->GetAttributeByUniqueId(static_cast<std::uint32_t>(id));
        if (a == nullptr || a->num_components() != components) {
            reject(std::string("no ") + name + " (Draco attribute " + std::to_string(id) +
                   " with " + std::to_string(components) + " components)");
        }
        return a;
    };
    DecodedChunk out;
    out.points = points;
    const draco::PointAttribute* position = attribute(ids.position, 3, "POSITION");
    std::unordered_map<PositionKey, std::uint32_t, PositionHash> vertex_of;
    std::vector<std::uint32_t> point_vertex(points);
    for (std::uint32_t i = 0; i < points; ++i) {
        std::array<float, 3> p{};
        position->ConvertValue<float, 3>(position->mapped_index(draco::PointIndex(i)), p.data());
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            reject("point " + std::to_string(i) + " has a non-finite position");
        }
        const auto [it, added] =
            vertex_of.emplace(key_of(p), static_cast<std::uint32_t>(out.positions.size()));
        if (added) {
            out.positions.push_back(key_of(p).v);
        }
        point_vertex[i] = it->second;
    }
    const auto scalar = [&](int id, const char* name) {
        const draco::PointAttribute* a = attribute(id, 1, name);
        std::vector<std::uint32_t> values(points);
        for (std::uint32_t i = 0; i < points; ++i) {
            std::uint32_t v = 0;
            if (!a->ConvertValue<std::uint32_t, 1>(a->mapped_index(draco::PointIndex(i)), &v)) {
                reject(std::string("cannot read ") + name);
            }
            values[i] = v;
        }
        return values;
    };
    std::vector<std::uint32_t> point_cluster;
    if (ids.cluster >= 0) {
        point_cluster = scalar(ids.cluster, "_CLUSTER");
    }
    if (ids.slot >= 0) {
        const std::vector<std::uint32_t> slots = scalar(ids.slot, "_SLOT");
        constexpr std::uint32_t kUnset = 1u << 31;
        std::vector<std::uint32_t> slot(out.positions.size(), kUnset);
        for (std::uint32_t i = 0; i < points; ++i) {
            std::uint32_t& s = slot[point_vertex[i]];
            if (slots[i] > 255 || (s != kUnset && s != slots[i])) {
                reject("point " + std::to_string(i) + ": _SLOT " + std::to_string(slots[i]) +
                       ", expected one uint8 per position");
            }
            s = slots[i];
        }
        out.slots.assign(slot.begin(), slot.end());
    }
    if (ids.normal >= 0) {
        const draco::PointAttribute* normal = attribute(ids.normal, 3, "NORMAL");
        out.normals.resize(out.positions.size());
        std::vector<bool> seen(out.positions.size(), false);
        for (std::uint32_t i = 0; i < points; ++i) {
            if (!seen[point_vertex[i]]) {
                seen[point_vertex[i]] = true;
                normal->ConvertValue<float, 3>(normal->mapped_index(draco::PointIndex(i)),
                                               out.normals[point_vertex[i]].data());
            }
        }
    }
    out.triangles.reserve(faces);
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
        const auto& face = mesh->face(f);
        std::array<std::uint32_t, 3> t{};
        for (int i = 0; i < 3; ++i) {
            t[i] = point_vertex[face[i].value()];
        }
        if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
            reject("triangle " + std::to_string(f.value()) + " repeats a vertex");
        }
        out.triangles.push_back(t);
        if (!point_cluster.empty()) {
            const std::uint32_t k = point_cluster[face[0].value()];
            if (k >= cluster_count || point_cluster[face[1].value()] != k ||
                point_cluster[face[2].value()] != k) {
                reject("triangle " + std::to_string(f.value()) + ": _CLUSTER values " +
                       std::to_string(k) + ", " + std::to_string(point_cluster[face[1].value()]) +
                       ", " + std::to_string(point_cluster[face[2].value()]) +
                       ", expected one value < " + std::to_string(cluster_count));
            }
            out.triangle_cluster.push_back(k);
        }
    }
    return out;
}

NeighbourLists ordered_neighbours(const std::vector<std::array<float, 3>>& positions,
                                  const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                  const std::vector<bool>& survivor) {
    const std::size_t n = positions.size();
    NeighbourLists nb;
    // every corner gives its vertex the two others: counted, then placed, in triangle order
    std::vector<std::uint32_t> fill(n + 1, 0);
    for (const auto& t : triangles) {
        for (int i = 0; i < 3; ++i) {
            fill[t[i] + 1] += 2;
        }
    }
    for (std::size_t v = 0; v < n; ++v) {
        fill[v + 1] += fill[v];
    }
    std::vector<std::uint32_t> raw(fill[n]);
    for (const auto& t : triangles) {
        for (int i = 0; i < 3; ++i) {
            std::uint32_t& at = fill[t[i]];
            raw[at++] = t[(i + 1) % 3];
            raw[at++] = t[(i + 2) % 3];
        }
    }
    const auto length2 = [&](std::uint32_t a, std::uint32_t b) {
        const double dx = double(positions[b][0]) - double(positions[a][0]);
        const double dy = double(positions[b][1]) - double(positions[a][1]);
        const double dz = double(positions[b][2]) - double(positions[a][2]);
        return ((dx * dx) + (dy * dy)) + (dz * dz);
    };
    nb.start.resize(n + 1);
    nb.items.reserve(raw.size() / 2);
    std::uint32_t begin = 0;  // vertex v's raw entries: [begin, fill[v]) after the placing
    for (std::uint32_t v = 0; v < n; ++v) {
        nb.start[v] = static_cast<std::uint32_t>(nb.items.size());
        const auto first = raw.begin() + begin;
        const auto last = raw.begin() + fill[v];
        begin = fill[v];
        std::sort(first, last);
        const auto list = nb.items.insert(nb.items.end(), first, std::unique(first, last));
        std::sort(list, nb.items.end(), [&](std::uint32_t a, std::uint32_t b) {
            if (survivor[a] != survivor[b]) {
                return bool(survivor[a]);
            }
            const double la = length2(v, a), lb = length2(v, b);
            if (la != lb) {
                return la < lb;
            }
            return positions[a] < positions[b];
        });
    }
    nb.start[n] = static_cast<std::uint32_t>(nb.items.size());
    return nb;
}

std::vector<std::uint8_t> encode_slots(const std::vector<std::array<float, 3>>& positions,
                                       const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                       const std::vector<std::uint32_t>& coarse) {
    const std::size_t n = positions.size();
    std::vector<bool> survivor(n);
    for (std::uint32_t v = 0; v < n; ++v) {
        survivor[v] = coarse[v] == v;
    }
    const auto nb = ordered_neighbours(positions, triangles, survivor);
    // breadth-first from every survivor, inside the set of vertices that collapse into it
    constexpr std::uint32_t kFar = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> depth(n, kFar), queue;
    for (std::uint32_t v = 0; v < n; ++v) {
        if (survivor[v]) {
            depth[v] = 0;
            queue.push_back(v);
        }
    }
    for (std::size_t i = 0; i < queue.size(); ++i) {
        const std::uint32_t u = queue[i];
        for (std::size_t r = 0; r < nb.size(u); ++r) {
            const std::uint32_t w = nb.at(u, r);
            if (depth[w] == kFar && coarse[w] == coarse[u]) {
                depth[w] = depth[u] + 1;
                queue.push_back(w);
            }
        }
    }
    std::vector<std::uint8_t> slots(n, 0);
    for (std::uint32_t v = 0; v < n; ++v) {
        if (survivor[v]) {
            continue;
        }
        std::size_t rank = 0;
        const std::size_t count = nb.size(v);
        while (rank < count && rank < 255 &&
               !(coarse[nb.at(v, rank)] == coarse[v] && depth[v] != kFar &&
                 depth[nb.at(v, rank)] + 1 == depth[v])) {
            ++rank;
        }
        if (rank >= count || rank >= 255) {
            throw Error(ErrorCode::Internal,
                        "vertex " + std::to_string(v) +
                            " has no neighbour closer to the vertex it collapses to (slot "
                            "encoding)");
        }
        slots[v] = static_cast<std::uint8_t>(rank + 1);
    }
    return slots;
}

std::vector<std::uint32_t> resolve_slots(const std::vector<std::array<float, 3>>& positions,
                                         const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                         const std::vector<std::uint8_t>& slots) {
    const std::size_t n = positions.size();
    std::vector<bool> survivor(n);
    for (std::uint32_t v = 0; v < n; ++v) {
        survivor[v] = slots[v] == 0;
    }
    const auto nb = ordered_neighbours(positions, triangles, survivor);
    constexpr std::uint32_t kUnknown = std::numeric_limits<std::uint32_t>::max();
    constexpr std::uint32_t kVisiting = kUnknown - 1;
    std::vector<std::uint32_t> coarse(n, kUnknown), chain;
    for (std::uint32_t v = 0; v < n; ++v) {
        std::uint32_t u = v;
        while (coarse[u] == kUnknown) {
            if (survivor[u]) {
                coarse[u] = u;
                break;
            }
            if (slots[u] > nb.size(u)) {
                reject("vertex " + std::to_string(u) + ": _SLOT " + std::to_string(slots[u]) +
                       ", but it has " + std::to_string(nb.size(u)) + " neighbours");
            }
            coarse[u] = kVisiting;
            chain.push_back(u);
            u = nb.at(u, slots[u] - 1u);
        }
        if (coarse[u] == kVisiting) {
            reject("the _SLOT chain from vertex " + std::to_string(v) +
                   " never reaches a surviving vertex");
        }
        for (const std::uint32_t w : chain) {
            coarse[w] = coarse[u];
        }
        chain.clear();
    }
    return coarse;
}

}  // namespace strata::detail

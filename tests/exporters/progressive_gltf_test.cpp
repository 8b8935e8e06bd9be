#include "exporters/progressive_gltf.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include <draco/compression/decode.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "exporters/progressive_format.h"
#include "exporters/read_progressive_gltf.h"
#include "mesh/mesh_checks.h"
#include "mesh/shading_normals.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

std::uint32_t u32(const std::string& bytes, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
}

/// A written file, parsed independently of the writer: the JSON and every buffer's bytes.
struct Written {
    Json json;
    std::vector<std::string> buffers;
};

Written load(const fs::path& path) {
    Written w;
    const std::string bytes = test::read_file(path);
    if (path.extension() == ".glb") {
        EXPECT_EQ(u32(bytes, 0), 0x46546C67u);
        EXPECT_EQ(u32(bytes, 4), 2u);
        EXPECT_EQ(u32(bytes, 8), bytes.size());
        const std::uint32_t json_length = u32(bytes, 12);
        EXPECT_EQ(u32(bytes, 16), 0x4E4F534Au);
        EXPECT_EQ(json_length % 4, 0u);
        w.json = Json::parse(bytes.substr(20, json_length));
        const std::size_t bin = 20 + json_length;
        EXPECT_EQ(u32(bytes, bin + 4), 0x004E4942u);
        w.buffers.push_back(bytes.substr(bin + 8, u32(bytes, bin)));
        EXPECT_EQ(w.json["buffers"].size(), 1u);
        EXPECT_FALSE(w.json["buffers"][0].contains("uri"));
    } else {
        w.json = Json::parse(bytes);
        for (const Json& buffer : w.json["buffers"]) {
            const fs::path file = path.parent_path() / buffer["uri"].get<std::string>();
            w.buffers.push_back(test::read_file(file));
            EXPECT_EQ(w.buffers.back().size(), buffer["byteLength"].get<std::size_t>()) << file;
        }
    }
    EXPECT_EQ(w.buffers.size(), w.json["buffers"].size());
    return w;
}

std::string view_bytes(const Written& w, int view) {
    const Json& v = w.json["bufferViews"][view];
    return w.buffers.at(v["buffer"].get<std::size_t>())
        .substr(v.value("byteOffset", std::size_t{0}), v["byteLength"].get<std::size_t>());
}

template <class T>
std::vector<T> accessor_values(const Written& w, int accessor) {
    const Json& a = w.json["accessors"][accessor];
    const std::string bytes = view_bytes(w, a["bufferView"].get<int>());
    const std::size_t components = a["type"] == "VEC3" ? 3 : 1;
    std::vector<T> out(a["count"].get<std::size_t>() * components);
    EXPECT_EQ(bytes.size(), out.size() * sizeof(T));
    std::memcpy(out.data(), bytes.data(), std::min(bytes.size(), out.size() * sizeof(T)));
    return out;
}

using Tri = std::array<std::uint32_t, 3>;

Tri canonical(Tri t) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
}

/// The model as the file must hold it: for each vertex the storage coordinates.
struct Expect {
    const MultiresMesh* model;
    double d;
    double flip;
    std::map<std::array<float, 3>, std::uint32_t> vertex_at;
    std::vector<std::array<float, 3>> storage;
};

Expect expectations(const MultiresMesh& model, double d, double flip) {
    Expect e{&model, d, flip, {}, {}};
    for (std::uint32_t v = 0; v < model.positions.size(); ++v) {
        const Vec3 p = model.positions[v];
        const std::array<float, 3> s{static_cast<float>(flip * p.x), static_cast<float>(p.y),
                                     static_cast<float>(p.z / d)};
        EXPECT_TRUE(e.vertex_at.emplace(s, v).second) << "two vertices at one storage point";
        e.storage.push_back(s);
    }
    return e;
}

/// Triangles of cluster `c` as global ids, canonical and sorted, oriented as in the storage frame.
std::vector<Tri> cluster_triangles(const MultiresMesh& model, std::uint32_t c, bool reverse) {
    std::vector<Tri> out;
    const MultiresCluster& cluster = model.clusters[c];
    for (const auto& t : cluster.triangles) {
        Tri g{cluster.vertices[t[0]], cluster.vertices[t[1]], cluster.vertices[t[2]]};
        if (reverse) {
            std::swap(g[1], g[2]);
        }
        out.push_back(canonical(g));
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// 4x4 column-major product.
std::array<double, 16> multiply(const Json& a, const Json& b) {
    std::array<double, 16> m{};
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            double sum = 0.0;
            for (int k = 0; k < 4; ++k) {
                sum += a[4 * k + r].get<double>() * b[4 * c + k].get<double>();
            }
            m[4 * c + r] = sum;
        }
    }
    return m;
}

Vec3 transform_point(const std::array<double, 16>& m, const std::array<float, 3>& p) {
    Vec3 out;
    for (int r = 0; r < 3; ++r) {
        out[r] = m[12 + r] + m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2];
    }
    return out;
}

struct Model {
    Reconstruction result;
    SliceFrame frame;
};

/// The torus with a frame like a CT's: 0.7 mm pixels, slices 2.5 mm apart, shifted origin.
const Model& torus() {
    static const Model model = [] {
        Model m;
        const Phantom phantom = make_phantom("torus");
        ReconstructOptions options;
        options.multires.cluster_triangles = 256;
        Report report;
        m.result = reconstruct(phantom.stack, options, report);
        const double d = m.result.slice_spacing_px;
        m.frame.linear = {0.7, 0, 0, 0, 0.7, 0, 0, 0, 0.7};
        m.frame.origin = {-120.5, 33.25, 410.0};
        m.frame.slice_spacing_px = d;
        m.frame.error_mm_per_px = 0.7;
        return m;
    }();
    return model;
}

/// The torus kept at full resolution only, as the pipeline keeps a surface that failed
/// verification: a model without groups.
const Model& single_level_torus() {
    static const Model model = [] {
        Model m = torus();
        const Phantom phantom = make_phantom("torus");
        ReconstructOptions options;
        options.multires.cluster_triangles = 256;
        options.multires.max_levels = 0;
        Report report;
        m.result = reconstruct(phantom.stack, options, report);
        return m;
    }();
    return model;
}

std::vector<ProgressiveObject> objects_of(const Model& m) {
    std::vector<ProgressiveObject> objects;
    for (std::size_t i = 0; i < m.result.models.size(); ++i) {
        ProgressiveObject o;
        o.name = "torus";
        o.label = m.result.surfaces[i].label;
        o.srgb = {0.8, 0.5, 0.25};
        o.volume_ml = 12.5;
        o.model = &m.result.models[i];
        objects.push_back(o);
    }
    return objects;
}

SceneInfo info() {
    SceneInfo info;
    info.source = "phantom torus";
    info.spacing_mm = {0.7, 0.7, 2.5};
    info.generator = "strata test";
    return info;
}

/// A Draco mesh decoded here (not by the exporter's decoder): points, their attributes by unique
/// id, triangles of point indices.
struct Decoded {
    std::vector<std::array<float, 3>> position;
    std::vector<std::array<float, 3>> normal;
    std::vector<std::uint32_t> cluster, slot;
    std::vector<Tri> faces;
};

Decoded draco_decode(const std::string& bytes, int position, int cluster, int slot, int normal) {
    draco::DecoderBuffer buffer;
    buffer.Init(bytes.data(), bytes.size());
    draco::Decoder decoder;
    auto mesh_or = decoder.DecodeMeshFromBuffer(&buffer);
    EXPECT_TRUE(mesh_or.ok());
    Decoded out;
    if (!mesh_or.ok()) {
        return out;
    }
    const std::unique_ptr<draco::Mesh> mesh = std::move(mesh_or).value();
    const auto read = [&](int id, auto& values, int components) {
        if (id < 0) {
            return;
        }
        const draco::PointAttribute* a = mesh->GetAttributeByUniqueId(id);
        ASSERT_NE(a, nullptr) << "attribute " << id;
        ASSERT_EQ(a->num_components(), components);
        values.resize(mesh->num_points());
        for (std::uint32_t i = 0; i < mesh->num_points(); ++i) {
            using T = std::decay_t<decltype(values[0])>;
            if constexpr (std::is_same_v<T, std::uint32_t>) {
                a->ConvertValue<std::uint32_t, 1>(a->mapped_index(draco::PointIndex(i)),
                                                  &values[i]);
            } else {
                a->ConvertValue<float, 3>(a->mapped_index(draco::PointIndex(i)), values[i].data());
            }
        }
    };
    read(position, out.position, 3);
    read(cluster, out.cluster, 1);
    read(slot, out.slot, 1);
    read(normal, out.normal, 3);
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
        const auto& face = mesh->face(f);
        out.faces.push_back({face[0].value(), face[1].value(), face[2].value()});
    }
    return out;
}

/// Per `_CLUSTER` value: the triangles as model vertex ids, canonical and sorted.
std::map<std::uint32_t, std::vector<Tri>> triangles_by_cluster(const Decoded& d, const Expect& e) {
    std::map<std::uint32_t, std::vector<Tri>> out;
    for (const Tri& f : d.faces) {
        EXPECT_EQ(d.cluster[f[0]], d.cluster[f[1]]);
        EXPECT_EQ(d.cluster[f[0]], d.cluster[f[2]]);
        Tri t{};
        for (int i = 0; i < 3; ++i) {
            const auto it = e.vertex_at.find(d.position[f[i]]);
            EXPECT_NE(it, e.vertex_at.end()) << "a decoded position is no vertex of the model";
            t[i] = it == e.vertex_at.end() ? 0 : it->second;
        }
        out[d.cluster[f[0]]].push_back(canonical(t));
    }
    for (auto& [k, list] : out) {
        std::sort(list.begin(), list.end());
    }
    return out;
}

/// The coarse vertex of every model vertex of a chunk, from its slots, resolved here as the
/// spec says: neighbours ordered survivors first, then by squared length, then by position.
std::map<std::uint32_t, std::uint32_t> coarse_from_slots(const Decoded& d, const Expect& e) {
    std::map<std::uint32_t, std::uint32_t> slot;
    std::map<std::uint32_t, std::set<std::uint32_t>> nb;
    for (std::size_t i = 0; i < d.position.size(); ++i) {
        slot[e.vertex_at.at(d.position[i])] = d.slot[i];
    }
    for (const Tri& f : d.faces) {
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                if (i != j) {
                    nb[e.vertex_at.at(d.position[f[i]])].insert(e.vertex_at.at(d.position[f[j]]));
                }
            }
        }
    }
    const auto resolve = [&](std::uint32_t v) {
        for (int step = 0; step < 1000; ++step) {
            if (slot.at(v) == 0) {
                return v;
            }
            std::vector<std::uint32_t> order(nb[v].begin(), nb[v].end());
            const auto& p = e.storage;
            std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
                const auto key = [&](std::uint32_t u) {
                    double sq = 0.0;
                    for (int k = 0; k < 3; ++k) {
                        const double dk = double(p[u][k]) - double(p[v][k]);
                        sq += dk * dk;
                    }
                    return std::make_tuple(slot.at(u) != 0, sq, p[u]);
                };
                return key(a) < key(b);
            });
            EXPECT_LE(slot.at(v), order.size());
            if (slot.at(v) > order.size()) {
                return v;
            }
            v = order[slot.at(v) - 1];
        }
        ADD_FAILURE() << "a slot chain does not end";
        return v;
    };
    std::map<std::uint32_t, std::uint32_t> out;
    for (const auto& [v, s] : slot) {
        out[v] = resolve(v);
    }
    return out;
}

std::uint32_t table_u32(const std::string& t, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, t.data() + at, 4);
    return v;
}

std::uint32_t table_u16(const std::string& t, std::size_t at) {
    std::uint16_t v = 0;
    std::memcpy(&v, t.data() + at, 2);
    return v;
}

float table_f32(const std::string& t, std::size_t at) {
    float v = 0;
    std::memcpy(&v, t.data() + at, 4);
    return v;
}

/// Everything the file says about the model, checked against it: the DAG table (parsed here
/// from the spec's byte layout), the base mesh and every chunk (decoded here with Draco), the
/// slots (resolved here), spheres in the scene frame.
void expect_file_holds_model(const fs::path& path, const Model& m, double flip) {
    const Written w = load(path);
    const Json& json = w.json;
    ASSERT_EQ(json["extensionsRequired"], Json({"KHR_draco_mesh_compression"}));
    ASSERT_EQ(json["extensionsUsed"],
              Json({"KHR_draco_mesh_compression", "STRATA_progressive_mesh"}));
    // patient -> storage (the shared storage frame) -> one node per object, without a matrix
    ASSERT_EQ(json["nodes"][0]["children"], Json({1}));
    const Json& storage = json["nodes"][1];
    EXPECT_EQ(storage["name"], "storage");
    ASSERT_EQ(storage["children"].size(), m.result.models.size());
    const MultiresMesh& model = m.result.models[0];
    const Json& node = json["nodes"][storage["children"][0].get<int>()];
    EXPECT_FALSE(node.contains("matrix"));
    const Json& ext = node["extensions"]["STRATA_progressive_mesh"];
    const Json& file_ext = json["extensions"]["STRATA_progressive_mesh"];
    EXPECT_EQ(file_ext["version"], 3);
    EXPECT_FALSE(ext.contains("version"));
    ASSERT_EQ(ext["errors"].size(), model.groups.size());
    EXPECT_EQ(ext["gridStep"].get<double>(), model.grid_step);
    const double m_per_px = m.frame.error_mm_per_px / 1000.0;
    // bounds are written rounded up to 3 significant digits
    const auto expect_written_bound = [](double written, double exact) {
        EXPECT_GE(written, exact);
        EXPECT_LE(written, exact * (1.0 + 1e-2));
    };
    expect_written_bound(ext["fullResolutionError"].get<double>(),
                         model.full_resolution_error_px * m_per_px);
    EXPECT_EQ(node["extras"]["label"], m.result.surfaces[0].label);
    const std::array<double, 16> to_scene = multiply(json["nodes"][0]["matrix"], storage["matrix"]);
    const Json& nm = storage["matrix"];
    const double det = nm[0].get<double>() * (nm[5].get<double>() * nm[10].get<double>() -
                                              nm[9].get<double>() * nm[6].get<double>()) -
                       nm[4].get<double>() * (nm[1].get<double>() * nm[10].get<double>() -
                                              nm[9].get<double>() * nm[2].get<double>()) +
                       nm[8].get<double>() * (nm[1].get<double>() * nm[6].get<double>() -
                                              nm[5].get<double>() * nm[2].get<double>());
    EXPECT_GT(det, 0.0) << "the node matrix mirrors";
    const Expect e = expectations(model, m.result.slice_spacing_px, flip);
    const bool reverse = flip < 0.0;

    // the DAG table, byte by byte as schema/README.md states it
    // (the node names its table's byte offset in the file's dag view)
    const std::string table =
        view_bytes(w, file_ext["dag"].get<int>()).substr(ext["dag"].get<std::size_t>());
    // the chunks view exists exactly when there are groups (glTF buffer views are never empty)
    ASSERT_EQ(file_ext.contains("chunks"), !model.groups.empty());
    const std::string chunks =
        model.groups.empty() ? "" : view_bytes(w, file_ext["chunks"].get<int>());
    ASSERT_GE(table.size(), 16u);
    EXPECT_EQ(table.substr(0, 4), "SDAG");
    EXPECT_EQ(table_u32(table, 4), model.clusters.size());
    ASSERT_EQ(table_u32(table, 8), model.groups.size());
    const std::uint32_t id_bytes = table_u32(table, 12);
    EXPECT_EQ(id_bytes, model.clusters.size() <= 65535 ? 2u : 4u);
    std::size_t list = 16 + 32 * model.groups.size();
    std::vector<std::array<float, 4>> spheres;
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        SCOPED_TRACE("group " + std::to_string(g));
        const MultiresGroup& group = model.groups[g];
        const std::size_t at = 16 + 32 * g;
        const std::array<float, 4> sphere{table_f32(table, at), table_f32(table, at + 4),
                                          table_f32(table, at + 8), table_f32(table, at + 12)};
        spheres.push_back(sphere);
        const std::uint32_t offset = table_u32(table, at + 16);
        const std::uint32_t length = table_u32(table, at + 20);
        ASSERT_EQ(table_u16(table, at + 24), group.consumed.size());
        ASSERT_EQ(table_u16(table, at + 26), group.produced.size());
        EXPECT_EQ(table_u16(table, at + 28), group.level);
        // the bound against the finest level, a fraction of the written error, holds the model's
        const double fine =
            format::fine_error(ext["errors"][g].get<double>(), table_u16(table, at + 30));
        EXPECT_GE(fine, group.fine_error_px * m_per_px * (1.0 - 1e-12));
        EXPECT_LE(fine, ext["errors"][g].get<double>());
        std::vector<std::uint32_t> ids;
        for (std::size_t i = 0; i < group.consumed.size() + group.produced.size(); ++i) {
            ids.push_back(id_bytes == 2 ? table_u16(table, list) : table_u32(table, list));
            list += id_bytes;
        }
        EXPECT_EQ(
            std::vector<std::uint32_t>(ids.begin(), ids.begin() + long(group.consumed.size())),
            group.consumed);
        EXPECT_EQ(std::vector<std::uint32_t>(ids.begin() + long(group.consumed.size()), ids.end()),
                  group.produced);
        expect_written_bound(ext["errors"][g].get<double>(), group.error_px * m_per_px);
        // the sphere holds every vertex of its clusters in the scene frame
        for (const auto* clusters : {&group.consumed, &group.produced}) {
            for (const std::uint32_t c : *clusters) {
                for (const std::uint32_t v : model.clusters[c].vertices) {
                    const Vec3 p = transform_point(to_scene, e.storage[v]);
                    EXPECT_LE(norm(p - Vec3{sphere[0], sphere[1], sphere[2]}), sphere[3]);
                }
            }
        }
        // the chunk: decoded here, triangles and coarse vertices as in memory
        ASSERT_LE(std::uint64_t{offset} + length, chunks.size());
        const Decoded d = draco_decode(chunks.substr(offset, length), 0, 1, 2, -1);
        const auto by_cluster = triangles_by_cluster(d, e);
        ASSERT_EQ(by_cluster.size(), group.consumed.size());
        for (std::uint32_t k = 0; k < group.consumed.size(); ++k) {
            EXPECT_EQ(by_cluster.at(k), cluster_triangles(model, group.consumed[k], reverse))
                << "consumed cluster " << k;
        }
        const auto coarse = coarse_from_slots(d, e);
        for (const std::uint32_t c : group.consumed) {
            const MultiresCluster& cluster = model.clusters[c];
            for (std::size_t i = 0; i < cluster.vertices.size(); ++i) {
                EXPECT_EQ(coarse.at(cluster.vertices[i]), cluster.coarse_vertices[i]);
            }
        }
    }
    EXPECT_LE((list + 3) / 4 * 4, table.size());
    // the base mesh: one Draco primitive, every root by _CLUSTER, with unit normals that agree
    // with the area-weighted normals computed here
    const Json& mesh = json["meshes"][node["mesh"].get<int>()];
    ASSERT_EQ(mesh["primitives"].size(), 1u);
    const Json& draco = mesh["primitives"][0]["extensions"]["KHR_draco_mesh_compression"];
    const Json& ids = draco["attributes"];
    const auto roots = model.roots();
    // _CLUSTER only when there are several roots
    ASSERT_EQ(ids.contains("_CLUSTER"), roots.size() > 1);
    Decoded base = draco_decode(view_bytes(w, draco["bufferView"].get<int>()), ids["POSITION"],
                                ids.value("_CLUSTER", -1), -1, ids["NORMAL"]);
    base.cluster.resize(base.position.size(), 0);
    const auto by_root = triangles_by_cluster(base, e);
    ASSERT_EQ(by_root.size(), roots.size());
    // the expected normals: shading_normals of the base surface in patient mm (node matrix),
    // its vertices welded by model id
    const Json& nmx = storage["matrix"];
    std::array<double, 16> to_patient{};
    for (int i = 0; i < 16; ++i) {
        to_patient[i] = nmx[i].get<double>();
    }
    TriMesh patient;
    std::map<std::uint32_t, std::uint32_t> index_of;
    for (std::uint32_t k = 0; k < roots.size(); ++k) {
        EXPECT_EQ(by_root.at(k), cluster_triangles(model, roots[k], reverse)) << "root " << k;
        for (const Tri& t : by_root.at(k)) {
            std::array<std::uint32_t, 3> tri{};
            for (int i = 0; i < 3; ++i) {
                const auto [it, added] =
                    index_of.emplace(t[i], static_cast<std::uint32_t>(patient.positions.size()));
                if (added) {
                    patient.positions.push_back(transform_point(to_patient, e.storage[t[i]]));
                }
                tri[i] = it->second;
            }
            patient.triangles.push_back(tri);
        }
    }
    const std::vector<Vec3> expected_normals = shading_normals(patient);
    double base_volume = 0.0;  // in the scene frame: > 0 when the base faces outwards
    for (const Tri& f : base.faces) {
        const Vec3 a = transform_point(to_scene, base.position[f[0]]);
        const Vec3 b = transform_point(to_scene, base.position[f[1]]);
        const Vec3 c = transform_point(to_scene, base.position[f[2]]);
        base_volume += dot(a, cross(b, c)) / 6.0;
    }
    EXPECT_GT(base_volume, 0.0) << "the base faces inwards in the scene frame";
    // a file normal n (storage frame) is drawn as M^-T n: its direction satisfies
    // M^T (drawn) ~ n, so compare n with M^T times the expected patient-frame normal
    for (std::size_t i = 0; i < base.position.size(); ++i) {
        const Vec3 n{base.normal[i][0], base.normal[i][1], base.normal[i][2]};
        const Vec3 world = expected_normals[index_of.at(e.vertex_at.at(base.position[i]))];
        Vec3 expected;
        for (int c = 0; c < 3; ++c) {
            expected[c] = to_patient[4 * c] * world.x + to_patient[4 * c + 1] * world.y +
                          to_patient[4 * c + 2] * world.z;
        }
        EXPECT_NEAR(norm(n), 1.0, 1e-3);
        EXPECT_GT(dot(n, (1.0 / norm(expected)) * expected), std::cos(1.0 * std::numbers::pi / 180))
            << "normal off by more than 1 degree";
    }
}

TEST(ProgressiveGltf, GlbHoldsTheModelExactly) {
    const Model& m = torus();
    ASSERT_GT(m.result.models.at(0).grid_step, 0.0);
    ASSERT_GT(m.result.models[0].groups.size(), 2u);
    const fs::path dir = test::fresh_temp_dir("progressive_glb");
    const ProgressiveStats stats =
        write_progressive_gltf(dir / "torus.glb", objects_of(m), m.frame, info());
    EXPECT_EQ(stats.total_bytes, fs::file_size(dir / "torus.glb"));
    EXPECT_EQ(stats.chunks, m.result.models[0].groups.size());
    EXPECT_LT(stats.base_bytes, stats.total_bytes);
    expect_file_holds_model(dir / "torus.glb", m, 1.0);
    // The tables and bases are one range at the start of the BIN chunk (one request for a first
    // frame), ending where base_bytes says; the chunks follow, parents (coarse) first.
    const Written w = load(dir / "torus.glb");
    const std::string bytes = test::read_file(dir / "torus.glb");
    const std::size_t bin = 28 + u32(bytes, 12);
    const Json& ext = w.json["extensions"]["STRATA_progressive_mesh"];
    const std::size_t table_offset =
        w.json["nodes"][2]["extensions"]["STRATA_progressive_mesh"]["dag"].get<std::size_t>();
    const Json& views = w.json["bufferViews"];
    const int base_view = w.json["meshes"][0]["primitives"][0]["extensions"]
                                ["KHR_draco_mesh_compression"]["bufferView"];
    const auto end_of = [&](int v) {
        return bin + views[v].value("byteOffset", std::size_t{0}) +
               views[v]["byteLength"].get<std::size_t>();
    };
    EXPECT_LE(std::max(end_of(ext["dag"]), end_of(base_view)), stats.base_bytes);
    EXPECT_GE(bin + views[ext["chunks"].get<int>()]["byteOffset"].get<std::size_t>(),
              stats.base_bytes);
    const std::string table = view_bytes(w, ext["dag"].get<int>()).substr(table_offset);
    // chunks by decreasing error (as the JSON states it), each parent before its children
    const MultiresMesh& model = m.result.models[0];
    const Json& errors = w.json["nodes"][2]["extensions"]["STRATA_progressive_mesh"]["errors"];
    const auto offset = [&](std::size_t g) { return table_u32(table, 16 + 32 * g + 16); };
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        for (std::size_t h = 0; h < model.groups.size(); ++h) {
            if (errors[g].get<double>() > errors[h].get<double>()) {
                EXPECT_LT(offset(g), offset(h)) << "group " << g << " (larger error) after " << h;
            }
        }
        for (const std::uint32_t c : model.groups[g].consumed) {
            const std::int32_t child = model.clusters[c].producer;
            if (child >= 0) {
                EXPECT_LT(offset(g), offset(std::size_t(child)))
                    << "group " << g << "'s chunk after its child " << child << "'s";
            }
        }
    }
}

// glTF 2.0 requires bufferView.byteLength >= 1: an object without groups has no chunks view
// (the TotalSegmentator example's lung_middle_lobe_right had an empty one, which the Khronos
// validator reports as an error).
TEST(ProgressiveGltf, ObjectWithoutGroupsHasNoEmptyBufferView) {
    const Model& m = single_level_torus();
    ASSERT_TRUE(m.result.models.at(0).groups.empty());
    ASSERT_GT(m.result.models[0].clusters.size(), 1u);
    const fs::path dir = test::fresh_temp_dir("progressive_single_level");
    write_progressive_gltf(dir / "torus.glb", objects_of(m), m.frame, info());
    const Written w = load(dir / "torus.glb");
    for (std::size_t v = 0; v < w.json["bufferViews"].size(); ++v) {
        EXPECT_GE(w.json["bufferViews"][v]["byteLength"].get<std::size_t>(), 1u)
            << "buffer view " << v;
    }
    expect_file_holds_model(dir / "torus.glb", m, 1.0);
    const ProgressiveFile file = read_progressive_gltf(dir / "torus.glb");
    ASSERT_EQ(file.objects.size(), 1u);
    EXPECT_TRUE(file.objects[0].model.groups.empty());
    EXPECT_EQ(file.objects[0].model.clusters.size(), m.result.models[0].clusters.size());
}

TEST(ProgressiveGltf, GltfKeepsEverythingInOneBinBesideIt) {
    const Model& m = torus();
    const fs::path dir = test::fresh_temp_dir("progressive_gltf");
    write_progressive_gltf(dir / "torus.gltf", objects_of(m), m.frame, info());
    const Written w = load(dir / "torus.gltf");
    ASSERT_EQ(w.json["buffers"].size(), 1u);
    EXPECT_EQ(w.json["buffers"][0]["uri"], "torus.bin");
    expect_file_holds_model(dir / "torus.gltf", m, 1.0);
}

TEST(ProgressiveGltf, MirroredFramesKeepTrianglesOutward) {
    Model m = torus();
    m.frame.linear = {-0.7, 0, 0, 0, 0.7, 0, 0, 0, 0.7};  // x flipped: a mirror
    const fs::path dir = test::fresh_temp_dir("progressive_mirror");
    write_progressive_gltf(dir / "mirror.glb", objects_of(m), m.frame, info());
    expect_file_holds_model(dir / "mirror.glb", m, -1.0);
}

TEST(ProgressiveGltf, RejectsBadInputAndKeepsOldFiles) {
    const Model& m = torus();
    const fs::path dir = test::fresh_temp_dir("progressive_bad");
    const fs::path file = dir / "model.glb";
    { std::ofstream(file) << "old"; }
    const auto expect_error = [&](const std::vector<ProgressiveObject>& objects,
                                  const SliceFrame& frame, const fs::path& path,
                                  const std::string& fragment) {
        try {
            write_progressive_gltf(path, objects, frame, info());
            ADD_FAILURE() << "no error, expected " << fragment;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
        }
        EXPECT_EQ(test::read_file(file), "old");
    };
    expect_error(objects_of(m), m.frame, dir / "model.obj", "expected .glb or .gltf");
    expect_error({}, m.frame, file, "no objects");
    MultiresMesh unsnapped = m.result.models[0];
    unsnapped.grid_step = 0.0;
    auto objects = objects_of(m);
    objects[0].model = &unsnapped;
    expect_error(objects, m.frame, file, "not on a grid");
    objects = objects_of(m);
    objects[0].srgb[1] = 1.5;
    expect_error(objects, m.frame, file, "expected sRGB in [0, 1]");
    SliceFrame sheared = m.frame;
    sheared.linear[1] = 0.3;
    expect_error(objects_of(m), sheared, file, "sheared");
    MultiresMesh broken = m.result.models[0];
    broken.clusters.back().vertices.push_back(static_cast<std::uint32_t>(broken.positions.size()));
    objects = objects_of(m);
    objects[0].model = &broken;
    expect_error(objects, m.frame, file, "uses vertex");
}

/// Files for the Khronos validator (CTest gltf_validator_progressive) when
/// STRATA_GLTF_SAMPLE_DIR is set.
TEST(ProgressiveGltfSamples, WritesValidatorSamples) {
    const char* dir = std::getenv("STRATA_GLTF_SAMPLE_DIR");
    if (dir == nullptr) {
        GTEST_SKIP() << "STRATA_GLTF_SAMPLE_DIR not set";
    }
    const Model& m = torus();
    write_progressive_gltf(fs::path(dir) / "progressive.glb", objects_of(m), m.frame, info());
    write_progressive_gltf(fs::path(dir) / "progressive.gltf", objects_of(m), m.frame, info());
    const Model& single = single_level_torus();
    write_progressive_gltf(fs::path(dir) / "progressive_single_level.glb", objects_of(single),
                           single.frame, info());
}

}  // namespace
}  // namespace strata

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
#include <vector>

#include <draco/compression/decode.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "mesh/mesh_checks.h"
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

bool inside(const Json& sphere, const Vec3& p) {
    const Vec3 c{sphere[0].get<double>(), sphere[1].get<double>(), sphere[2].get<double>()};
    return norm(p - c) <= sphere[3].get<double>();
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

/// Per model vertex, the sum of the (storage-frame) normals of its triangles in the cut of
/// `level`, computed here from the cut and the expected storage points (not by the writer).
std::vector<Vec3> level_normal_sums(const Expect& e, std::uint32_t level) {
    const MultiresMesh& model = *e.model;
    std::vector<Vec3> sum(model.positions.size());
    const auto at = [&](std::uint32_t v) {
        return Vec3{e.storage[v][0], e.storage[v][1], e.storage[v][2]};
    };
    for (const std::uint32_t c : select_cut_at_level(model, level).clusters) {
        const MultiresCluster& cluster = model.clusters[c];
        for (const auto& t : cluster.triangles) {
            const Vec3 a = at(cluster.vertices[t[0]]);
            Vec3 n = cross(at(cluster.vertices[t[1]]) - a, at(cluster.vertices[t[2]]) - a);
            if (e.flip < 0.0) {
                n = -1.0 * n;  // the file's triangles are reversed
            }
            for (const std::uint32_t i : t) {
                sum[cluster.vertices[i]] = sum[cluster.vertices[i]] + n;
            }
        }
    }
    return sum;
}

/// Everything the file says about the model, checked against it: the DAG, every base primitive
/// and every Draco chunk (decoded here), spheres in the scene frame.
void expect_file_holds_model(const fs::path& path, const Model& m, double flip) {
    const Written w = load(path);
    const Json& json = w.json;
    ASSERT_EQ(json["extensionsRequired"], Json({"KHR_draco_mesh_compression"}));
    ASSERT_EQ(json["extensionsUsed"],
              Json({"KHR_draco_mesh_compression", "STRATA_progressive_mesh"}));
    ASSERT_EQ(json["nodes"][0]["children"].size(), m.result.models.size());
    const MultiresMesh& model = m.result.models[0];
    const Json& node = json["nodes"][json["nodes"][0]["children"][0].get<int>()];
    const Json& ext = node["extensions"]["STRATA_progressive_mesh"];
    ASSERT_EQ(ext["clusters"].size(), model.clusters.size());
    ASSERT_EQ(ext["groups"].size(), model.groups.size());
    EXPECT_EQ(ext["gridStep"].get<double>(), model.grid_step);
    const double m_per_px = m.frame.error_mm_per_px / 1000.0;
    // bounds are written rounded up to 7 significant digits
    const auto expect_written_bound = [](double written, double exact) {
        EXPECT_GE(written, exact);
        EXPECT_LE(written, exact * (1.0 + 1e-6));
    };
    expect_written_bound(ext["fullResolutionError"].get<double>(),
                         model.full_resolution_error_px * m_per_px);
    EXPECT_EQ(node["extras"]["label"], m.result.surfaces[0].label);
    const std::array<double, 16> to_scene = multiply(json["nodes"][0]["matrix"], node["matrix"]);
    // the node matrix has a positive determinant (no mirror)
    const Json& nm = node["matrix"];
    const double det = nm[0].get<double>() * (nm[5].get<double>() * nm[10].get<double>() -
                                              nm[9].get<double>() * nm[6].get<double>()) -
                       nm[4].get<double>() * (nm[1].get<double>() * nm[10].get<double>() -
                                              nm[9].get<double>() * nm[2].get<double>()) +
                       nm[8].get<double>() * (nm[1].get<double>() * nm[6].get<double>() -
                                              nm[5].get<double>() * nm[2].get<double>());
    EXPECT_GT(det, 0.0);

    const Expect e = expectations(model, m.result.slice_spacing_px, flip);
    const bool reverse = flip < 0.0;
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        const Json& group = ext["groups"][g];
        EXPECT_EQ(group["consumed"].get<std::vector<std::uint32_t>>(), model.groups[g].consumed);
        EXPECT_EQ(group["produced"].get<std::vector<std::uint32_t>>(), model.groups[g].produced);
        expect_written_bound(group["error"].get<double>(), model.groups[g].error_px * m_per_px);
    }
    std::size_t draco_chunks = 0;
    double base_volume = 0.0;  // signed volume of the base in the scene frame: > 0 when outward
    for (std::uint32_t c = 0; c < model.clusters.size(); ++c) {
        const MultiresCluster& cluster = model.clusters[c];
        const Json& entry = ext["clusters"][c];
        EXPECT_EQ(entry["level"].get<std::uint32_t>(), cluster.level);
        EXPECT_EQ(entry.value("producer", -1), cluster.producer);
        EXPECT_EQ(entry.value("consumer", -1), cluster.consumer);
        const Json& primitive =
            json["meshes"][entry["mesh"].get<int>()]["primitives"][entry.value("primitive", 0)];
        std::vector<std::array<float, 3>> positions;
        std::vector<std::uint32_t> indices;
        std::vector<std::array<float, 3>> coarse;
        std::vector<std::array<float, 3>> normals;
        if (cluster.consumer < 0) {
            ASSERT_EQ(entry["mesh"], node["mesh"]) << "root cluster " << c << " not in the base";
            ASSERT_FALSE(primitive.contains("extensions"));
            const auto p = accessor_values<float>(w, primitive["attributes"]["POSITION"]);
            for (std::size_t i = 0; i + 2 < p.size(); i += 3) {
                positions.push_back({p[i], p[i + 1], p[i + 2]});
            }
            const Json& ia = json["accessors"][primitive["indices"].get<int>()];
            if (ia["componentType"] == 5123) {
                for (std::uint16_t i : accessor_values<std::uint16_t>(w, primitive["indices"])) {
                    indices.push_back(i);
                }
            } else {
                indices = accessor_values<std::uint32_t>(w, primitive["indices"]);
            }
            const auto n = accessor_values<float>(w, primitive["attributes"]["NORMAL"]);
            for (std::size_t i = 0; i + 2 < n.size(); i += 3) {
                EXPECT_NEAR(std::hypot(n[i], n[i + 1], n[i + 2]), 1.0, 1e-5);
                normals.push_back({n[i], n[i + 1], n[i + 2]});
            }
        } else {
            ++draco_chunks;
            const Json& draco = primitive["extensions"]["KHR_draco_mesh_compression"];
            const std::string bytes = view_bytes(w, draco["bufferView"].get<int>());
            draco::DecoderBuffer in;
            in.Init(bytes.data(), bytes.size());
            draco::Decoder decoder;
            auto decoded = decoder.DecodeMeshFromBuffer(&in);
            ASSERT_TRUE(decoded.ok()) << "cluster " << c;
            const draco::Mesh& mesh = *decoded.value();
            const auto* pa =
                mesh.GetAttributeByUniqueId(draco["attributes"]["POSITION"].get<int>());
            const auto* ca =
                mesh.GetAttributeByUniqueId(draco["attributes"]["_COARSE_POSITION"].get<int>());
            const auto* na = mesh.GetAttributeByUniqueId(draco["attributes"]["NORMAL"].get<int>());
            ASSERT_TRUE(pa != nullptr && ca != nullptr && na != nullptr);
            const Json& pos_accessor =
                json["accessors"][primitive["attributes"]["POSITION"].get<int>()];
            EXPECT_EQ(pos_accessor["count"].get<std::uint32_t>(), mesh.num_points());
            EXPECT_FALSE(pos_accessor.contains("bufferView"));
            EXPECT_EQ(json["accessors"][primitive["indices"].get<int>()]["count"],
                      3 * mesh.num_faces());
            for (std::uint32_t i = 0; i < mesh.num_points(); ++i) {
                std::array<float, 3> p{}, q{};
                pa->ConvertValue<float, 3>(pa->mapped_index(draco::PointIndex(i)), p.data());
                ca->ConvertValue<float, 3>(ca->mapped_index(draco::PointIndex(i)), q.data());
                std::array<float, 3> n{};
                na->ConvertValue<float, 3>(na->mapped_index(draco::PointIndex(i)), n.data());
                normals.push_back(n);
                positions.push_back(p);
                coarse.push_back(q);
            }
            for (draco::FaceIndex f(0); f < mesh.num_faces(); ++f) {
                for (int k = 0; k < 3; ++k) {
                    indices.push_back(mesh.face(f)[k].value());
                }
            }
        }
        // positions exactly on the model's vertices; triangles equal, same orientation
        std::vector<std::uint32_t> global;
        for (std::size_t i = 0; i < positions.size(); ++i) {
            const auto it = e.vertex_at.find(positions[i]);
            ASSERT_NE(it, e.vertex_at.end()) << "cluster " << c << " point " << i << " off grid";
            global.push_back(it->second);
            ASSERT_TRUE(inside(entry["sphere"], transform_point(to_scene, positions[i])))
                << "cluster " << c << " point " << i << " outside its sphere";
            if (cluster.producer >= 0) {
                ASSERT_TRUE(inside(ext["groups"][cluster.producer]["sphere"],
                                   transform_point(to_scene, positions[i])));
            }
        }
        // NORMAL: the vertex normal of the cluster's level cut (10-bit octahedral in the chunks)
        ASSERT_EQ(normals.size(), positions.size());
        const std::vector<Vec3> sums = level_normal_sums(e, cluster.level);
        for (std::size_t i = 0; i < normals.size(); ++i) {
            const Vec3 expected = sums[global[i]];
            const Vec3 got{normals[i][0], normals[i][1], normals[i][2]};
            const double cosine = dot(expected, got) / (norm(expected) * norm(got));
            EXPECT_GT(cosine, std::cos(0.5 * std::numbers::pi / 180.0))
                << "cluster " << c << " point " << i << ": NORMAL off the level-" << cluster.level
                << " surface normal";
        }
        if (!coarse.empty()) {
            for (std::size_t i = 0; i < coarse.size(); ++i) {
                const auto at =
                    std::find(cluster.vertices.begin(), cluster.vertices.end(), global[i]);
                ASSERT_NE(at, cluster.vertices.end());
                const std::uint32_t target = cluster.coarse_vertices[at - cluster.vertices.begin()];
                EXPECT_EQ(coarse[i], e.storage[target]) << "cluster " << c << " point " << i;
            }
        }
        std::vector<Tri> got;
        for (std::size_t i = 0; i + 2 < indices.size(); i += 3) {
            got.push_back(
                canonical({global[indices[i]], global[indices[i + 1]], global[indices[i + 2]]}));
        }
        std::sort(got.begin(), got.end());
        EXPECT_EQ(got, cluster_triangles(model, c, reverse)) << "cluster " << c;
        if (cluster.consumer < 0) {
            for (std::size_t i = 0; i + 2 < indices.size(); i += 3) {
                const Vec3 a = transform_point(to_scene, positions[indices[i]]);
                const Vec3 b = transform_point(to_scene, positions[indices[i + 1]]);
                const Vec3 c3 = transform_point(to_scene, positions[indices[i + 2]]);
                base_volume += dot(a, cross(b, c3)) / 6.0;
            }
        }
    }
    EXPECT_GT(draco_chunks, 0u);
    EXPECT_GT(base_volume, 0.0) << "the base faces inwards in the scene frame";
}

TEST(ProgressiveGltf, GlbHoldsTheModelExactly) {
    const Model& m = torus();
    ASSERT_GT(m.result.models.at(0).grid_step, 0.0);
    ASSERT_GT(m.result.models[0].groups.size(), 2u);
    const fs::path dir = test::fresh_temp_dir("progressive_glb");
    const ProgressiveStats stats =
        write_progressive_gltf(dir / "torus.glb", objects_of(m), m.frame, info());
    EXPECT_EQ(stats.total_bytes, fs::file_size(dir / "torus.glb"));
    EXPECT_GT(stats.chunks, 0u);
    EXPECT_LT(stats.base_bytes, stats.total_bytes);
    expect_file_holds_model(dir / "torus.glb", m, 1.0);
    // The base meshes' data is one range at the start of the BIN chunk (one request for a first
    // frame); the chunks follow, coarsest level first.
    const Written w = load(dir / "torus.glb");
    std::set<int> chunk_views;
    std::vector<std::pair<std::size_t, std::uint32_t>> chunk_offsets;  // offset, level
    const Json& ext = w.json["nodes"][1]["extensions"]["STRATA_progressive_mesh"];
    for (const Json& cluster : ext["clusters"]) {
        const Json& p = w.json["meshes"][cluster["mesh"].get<int>()]["primitives"][0];
        if (p.contains("extensions")) {
            const int view = p["extensions"]["KHR_draco_mesh_compression"]["bufferView"];
            chunk_views.insert(view);
            chunk_offsets.emplace_back(w.json["bufferViews"][view]["byteOffset"].get<std::size_t>(),
                                       cluster["level"].get<std::uint32_t>());
        }
    }
    std::size_t base_end = 0, first_chunk = std::numeric_limits<std::size_t>::max();
    for (std::size_t v = 0; v < w.json["bufferViews"].size(); ++v) {
        const Json& view = w.json["bufferViews"][v];
        const std::size_t offset = view.value("byteOffset", std::size_t{0});
        if (chunk_views.count(static_cast<int>(v)) != 0) {
            first_chunk = std::min(first_chunk, offset);
        } else {
            base_end = std::max(base_end, offset + view["byteLength"].get<std::size_t>());
        }
    }
    EXPECT_LE(base_end, first_chunk) << "base data interleaved with chunks";
    std::sort(chunk_offsets.begin(), chunk_offsets.end());
    for (std::size_t i = 1; i < chunk_offsets.size(); ++i) {
        EXPECT_GE(chunk_offsets[i - 1].second, chunk_offsets[i].second) << "finer level first";
    }
}

TEST(ProgressiveGltf, GltfKeepsChunksInOneBufferFilePerLevel) {
    const Model& m = torus();
    const fs::path dir = test::fresh_temp_dir("progressive_gltf");
    write_progressive_gltf(dir / "torus.gltf", objects_of(m), m.frame, info());
    const Written w = load(dir / "torus.gltf");
    EXPECT_EQ(w.json["buffers"][0]["uri"], "torus.bin");
    const std::uint32_t levels = level_count(m.result.models[0]);
    // one buffer per level that has non-root clusters (every level below the top one)
    EXPECT_EQ(w.json["buffers"].size(), 1u + (levels - 1));
    for (std::uint32_t l = 0; l + 1 < levels; ++l) {
        EXPECT_TRUE(fs::exists(dir / ("torus.level" + std::to_string(l) + ".bin"))) << l;
    }
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
}

}  // namespace
}  // namespace strata

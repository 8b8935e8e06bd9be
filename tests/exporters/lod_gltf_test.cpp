#include "exporters/lod_gltf.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <draco/compression/decode.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "exporters/detail/meshopt_scene.h"
#include "exporters/detail/meshopt_streams.h"
#include "mesh/mesh_checks.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/cut_checks.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

struct Model {
    Reconstruction result;
    SliceFrame frame;
};

/// The torus with a frame like a CT's (0.7 mm pixels, slices 2.5 mm apart, shifted origin),
/// mirrored when `mirror` (x flipped, as a RAS volume read into LPS).
Model torus(bool mirror) {
    Model m;
    const Phantom phantom = make_phantom("torus");
    ReconstructOptions options;
    options.multires.cluster_triangles = 256;
    Report report;
    m.result = reconstruct(phantom.stack, options, report);
    const double d = m.result.slice_spacing_px;
    m.frame.linear = {mirror ? -0.7 : 0.7, 0, 0, 0, 0.7, 0, 0, 0, 0.7};
    m.frame.origin = {-120.5, 33.25, 410.0};
    m.frame.slice_spacing_px = d;
    m.frame.error_mm_per_px = 0.7;
    return m;
}

const Model& plain_torus() {
    static const Model m = torus(false);
    return m;
}

std::vector<LodObject> objects_of(const Model& m) {
    std::vector<LodObject> objects;
    for (std::size_t i = 0; i < m.result.models.size(); ++i) {
        objects.push_back(
            {"torus", m.result.surfaces[i].label, {0.8, 0.5, 0.25}, &m.result.models[i]});
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

struct Glb {
    Json json;
    std::string bin;
};

Glb read_glb(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto u32 = [&](std::size_t at) {
        std::uint32_t v = 0;
        std::memcpy(&v, bytes.data() + at, 4);
        return v;
    };
    Glb g;
    EXPECT_EQ(u32(0), 0x46546C67u);
    EXPECT_EQ(u32(8), bytes.size());
    const std::uint32_t json_length = u32(12);
    g.json = Json::parse(bytes.substr(20, json_length));
    const std::size_t bin_at = 20 + json_length;
    if (bin_at + 8 <= bytes.size()) {
        g.bin = bytes.substr(bin_at + 8, u32(bin_at));
    }
    return g;
}

/// Slice space of a point stored in a node with column-major `matrix` (stored -> LPS mm): the
/// inverse of the frame's linear map applied to LPS - origin, snapped to the model's grid (x, y
/// multiples of the step, z of step * d) after checking it lies within 1e-6 px of it.
Vec3 to_slice_space(const Json& matrix,
                    const std::array<double, 3>& stored,
                    const Model& m,
                    double step) {
    Vec3 lps;
    for (int r = 0; r < 3; ++r) {
        lps[r] = matrix[12 + r].get<double>();
        for (int c = 0; c < 3; ++c) {
            lps[r] += matrix[4 * c + r].get<double>() * stored[c];
        }
    }
    const auto& l = m.frame.linear;  // diagonal in these tests
    Vec3 p{(lps.x - m.frame.origin[0]) / l[0], (lps.y - m.frame.origin[1]) / l[4],
           (lps.z - m.frame.origin[2]) / l[8]};
    const double d = m.frame.slice_spacing_px;
    const Vec3 snapped{std::nearbyint(p.x / step) * step, std::nearbyint(p.y / step) * step,
                       std::nearbyint(p.z / (d * step)) * d * step};
    EXPECT_LT(norm(snapped - p), 1e-6) << "a decoded position is off the model's grid";
    return snapped;
}

const Json* accessor(const Glb& g, int index) {
    return &g.json["accessors"][index];
}

/// The mesh of one level node, decoded here (Draco's decoder, or the meshopt decoders with the
/// accessors' component types), in slice space.
TriMesh decode_level(const Glb& g, const Json& node, const Model& m, double step) {
    const Json& primitive = g.json["meshes"][node["mesh"].get<int>()]["primitives"][0];
    std::vector<std::array<double, 3>> stored;
    std::vector<std::array<std::uint32_t, 3>> triangles;
    if (primitive.contains("extensions") &&
        primitive["extensions"].contains("KHR_draco_mesh_compression")) {
        const Json& ext = primitive["extensions"]["KHR_draco_mesh_compression"];
        const Json& view = g.json["bufferViews"][ext["bufferView"].get<int>()];
        draco::DecoderBuffer in;
        in.Init(g.bin.data() + view["byteOffset"].get<std::size_t>(),
                view["byteLength"].get<std::size_t>());
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&in);
        EXPECT_TRUE(decoded.ok());
        if (!decoded.ok()) {
            return {};
        }
        const auto mesh = std::move(decoded).value();
        const auto* pos = mesh->GetAttributeByUniqueId(ext["attributes"]["POSITION"].get<int>());
        EXPECT_NE(pos, nullptr);
        EXPECT_EQ((*accessor(g, primitive["attributes"]["POSITION"].get<int>()))["count"],
                  mesh->num_points());
        for (std::uint32_t i = 0; i < mesh->num_points(); ++i) {
            std::array<float, 3> p{};
            pos->ConvertValue<float, 3>(pos->mapped_index(draco::PointIndex(i)), p.data());
            stored.push_back({p[0], p[1], p[2]});
        }
        for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
            triangles.push_back(
                {mesh->face(f)[0].value(), mesh->face(f)[1].value(), mesh->face(f)[2].value()});
        }
    } else {
        const Json& pa = *accessor(g, primitive["attributes"]["POSITION"].get<int>());
        const Json& ia = *accessor(g, primitive["indices"].get<int>());
        const auto stream = [&](const Json& a) {
            const Json& ext = g.json["bufferViews"][a["bufferView"].get<int>()]["extensions"]
                                    ["EXT_meshopt_compression"];
            return std::pair{g.bin.substr(ext["byteOffset"].get<std::size_t>(),
                                          ext["byteLength"].get<std::size_t>()),
                             ext};
        };
        const auto [pbytes, pext] = stream(pa);
        const auto raw = detail::decode_meshopt_vertices(pbytes, pext["count"].get<std::uint32_t>(),
                                                         pext["byteStride"].get<std::uint32_t>());
        const std::uint32_t stride = pext["byteStride"].get<std::uint32_t>();
        for (std::uint32_t i = 0; i < pa["count"].get<std::uint32_t>(); ++i) {
            std::array<double, 3> p{};
            for (int k = 0; k < 3; ++k) {
                if (pa["componentType"] == 5123) {
                    std::uint16_t q = 0;
                    std::memcpy(&q, &raw[i * stride + 2 * k], 2);
                    p[k] = q;
                } else {
                    float f = 0;
                    std::memcpy(&f, &raw[i * stride + 4 * k], 4);
                    p[k] = f;
                }
            }
            stored.push_back(p);
        }
        const auto [ibytes, iext] = stream(ia);
        const auto indices =
            detail::decode_meshopt_indices(ibytes, ia["count"].get<std::uint32_t>());
        for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
            triangles.push_back({indices[t], indices[t + 1], indices[t + 2]});
        }
    }
    TriMesh mesh;
    for (const auto& p : stored) {
        mesh.positions.push_back(to_slice_space(node["matrix"], p, m, step));
    }
    mesh.triangles = triangles;
    if (m.frame.linear[0] < 0.0) {
        // the stored frame keeps the node matrix a rotation: in slice space orientation flips
        for (auto& t : mesh.triangles) {
            std::swap(t[1], t[2]);
        }
    }
    return mesh;
}

/// Every level of every object in `path`: names, MSFT_lod, coarse-first buffer, extras, screen
/// coverage (recomputed here from the decoded finest level), and the exact mesh checks and the
/// oracle's error bound on each decoded level. Returns the levels' error bounds (mm).
std::vector<double> expect_lod_file(const fs::path& path,
                                    const Model& m,
                                    const std::vector<double>& requested_mm) {
    const Glb g = read_glb(path);
    const Json& json = g.json;
    const auto& models = m.result.models;
    EXPECT_EQ(json["nodes"][0]["name"], "patient");
    EXPECT_EQ(json["nodes"][0]["children"].size(), models.size());
    std::vector<double> errors;
    for (std::size_t o = 0; o < models.size(); ++o) {
        const Json& lod0 = json["nodes"][json["nodes"][0]["children"][o].get<int>()];
        std::vector<const Json*> nodes{&lod0};
        if (lod0.contains("extensions")) {
            for (const Json& id : lod0["extensions"]["MSFT_lod"]["ids"]) {
                nodes.push_back(&json["nodes"][id.get<int>()]);
            }
        }
        const std::size_t n = nodes.size();
        EXPECT_GE(n, 2u);
        const std::vector<int> genera = test::sorted_genera(check_mesh(m.result.surfaces[o].mesh));
        const Json& coverage = lod0["extras"]["MSFT_screencoverage"];
        EXPECT_EQ(coverage.size(), n);
        if (coverage.size() != n) {
            return errors;
        }
        double radius_mm = 0.0;
        std::size_t previous_offset = std::numeric_limits<std::size_t>::max();
        for (std::size_t i = 0; i < n; ++i) {
            const Json& node = *nodes[i];
            EXPECT_EQ(node["name"], "torus_LOD" + std::to_string(i));
            const double error_mm = node["extras"]["error_mm"].get<double>();
            EXPECT_EQ(node["extras"]["lod"], i);
            if (i > 0) {
                EXPECT_GT(error_mm, errors.back()) << "levels must coarsen";
            }
            // Requested bounds are met (the finest may be the full resolution, above the request).
            if (!requested_mm.empty() && i > 0) {
                EXPECT_LE(error_mm, requested_mm.back() + 1e-9);
            }
            errors.push_back(error_mm);
            const TriMesh mesh = decode_level(g, node, m, models[o].grid_step);
            EXPECT_EQ(mesh.triangles.size(), node["extras"]["triangles"].get<std::size_t>());
            SCOPED_TRACE(node["name"].get<std::string>());
            test::expect_valid_cut(mesh, m.result, o, genera, error_mm / m.frame.error_mm_per_px);

            // Buffer: finer levels lie after coarser ones.
            const Json& primitive = json["meshes"][node["mesh"].get<int>()]["primitives"][0];
            std::size_t offset = 0;
            if (primitive.contains("extensions")) {
                offset = json["bufferViews"]
                             [primitive["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
                                  .get<int>()]["byteOffset"];
            } else {
                const int view =
                    (*accessor(g, primitive["attributes"]["POSITION"].get<int>()))["bufferView"];
                offset = json["bufferViews"][view]["extensions"]["EXT_meshopt_compression"]
                             ["byteOffset"];
            }
            if (i > 0) {
                EXPECT_LT(offset, previous_offset) << "a coarser level lies after a finer one";
            }
            previous_offset = offset;

            if (i == 0) {
                // The bounding sphere of the finest level in LPS mm (box half-diagonal).
                Vec3 lo{1e300, 1e300, 1e300};
                Vec3 hi = -1.0 * lo;
                for (const Vec3& p : mesh.positions) {
                    const auto& l = m.frame.linear;
                    const Vec3 w{m.frame.origin[0] + l[0] * p.x, m.frame.origin[1] + l[4] * p.y,
                                 m.frame.origin[2] + l[8] * p.z};
                    for (int k = 0; k < 3; ++k) {
                        lo[k] = std::min(lo[k], w[k]);
                        hi[k] = std::max(hi[k], w[k]);
                    }
                }
                radius_mm = 0.5 * norm(hi - lo);
            }
        }
        // Coverage: level i + 1's bound projects to 1 px (of 1080, 16:9) when the sphere's
        // projected radius is r / e_{i+1} px; the area ratio at that size, 0 for the coarsest.
        for (std::size_t i = 0; i + 1 < n; ++i) {
            const double e = errors[errors.size() - n + i + 1];
            const double expected =
                std::numbers::pi * std::pow(radius_mm / e / 1080.0, 2) / (16.0 / 9.0);
            EXPECT_NEAR(coverage[i].get<double>(), expected, 1e-6 * expected);
            EXPECT_LE(coverage[i].get<double>(), expected * (1 + 1e-12));
            if (i > 0) {
                EXPECT_LT(coverage[i].get<double>(), coverage[i - 1].get<double>());
            }
        }
        EXPECT_EQ(coverage[n - 1].get<double>(), 0.0);
    }
    return errors;
}

fs::path temp_dir(const std::string& name) {
    return test::fresh_temp_dir(name);
}

TEST(LodGltf, DracoLevelsAreValidCutsWithinTheirBounds) {
    const Model& m = plain_torus();
    const fs::path dir = temp_dir("lod_gltf_draco");
    LodOptions options;
    options.error_mm = {0.5, 2.0, 5.0};
    const LodStats stats =
        write_lod_gltf(dir / "lods.glb", objects_of(m), m.frame, info(), options);
    EXPECT_EQ(stats.total_bytes, fs::file_size(dir / "lods.glb"));
    const Glb g = read_glb(dir / "lods.glb");
    EXPECT_EQ(g.json["extensionsRequired"], Json({"KHR_draco_mesh_compression"}));
    const std::vector<double> errors = expect_lod_file(dir / "lods.glb", m, options.error_mm);
    ASSERT_EQ(errors.size(), stats.objects[0].size());
    EXPECT_GT(stats.objects[0].front().triangles, 4 * stats.objects[0].back().triangles);
}

TEST(LodGltf, MeshoptLevelsAreTheSameCuts) {
    const Model& m = plain_torus();
    const fs::path dir = temp_dir("lod_gltf_meshopt");
    LodOptions options;
    options.error_mm = {0.5, 2.0, 5.0};
    write_lod_gltf(dir / "draco.glb", objects_of(m), m.frame, info(), options);
    options.compression = LodCompression::Meshopt;
    write_lod_gltf(dir / "meshopt.glb", objects_of(m), m.frame, info(), options);
    const Glb g = read_glb(dir / "meshopt.glb");
    EXPECT_EQ(g.json["extensionsRequired"],
              Json({"EXT_meshopt_compression", "KHR_mesh_quantization"}));
    EXPECT_EQ(expect_lod_file(dir / "meshopt.glb", m, options.error_mm),
              expect_lod_file(dir / "draco.glb", m, options.error_mm));
}

TEST(LodGltf, CountSpreadsOverTheModelLevels) {
    const Model& m = plain_torus();
    const fs::path dir = temp_dir("lod_gltf_count");
    LodOptions options;
    options.level_count = 4;
    write_lod_gltf(dir / "lods.glb", objects_of(m), m.frame, info(), options);
    const std::vector<double> errors = expect_lod_file(dir / "lods.glb", m, {});
    EXPECT_EQ(errors.size(), 4u);
    // The coarsest is the model's root level, the finest its full resolution.
    const MultiresMesh& model = m.result.models[0];
    EXPECT_NEAR(errors.front(), model.full_resolution_error_px * 0.7, 1e-5);
    EXPECT_NEAR(errors.back(), select_cut_at_level(model, level_count(model) - 1).error_px * 0.7,
                1e-5);
}

TEST(LodGltf, MirroredFramesKeepLevelsOutward) {
    const Model m = torus(true);
    const fs::path dir = temp_dir("lod_gltf_mirror");
    LodOptions options;
    options.error_mm = {0.5, 3.0};
    for (const LodCompression c : {LodCompression::Draco, LodCompression::Meshopt}) {
        options.compression = c;
        write_lod_gltf(dir / "lods.glb", objects_of(m), m.frame, info(), options);
        expect_lod_file(dir / "lods.glb", m, options.error_mm);  // positive volumes checked there
    }
}

TEST(LodGltf, RejectsBadInputAndKeepsOldFiles) {
    const Model& m = plain_torus();
    const fs::path dir = temp_dir("lod_gltf_bad");
    const fs::path file = dir / "lods.glb";
    write_lod_gltf(file, objects_of(m), m.frame, info());
    const auto size = fs::file_size(file);
    const auto expect_code = [&](ErrorCode code, const fs::path& path,
                                 const std::vector<LodObject>& objects, const LodOptions& o) {
        try {
            write_lod_gltf(path, objects, m.frame, info(), o);
            ADD_FAILURE() << "no error";
        } catch (const Error& e) {
            EXPECT_EQ(e.code(), code) << e.what();
        }
    };
    LodOptions decreasing;
    decreasing.error_mm = {2.0, 1.0};
    expect_code(ErrorCode::InvalidInput, file, objects_of(m), decreasing);
    LodOptions negative;
    negative.error_mm = {-1.0};
    expect_code(ErrorCode::InvalidInput, file, objects_of(m), negative);
    LodOptions none;
    none.level_count = 0;
    expect_code(ErrorCode::InvalidInput, file, objects_of(m), none);
    expect_code(ErrorCode::Unsupported, dir / "lods.gltf", objects_of(m), {});
    expect_code(ErrorCode::InvalidInput, file, {}, {});
    std::vector<LodObject> bad_colour = objects_of(m);
    bad_colour[0].srgb[1] = 1.5;
    expect_code(ErrorCode::InvalidInput, file, bad_colour, {});
    MultiresMesh unsnapped = m.result.models[0];
    unsnapped.grid_step = 0.0;
    std::vector<LodObject> off_grid = objects_of(m);
    off_grid[0].model = &unsnapped;
    expect_code(ErrorCode::InvalidInput, file, off_grid, {});
    EXPECT_EQ(fs::file_size(file), size);
    EXPECT_FALSE(fs::exists(dir / "lods.gltf"));
}

/// The single-rate scene with meshopt (scene_gltf's meshopt option): every object's triangles,
/// decoded here, are the input's with each position on the node's 16-bit grid (within half a
/// step per axis), and the decoded mesh is closed with the input's genera.
TEST(MeshoptScene, HoldsEveryTriangleOnItsGrid) {
    const Model& m = plain_torus();
    SceneObject object;
    object.name = "torus";
    object.label = 1;
    object.srgb = {0.8, 0.5, 0.25};
    object.mesh = m.result.surfaces[0].mesh;
    for (Vec3& p : object.mesh.positions) {
        p = Vec3{0.7 * p.x - 120.5, 0.7 * p.y + 33.25, 0.7 * p.z + 410.0};  // like LPS mm
    }
    const fs::path dir = temp_dir("meshopt_scene");
    detail::write_meshopt_scene(dir / "scene.glb", {object}, info());
    const Glb g = read_glb(dir / "scene.glb");
    EXPECT_EQ(g.json["extensionsRequired"],
              Json({"EXT_meshopt_compression", "KHR_mesh_quantization"}));
    const Json& node = g.json["nodes"][1];
    EXPECT_EQ(node["name"], "torus");
    const double step = node["extras"]["quantization_step_mm"].get<double>();
    const Json& matrix = node["matrix"];
    EXPECT_EQ(matrix[0].get<double>(), step);
    const std::array<double, 3> origin{matrix[12].get<double>(), matrix[13].get<double>(),
                                       matrix[14].get<double>()};
    // The input quantized here, independently of the writer: the nearest step, ties to even as
    // the writer states (balanced contour vertices put torus coordinates exactly half-way,
    // 45874.5 steps, where std::lround's ties away from zero picks the other neighbour).
    using Q = std::array<long, 3>;
    std::vector<Q> expected_q;
    for (const Vec3& p : object.mesh.positions) {
        Q q{};
        for (int k = 0; k < 3; ++k) {
            q[k] = static_cast<long>(std::nearbyint((p[k] - origin[k]) / step));
            EXPECT_LE(std::abs(q[k] * step + origin[k] - p[k]), 0.5 * step * (1 + 1e-9));
        }
        expected_q.push_back(q);
    }
    // Decoded through the meshopt decoders.
    const Json& primitive = g.json["meshes"][0]["primitives"][0];
    const Json& pa = g.json["accessors"][primitive["attributes"]["POSITION"].get<int>()];
    const Json& ia = g.json["accessors"][primitive["indices"].get<int>()];
    const auto ext = [&](const Json& a) {
        return g.json["bufferViews"][a["bufferView"].get<int>()]["extensions"]
                     ["EXT_meshopt_compression"];
    };
    const Json pe = ext(pa);
    const Json ie = ext(ia);
    EXPECT_EQ(pa["componentType"], 5123);
    const auto raw = detail::decode_meshopt_vertices(
        g.bin.substr(pe["byteOffset"].get<std::size_t>(), pe["byteLength"].get<std::size_t>()),
        pe["count"].get<std::uint32_t>(), pe["byteStride"].get<std::uint32_t>());
    std::vector<Q> decoded_q;
    TriMesh decoded;
    for (std::uint32_t i = 0; i < pe["count"].get<std::uint32_t>(); ++i) {
        std::array<std::uint16_t, 3> q{};
        std::memcpy(q.data(), &raw[8 * std::size_t(i)], 6);
        decoded_q.push_back({q[0], q[1], q[2]});
        decoded.positions.push_back(Vec3{double(q[0]), double(q[1]), double(q[2])});
    }
    const auto indices = detail::decode_meshopt_indices(
        g.bin.substr(ie["byteOffset"].get<std::size_t>(), ie["byteLength"].get<std::size_t>()),
        ia["count"].get<std::uint32_t>());
    for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
        decoded.triangles.push_back({indices[t], indices[t + 1], indices[t + 2]});
    }
    const auto canonical = [](const std::vector<Q>& q, const auto& triangles) {
        std::vector<std::array<Q, 3>> out;
        for (const auto& t : triangles) {
            std::array<Q, 3> c{q[t[0]], q[t[1]], q[t[2]]};
            std::rotate(c.begin(), std::min_element(c.begin(), c.end()), c.end());
            out.push_back(c);
        }
        std::sort(out.begin(), out.end());
        return out;
    };
    EXPECT_EQ(canonical(decoded_q, decoded.triangles),
              canonical(expected_q, object.mesh.triangles));
    const MeshReport report = check_mesh(decoded);
    EXPECT_TRUE(is_closed_manifold(report));
    EXPECT_EQ(test::sorted_genera(report), test::sorted_genera(check_mesh(object.mesh)));
    EXPECT_THROW(detail::write_meshopt_scene(dir / "scene.gltf", {object}, info()), Error);
}

/// Files for the Khronos validator and the clients (CTest gltf_validator_lods) when
/// STRATA_GLTF_SAMPLE_DIR is set.
TEST(LodGltfSamples, WritesValidatorSamples) {
    const char* dir = std::getenv("STRATA_GLTF_SAMPLE_DIR");
    if (dir == nullptr) {
        GTEST_SKIP() << "STRATA_GLTF_SAMPLE_DIR not set";
    }
    const Model& m = plain_torus();
    LodOptions options;
    options.error_mm = {0.5, 2.0, 5.0};
    write_lod_gltf(fs::path(dir) / "lods.glb", objects_of(m), m.frame, info(), options);
    options.compression = LodCompression::Meshopt;
    write_lod_gltf(fs::path(dir) / "lods_meshopt.glb", objects_of(m), m.frame, info(), options);
    SceneObject object;
    object.name = "torus";
    object.label = 1;
    object.srgb = {0.8, 0.5, 0.25};
    object.mesh = m.result.surfaces[0].mesh;
    detail::write_meshopt_scene(fs::path(dir) / "scene_meshopt.glb", {object}, info());
}

}  // namespace
}  // namespace strata

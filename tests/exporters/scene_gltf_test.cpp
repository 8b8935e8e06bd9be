#include "exporters/scene_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>
#include <vector>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "core/error.h"
#include "mesh/mesh_checks.h"
#include "mesh/shading_normals.h"
#include "support/mesh_shapes.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

// note: one coordinate per call: GCC 12.2 at -O2 may drop the float rounding of adjacent
// double -> float -> double conversions (see mesh_io_test.cpp).
[[gnu::noinline]] double rounded_to_float(double x) {
    return static_cast<float>(x);
}

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::string> folder_entries(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
        names.push_back(entry.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    return names;
}

/// Latitude-longitude sphere around `center`, outward-facing, with a vertex at each pole.
TriMesh uv_sphere(int rings, int segments, double radius, Vec3 center) {
    TriMesh mesh;
    mesh.positions.push_back(center + Vec3{0, 0, -radius});
    for (int r = 1; r < rings; ++r) {
        const double theta = std::numbers::pi * r / rings;  // from the south pole
        for (int s = 0; s < segments; ++s) {
            const double phi = 2.0 * std::numbers::pi * s / segments;
            mesh.positions.push_back(center + radius * Vec3{std::sin(theta) * std::cos(phi),
                                                            std::sin(theta) * std::sin(phi),
                                                            -std::cos(theta)});
        }
    }
    mesh.positions.push_back(center + Vec3{0, 0, radius});
    const auto south = 0u;
    const auto north = static_cast<std::uint32_t>(mesh.positions.size() - 1);
    auto id = [&](int r, int s) {
        return static_cast<std::uint32_t>(1 + (r - 1) * segments + (s % segments));
    };
    for (int s = 0; s < segments; ++s) {
        mesh.triangles.push_back({south, id(1, s + 1), id(1, s)});
        mesh.triangles.push_back({north, id(rings - 1, s), id(rings - 1, s + 1)});
    }
    for (int r = 1; r + 1 < rings; ++r) {
        for (int s = 0; s < segments; ++s) {
            test::add_quad(mesh, id(r, s), id(r, s + 1), id(r + 1, s + 1), id(r + 1, s));
        }
    }
    return mesh;
}

/// Two objects in patient LPS millimetres whose coordinates are not floats (sin/cos values).
std::vector<SceneObject> two_objects() {
    SceneObject liver;
    liver.name = "liver";
    liver.label = 5;
    liver.srgb = {0.5, 0.25, 1.0};
    liver.mesh = uv_sphere(9, 16, 31.7, {-12.3, 40.1, -300.7});
    SceneObject vessel;
    vessel.name = "portal vein";
    vessel.label = 7;
    vessel.srgb = {0.0, 0.04, 0.8};
    vessel.mesh = test::translated(test::torus(12, 8, 20.3, 4.1), {5.5, -7.25, -280.125});
    return {liver, vessel};
}

SceneInfo sample_info() {
    return {"phantom:scene", {0.7, 0.7, 5.0}, "strata 0.1.0"};
}

tinygltf::Model load(const fs::path& path) {
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string err;
    std::string warn;
    const bool ok = path.extension() == ".glb"
                        ? loader.LoadBinaryFromFile(&model, &err, &warn, path.string())
                        : loader.LoadASCIIFromFile(&model, &err, &warn, path.string());
    EXPECT_TRUE(ok) << path << ": " << err;
    EXPECT_EQ(warn, "") << path;
    return model;
}

/// The elements of accessor `index`, tightly packed or strided.
template <class T>
std::vector<T> read_accessor(const tinygltf::Model& model, int index) {
    const tinygltf::Accessor& accessor = model.accessors.at(index);
    const tinygltf::BufferView& view = model.bufferViews.at(accessor.bufferView);
    const tinygltf::Buffer& buffer = model.buffers.at(view.buffer);
    const std::size_t components = tinygltf::GetNumComponentsInType(accessor.type);
    const std::size_t element = components * sizeof(T);
    const std::size_t stride = view.byteStride == 0 ? element : view.byteStride;
    EXPECT_LE(accessor.byteOffset + (accessor.count - 1) * stride + element, view.byteLength);
    EXPECT_LE(view.byteOffset + view.byteLength, buffer.data.size());
    std::vector<T> out(accessor.count * components);
    for (std::size_t i = 0; i < accessor.count; ++i) {
        std::memcpy(&out[i * components],
                    buffer.data.data() + view.byteOffset + accessor.byteOffset + i * stride,
                    element);
    }
    return out;
}

std::vector<std::uint32_t> read_indices(const tinygltf::Model& model, int index) {
    const int type = model.accessors.at(index).componentType;
    if (type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) {
        const auto shorts = read_accessor<std::uint16_t>(model, index);
        return {shorts.begin(), shorts.end()};
    }
    EXPECT_EQ(type, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    return read_accessor<std::uint32_t>(model, index);
}

const tinygltf::Primitive& only_primitive(const tinygltf::Model& model, int node) {
    const tinygltf::Mesh& mesh = model.meshes.at(model.nodes.at(node).mesh);
    EXPECT_EQ(mesh.primitives.size(), 1u);
    return mesh.primitives.at(0);
}

/// Checks structure, names, positions (exactly the float of the double), bounds and indices.
void expect_scene_matches(const tinygltf::Model& model, const std::vector<SceneObject>& objects) {
    ASSERT_EQ(model.scenes.size(), 1u);
    EXPECT_EQ(model.defaultScene, 0);
    ASSERT_EQ(model.scenes[0].nodes.size(), 1u);
    const tinygltf::Node& root = model.nodes.at(model.scenes[0].nodes[0]);
    EXPECT_EQ(root.name, "patient");
    EXPECT_EQ(root.mesh, -1);
    ASSERT_EQ(root.children.size(), objects.size());
    EXPECT_EQ(model.nodes.size(), objects.size() + 1);
    EXPECT_EQ(model.meshes.size(), objects.size());
    EXPECT_EQ(model.materials.size(), objects.size());
    EXPECT_EQ(model.buffers.size(), 1u);
    EXPECT_EQ(model.asset.version, "2.0");
    EXPECT_EQ(model.asset.generator, "strata 0.1.0");

    for (std::size_t i = 0; i < objects.size(); ++i) {
        SCOPED_TRACE(objects[i].name);
        const TriMesh& mesh = objects[i].mesh;
        const int node_index = root.children[i];
        const tinygltf::Node& node = model.nodes.at(node_index);
        EXPECT_EQ(node.name, objects[i].name);
        EXPECT_EQ(model.meshes.at(node.mesh).name, objects[i].name);
        EXPECT_TRUE(node.matrix.empty() && node.rotation.empty() && node.scale.empty() &&
                    node.translation.empty())
            << "object nodes carry no transform of their own";
        const tinygltf::Primitive& primitive = only_primitive(model, node_index);
        EXPECT_EQ(primitive.mode, TINYGLTF_MODE_TRIANGLES);
        EXPECT_EQ(model.materials.at(primitive.material).name, objects[i].name);

        const tinygltf::Accessor& pos_accessor =
            model.accessors.at(primitive.attributes.at("POSITION"));
        EXPECT_EQ(pos_accessor.componentType, TINYGLTF_COMPONENT_TYPE_FLOAT);
        EXPECT_EQ(pos_accessor.type, TINYGLTF_TYPE_VEC3);
        const auto positions = read_accessor<float>(model, primitive.attributes.at("POSITION"));
        ASSERT_EQ(positions.size(), 3 * mesh.positions.size());
        std::vector<double> min(3, 1e300);
        std::vector<double> max(3, -1e300);
        for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
            for (int k = 0; k < 3; ++k) {
                const double expected = rounded_to_float(mesh.positions[v][k]);
                ASSERT_EQ(static_cast<double>(positions[3 * v + k]), expected)
                    << "vertex " << v << " coordinate " << k;
                min[k] = std::min(min[k], expected);
                max[k] = std::max(max[k], expected);
            }
        }
        EXPECT_EQ(pos_accessor.minValues, min);
        EXPECT_EQ(pos_accessor.maxValues, max);

        const auto indices = read_indices(model, primitive.indices);
        ASSERT_EQ(indices.size(), 3 * mesh.triangles.size());
        for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
            for (int k = 0; k < 3; ++k) {
                ASSERT_EQ(indices[3 * t + k], mesh.triangles[t][k]) << "triangle " << t;
            }
        }
    }
}

fs::path write_two_objects(const std::string& dir_name, const std::string& file_name) {
    const fs::path path = test::fresh_temp_dir(dir_name) / file_name;
    write_scene_gltf(path, two_objects(), sample_info());
    return path;
}

/// Expects `write_scene_gltf` to throw Error{code} whose message holds every fragment.
void expect_write_error(const fs::path& path,
                        const std::vector<SceneObject>& objects,
                        ErrorCode code,
                        const std::vector<std::string>& fragments) {
    try {
        write_scene_gltf(path, objects, sample_info());
        ADD_FAILURE() << "no error writing " << path;
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), code) << e.what();
        for (const std::string& fragment : fragments) {
            EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos)
                << "message: " << e.what() << "\nexpected fragment: " << fragment;
        }
    }
}

TEST(SceneGltf, GlbRoundTripsTwoObjects) {
    const fs::path path = write_two_objects("scene_gltf_glb", "scene.glb");
    EXPECT_EQ(read_bytes(path).substr(0, 4), "glTF");
    EXPECT_EQ(folder_entries(path.parent_path()), std::vector<std::string>{"scene.glb"});
    expect_scene_matches(load(path), two_objects());
}

TEST(SceneGltf, GltfWritesJsonAndBinBesideIt) {
    const fs::path path = write_two_objects("scene_gltf_gltf", "scene.gltf");
    EXPECT_EQ(folder_entries(path.parent_path()),
              (std::vector<std::string>{"scene.bin", "scene.gltf"}));
    const auto json = nlohmann::json::parse(read_bytes(path));
    ASSERT_EQ(json["buffers"].size(), 1u);
    EXPECT_EQ(json["buffers"][0]["uri"], "scene.bin");
    EXPECT_EQ(json["buffers"][0]["byteLength"], fs::file_size(path.parent_path() / "scene.bin"));
    expect_scene_matches(load(path), two_objects());
}

TEST(SceneGltf, BinNameIsUriEncoded) {
    const fs::path path = write_two_objects("scene_gltf_uri", "my scene #1.gltf");
    EXPECT_TRUE(fs::exists(path.parent_path() / "my scene #1.bin"));
    const auto json = nlohmann::json::parse(read_bytes(path));
    EXPECT_EQ(json["buffers"][0]["uri"], "my%20scene%20%231.bin");
    expect_scene_matches(load(path), two_objects());
}

TEST(SceneGltf, BufferViewsAreAlignedWithTargetsAndNoStride) {
    // one triangle first: 6 bytes of 16-bit indices, so the next view needs padding
    SceneObject triangle;
    triangle.name = "triangle";
    triangle.mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    triangle.mesh.triangles = {{0, 1, 2}};
    std::vector<SceneObject> objects = two_objects();
    objects.insert(objects.begin(), triangle);
    const fs::path path = test::fresh_temp_dir("scene_gltf_views") / "scene.gltf";
    write_scene_gltf(path, objects, sample_info());
    const auto json = nlohmann::json::parse(read_bytes(path));
    ASSERT_EQ(json["bufferViews"].size(), 9u);  // positions, normals, indices per object
    for (const auto& view : json["bufferViews"]) {
        EXPECT_EQ(view.value("byteOffset", 0) % 4, 0) << view;
        EXPECT_FALSE(view.contains("byteStride")) << view;
        ASSERT_TRUE(view.contains("target")) << view;
    }
    expect_scene_matches(load(path), objects);
    for (const auto& mesh : json["meshes"]) {
        const auto& primitive = mesh["primitives"][0];
        EXPECT_EQ(primitive["mode"], TINYGLTF_MODE_TRIANGLES);
        for (const char* attribute : {"POSITION", "NORMAL"}) {
            const int accessor = primitive["attributes"][attribute];
            const int view = json["accessors"][accessor]["bufferView"];
            EXPECT_EQ(json["bufferViews"][view]["target"], TINYGLTF_TARGET_ARRAY_BUFFER);
        }
        const int view = json["accessors"][primitive["indices"].get<int>()]["bufferView"];
        EXPECT_EQ(json["bufferViews"][view]["target"], TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
    }
}

TEST(SceneGltf, NormalsAreUnitAndPointOutward) {
    const std::vector<SceneObject> objects = two_objects();
    const SceneObject& sphere = objects[0];
    ASSERT_TRUE(is_closed_manifold(check_mesh(sphere.mesh)));
    ASSERT_GT(check_mesh(sphere.mesh).signed_volume, 0.0) << "the test sphere faces outwards";
    const fs::path path = write_two_objects("scene_gltf_normals", "scene.glb");
    const tinygltf::Model model = load(path);
    const auto normals =
        read_accessor<float>(model, only_primitive(model, 1).attributes.at("NORMAL"));
    ASSERT_EQ(normals.size(), 3 * sphere.mesh.positions.size());
    const Vec3 center{-12.3, 40.1, -300.7};
    for (std::size_t v = 0; v < sphere.mesh.positions.size(); ++v) {
        const Vec3 n{normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]};
        EXPECT_NEAR(norm(n), 1.0, 1e-6) << "vertex " << v;
        const Vec3 radial = sphere.mesh.positions[v] - center;
        // a fine sphere's vertex normals are close to radial
        EXPECT_GT(dot(n, (1.0 / norm(radial)) * radial), 0.95) << "vertex " << v;
    }
}

TEST(SceneGltf, TorusNormalsPointAwayFromTheTube) {
    const std::vector<SceneObject> objects = two_objects();
    const SceneObject& torus = objects[1];
    const tinygltf::Model model = load(write_two_objects("scene_gltf_torus", "scene.glb"));
    const auto normals =
        read_accessor<float>(model, only_primitive(model, 2).attributes.at("NORMAL"));
    const Vec3 center{5.5, -7.25, -280.125};
    for (std::size_t v = 0; v < torus.mesh.positions.size(); ++v) {
        const Vec3 n{normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]};
        EXPECT_NEAR(norm(n), 1.0, 1e-6) << "vertex " << v;
        const Vec3 p = torus.mesh.positions[v] - center;
        const double ring = std::hypot(p.x, p.y);
        const Vec3 tube_center{20.3 * p.x / ring, 20.3 * p.y / ring, 0.0};
        EXPECT_GT(dot(n, p - tube_center), 0.0) << "vertex " << v;
    }
}

TEST(SceneGltf, IsolatedVertexGetsAUnitNormal) {
    SceneObject object = two_objects()[0];
    object.mesh.positions.push_back({1, 2, 3});  // referenced by no triangle
    const fs::path path = test::fresh_temp_dir("scene_gltf_isolated") / "scene.glb";
    write_scene_gltf(path, {object}, sample_info());
    const tinygltf::Model model = load(path);
    const auto normals =
        read_accessor<float>(model, only_primitive(model, 1).attributes.at("NORMAL"));
    ASSERT_EQ(normals.size(), 3 * object.mesh.positions.size());
    const std::size_t last = normals.size() - 3;
    EXPECT_EQ(std::hypot(normals[last], normals[last + 1], normals[last + 2]), 1.0f);
}

TEST(SceneGltf, RootMapsLpsMillimetresToGltfMetres) {
    const tinygltf::Model model = load(write_two_objects("scene_gltf_root", "scene.glb"));
    const tinygltf::Node& root = model.nodes.at(model.scenes.at(0).nodes.at(0));
    ASSERT_EQ(root.matrix.size(), 16u);
    EXPECT_TRUE(root.rotation.empty() && root.scale.empty() && root.translation.empty());
    const auto& m = root.matrix;  // column-major
    auto apply = [&](Vec3 p) {
        Vec3 out;
        for (int r = 0; r < 3; ++r) {
            out[r] = m[r] * p.x + m[4 + r] * p.y + m[8 + r] * p.z + m[12 + r];
        }
        return out;
    };
    for (const Vec3 lps :
         {Vec3{12.5, -40.0, 300.0}, Vec3{-1, 0, 0}, Vec3{0, 1, 0}, Vec3{0, 0, 1}}) {
        const Vec3 gltf = apply(lps);
        const Vec3 expected = 0.001 * Vec3{lps.x, lps.z, -lps.y};
        EXPECT_NEAR(gltf.x, expected.x, 1e-15);
        EXPECT_NEAR(gltf.y, expected.y, 1e-15);
        EXPECT_NEAR(gltf.z, expected.z, 1e-15);
    }
    EXPECT_EQ(m[15], 1.0);
    EXPECT_EQ(m[3], 0.0);
    EXPECT_EQ(m[7], 0.0);
    EXPECT_EQ(m[11], 0.0);
    const Affine3 linear{{{{m[0], m[4], m[8]}, {m[1], m[5], m[9]}, {m[2], m[6], m[10]}}}};
    EXPECT_NEAR(linear.determinant(), 1e-9, 1e-21) << "a rotation with scale 0.001, no mirror";
}

TEST(SceneGltf, MaterialsAreLinearisedOpaqueAndSingleSided) {
    const tinygltf::Model model = load(write_two_objects("scene_gltf_colour", "scene.glb"));
    ASSERT_EQ(model.materials.size(), 2u);
    const auto& liver = model.materials[only_primitive(model, 1).material];
    const auto& vessel = model.materials[only_primitive(model, 2).material];
    ASSERT_EQ(liver.pbrMetallicRoughness.baseColorFactor.size(), 4u);
    EXPECT_NEAR(liver.pbrMetallicRoughness.baseColorFactor[0], 0.21404, 1e-5);  // sRGB 0.5
    EXPECT_NEAR(liver.pbrMetallicRoughness.baseColorFactor[1], 0.05088, 1e-5);  // sRGB 0.25
    EXPECT_EQ(liver.pbrMetallicRoughness.baseColorFactor[2], 1.0);
    EXPECT_EQ(liver.pbrMetallicRoughness.baseColorFactor[3], 1.0);
    EXPECT_EQ(vessel.pbrMetallicRoughness.baseColorFactor[0], 0.0);
    EXPECT_NEAR(vessel.pbrMetallicRoughness.baseColorFactor[1], 0.04 / 12.92, 1e-12);  // linear
    EXPECT_NEAR(vessel.pbrMetallicRoughness.baseColorFactor[2], 0.60383, 1e-5);        // sRGB 0.8
    for (const auto* material : {&liver, &vessel}) {
        EXPECT_EQ(material->pbrMetallicRoughness.metallicFactor, 0.0);
        EXPECT_NEAR(material->pbrMetallicRoughness.roughnessFactor, 0.6, 1e-12);
        EXPECT_FALSE(material->doubleSided);
        EXPECT_EQ(material->alphaMode, "OPAQUE");
    }
}

TEST(SceneGltf, NodeExtrasCarryLabelSourceSpacingAndUnits) {
    const tinygltf::Model model = load(write_two_objects("scene_gltf_extras", "scene.gltf"));
    const std::vector<SceneObject> objects = two_objects();
    const auto& root = model.nodes.at(0);
    ASSERT_EQ(root.children.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
        const tinygltf::Value& extras = model.nodes.at(root.children[i]).extras;
        ASSERT_TRUE(extras.IsObject());
        ASSERT_TRUE(extras.Get("label").IsInt());
        EXPECT_EQ(extras.Get("label").GetNumberAsInt(), objects[i].label);
        EXPECT_EQ(extras.Get("source").Get<std::string>(), "phantom:scene");
        EXPECT_EQ(extras.Get("units").Get<std::string>(), "mm");
        const tinygltf::Value& spacing = extras.Get("spacing_mm");
        ASSERT_TRUE(spacing.IsArray());
        ASSERT_EQ(spacing.ArrayLen(), 3u);
        EXPECT_EQ(spacing.Get(0).GetNumberAsDouble(), 0.7);
        EXPECT_EQ(spacing.Get(1).GetNumberAsDouble(), 0.7);
        EXPECT_EQ(spacing.Get(2).GetNumberAsDouble(), 5.0);
    }
}

TEST(SceneGltf, IndicesAreShortUpTo65535VerticesElseInt) {
    // 65535 vertices: indices up to 65534, below the 16-bit primitive restart value 65535
    TriMesh small;
    small.positions.resize(65535);
    for (std::size_t i = 0; i < small.positions.size(); ++i) {
        small.positions[i] = {static_cast<double>(i % 256), static_cast<double>(i / 256), 0.0};
    }
    small.triangles = {{0, 1, 256}, {65534, 65533, 65534 - 256}};
    TriMesh large = small;
    large.positions.push_back({0, 0, 1});
    large.triangles.push_back({0, 65535, 1});
    std::vector<SceneObject> objects(2);
    objects[0].name = "small";
    objects[0].mesh = small;
    objects[1].name = "large";
    objects[1].mesh = large;
    const fs::path path = test::fresh_temp_dir("scene_gltf_index_types") / "scene.glb";
    write_scene_gltf(path, objects, sample_info());
    const tinygltf::Model model = load(path);
    EXPECT_EQ(model.accessors.at(only_primitive(model, 1).indices).componentType,
              TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    EXPECT_EQ(model.accessors.at(only_primitive(model, 2).indices).componentType,
              TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
    EXPECT_EQ(read_indices(model, only_primitive(model, 1).indices),
              (std::vector<std::uint32_t>{0, 1, 256, 65534, 65533, 65534 - 256}));
    EXPECT_EQ(read_indices(model, only_primitive(model, 2).indices),
              (std::vector<std::uint32_t>{0, 1, 256, 65534, 65533, 65534 - 256, 0, 65535, 1}));
}

TEST(SceneGltf, EmptyObjectsAreSkipped) {
    std::vector<SceneObject> objects = two_objects();
    SceneObject empty;
    empty.name = "nothing";
    empty.label = 9;
    empty.mesh.positions = {{1, 2, 3}};  // vertices but no triangles: still empty
    objects.insert(objects.begin() + 1, empty);
    const fs::path path = test::fresh_temp_dir("scene_gltf_empty") / "scene.glb";
    write_scene_gltf(path, objects, sample_info());
    expect_scene_matches(load(path), two_objects());
}

TEST(SceneGltf, NoObjectsIsInvalidInput) {
    const fs::path dir = test::fresh_temp_dir("scene_gltf_no_objects");
    expect_write_error(dir / "scene.glb", {}, ErrorCode::InvalidInput, {"scene.glb", "no objects"});
    std::vector<SceneObject> all_empty(2);
    all_empty[0].name = "a";
    all_empty[1].name = "b";
    expect_write_error(dir / "scene.gltf", all_empty, ErrorCode::InvalidInput,
                       {"scene.gltf", "2 objects, none with a triangle"});
    EXPECT_TRUE(folder_entries(dir).empty());
}

TEST(SceneGltf, BadIndexNamesObjectTriangleAndIndexAndKeepsOldFile) {
    const fs::path path = write_two_objects("scene_gltf_bad_index", "scene.glb");
    const std::string old_bytes = read_bytes(path);
    std::vector<SceneObject> objects = two_objects();
    const auto n = static_cast<std::uint32_t>(objects[1].mesh.positions.size());
    objects[1].mesh.triangles[3][2] = n;
    expect_write_error(path, objects, ErrorCode::InvalidInput,
                       {"scene.glb", "object 1 'portal vein' (label 7)", "triangle 3",
                        "vertex index " + std::to_string(n), "expected < " + std::to_string(n)});
    EXPECT_EQ(read_bytes(path), old_bytes);
    EXPECT_EQ(folder_entries(path.parent_path()), std::vector<std::string>{"scene.glb"});
}

TEST(SceneGltf, BadInputIsInvalidInput) {
    const fs::path dir = test::fresh_temp_dir("scene_gltf_bad_input");
    std::vector<SceneObject> objects = two_objects();
    objects[0].mesh.positions[4].y = 1e39;  // finite as double, infinite as float32
    expect_write_error(dir / "a.glb", objects, ErrorCode::InvalidInput,
                       {"object 0 'liver'", "vertex 4", "not finite as float32"});
    objects = two_objects();
    objects[1].srgb[2] = 1.5;
    expect_write_error(dir / "b.glb", objects, ErrorCode::InvalidInput,
                       {"object 1 'portal vein'", "colour", "[0, 1]"});
    objects[1].srgb[2] = std::nan("");
    expect_write_error(dir / "c.glb", objects, ErrorCode::InvalidInput, {"colour"});
    expect_write_error(dir / "d.obj", two_objects(), ErrorCode::Unsupported,
                       {"d.obj", "'.obj'", ".glb or .gltf"});
    EXPECT_TRUE(folder_entries(dir).empty());
}

TEST(SceneGltf, UnwritableFolderThrowsIoAndLeavesNothing) {
    // note: like every strata writer, missing parent folders are created; a folder that cannot
    // be created (a file is in the way) is the failing case.
    const fs::path dir = test::fresh_temp_dir("scene_gltf_unwritable");
    std::ofstream(dir / "plain") << "x";
    for (const char* name : {"scene.glb", "scene.gltf"}) {
        try {
            write_scene_gltf(dir / "plain" / "missing" / name, two_objects(), sample_info());
            ADD_FAILURE() << "expected Error for " << name;
        } catch (const Error& e) {
            EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
            EXPECT_NE(std::string(e.what()).find("plain"), std::string::npos) << e.what();
        }
    }
    EXPECT_EQ(folder_entries(dir), std::vector<std::string>{"plain"});
    EXPECT_EQ(read_bytes(dir / "plain"), "x");
}

TEST(SceneGltf, CreatesMissingParentFolders) {
    const fs::path dir = test::fresh_temp_dir("scene_gltf_parents");
    write_scene_gltf(dir / "a" / "b" / "scene.gltf", two_objects(), sample_info());
    EXPECT_EQ(folder_entries(dir / "a" / "b"),
              (std::vector<std::string>{"scene.bin", "scene.gltf"}));
}

TEST(SceneGltf, GltfKeepsOldFilesWhenBinCannotBeWritten) {
    const fs::path path = write_two_objects("scene_gltf_pair", "scene.gltf");
    const fs::path dir = path.parent_path();
    const std::string old_json = read_bytes(path);
    // a non-empty folder where the .bin goes: its rename fails
    fs::remove(dir / "scene.bin");
    fs::create_directories(dir / "scene.bin" / "keep");
    std::vector<SceneObject> objects = two_objects();
    objects[0].srgb = {1, 1, 1};
    try {
        write_scene_gltf(path, objects, sample_info());
        ADD_FAILURE() << "expected Error";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
    }
    EXPECT_EQ(read_bytes(path), old_json);
    EXPECT_EQ(folder_entries(dir), (std::vector<std::string>{"scene.bin", "scene.gltf"}));
    EXPECT_TRUE(fs::is_directory(dir / "scene.bin" / "keep"));
}

TEST(SceneGltf, DracoPrimitivesDecodeToTheTrianglesAndShadingNormals) {
    const std::vector<SceneObject> objects = two_objects();
    const fs::path dir = test::fresh_temp_dir("scene_gltf_draco");
    SceneGltfOptions options;
    options.draco = true;
    write_scene_gltf(dir / "scene.glb", objects, sample_info(), options);
    // parsed here: tinygltf reads no Draco
    const std::string bytes = read_bytes(dir / "scene.glb");
    std::uint32_t json_length = 0;
    std::uint32_t bin_length = 0;
    ASSERT_GT(bytes.size(), 28u);
    std::memcpy(&json_length, bytes.data() + 12, 4);
    std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
    const nlohmann::json json = nlohmann::json::parse(bytes.substr(20, json_length));
    const std::string bin = bytes.substr(28 + json_length, bin_length);
    EXPECT_EQ(json["extensionsRequired"], nlohmann::json::array({"KHR_draco_mesh_compression"}));
    ASSERT_EQ(json["meshes"].size(), 2u);
    for (std::size_t o = 0; o < 2; ++o) {
        const TriMesh& mesh = objects[o].mesh;
        const std::vector<Vec3> expected_normals = shading_normals(mesh);
        const nlohmann::json& primitive = json["meshes"][o]["primitives"][0];
        const nlohmann::json& ext = primitive["extensions"]["KHR_draco_mesh_compression"];
        const nlohmann::json& view = json["bufferViews"][ext["bufferView"].get<std::size_t>()];
        for (const char* attribute : {"POSITION", "NORMAL"}) {
            EXPECT_FALSE(
                json["accessors"][primitive["attributes"][attribute].get<std::size_t>()].contains(
                    "bufferView"));
        }
        draco::DecoderBuffer in;
        in.Init(bin.data() + view.value("byteOffset", std::size_t{0}),
                view["byteLength"].get<std::size_t>());
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&in);
        ASSERT_TRUE(decoded.ok()) << "object " << o;
        const draco::Mesh& back = *decoded.value();
        const draco::PointAttribute* position =
            back.GetAttributeByUniqueId(ext["attributes"]["POSITION"].get<std::uint32_t>());
        const draco::PointAttribute* normal =
            back.GetAttributeByUniqueId(ext["attributes"]["NORMAL"].get<std::uint32_t>());
        ASSERT_EQ(back.num_faces(), mesh.triangles.size());
        EXPECT_EQ(
            json["accessors"][primitive["attributes"]["POSITION"].get<std::size_t>()]["count"],
            back.num_points());
        EXPECT_EQ(json["accessors"][primitive["indices"].get<std::size_t>()]["count"],
                  3 * std::size_t(back.num_faces()));
        ASSERT_NE(position, nullptr);
        ASSERT_NE(normal, nullptr);
        // every decoded point near exactly one original vertex (16 bits over < 80 mm), and its
        // normal near that vertex's shading normal (12-bit octahedral)
        std::vector<std::uint32_t> original(back.num_points());
        for (draco::PointIndex i(0); i < back.num_points(); ++i) {
            float p[3] = {};
            float n[3] = {};
            position->GetMappedValue(i, p);
            normal->GetMappedValue(i, n);
            std::size_t best = 0;
            double best_d = 1e300;
            for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
                const double d = norm(mesh.positions[v] - Vec3{p[0], p[1], p[2]});
                if (d < best_d) {
                    best_d = d;
                    best = v;
                }
            }
            EXPECT_LT(best_d, 0.01) << "object " << o << " point " << i.value();
            original[i.value()] = std::uint32_t(best);
            EXPECT_GT(dot(expected_normals[best], Vec3{n[0], n[1], n[2]}), std::cos(0.01))
                << "object " << o << " point " << i.value();
        }
        // the same triangles, same orientation
        std::vector<std::array<std::uint32_t, 3>> expected;
        std::vector<std::array<std::uint32_t, 3>> got;
        auto canonical = [](std::array<std::uint32_t, 3> t) {
            while (t[0] != std::min({t[0], t[1], t[2]})) {
                t = {t[1], t[2], t[0]};
            }
            return t;
        };
        for (const auto& t : mesh.triangles) {
            expected.push_back(canonical(t));
        }
        for (draco::FaceIndex f(0); f < back.num_faces(); ++f) {
            const auto& face = back.face(f);
            got.push_back(canonical(
                {original[face[0].value()], original[face[1].value()], original[face[2].value()]}));
        }
        std::sort(expected.begin(), expected.end());
        std::sort(got.begin(), got.end());
        EXPECT_EQ(got, expected) << "object " << o;
    }
}

TEST(SceneGltf, DracoFileIsTheSameForAnyThreadCount) {
    // the objects are encoded on several threads, their primitives laid out in object order
    std::vector<SceneObject> objects = two_objects();
    objects.insert(objects.begin() + 1, SceneObject{});  // an empty one between, skipped
    objects[1].name = "empty";
    objects.push_back(two_objects()[0]);
    const fs::path dir = test::fresh_temp_dir("scene_gltf_draco_threads");
    SceneGltfOptions options;
    options.draco = true;
    write_scene_gltf(dir / "serial.glb", objects, sample_info(), options);
    const std::string serial = read_bytes(dir / "serial.glb");
    for (const unsigned threads : {2u, 3u}) {
        options.threads = threads;
        const fs::path path = dir / ("threads" + std::to_string(threads) + ".glb");
        write_scene_gltf(path, objects, sample_info(), options);
        EXPECT_EQ(read_bytes(path), serial) << threads << " threads";
    }
}

/// Files for the Khronos validator (tests/node/validate_gltf.mjs, CTest gltf_validator_scene):
/// written to $STRATA_GLTF_SAMPLE_DIR when set, else to a temp folder and only read back.
TEST(SceneGltfSamples, WritesValidatorSamples) {
    const char* env = std::getenv("STRATA_GLTF_SAMPLE_DIR");
    const fs::path dir = env != nullptr && *env != '\0'
                             ? fs::path(env)
                             : test::fresh_temp_dir("scene_gltf_validator_samples");
    std::vector<SceneObject> objects = two_objects();
    SceneObject big;  // more than 65535 vertices: 32-bit indices
    big.name = "big torus";
    big.label = 300;
    big.srgb = {0.9, 0.6, 0.3};
    big.mesh = test::translated(test::torus(260, 256, 80.0, 15.0), {0.0, 0.0, -250.0});
    ASSERT_GT(big.mesh.positions.size(), 65535u);
    objects.push_back(big);
    SceneObject empty;  // skipped
    empty.name = "empty";
    objects.push_back(empty);
    for (const char* name : {"scene.glb", "scene.gltf"}) {
        write_scene_gltf(dir / name, objects, sample_info());
        const tinygltf::Model model = load(dir / name);
        EXPECT_EQ(model.meshes.size(), 3u) << name;
    }
    SceneGltfOptions draco;
    draco.draco = true;
    write_scene_gltf(dir / "scene_draco.glb", objects, sample_info(), draco);
    EXPECT_TRUE(fs::exists(dir / "scene_draco.glb"));
    EXPECT_TRUE(fs::exists(dir / "scene.bin"));
}

}  // namespace
}  // namespace strata

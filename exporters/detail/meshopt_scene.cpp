#include "exporters/detail/meshopt_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "exporters/detail/glb_container.h"
#include "exporters/detail/gltf_assembly.h"
#include "exporters/detail/gltf_common.h"
#include "exporters/detail/meshopt_streams.h"
#include "mesh/shading_normals.h"

namespace strata::detail {

namespace {

using Json = GltfAssembly::Json;

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

}  // namespace

void write_meshopt_scene(const std::filesystem::path& path,
                         const std::vector<SceneObject>& objects,
                         const SceneInfo& info) {
    if (lowercase_extension(path) != ".glb") {
        fail(ErrorCode::Unsupported, path,
             "unsupported extension '" + path.extension().string() +
                 "', expected .glb (meshopt scenes are binary)");
    }
    GltfAssembly a;
    Json& json = a.json;
    json["asset"] = {{"version", "2.0"}, {"generator", info.generator}};
    json["extensionsUsed"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
    json["extensionsRequired"] = {"EXT_meshopt_compression", "KHR_mesh_quantization"};
    json["scene"] = 0;
    json["scenes"] = Json::array({{{"nodes", Json::array({0})}}});
    Json root = {{"name", kRootNodeName}, {"matrix", Json::array()}, {"children", Json::array()}};
    for (const double v : kPatientToGltf) {
        root["matrix"].push_back(v);
    }
    json["nodes"] = Json::array({root});
    json["meshes"] = Json::array();
    json["materials"] = Json::array();
    json["accessors"] = Json::array();
    json["bufferViews"] = Json::array();
    for (std::size_t o = 0; o < objects.size(); ++o) {
        const SceneObject& object = objects[o];
        const TriMesh& mesh = object.mesh;
        const std::string name =
            object.name.empty() ? "label " + std::to_string(object.label) : object.name;
        const std::string where = "object " + std::to_string(o) + " '" + name + "'";
        if (mesh.triangles.empty()) {
            continue;
        }
        for (const double c : object.srgb) {
            if (!(c >= 0.0 && c <= 1.0)) {
                fail(ErrorCode::InvalidInput, path,
                     where + ": colour channel " + std::to_string(c) + ", expected sRGB in [0, 1]");
            }
        }
        Vec3 lo{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                std::numeric_limits<double>::infinity()};
        Vec3 hi = -1.0 * lo;
        for (const Vec3& p : mesh.positions) {
            for (int k = 0; k < 3; ++k) {
                if (!std::isfinite(p[k])) {
                    fail(ErrorCode::InvalidInput, path, where + ": a position is not finite");
                }
                lo[k] = std::min(lo[k], p[k]);
                hi[k] = std::max(hi[k], p[k]);
            }
        }
        const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        const double step = extent > 0.0 ? extent / 65535.0 : 1.0;
        MeshoptInput input;
        input.triangles = mesh.triangles;
        for (const Vec3& p : mesh.positions) {
            std::array<std::uint16_t, 3> q{};
            for (int k = 0; k < 3; ++k) {
                q[k] = static_cast<std::uint16_t>(
                    std::clamp(std::nearbyint((p[k] - lo[k]) / step), 0.0, 65535.0));
            }
            input.grid_positions.push_back(q);
        }
        for (const Vec3& n : object.normals.empty() ? shading_normals(mesh) : object.normals) {
            input.normals.push_back({to_float(n.x), to_float(n.y), to_float(n.z)});
        }
        MeshoptMesh encoded;
        try {
            encoded = encode_meshopt_mesh(input);
        } catch (const Error& e) {
            fail(e.code(), path, where + ": " + e.what());
        }
        json["materials"].push_back(
            {{"name", name},
             {"pbrMetallicRoughness",
              {{"baseColorFactor",
                {srgb_to_linear(object.srgb[0]), srgb_to_linear(object.srgb[1]),
                 srgb_to_linear(object.srgb[2]), 1.0}},
               {"metallicFactor", 0.0},
               {"roughnessFactor", 0.6}}}});
        const int material = static_cast<int>(json["materials"].size() - 1);
        json["meshes"].push_back(
            {{"name", name},
             {"primitives", Json::array({a.add_meshopt_primitive(encoded, material)})}});
        Json node = {{"name", name},
                     {"mesh", json["meshes"].size() - 1},
                     {"matrix", {step, 0, 0, 0, 0, step, 0, 0, 0, 0, step, 0, lo.x, lo.y, lo.z, 1}},
                     {"extras",
                      {{"label", object.label},
                       {"source", info.source},
                       {"spacing_mm", {info.spacing_mm[0], info.spacing_mm[1], info.spacing_mm[2]}},
                       {"units", "mm"},
                       {"quantization_step_mm", step}}}};
        json["nodes"][0]["children"].push_back(json["nodes"].size());
        json["nodes"].push_back(node);
    }
    if (json["meshes"].empty()) {
        fail(ErrorCode::InvalidInput, path, "no object has a triangle, expected at least one");
    }
    a.finish_buffers();
    write_file_atomically(path, glb_container(path, json.dump(), a.bin));
}

}  // namespace strata::detail

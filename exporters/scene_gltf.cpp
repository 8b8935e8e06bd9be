// A plain glTF 2.0 scene (Khronos, "glTF 2.0 Specification", version 2.0.1, 2021): one node
// and one indexed triangle mesh per object under a root node holding the patient -> glTF
// transform. Colours are linearised with the sRGB transfer function (IEC 61966-2-1:1999).
//
// tinygltf serialises the model; the vertex data, alignment and accessor bounds are ours. Its
// file writers open the final paths directly, so we serialise to memory and let
// write_file_atomically place the bytes.
#include "exporters/scene_gltf.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>

#include <draco/compression/decode.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "core/atomic_write.h"
#include "core/error.h"
#include "core/file_names.h"
#include "core/parallel.h"
#include "exporters/detail/gltf_common.h"
#include "mesh/shading_normals.h"

namespace strata {

namespace {

using detail::srgb_to_linear;
using detail::staging_name;
using detail::to_float;
using detail::uri_encode;

constexpr double kRoughness = 0.6;
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr std::size_t kMaxShortVertices = 65535;  // index 65535 is the primitive restart value
constexpr std::size_t kMaxIntVertices = std::numeric_limits<std::uint32_t>::max();

[[noreturn]] void fail(ErrorCode code, const std::filesystem::path& path, const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

std::string object_name(const SceneObject& object) {
    return object.name.empty() ? "label " + std::to_string(object.label) : object.name;
}

/// "object 1 'liver' (label 5)" for messages.
std::string describe(const SceneObject& object, std::size_t index) {
    return "object " + std::to_string(index) + " '" + object_name(object) + "' (label " +
           std::to_string(object.label) + ")";
}

void check_object(const std::filesystem::path& path, const SceneObject& object, std::size_t index) {
    const TriMesh& mesh = object.mesh;
    const std::size_t n = mesh.positions.size();
    if (n > kMaxIntVertices) {
        fail(ErrorCode::Unsupported, path,
             describe(object, index) + ": " + std::to_string(n) +
                 " vertices, at most 4294967295 fit 32-bit glTF indices");
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (std::uint32_t v : mesh.triangles[t]) {
            if (v >= n) {
                fail(ErrorCode::InvalidInput, path,
                     describe(object, index) + ": triangle " + std::to_string(t) +
                         " uses vertex index " + std::to_string(v) + ", expected < " +
                         std::to_string(n) + " (the number of vertices)");
            }
        }
    }
    for (std::size_t v = 0; v < n; ++v) {
        const Vec3 p = mesh.positions[v];
        for (int k = 0; k < 3; ++k) {
            if (!std::isfinite(to_float(p[k]))) {
                fail(ErrorCode::InvalidInput, path,
                     describe(object, index) + ": vertex " + std::to_string(v) +
                         " has a coordinate that is not finite as float32 (" +
                         std::to_string(p[k]) + ")");
            }
        }
    }
    for (double c : object.srgb) {
        if (!(c >= 0.0 && c <= 1.0)) {
            fail(ErrorCode::InvalidInput, path,
                 describe(object, index) + ": colour channel " + std::to_string(c) +
                     ", expected sRGB in [0, 1]");
        }
    }
}

/// The object's shading normals (mesh/shading_normals.h; SceneObject::normals when given), as
/// float32; +z where one is not finite (a sum of products of finite floats can overflow).
std::vector<float> float_normals(const SceneObject& object) {
    const TriMesh& mesh = object.mesh;
    std::vector<float> out;
    out.reserve(3 * mesh.positions.size());
    for (Vec3 n : object.normals.empty() ? shading_normals(mesh) : object.normals) {
        if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z))) {
            n = {0.0, 0.0, 1.0};
        }
        for (int k = 0; k < 3; ++k) {
            out.push_back(to_float(n[k]));
        }
    }
    return out;
}

/// The one binary buffer: appends 4-byte aligned buffer views.
class BufferBuilder {
public:
    explicit BufferBuilder(tinygltf::Model& model) : model_(model) {}

    /// Appends `bytes` as a new buffer view with `target`; returns its index.
    int add_view(const void* bytes, std::size_t size, int target) {
        tinygltf::BufferView view;
        view.buffer = 0;
        view.byteOffset = data_.size();
        view.byteLength = size;
        view.target = target;  // byteStride stays 0: tightly packed, omitted
        const auto* p = static_cast<const unsigned char*>(bytes);
        data_.insert(data_.end(), p, p + size);
        data_.resize((data_.size() + 3) / 4 * 4, 0);
        model_.bufferViews.push_back(std::move(view));
        return static_cast<int>(model_.bufferViews.size() - 1);
    }

    int add_accessor(int view, int component_type, int type, std::size_t count) {
        tinygltf::Accessor accessor;
        accessor.bufferView = view;
        accessor.componentType = component_type;
        accessor.type = type;
        accessor.count = count;
        model_.accessors.push_back(std::move(accessor));
        return static_cast<int>(model_.accessors.size() - 1);
    }

    std::vector<unsigned char> take() { return std::move(data_); }

private:
    tinygltf::Model& model_;
    std::vector<unsigned char> data_;
};

template <class Index>
std::vector<Index> flat_indices(const TriMesh& mesh) {
    std::vector<Index> out;
    out.reserve(3 * mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
        for (std::uint32_t v : t) {
            out.push_back(static_cast<Index>(v));
        }
    }
    return out;
}

/// The positions as float32, with their bounds.
std::vector<float> float_positions(const TriMesh& mesh,
                                   std::vector<double>& min,
                                   std::vector<double>& max) {
    std::vector<float> positions;
    positions.reserve(3 * mesh.positions.size());
    min.assign(3, std::numeric_limits<double>::infinity());
    max.assign(3, -std::numeric_limits<double>::infinity());
    for (const Vec3& p : mesh.positions) {
        for (int k = 0; k < 3; ++k) {
            const float f = to_float(p[k]);
            positions.push_back(f);
            min[k] = std::min(min[k], static_cast<double>(f));
            max[k] = std::max(max[k], static_cast<double>(f));
        }
    }
    return positions;
}

/// One object's triangles, positions and normals as a Draco (Edgebreaker) primitive, with the
/// counts and position bounds of the decoded mesh (decoded here once to read them).
struct DracoPrimitive {
    std::vector<char> bytes;
    std::uint32_t points = 0;
    std::size_t faces = 0;
    std::vector<double> min, max;
    int position_id = 0;  ///< the attributes' unique ids in the Draco stream
    int normal_id = 0;
};

DracoPrimitive encode_draco(const std::filesystem::path& path,
                            const SceneObject& object,
                            const SceneGltfOptions& options) {
    const TriMesh& mesh = object.mesh;
    std::vector<double> min, max;
    const std::vector<float> positions = float_positions(mesh, min, max);
    const std::vector<float> normals = float_normals(object);
    const auto n = static_cast<std::uint32_t>(mesh.positions.size());
    draco::Mesh dm;
    dm.set_num_points(n);
    const auto add = [&](draco::GeometryAttribute::Type type, const std::vector<float>& values) {
        draco::GeometryAttribute attribute;
        attribute.Init(type, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
        const int id = dm.AddAttribute(attribute, true, n);
        for (std::uint32_t i = 0; i < n; ++i) {
            dm.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(i), &values[3 * i]);
        }
        return id;
    };
    const int position = add(draco::GeometryAttribute::POSITION, positions);
    const int normal = add(draco::GeometryAttribute::NORMAL, normals);
    for (const auto& t : mesh.triangles) {
        dm.AddFace({draco::PointIndex(t[0]), draco::PointIndex(t[1]), draco::PointIndex(t[2])});
    }
    draco::Encoder encoder;
    encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    encoder.SetSpeedOptions(options.draco_speed, options.draco_speed);
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.position_bits);
    encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, options.normal_bits);
    draco::EncoderBuffer encoded;
    const draco::Status status = encoder.EncodeMeshToBuffer(dm, &encoded);
    if (!status.ok()) {
        fail(ErrorCode::Internal, path, "Draco encoding failed: " + status.error_msg_string());
    }
    draco::DecoderBuffer in;
    in.Init(encoded.data(), encoded.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded.ok() || decoded.value()->num_faces() != mesh.triangles.size()) {
        fail(ErrorCode::Internal, path, "the Draco primitive does not decode to its triangles");
    }
    const draco::Mesh& back = *decoded.value();
    const draco::PointAttribute* back_position =
        back.GetNamedAttribute(draco::GeometryAttribute::POSITION);
    DracoPrimitive out;
    out.min.assign(3, std::numeric_limits<double>::infinity());
    out.max.assign(3, -std::numeric_limits<double>::infinity());
    for (draco::PointIndex i(0); i < back.num_points(); ++i) {
        float p[3] = {};
        back_position->GetMappedValue(i, p);
        for (int k = 0; k < 3; ++k) {
            out.min[k] = std::min(out.min[k], static_cast<double>(p[k]));
            out.max[k] = std::max(out.max[k], static_cast<double>(p[k]));
        }
    }
    out.bytes.assign(encoded.data(), encoded.data() + encoded.size());
    out.points = back.num_points();
    out.faces = back.num_faces();
    out.position_id = static_cast<int>(dm.attribute(position)->unique_id());
    out.normal_id = static_cast<int>(dm.attribute(normal)->unique_id());
    return out;
}

/// The Draco primitive's bytes in a buffer view, accessors without views for POSITION, NORMAL
/// and the indices.
void add_draco_primitive(tinygltf::Model& model,
                         BufferBuilder& buffer,
                         tinygltf::Primitive& primitive,
                         const DracoPrimitive& draco) {
    const int view = buffer.add_view(draco.bytes.data(), draco.bytes.size(), /*target=*/0);
    const int position_accessor =
        buffer.add_accessor(-1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, draco.points);
    model.accessors[position_accessor].minValues = draco.min;
    model.accessors[position_accessor].maxValues = draco.max;
    primitive.attributes["POSITION"] = position_accessor;
    primitive.attributes["NORMAL"] =
        buffer.add_accessor(-1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, draco.points);
    primitive.indices = buffer.add_accessor(-1,
                                            draco.points <= kMaxShortVertices
                                                ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT
                                                : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                            TINYGLTF_TYPE_SCALAR, 3 * draco.faces);
    tinygltf::Value::Object attributes;
    attributes["POSITION"] = tinygltf::Value(draco.position_id);
    attributes["NORMAL"] = tinygltf::Value(draco.normal_id);
    tinygltf::Value::Object extension;
    extension["bufferView"] = tinygltf::Value(view);
    extension["attributes"] = tinygltf::Value(std::move(attributes));
    primitive.extensions[kDraco] = tinygltf::Value(std::move(extension));
}

/// Adds the mesh, material and node of one object; returns the node index.
/// `draco`: the object's Draco primitive (options.draco), else null.
int add_object(tinygltf::Model& model,
               BufferBuilder& buffer,
               const SceneObject& object,
               const DracoPrimitive* draco,
               const SceneInfo& info) {
    const TriMesh& mesh = object.mesh;
    const std::size_t n = mesh.positions.size();

    tinygltf::Primitive primitive;
    primitive.mode = TINYGLTF_MODE_TRIANGLES;  // note: tinygltf's default -1 would be written
    if (draco != nullptr) {
        add_draco_primitive(model, buffer, primitive, *draco);
    } else {
        std::vector<double> min, max;
        const std::vector<float> positions = float_positions(mesh, min, max);
        const std::vector<float> normals = float_normals(object);
        const int position_view = buffer.add_view(
            positions.data(), positions.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
        const int position_accessor = buffer.add_accessor(
            position_view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);
        model.accessors[position_accessor].minValues = min;
        model.accessors[position_accessor].maxValues = max;
        primitive.attributes["POSITION"] = position_accessor;
        const int normal_view = buffer.add_view(normals.data(), normals.size() * sizeof(float),
                                                TINYGLTF_TARGET_ARRAY_BUFFER);
        primitive.attributes["NORMAL"] =
            buffer.add_accessor(normal_view, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, n);

        const std::size_t index_count = 3 * mesh.triangles.size();
        if (n <= kMaxShortVertices) {
            const auto indices = flat_indices<std::uint16_t>(mesh);
            const int view = buffer.add_view(indices.data(), indices.size() * sizeof(std::uint16_t),
                                             TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
            primitive.indices = buffer.add_accessor(view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
                                                    TINYGLTF_TYPE_SCALAR, index_count);
        } else {
            const auto indices = flat_indices<std::uint32_t>(mesh);
            const int view = buffer.add_view(indices.data(), indices.size() * sizeof(std::uint32_t),
                                             TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
            primitive.indices = buffer.add_accessor(view, TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT,
                                                    TINYGLTF_TYPE_SCALAR, index_count);
        }
    }

    const std::string name = object_name(object);
    tinygltf::Material material;
    material.name = name;
    material.pbrMetallicRoughness.baseColorFactor = {srgb_to_linear(object.srgb[0]),
                                                     srgb_to_linear(object.srgb[1]),
                                                     srgb_to_linear(object.srgb[2]), 1.0};
    material.pbrMetallicRoughness.metallicFactor = 0.0;
    material.pbrMetallicRoughness.roughnessFactor = kRoughness;
    material.doubleSided = false;  // closed, outward-oriented surfaces
    model.materials.push_back(std::move(material));
    primitive.material = static_cast<int>(model.materials.size() - 1);

    tinygltf::Mesh gltf_mesh;
    gltf_mesh.name = name;
    gltf_mesh.primitives.push_back(std::move(primitive));
    model.meshes.push_back(std::move(gltf_mesh));

    tinygltf::Value::Array spacing;
    for (double s : info.spacing_mm) {
        spacing.emplace_back(s);
    }
    tinygltf::Value::Object extras;
    extras["label"] = tinygltf::Value(static_cast<int>(object.label));
    extras["source"] = tinygltf::Value(info.source);
    extras["spacing_mm"] = tinygltf::Value(std::move(spacing));
    extras["units"] = tinygltf::Value(std::string("mm"));

    tinygltf::Node node;
    node.name = name;
    node.mesh = static_cast<int>(model.meshes.size() - 1);
    node.extras = tinygltf::Value(std::move(extras));
    model.nodes.push_back(std::move(node));
    return static_cast<int>(model.nodes.size() - 1);
}

std::string serialise(const std::filesystem::path& path,
                      const tinygltf::Model& model,
                      bool binary) {
    tinygltf::TinyGLTF writer;
    std::ostringstream out;
    if (!writer.WriteGltfSceneToStream(&model, out, /*prettyPrint=*/!binary,
                                       /*writeBinary=*/binary)) {
        fail(ErrorCode::Internal, path, "tinygltf: serialising the scene failed");
    }
    return std::move(out).str();
}

/// `.gltf` + `.bin`: the JSON is staged first, so a failing `.bin` leaves both old files; the
/// `.bin` then replaces the old one and the JSON follows (a reader racing the two renames may
/// see the new `.bin` with the old JSON).
void write_gltf_pair(const std::filesystem::path& path,
                     tinygltf::Model& model,
                     std::vector<unsigned char> bin) {
    const std::filesystem::path bin_path = std::filesystem::path(path).replace_extension(".bin");
    // note: tinygltf's stream writer embeds every buffer as a data URI; serialise an empty
    // buffer and point it at the .bin afterwards.
    model.buffers[0].data.clear();
    nlohmann::json json;
    try {
        json = nlohmann::json::parse(serialise(path, model, /*binary=*/false));
        json["buffers"][0]["uri"] = uri_encode(bin_path.filename().string());
        json["buffers"][0]["byteLength"] = bin.size();
    } catch (const nlohmann::json::exception& e) {
        fail(ErrorCode::Internal, path, std::string("tinygltf output: ") + e.what());
    }
    const std::string text = json.dump(2) + "\n";

    const std::filesystem::path staged = staging_name(path);
    write_file_atomically(staged, text);
    std::error_code ec;
    try {
        write_file_atomically(
            bin_path, std::string_view(reinterpret_cast<const char*>(bin.data()), bin.size()));
    } catch (...) {
        std::filesystem::remove(staged, ec);
        throw;
    }
    std::filesystem::rename(staged, path, ec);
    if (ec) {
        std::error_code ignored;
        std::filesystem::remove(staged, ignored);
        fail(ErrorCode::Io, path, "cannot rename " + staged.string() + ": " + ec.message());
    }
}

}  // namespace

void write_scene_gltf(const std::filesystem::path& path,
                      const std::vector<SceneObject>& objects,
                      const SceneInfo& info,
                      const SceneGltfOptions& options) {
    detail::require_gltf_extension(path);
    const std::string ext = lowercase_extension(path);
    if (objects.empty()) {
        fail(ErrorCode::InvalidInput, path, "no objects to write, expected at least one");
    }
    for (double s : info.spacing_mm) {
        if (!std::isfinite(s)) {
            fail(ErrorCode::InvalidInput, path, "spacing_mm is not finite");
        }
    }
    std::size_t non_empty = 0;
    for (std::size_t i = 0; i < objects.size(); ++i) {
        check_object(path, objects[i], i);
        non_empty += objects[i].mesh.triangles.empty() ? 0 : 1;
    }
    if (non_empty == 0) {
        fail(ErrorCode::InvalidInput, path,
             std::to_string(objects.size()) +
                 " objects, none with a triangle: nothing to write, expected at least one "
                 "non-empty object");
    }

    if (options.draco &&
        !(options.position_bits >= 1 && options.position_bits <= 30 && options.normal_bits >= 1 &&
          options.normal_bits <= 30 && options.draco_speed >= 0 && options.draco_speed <= 10)) {
        fail(ErrorCode::InvalidInput, path,
             "Draco options out of range: position_bits and normal_bits 1-30, speed 0-10");
    }

    tinygltf::Model model;
    model.asset.version = "2.0";
    model.asset.generator = info.generator;
    if (options.draco) {
        model.extensionsUsed = {kDraco};
        model.extensionsRequired = {kDraco};
    }

    tinygltf::Node root;
    root.name = detail::kRootNodeName;
    root.matrix.assign(detail::kPatientToGltf.begin(), detail::kPatientToGltf.end());
    model.nodes.push_back(std::move(root));

    // note: the objects' Draco encodings (most of the time) go over the threads, each object's
    // alone; the buffer is laid out in object order
    std::vector<DracoPrimitive> draco(options.draco ? objects.size() : 0);
    if (options.draco) {
        parallel_for(objects.size(), options.threads, [&](std::size_t i) {
            if (!objects[i].mesh.triangles.empty()) {
                draco[i] = encode_draco(path, objects[i], options);
            }
        });
    }
    BufferBuilder buffer(model);
    std::vector<int> children;
    for (std::size_t i = 0; i < objects.size(); ++i) {
        if (!objects[i].mesh.triangles.empty()) {
            children.push_back(
                add_object(model, buffer, objects[i], options.draco ? &draco[i] : nullptr, info));
            if (options.draco) {
                draco[i] = {};
            }
        }
    }
    model.nodes[0].children = std::move(children);

    tinygltf::Scene scene;
    scene.nodes = {0};
    model.scenes.push_back(std::move(scene));
    model.defaultScene = 0;

    std::vector<unsigned char> bin = buffer.take();
    model.buffers.emplace_back();
    if (ext == ".glb") {
        model.buffers[0].data = std::move(bin);
        write_file_atomically(path, serialise(path, model, /*binary=*/true));
    } else {
        write_gltf_pair(path, model, std::move(bin));
    }
}

}  // namespace strata

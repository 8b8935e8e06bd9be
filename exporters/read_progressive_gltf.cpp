// Reader of strata's progressive glTF (schema/README.md): everything is validated before use, so
// a corrupt or hostile file ends in Error{InvalidInput} naming what and where, never in a crash.
// The JSON is parsed with nlohmann_json (bounded size), the GLB container (glTF 2.0 section 4.4)
// by hand, the chunks with Draco's decoder.
#include "exporters/read_progressive_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <unordered_map>

#include <draco/compression/decode.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_names.h"

namespace strata {

namespace {

using Json = nlohmann::json;

constexpr std::uint64_t kMaxFileBytes = std::uint64_t{4} << 30;  // a GLB cannot be larger
constexpr std::size_t kMaxJsonBytes = std::size_t{512} << 20;
constexpr const char* kExtension = "STRATA_progressive_mesh";
constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kCoarse = "_COARSE_POSITION";

/// Messages name the file and a JSON pointer.
class Reader {
public:
    Reader(const std::string& name, const Json& json) : name_(name), json_(json) {}

    [[noreturn]] void fail(const std::string& where, const std::string& what) const {
        throw Error(ErrorCode::InvalidInput, name_ + ": " + where + ": " + what);
    }

    const Json& array(const Json& parent,
                      const std::string& key,
                      const std::string& where,
                      bool required = true) const {
        static const Json kEmpty = Json::array();
        if (!parent.contains(key)) {
            if (required) {
                fail(where, "missing \"" + key + "\", expected an array");
            }
            return kEmpty;
        }
        const Json& a = parent[key];
        if (!a.is_array()) {
            fail(where + "/" + key, "expected an array");
        }
        return a;
    }

    const Json& object(const Json& parent, const std::string& key, const std::string& where) const {
        if (!parent.contains(key) || !parent[key].is_object()) {
            fail(where + "/" + key, "missing or not an object");
        }
        return parent[key];
    }

    /// A non-negative integer below `limit`.
    std::uint64_t index(const Json& value,
                        const std::string& where,
                        std::uint64_t limit,
                        const std::string& what) const {
        if (!value.is_number_integer() || value.get<std::int64_t>() < 0) {
            fail(where, "expected a non-negative integer (" + what + ")");
        }
        const std::uint64_t v = value.get<std::uint64_t>();
        if (v >= limit) {
            fail(where, what + " " + std::to_string(v) + " out of range, expected < " +
                            std::to_string(limit));
        }
        return v;
    }

    std::uint64_t index(const Json& parent,
                        const std::string& key,
                        const std::string& where,
                        std::uint64_t limit,
                        const std::string& what) const {
        if (!parent.contains(key)) {
            fail(where, "missing \"" + key + "\" (" + what + ")");
        }
        return index(parent[key], where + "/" + key, limit, what);
    }

    double number(const Json& parent,
                  const std::string& key,
                  const std::string& where,
                  double min) const {
        if (!parent.contains(key) || !parent[key].is_number()) {
            fail(where + "/" + key, "missing or not a number");
        }
        const double v = parent[key].get<double>();
        if (!std::isfinite(v) || v < min) {
            fail(where + "/" + key, "value " + std::to_string(v) +
                                        ", expected a finite number >= " + std::to_string(min));
        }
        return v;
    }

    Sphere sphere(const Json& parent, const std::string& where) const {
        if (!parent.contains("sphere") || !parent["sphere"].is_array() ||
            parent["sphere"].size() != 4) {
            fail(where + "/sphere", "expected [x, y, z, radius]");
        }
        std::array<double, 4> v{};
        for (int i = 0; i < 4; ++i) {
            const Json& x = parent["sphere"][i];
            if (!x.is_number() || !std::isfinite(x.get<double>())) {
                fail(where + "/sphere/" + std::to_string(i), "not a finite number");
            }
            v[i] = x.get<double>();
        }
        if (v[3] < 0.0) {
            fail(where + "/sphere/3", "negative radius");
        }
        return {{v[0], v[1], v[2]}, v[3]};
    }

    std::array<double, 16> matrix(const Json& node, const std::string& where) const {
        std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        if (!node.contains("matrix")) {
            return m;
        }
        const Json& a = node["matrix"];
        if (!a.is_array() || a.size() != 16) {
            fail(where + "/matrix", "expected 16 numbers");
        }
        for (int i = 0; i < 16; ++i) {
            if (!a[i].is_number() || !std::isfinite(a[i].get<double>())) {
                fail(where + "/matrix/" + std::to_string(i), "not a finite number");
            }
            m[i] = a[i].get<double>();
        }
        return m;
    }

    const Json& json() const { return json_; }
    const std::string& name() const { return name_; }

private:
    std::string name_;
    const Json& json_;
};

std::uint32_t le32(std::string_view bytes, std::size_t at) {
    std::uint32_t v = 0;
    for (int i = 3; i >= 0; --i) {
        v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
    }
    return v;
}

std::array<double, 16> multiply(const std::array<double, 16>& a, const std::array<double, 16>& b) {
    std::array<double, 16> m{};
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            double sum = 0.0;
            for (int k = 0; k < 4; ++k) {
                sum += a[4 * k + r] * b[4 * c + k];
            }
            m[4 * c + r] = sum;
        }
    }
    return m;
}

/// Buffers and views, validated once.
struct Data {
    std::vector<std::string> buffers;
    struct View {
        std::size_t buffer, offset, length;
    };
    std::vector<View> views;

    std::string_view view(std::size_t v) const {
        const View& w = views[v];
        return std::string_view(buffers[w.buffer]).substr(w.offset, w.length);
    }
};

Data load_data(const Reader& r,
               std::string_view glb_bin,
               bool is_glb,
               const std::function<std::string(const std::string&)>& load_buffer) {
    const Json& json = r.json();
    Data data;
    const Json& buffers = r.array(json, "buffers", "", false);
    for (std::size_t b = 0; b < buffers.size(); ++b) {
        const std::string where = "/buffers/" + std::to_string(b);
        const Json& buffer = buffers[b];
        if (!buffer.is_object()) {
            r.fail(where, "expected an object");
        }
        const std::uint64_t length =
            r.index(buffer, "byteLength", where, kMaxFileBytes + 1, "byte length");
        std::string bytes;
        if (!buffer.contains("uri")) {
            if (!is_glb || b != 0) {
                r.fail(where, "no \"uri\": only the first buffer of a .glb may use its BIN chunk");
            }
            bytes.assign(glb_bin);
        } else {
            if (!buffer["uri"].is_string()) {
                r.fail(where + "/uri", "expected a string");
            }
            bytes = load_buffer(buffer["uri"].get<std::string>());
        }
        if (bytes.size() < length) {
            r.fail(where, "byteLength " + std::to_string(length) + " but only " +
                              std::to_string(bytes.size()) + " bytes are there");
        }
        bytes.resize(length);
        data.buffers.push_back(std::move(bytes));
    }
    const Json& views = r.array(json, "bufferViews", "", false);
    for (std::size_t v = 0; v < views.size(); ++v) {
        const std::string where = "/bufferViews/" + std::to_string(v);
        const Json& view = views[v];
        if (!view.is_object()) {
            r.fail(where, "expected an object");
        }
        const std::size_t buffer = r.index(view, "buffer", where, data.buffers.size(), "buffer");
        const std::uint64_t size = data.buffers[buffer].size();
        const std::uint64_t offset =
            view.contains("byteOffset")
                ? r.index(view["byteOffset"], where + "/byteOffset", size + 1, "byte offset")
                : 0;
        const std::uint64_t length =
            r.index(view, "byteLength", where, size - offset + 1, "byte length");
        if (view.contains("byteStride")) {
            r.fail(where + "/byteStride", "interleaved data is not used by this format");
        }
        data.views.push_back(
            {buffer, static_cast<std::size_t>(offset), static_cast<std::size_t>(length)});
    }
    return data;
}

/// An accessor's description, checked.
struct Accessor {
    int component_type = 0;
    std::size_t components = 0;
    std::size_t count = 0;
    std::int64_t view = -1;
    std::size_t offset = 0;
};

Accessor accessor(
    const Reader& r, const Data& data, const Json& ref, const std::string& where, bool draco) {
    const Json& accessors = r.array(r.json(), "accessors", "");
    const std::size_t a = r.index(ref, where, accessors.size(), "accessor");
    const std::string at = "/accessors/" + std::to_string(a);
    const Json& j = accessors[a];
    if (!j.is_object()) {
        r.fail(at, "expected an object");
    }
    Accessor out;
    if (!j.contains("componentType") || !j["componentType"].is_number_integer()) {
        r.fail(at, "missing componentType");
    }
    out.component_type = j["componentType"].get<int>();
    if (!j.contains("type") || !j["type"].is_string()) {
        r.fail(at, "missing type");
    }
    const std::string type = j["type"].get<std::string>();
    out.components = type == "SCALAR" ? 1 : type == "VEC3" ? 3 : 0;
    if (out.components == 0) {
        r.fail(at + "/type", "\"" + type + "\", expected SCALAR or VEC3");
    }
    out.count = r.index(j, "count", at, std::uint64_t{1} << 32, "count");
    if (j.value("normalized", false) || j.contains("sparse")) {
        r.fail(at, "normalized or sparse accessors are not used by this format");
    }
    if (draco) {
        if (j.contains("bufferView")) {
            r.fail(at, "an accessor of a Draco primitive must not have a bufferView");
        }
        return out;
    }
    out.view = static_cast<std::int64_t>(r.index(j, "bufferView", at, data.views.size(), "view"));
    out.offset = j.contains("byteOffset") ? r.index(j["byteOffset"], at + "/byteOffset",
                                                    std::uint64_t{1} << 40, "offset")
                                          : 0;
    const std::size_t size = out.component_type == 5126 || out.component_type == 5125 ? 4
                             : out.component_type == 5123                             ? 2
                                                                                      : 0;
    if (size == 0) {
        r.fail(at + "/componentType",
               std::to_string(out.component_type) + ", expected 5123, 5125 or 5126");
    }
    const std::uint64_t need = std::uint64_t{out.count} * out.components * size;
    const std::size_t available = data.views[out.view].length;
    if (out.offset > available || need > available - out.offset) {
        r.fail(at, std::to_string(need) + " bytes from offset " + std::to_string(out.offset) +
                       " do not fit buffer view " + std::to_string(out.view) + " of " +
                       std::to_string(available) + " bytes");
    }
    if (out.offset % size != 0 || data.views[out.view].offset % size != 0) {
        r.fail(at, "data not aligned to its component size");
    }
    return out;
}

std::vector<float> floats(const Data& data, const Accessor& a) {
    std::vector<float> out(a.count * a.components);
    std::memcpy(out.data(), data.view(a.view).data() + a.offset, out.size() * sizeof(float));
    return out;
}

std::vector<std::uint32_t> indices(const Reader& r,
                                   const Data& data,
                                   const Accessor& a,
                                   const std::string& where) {
    std::vector<std::uint32_t> out(a.count);
    const char* p = data.view(a.view).data() + a.offset;
    if (a.component_type == 5125) {
        std::memcpy(out.data(), p, out.size() * 4);
    } else if (a.component_type == 5123) {
        for (std::size_t i = 0; i < out.size(); ++i) {
            std::uint16_t v = 0;
            std::memcpy(&v, p + 2 * i, 2);
            out[i] = v;
        }
    } else {
        r.fail(where, "indices must be unsigned short or unsigned int");
    }
    return out;
}

/// Positions, triangles and coarse positions of one cluster as stored.
struct RawCluster {
    std::vector<std::array<float, 3>> positions;
    std::vector<std::array<std::uint32_t, 3>> triangles;
    std::vector<std::array<float, 3>> coarse;  ///< empty for roots
    std::size_t bytes = 0;                     ///< stored bytes (accessor data or Draco blob)
};

RawCluster plain_primitive(const Reader& r,
                           const Data& data,
                           const Json& primitive,
                           const std::string& where) {
    RawCluster out;
    const Json& attributes = r.object(primitive, "attributes", where);
    const Accessor pa =
        accessor(r, data, attributes.contains("POSITION") ? attributes["POSITION"] : Json(),
                 where + "/attributes/POSITION", false);
    if (pa.component_type != 5126 || pa.components != 3) {
        r.fail(where + "/attributes/POSITION", "expected float VEC3");
    }
    const std::vector<float> p = floats(data, pa);
    for (std::size_t i = 0; i < pa.count; ++i) {
        out.positions.push_back({p[3 * i], p[3 * i + 1], p[3 * i + 2]});
    }
    if (!primitive.contains("indices")) {
        r.fail(where, "missing \"indices\"");
    }
    const Accessor ia = accessor(r, data, primitive["indices"], where + "/indices", false);
    if (ia.components != 1 || ia.count % 3 != 0) {
        r.fail(where + "/indices", "expected SCALAR indices, a multiple of 3");
    }
    const std::vector<std::uint32_t> idx = indices(r, data, ia, where + "/indices");
    out.bytes = data.views[pa.view].length + data.views[ia.view].length;
    if (attributes.contains("NORMAL")) {
        const Accessor na =
            accessor(r, data, attributes["NORMAL"], where + "/attributes/NORMAL", false);
        if (na.count != pa.count || na.components != 3 || na.component_type != 5126) {
            r.fail(where + "/attributes/NORMAL", "expected float VEC3, one per position");
        }
        out.bytes += data.views[na.view].length;
    }
    for (std::size_t i = 0; i < idx.size(); i += 3) {
        out.triangles.push_back({idx[i], idx[i + 1], idx[i + 2]});
    }
    return out;
}

RawCluster draco_primitive(const Reader& r,
                           const Data& data,
                           const Json& primitive,
                           const std::string& where) {
    RawCluster out;
    const Json& ext =
        r.object(r.object(primitive, "extensions", where), kDraco, where + "/extensions");
    const std::string at = where + "/extensions/" + kDraco;
    const std::size_t view = r.index(ext, "bufferView", at, data.views.size(), "buffer view");
    const Json& ids = r.object(ext, "attributes", at);
    const Json& attributes = r.object(primitive, "attributes", where);
    for (const char* name : {"POSITION", kCoarse}) {
        if (!ids.contains(name) || !attributes.contains(name)) {
            r.fail(at, std::string("attribute ") + name + " missing");
        }
    }
    const Accessor pa =
        accessor(r, data, attributes["POSITION"], where + "/attributes/POSITION", true);
    const Accessor ca =
        accessor(r, data, attributes[kCoarse], where + "/attributes/" + kCoarse, true);
    if (!primitive.contains("indices")) {
        r.fail(where, "missing \"indices\"");
    }
    const Accessor ia = accessor(r, data, primitive["indices"], where + "/indices", true);

    const std::string_view bytes = data.view(view);
    out.bytes = bytes.size();
    draco::DecoderBuffer in;
    in.Init(bytes.data(), bytes.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded.ok()) {
        r.fail(at, "Draco cannot decode buffer view " + std::to_string(view) + ": " +
                       decoded.status().error_msg());
    }
    const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    const auto attribute = [&](const char* name, const Accessor& a) {
        const Json& id = ids[name];
        if (!id.is_number_integer()) {
            r.fail(at + "/attributes/" + name, "expected an integer id");
        }
        const draco::PointAttribute* decoded_attribute =
            mesh->GetAttributeByUniqueId(static_cast<std::uint32_t>(id.get<std::int64_t>()));
        if (decoded_attribute == nullptr || decoded_attribute->num_components() != 3) {
            r.fail(at + "/attributes/" + name, "no 3-component attribute with that id");
        }
        if (a.count != mesh->num_points() || a.components != 3 || a.component_type != 5126) {
            r.fail(where + "/attributes/" + name, "accessor says " + std::to_string(a.count) +
                                                      " points, Draco decoded " +
                                                      std::to_string(mesh->num_points()));
        }
        std::vector<std::array<float, 3>> values(mesh->num_points());
        for (std::uint32_t i = 0; i < mesh->num_points(); ++i) {
            if (!decoded_attribute->ConvertValue<float, 3>(
                    decoded_attribute->mapped_index(draco::PointIndex(i)), values[i].data())) {
                r.fail(at, std::string("cannot read ") + name);
            }
        }
        return values;
    };
    out.positions = attribute("POSITION", pa);
    out.coarse = attribute(kCoarse, ca);
    if (ia.count != 3 * std::size_t{mesh->num_faces()} || ia.components != 1) {
        r.fail(where + "/indices", "accessor says " + std::to_string(ia.count) +
                                       " indices, Draco decoded " +
                                       std::to_string(mesh->num_faces()) + " triangles");
    }
    for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
        const auto& face = mesh->face(f);
        out.triangles.push_back({face[0].value(), face[1].value(), face[2].value()});
    }
    return out;
}

/// One object node: the extension's DAG checked, clusters decoded and merged into one model.
ProgressiveFileObject read_object(const Reader& r,
                                  const Data& data,
                                  std::size_t n,
                                  const std::array<double, 16>& patient) {
    const Json& json = r.json();
    const std::string where = "/nodes/" + std::to_string(n);
    const Json& node = json["nodes"][n];
    const std::string at = where + "/extensions/" + kExtension;
    const Json& ext = node["extensions"][kExtension];
    if (!ext.is_object()) {
        r.fail(at, "expected an object");
    }
    ProgressiveFileObject object;
    object.name = node.value("name", std::string());
    if (node.contains("extras") && node["extras"].is_object() && node["extras"].contains("label") &&
        node["extras"]["label"].is_number_integer()) {
        object.label = node["extras"]["label"].get<std::int64_t>();
    }
    object.to_patient = r.matrix(node, where);
    object.to_scene = multiply(patient, object.to_patient);
    MultiresMesh& model = object.model;
    model.full_resolution_error_px = r.number(ext, "fullResolutionError", at, 0.0);
    model.grid_step = r.number(ext, "gridStep", at, 0.0);
    if (!(model.grid_step > 0.0)) {
        r.fail(at + "/gridStep", "expected a positive number");
    }
    const Json& meshes = r.array(json, "meshes", "");
    const std::size_t base_mesh = r.index(node, "mesh", where, meshes.size(), "mesh");

    const Json& groups = r.array(ext, "groups", at);
    const Json& clusters = r.array(ext, "clusters", at);
    if (clusters.empty()) {
        r.fail(at + "/clusters", "no clusters");
    }
    model.clusters.resize(clusters.size());
    model.groups.resize(groups.size());
    for (std::size_t g = 0; g < groups.size(); ++g) {
        const std::string gw = at + "/groups/" + std::to_string(g);
        const Json& group = groups[g];
        if (!group.is_object()) {
            r.fail(gw, "expected an object");
        }
        MultiresGroup& out = model.groups[g];
        out.level = static_cast<std::uint32_t>(r.index(group, "level", gw, 1u << 16, "level"));
        if (out.level == 0) {
            r.fail(gw + "/level", "a group's level is at least 1");
        }
        out.error_px = r.number(group, "error", gw, 0.0);
        out.bounds = r.sphere(group, gw);
        for (const char* list : {"consumed", "produced"}) {
            const Json& ids = r.array(group, list, gw);
            if (ids.empty()) {
                r.fail(gw + "/" + list, "empty");
            }
            auto& target = std::string(list) == "consumed" ? out.consumed : out.produced;
            for (std::size_t i = 0; i < ids.size(); ++i) {
                target.push_back(static_cast<std::uint32_t>(
                    r.index(ids[i], gw + "/" + list + "/" + std::to_string(i), clusters.size(),
                            "cluster")));
            }
        }
    }
    std::size_t root_primitives = 0;
    object.level_bytes.clear();
    std::vector<RawCluster> raw(clusters.size());
    for (std::size_t c = 0; c < clusters.size(); ++c) {
        const std::string cw = at + "/clusters/" + std::to_string(c);
        const Json& cluster = clusters[c];
        if (!cluster.is_object()) {
            r.fail(cw, "expected an object");
        }
        MultiresCluster& out = model.clusters[c];
        out.level = static_cast<std::uint32_t>(r.index(cluster, "level", cw, 1u << 16, "level"));
        out.producer = cluster.contains("producer")
                           ? static_cast<std::int32_t>(r.index(
                                 cluster["producer"], cw + "/producer", groups.size(), "group"))
                           : -1;
        out.consumer = cluster.contains("consumer")
                           ? static_cast<std::int32_t>(r.index(
                                 cluster["consumer"], cw + "/consumer", groups.size(), "group"))
                           : -1;
        out.bounds = r.sphere(cluster, cw);
        const std::size_t mesh = r.index(cluster, "mesh", cw, meshes.size(), "mesh");
        const Json& primitives =
            r.array(meshes[mesh], "primitives", "/meshes/" + std::to_string(mesh));
        const std::size_t p =
            cluster.contains("primitive")
                ? r.index(cluster["primitive"], cw + "/primitive", primitives.size(), "primitive")
                : r.index(Json(0), cw + "/primitive", primitives.size(), "primitive");
        const std::string pw =
            "/meshes/" + std::to_string(mesh) + "/primitives/" + std::to_string(p);
        const Json& primitive = primitives[p];
        if (!primitive.is_object()) {
            r.fail(pw, "expected an object");
        }
        if (primitive.value("mode", 4) != 4) {
            r.fail(pw + "/mode", "expected TRIANGLES (4)");
        }
        if (out.consumer < 0) {
            if (mesh != base_mesh) {
                r.fail(cw + "/mesh", "a root cluster must be a primitive of the node's mesh " +
                                         std::to_string(base_mesh));
            }
            ++root_primitives;
            raw[c] = plain_primitive(r, data, primitive, pw);
            object.base_bytes += raw[c].bytes;
        } else {
            if (mesh == base_mesh || primitives.size() != 1) {
                r.fail(cw + "/mesh",
                       "a refinement cluster needs a mesh of its own with one Draco primitive");
            }
            raw[c] = draco_primitive(r, data, primitive, pw);
            if (object.level_bytes.size() <= out.level) {
                object.level_bytes.resize(out.level + 1, 0);
            }
            object.level_bytes[out.level] += raw[c].bytes;
        }
    }
    const Json& base_primitives = r.array(meshes[base_mesh], "primitives", "");
    if (!base_primitives.empty() && base_primitives[0].contains("material")) {
        const Json& materials = r.array(json, "materials", "");
        const std::size_t m =
            r.index(base_primitives[0]["material"],
                    "/meshes/" + std::to_string(base_mesh) + "/primitives/0/material",
                    materials.size(), "material");
        const Json& pbr = materials[m].value("pbrMetallicRoughness", Json::object());
        const Json color = pbr.value("baseColorFactor", Json::array({1, 1, 1, 1}));
        for (int i = 0; i < 4 && color.is_array() && color.size() == 4; ++i) {
            if (color[i].is_number()) {
                object.base_color[i] = color[i].get<double>();
            }
        }
    }
    if (root_primitives != base_primitives.size()) {
        r.fail(where + "/mesh", "the base mesh has primitives that are not root clusters");
    }

    // The DAG: links both ways agree, children first (acyclic), levels and errors monotone.
    std::vector<int> consumed_by(clusters.size(), -1), produced_by(clusters.size(), -1);
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        const std::string gw = at + "/groups/" + std::to_string(g);
        MultiresGroup& group = model.groups[g];
        for (const std::uint32_t c : group.consumed) {
            if (consumed_by[c] >= 0 || model.clusters[c].consumer != static_cast<int>(g)) {
                r.fail(gw + "/consumed", "cluster " + std::to_string(c) +
                                             " is consumed twice or its \"consumer\" is not " +
                                             std::to_string(g));
            }
            consumed_by[c] = static_cast<int>(g);
            const int producer = model.clusters[c].producer;
            if (producer >= static_cast<int>(g)) {
                r.fail(gw + "/consumed",
                       "cluster " + std::to_string(c) + " is made by group " +
                           std::to_string(producer) +
                           ", not listed before: groups must come children first");
            }
            const double below =
                producer < 0 ? model.full_resolution_error_px : model.groups[producer].error_px;
            if (group.error_px < below) {
                r.fail(gw + "/error", "error " + std::to_string(group.error_px) +
                                          " below the error " + std::to_string(below) +
                                          " of what it replaces: errors must be monotone");
            }
            if (model.clusters[c].level >= group.level) {
                r.fail(gw, "consumes cluster " + std::to_string(c) + " of level " +
                               std::to_string(model.clusters[c].level) + ", not below its own");
            }
        }
        for (const std::uint32_t c : group.produced) {
            if (produced_by[c] >= 0 || model.clusters[c].producer != static_cast<int>(g)) {
                r.fail(gw + "/produced", "cluster " + std::to_string(c) +
                                             " is produced twice or its \"producer\" is not " +
                                             std::to_string(g));
            }
            produced_by[c] = static_cast<int>(g);
            if (model.clusters[c].level != group.level) {
                r.fail(gw, "produces cluster " + std::to_string(c) + " of another level");
            }
        }
    }
    for (std::size_t c = 0; c < clusters.size(); ++c) {
        if (consumed_by[c] != model.clusters[c].consumer ||
            produced_by[c] != model.clusters[c].producer) {
            r.fail(at + "/clusters/" + std::to_string(c),
                   "\"producer\"/\"consumer\" disagree with the groups' lists");
        }
        if ((model.clusters[c].producer < 0) != (model.clusters[c].level == 0)) {
            r.fail(at + "/clusters/" + std::to_string(c),
                   "exactly the level-0 clusters have no producer");
        }
    }

    // Vertices: merged by position (bit-identical on the grid); positions must be on the grid.
    std::map<std::array<float, 3>, std::uint32_t> ids;
    const double step = model.grid_step;
    for (std::size_t c = 0; c < raw.size(); ++c) {
        for (const auto& p : raw[c].positions) {
            for (float x : p) {
                const double q = x / step;
                if (!std::isfinite(x) || q != std::nearbyint(q)) {
                    r.fail(at + "/clusters/" + std::to_string(c),
                           "a position is off the grid of step " + std::to_string(step));
                }
            }
            if (ids.emplace(p, static_cast<std::uint32_t>(ids.size())).second) {
                model.positions.push_back({p[0], p[1], p[2]});
            }
        }
    }
    for (std::size_t c = 0; c < raw.size(); ++c) {
        const std::string cw = at + "/clusters/" + std::to_string(c);
        MultiresCluster& out = model.clusters[c];
        const RawCluster& in = raw[c];
        std::vector<std::uint32_t> global(in.positions.size());
        for (std::size_t i = 0; i < global.size(); ++i) {
            global[i] = ids.at(in.positions[i]);
        }
        // local vertex lists increasing by id, as MultiresCluster promises
        std::vector<std::uint32_t> order(global);
        std::sort(order.begin(), order.end());
        order.erase(std::unique(order.begin(), order.end()), order.end());
        // note: Draco's Edgebreaker may split a vertex where the cluster is not manifold (two
        // fans touching at it) into points with one position: they are one vertex again here.
        out.vertices = order;
        const auto local = [&](std::uint32_t g) {
            return static_cast<std::uint32_t>(std::lower_bound(order.begin(), order.end(), g) -
                                              order.begin());
        };
        for (const auto& t : in.triangles) {
            for (std::uint32_t v : t) {
                if (v >= global.size()) {
                    r.fail(cw, "triangle index " + std::to_string(v) +
                                   " out of range, expected < " + std::to_string(global.size()));
                }
            }
            if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
                r.fail(cw, "a triangle repeats a vertex");
            }
            out.triangles.push_back(
                {local(global[t[0]]), local(global[t[1]]), local(global[t[2]])});
        }
        if (!in.coarse.empty()) {
            constexpr std::uint32_t kUnset = std::numeric_limits<std::uint32_t>::max();
            out.coarse_vertices.assign(order.size(), kUnset);
            for (std::size_t i = 0; i < in.coarse.size(); ++i) {
                const auto it = ids.find(in.coarse[i]);
                if (it == ids.end()) {
                    r.fail(cw, "a _COARSE_POSITION is not a vertex of the object");
                }
                std::uint32_t& target = out.coarse_vertices[local(global[i])];
                if (target != kUnset && target != it->second) {
                    r.fail(cw, "points at one position have different _COARSE_POSITIONs");
                }
                target = it->second;
            }
        }
    }
    return object;
}

ProgressiveFile read_document(std::string_view bytes,
                              const std::string& name,
                              const std::function<std::string(const std::string&)>& load_buffer) {
    const bool is_glb = bytes.size() >= 4 && le32(bytes, 0) == 0x46546C67;
    std::string_view json_text = bytes;
    std::string_view bin;
    if (is_glb) {
        if (bytes.size() < 20) {
            throw Error(ErrorCode::InvalidInput, name + ": GLB of " + std::to_string(bytes.size()) +
                                                     " bytes, shorter than its 20-byte header");
        }
        if (le32(bytes, 4) != 2) {
            throw Error(ErrorCode::Unsupported,
                        name + ": GLB version " + std::to_string(le32(bytes, 4)) + ", expected 2");
        }
        if (le32(bytes, 8) != bytes.size()) {
            throw Error(ErrorCode::InvalidInput,
                        name + ": GLB header says " + std::to_string(le32(bytes, 8)) +
                            " bytes, the file has " + std::to_string(bytes.size()) +
                            " (truncated or padded)");
        }
        const std::uint64_t json_length = le32(bytes, 12);
        if (le32(bytes, 16) != 0x4E4F534A || json_length > bytes.size() - 20) {
            throw Error(ErrorCode::InvalidInput,
                        name + ": the first GLB chunk (at byte 12) is not a JSON chunk that fits");
        }
        json_text = bytes.substr(20, json_length);
        const std::uint64_t next = 20 + json_length;
        if (next + 8 <= bytes.size()) {
            const std::uint64_t bin_length = le32(bytes, next);
            if (le32(bytes, next + 4) != 0x004E4942 || bin_length > bytes.size() - next - 8) {
                throw Error(ErrorCode::InvalidInput, name + ": the GLB chunk at byte " +
                                                         std::to_string(next) +
                                                         " is not a BIN chunk that fits");
            }
            bin = bytes.substr(next + 8, bin_length);
        }
    }
    if (json_text.size() > kMaxJsonBytes) {
        throw Error(ErrorCode::InvalidInput, name + ": JSON of " +
                                                 std::to_string(json_text.size()) +
                                                 " bytes, more than the limit of 512 MiB");
    }
    Json json;
    try {
        json = Json::parse(json_text);
    } catch (const Json::exception& e) {
        throw Error(ErrorCode::InvalidInput, name + ": not glTF JSON: " + e.what());
    }
    if (!json.is_object()) {
        throw Error(ErrorCode::InvalidInput, name + ": the JSON is not an object");
    }
    const Reader r(name, json);
    const Json& asset = r.object(json, "asset", "");
    if (asset.value("version", std::string()) != "2.0") {
        r.fail("/asset/version", "expected \"2.0\"");
    }
    ProgressiveFile file;
    file.generator = asset.value("generator", std::string());
    const Data data = load_data(r, bin, is_glb, load_buffer);
    file.total_bytes = bytes.size();
    if (!is_glb) {
        for (const std::string& b : data.buffers) {
            file.total_bytes += b.size();
        }
    }
    const Json& nodes = r.array(json, "nodes", "");
    // The root node "patient": the scene's first node; object nodes are its children.
    const Json& scenes = r.array(json, "scenes", "");
    const std::size_t scene = json.contains("scene")
                                  ? r.index(json["scene"], "/scene", scenes.size(), "scene")
                                  : r.index(Json(0), "/scene", scenes.size(), "scene");
    const Json& roots = r.array(scenes[scene], "nodes", "/scenes/" + std::to_string(scene));
    for (std::size_t i = 0; i < roots.size(); ++i) {
        const std::size_t root = r.index(roots[i], "/scenes/0/nodes", nodes.size(), "node");
        const std::array<double, 16> patient =
            r.matrix(nodes[root], "/nodes/" + std::to_string(root));
        const Json& children =
            r.array(nodes[root], "children", "/nodes/" + std::to_string(root), false);
        for (std::size_t k = 0; k < children.size(); ++k) {
            const std::size_t n = r.index(
                children[k], "/nodes/" + std::to_string(root) + "/children", nodes.size(), "node");
            const Json& node = nodes[n];
            if (node.is_object() && node.contains("extensions") && node["extensions"].is_object() &&
                node["extensions"].contains(kExtension)) {
                file.objects.push_back(read_object(r, data, n, patient));
            }
        }
    }
    if (file.objects.empty()) {
        throw Error(ErrorCode::Unsupported,
                    name + ": no node uses STRATA_progressive_mesh; not a progressive strata file");
    }
    return file;
}

}  // namespace

ProgressiveFile read_progressive_gltf(
    std::string_view bytes,
    const std::string& name,
    const std::function<std::string(const std::string& uri)>& load_buffer) {
    return read_document(bytes, name, load_buffer);
}

ProgressiveFile read_progressive_gltf(const std::filesystem::path& path) {
    const auto read_file = [](const std::filesystem::path& file, const std::string& what) {
        std::error_code ec;
        const std::uintmax_t size = std::filesystem::file_size(file, ec);
        if (ec) {
            throw Error(ErrorCode::Io,
                        file.string() + ": cannot read " + what + ": " + ec.message());
        }
        if (size > kMaxFileBytes) {
            throw Error(ErrorCode::InvalidInput, file.string() + ": " + std::to_string(size) +
                                                     " bytes, more than a glTF file of 4 GiB");
        }
        std::ifstream in(file, std::ios::binary);
        std::string bytes(size, '\0');
        if (!in.read(bytes.data(), static_cast<std::streamsize>(size))) {
            throw Error(ErrorCode::Io, file.string() + ": cannot read " + what);
        }
        return bytes;
    };
    const std::string bytes = read_file(path, "the file");
    const std::filesystem::path dir = path.parent_path();
    return read_document(bytes, path.string(), [&](const std::string& uri) {
        std::string decoded;
        for (std::size_t i = 0; i < uri.size(); ++i) {
            if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(uri[i + 1]) &&
                std::isxdigit(uri[i + 2])) {
                decoded += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
                i += 2;
            } else {
                decoded += uri[i];
            }
        }
        const std::filesystem::path relative(decoded);
        const bool escapes =
            std::any_of(relative.begin(), relative.end(),
                        [](const std::filesystem::path& part) { return part == ".."; });
        if (decoded.empty() || relative.is_absolute() || escapes ||
            decoded.find(':') != std::string::npos) {
            throw Error(ErrorCode::InvalidInput,
                        path.string() + ": buffer uri \"" + uri +
                            "\" is not a relative file name beside the file (no data: URIs, "
                            "absolute paths or ..)");
        }
        return read_file(dir / relative, "buffer \"" + uri + "\"");
    });
}

TriMesh file_cut_to_patient(const ProgressiveFileObject& object, const MultiresCut& cut) {
    TriMesh mesh = cut_mesh(object.model, cut);
    const auto& m = object.to_patient;
    for (Vec3& p : mesh.positions) {
        const Vec3 s = p;
        for (int r = 0; r < 3; ++r) {
            p[r] = m[12 + r] + m[r] * s.x + m[4 + r] * s.y + m[8 + r] * s.z;
        }
    }
    const double det = m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
                       m[8] * (m[1] * m[6] - m[5] * m[2]);
    if (det < 0.0) {
        for (auto& t : mesh.triangles) {
            std::swap(t[1], t[2]);
        }
    }
    return mesh;
}

}  // namespace strata

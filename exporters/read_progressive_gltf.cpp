// Reader of strata's progressive glTF, STRATA_progressive_mesh version 3 (schema/README.md):
// parse, check the graph, decode, each step complete before the next, so a corrupt or hostile
// file ends in Error{InvalidInput} naming what and where before any large allocation, never in a
// crash or another exception. The JSON is parsed with nlohmann_json (bounded size) and every field
// is read through JsonReader, which checks its type; the GLB container (glTF 2.0 section 4.4) by
// hand; the chunks with Draco's decoder (exporters/detail/draco_chunk.h).
//
// One file: its three steps (parse, check the graph, decode) pass the file-local JsonReader,
// Data, ParsedObject and Graph between them and share the one error rule (Error{InvalidInput}
// naming the JSON pointer); apart, each step would export these types, which no other code reads.
#include "exporters/read_progressive_gltf.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>

#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/file_names.h"
#include "exporters/detail/draco_chunk.h"
#include "exporters/progressive_format.h"

namespace strata {

namespace {

using Json = nlohmann::json;

constexpr std::uint64_t kMaxFileBytes = std::uint64_t{4} << 30;  // a GLB cannot be larger
constexpr std::size_t kMaxJsonBytes = std::size_t{512} << 20;

std::string key(std::string_view name) {
    return std::string(name);
}

// ---- parse: JSON fields, type-checked -------------------------------------------------------

/// Every JSON field is read through this: a wrong type, a missing required field or a value out
/// of range is Error{InvalidInput} "<file>: <JSON pointer>: <what>, expected <what>".
class JsonReader {
public:
    JsonReader(const std::string& name, const Json& json) : name_(name), json_(json) {}

    [[noreturn]] void fail(const std::string& where, const std::string& what) const {
        throw Error(ErrorCode::InvalidInput,
                    name_ + ": " + (where.empty() ? "/" : where) + ": " + what);
    }

    /// The member `key` of `parent` (an object), or nullptr.
    static const Json* find(const Json& parent, const std::string& key) {
        if (!parent.is_object()) {
            return nullptr;
        }
        const auto it = parent.find(key);
        return it == parent.end() ? nullptr : &*it;
    }

    const Json& required(const Json& parent,
                         const std::string& key,
                         const std::string& where,
                         const char* expected) const {
        const Json* v = find(parent, key);
        if (v == nullptr) {
            fail(where, "missing \"" + key + "\", expected " + expected);
        }
        return *v;
    }

    const Json& object(const Json& v, const std::string& where) const {
        if (!v.is_object()) {
            fail(where, std::string(type_of(v)) + ", expected an object");
        }
        return v;
    }

    const Json& object(const Json& parent, const std::string& key, const std::string& where) const {
        return object(required(parent, key, where, "an object"), where + "/" + key);
    }

    /// An array member; absent optional arrays read as empty.
    const Json& array(const Json& parent,
                      const std::string& key,
                      const std::string& where,
                      bool is_required = true) const {
        static const Json kEmpty = Json::array();
        const Json* v = find(parent, key);
        if (v == nullptr) {
            if (is_required) {
                fail(where, "missing \"" + key + "\", expected an array");
            }
            return kEmpty;
        }
        if (!v->is_array()) {
            fail(where + "/" + key, std::string(type_of(*v)) + ", expected an array");
        }
        return *v;
    }

    /// A non-negative integer below `limit`.
    std::uint64_t index(const Json& v,
                        const std::string& where,
                        std::uint64_t limit,
                        const std::string& what) const {
        if (!v.is_number_integer() ||
            (v.is_number_integer() && !v.is_number_unsigned() && v.get<std::int64_t>() < 0)) {
            fail(where,
                 std::string(type_of(v)) + ", expected a non-negative integer (" + what + ")");
        }
        const std::uint64_t x = v.get<std::uint64_t>();
        if (x >= limit) {
            fail(where, what + " " + std::to_string(x) + " out of range, expected < " +
                            std::to_string(limit));
        }
        return x;
    }

    std::uint64_t index(const Json& parent,
                        const std::string& key,
                        const std::string& where,
                        std::uint64_t limit,
                        const std::string& what) const {
        return index(required(parent, key, where, "an integer"), where + "/" + key, limit, what);
    }

    /// An optional integer index with a default.
    std::uint64_t index_or(const Json& parent,
                           const std::string& key,
                           const std::string& where,
                           std::uint64_t limit,
                           std::uint64_t fallback,
                           const std::string& what) const {
        const Json* v = find(parent, key);
        return v == nullptr ? fallback : index(*v, where + "/" + key, limit, what);
    }

    double number(const Json& v, const std::string& where, double min) const {
        if (!v.is_number()) {
            fail(where, std::string(type_of(v)) + ", expected a number");
        }
        const double x = v.get<double>();
        if (!std::isfinite(x) || x < min) {
            fail(where, "value " + std::to_string(x) +
                            ", expected a finite number >= " + std::to_string(min));
        }
        return x;
    }

    double number(const Json& parent,
                  const std::string& key,
                  const std::string& where,
                  double min) const {
        return number(required(parent, key, where, "a number"), where + "/" + key, min);
    }

    /// An optional string member ("" when absent).
    std::string string(const Json& parent, const std::string& key, const std::string& where) const {
        const Json* v = find(parent, key);
        if (v == nullptr) {
            return {};
        }
        if (!v->is_string()) {
            fail(where + "/" + key, std::string(type_of(*v)) + ", expected a string");
        }
        return v->get<std::string>();
    }

    /// An optional array of `n` finite numbers.
    template <std::size_t N>
    std::array<double, N> numbers(const Json& parent,
                                  const std::string& key,
                                  const std::string& where,
                                  const std::array<double, N>& fallback) const {
        const Json* v = find(parent, key);
        if (v == nullptr) {
            return fallback;
        }
        if (!v->is_array() || v->size() != N) {
            fail(where + "/" + key, std::string(type_of(*v)) + ", expected an array of " +
                                        std::to_string(N) + " numbers");
        }
        std::array<double, N> out{};
        for (std::size_t i = 0; i < N; ++i) {
            out[i] = number((*v)[i], where + "/" + key + "/" + std::to_string(i),
                            -std::numeric_limits<double>::max());
        }
        return out;
    }

    const Json& json() const { return json_; }
    const std::string& name() const { return name_; }

private:
    static const char* type_of(const Json& v) { return v.type_name(); }

    std::string name_;
    const Json& json_;
};

std::uint32_t le32(std::string_view bytes, std::size_t at) {
    std::uint32_t v = 0;
    for (int i = 3; i >= 0; --i) {
        v = (v << 8) | static_cast<unsigned char>(bytes[at + static_cast<std::size_t>(i)]);
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

constexpr std::array<double, 16> kIdentity{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

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

Data load_data(const JsonReader& r,
               std::string_view glb_bin,
               bool is_glb,
               const std::function<std::string(const std::string&)>& load_buffer) {
    Data data;
    const Json& buffers = r.array(r.json(), "buffers", "", false);
    for (std::size_t b = 0; b < buffers.size(); ++b) {
        const std::string where = "/buffers/" + std::to_string(b);
        const Json& buffer = r.object(buffers[b], where);
        const std::uint64_t length =
            r.index(buffer, "byteLength", where, kMaxFileBytes + 1, "byte length");
        std::string bytes;
        if (JsonReader::find(buffer, "uri") == nullptr) {
            if (!is_glb || b != 0) {
                r.fail(where, "no \"uri\": only the first buffer of a .glb may use its BIN chunk");
            }
            bytes.assign(glb_bin);
        } else {
            bytes = load_buffer(r.string(buffer, "uri", where));
        }
        if (bytes.size() < length) {
            r.fail(where, "byteLength " + std::to_string(length) + " but only " +
                              std::to_string(bytes.size()) + " bytes are there");
        }
        bytes.resize(length);
        data.buffers.push_back(std::move(bytes));
    }
    const Json& views = r.array(r.json(), "bufferViews", "", false);
    for (std::size_t v = 0; v < views.size(); ++v) {
        const std::string where = "/bufferViews/" + std::to_string(v);
        const Json& view = r.object(views[v], where);
        const std::size_t buffer = r.index(view, "buffer", where, data.buffers.size(), "buffer");
        const std::uint64_t size = data.buffers[buffer].size();
        const std::uint64_t offset =
            r.index_or(view, "byteOffset", where, size + 1, 0, "byte offset");
        const std::uint64_t length =
            r.index(view, "byteLength", where, size - offset + 1, "byte length");
        if (JsonReader::find(view, "byteStride") != nullptr) {
            r.fail(where + "/byteStride", "interleaved data is not used by this format");
        }
        data.views.push_back(
            {buffer, static_cast<std::size_t>(offset), static_cast<std::size_t>(length)});
    }
    return data;
}

/// A Draco primitive's accessor (no bufferView), checked: component type, type, count.
std::size_t draco_accessor(const JsonReader& r,
                           const Json& attributes,
                           const std::string& name,
                           const std::string& where,
                           const std::vector<int>& component_types,
                           const char* type) {
    const Json& accessors = r.array(r.json(), "accessors", "");
    const std::size_t a = r.index(attributes, name, where, accessors.size(), "accessor");
    const std::string at = "/accessors/" + std::to_string(a);
    const Json& j = r.object(accessors[a], at);
    const int component =
        static_cast<int>(r.index(j, "componentType", at, 1u << 16, "component type"));
    if (std::find(component_types.begin(), component_types.end(), component) ==
        component_types.end()) {
        r.fail(at + "/componentType", std::to_string(component) + ", not allowed for " + name);
    }
    if (r.string(j, "type", at) != type) {
        r.fail(at + "/type", "\"" + r.string(j, "type", at) + "\", expected \"" + type + "\"");
    }
    const Json* normalized = JsonReader::find(j, "normalized");
    if (normalized != nullptr && !normalized->is_boolean()) {
        r.fail(at + "/normalized", std::string(normalized->type_name()) + ", expected a boolean");
    }
    if ((normalized != nullptr && normalized->get<bool>()) ||
        JsonReader::find(j, "sparse") != nullptr || JsonReader::find(j, "bufferView") != nullptr) {
        r.fail(at, "a Draco primitive's accessor has no bufferView, is not sparse nor normalized");
    }
    return r.index(j, "count", at, std::uint64_t{1} << 32, "count");
}

/// The base mesh: one Draco primitive, as parsed (decoded later).
struct ParsedBase {
    std::string_view bytes;
    detail::DracoAttributeIds ids;
    std::size_t points = 0;   ///< the accessors' count
    std::size_t indices = 0;  ///< the indices accessor's count
    std::array<double, 4> color{1, 1, 1, 1};
};

ParsedBase parse_base(const JsonReader& r, const Data& data, std::size_t mesh) {
    const std::string where = "/meshes/" + std::to_string(mesh);
    const Json& meshes = r.array(r.json(), "meshes", "");
    const Json& primitives = r.array(r.object(meshes[mesh], where), "primitives", where);
    if (primitives.size() != 1) {
        r.fail(where + "/primitives",
               std::to_string(primitives.size()) + " primitives, expected 1 (the base mesh)");
    }
    const std::string pw = where + "/primitives/0";
    const Json& primitive = r.object(primitives[0], pw);
    if (r.index_or(primitive, "mode", pw, 7, format::kTriangles, "mode") != format::kTriangles) {
        r.fail(pw + "/mode", "expected TRIANGLES (4)");
    }
    const std::string at = pw + "/extensions/" + key(format::kDraco);
    const Json& ext =
        r.object(r.object(primitive, "extensions", pw), key(format::kDraco), pw + "/extensions");
    ParsedBase base;
    base.bytes = data.view(r.index(ext, "bufferView", at, data.views.size(), "buffer view"));
    const Json& ids = r.object(ext, "attributes", at);
    const Json& attributes = r.object(primitive, "attributes", pw);
    const auto id = [&](std::string_view name) {
        return static_cast<int>(r.index(ids, key(name), at + "/attributes", 1u << 16, "Draco id"));
    };
    // _CLUSTER is absent when the object has one root
    const bool clustered = JsonReader::find(ids, key(format::kCluster)) != nullptr ||
                           JsonReader::find(attributes, key(format::kCluster)) != nullptr;
    base.ids = {id(format::kPosition), clustered ? id(format::kCluster) : -1, -1,
                id(format::kNormal)};
    const std::string aw = pw + "/attributes";
    base.points =
        draco_accessor(r, attributes, key(format::kPosition), aw, {format::kFloat}, "VEC3");
    if (draco_accessor(r, attributes, key(format::kNormal), aw, {format::kFloat}, "VEC3") !=
            base.points ||
        (clustered && draco_accessor(r, attributes, key(format::kCluster), aw,
                                     {format::kUnsignedByte, format::kUnsignedShort},
                                     "SCALAR") != base.points)) {
        r.fail(aw, "the attributes' accessors disagree on the number of points");
    }
    base.indices = draco_accessor(r, primitive, "indices", pw,
                                  {format::kUnsignedShort, format::kUnsignedInt}, "SCALAR");
    if (JsonReader::find(primitive, "material") != nullptr) {
        const Json& materials = r.array(r.json(), "materials", "");
        const std::size_t m = r.index(primitive, "material", pw, materials.size(), "material");
        const std::string mw = "/materials/" + std::to_string(m);
        const Json& material = r.object(materials[m], mw);
        if (JsonReader::find(material, "pbrMetallicRoughness") != nullptr) {
            const Json& pbr = r.object(material, "pbrMetallicRoughness", mw);
            base.color =
                r.numbers<4>(pbr, "baseColorFactor", mw + "/pbrMetallicRoughness", base.color);
        }
    }
    return base;
}

/// One object node, parsed: everything the graph check and the decoder need.
struct ParsedObject {
    std::string where;          ///< the extension's JSON pointer
    ProgressiveFileObject out;  ///< name, label, matrices, colour; model filled by decode
    std::vector<double> errors;
    double full_resolution_error = 0.0;
    double grid_step = 0.0;
    format::DagTable table;
    std::size_t dag_offset = 0;  ///< the table's bytes in the file's `dag` view
    std::string_view chunks;     ///< the file's `chunks` view (empty when absent)
    ParsedBase base;
};

/// The top-level extension object: the version and the file's two buffer views.
struct FileViews {
    std::string_view dag;
    std::string_view chunks;
    bool has_chunks = false;
};

FileViews parse_file_extension(const JsonReader& r, const Data& data) {
    const Json* extensions = JsonReader::find(r.json(), "extensions");
    const Json* ext =
        extensions == nullptr ? nullptr : JsonReader::find(*extensions, key(format::kExtension));
    const std::string where = "/extensions/" + key(format::kExtension);
    if (ext == nullptr) {
        throw Error(ErrorCode::Unsupported,
                    r.name() + ": " + where +
                        ": absent; not a progressive file of this strata (an earlier one: "
                        "rebuild it with this strata)");
    }
    r.object(*ext, where);
    const Json* version = JsonReader::find(*ext, "version");
    if (version == nullptr || !version->is_number_integer() ||
        version->get<std::int64_t>() != format::kVersion) {
        throw Error(ErrorCode::Unsupported,
                    r.name() + ": " + where + "/version: not " + std::to_string(format::kVersion) +
                        " (a file of an earlier strata, or a newer one): rebuild it with this "
                        "strata");
    }
    FileViews views;
    views.dag = data.view(r.index(*ext, "dag", where, data.views.size(), "buffer view"));
    // note: absent when no object has a group (a glTF buffer view cannot be empty)
    if (JsonReader::find(*ext, "chunks") != nullptr) {
        views.chunks = data.view(r.index(*ext, "chunks", where, data.views.size(), "buffer view"));
        views.has_chunks = true;
    }
    return views;
}

ParsedObject parse_object(const JsonReader& r,
                          const Data& data,
                          const FileViews& views,
                          std::size_t n,
                          const std::array<double, 16>& patient,
                          const std::array<double, 16>& to_patient) {
    const Json& nodes = r.array(r.json(), "nodes", "");
    const std::string where = "/nodes/" + std::to_string(n);
    const Json& node = r.object(nodes[n], where);
    ParsedObject p;
    p.where = where + "/extensions/" + key(format::kExtension);
    const Json& ext = r.object(r.object(node, "extensions", where), key(format::kExtension),
                               where + "/extensions");
    p.out.name = r.string(node, "name", where);
    const Json* extras = JsonReader::find(node, "extras");
    if (extras != nullptr && extras->is_object()) {
        const Json* label = JsonReader::find(*extras, "label");
        if (label != nullptr) {
            p.out.label = static_cast<std::int64_t>(
                r.index(*label, where + "/extras/label", std::uint64_t{1} << 32, "label"));
        }
    }
    p.out.to_patient = multiply(to_patient, r.numbers<16>(node, "matrix", where, kIdentity));
    p.out.to_scene = multiply(patient, p.out.to_patient);
    p.full_resolution_error = r.number(ext, "fullResolutionError", p.where, 0.0);
    p.grid_step = r.number(ext, "gridStep", p.where, 0.0);
    if (!(p.grid_step > 0.0)) {
        r.fail(p.where + "/gridStep", "0, expected a positive number");
    }
    const Json& errors = r.array(ext, "errors", p.where);
    for (std::size_t g = 0; g < errors.size(); ++g) {
        p.errors.push_back(r.number(errors[g], p.where + "/errors/" + std::to_string(g), 0.0));
    }
    p.dag_offset = r.index(ext, "dag", p.where, views.dag.size(), "byte offset in the dag view");
    if (p.dag_offset % 4 != 0) {
        r.fail(p.where + "/dag", std::to_string(p.dag_offset) + ", expected a multiple of 4");
    }
    const std::string table_where = r.name() + ": " + p.where + "/dag (byte " +
                                    std::to_string(p.dag_offset) + " of the dag buffer view)";
    const std::string_view rest = views.dag.substr(p.dag_offset);
    p.out.dag_bytes = format::dag_table_length(rest, table_where);
    p.table = format::parse_dag_table(rest.substr(0, p.out.dag_bytes), errors.size(), table_where);
    if (!errors.empty() && !views.has_chunks) {
        r.fail("/extensions/" + key(format::kExtension),
               "no chunks buffer view, expected one (" + p.where + " has groups)");
    }
    p.chunks = views.chunks;
    const Json& meshes = r.array(r.json(), "meshes", "");
    p.base = parse_base(r, data, r.index(node, "mesh", where, meshes.size(), "mesh"));
    p.out.base_bytes = p.base.bytes.size();
    p.out.base_color = p.base.color;
    return p;
}

// ---- check the graph (before any decode) ----------------------------------------------------

/// What the cluster lists imply per cluster.
struct Graph {
    std::vector<std::int32_t> producer, consumer;
    std::vector<std::uint32_t> level;
    std::vector<std::uint32_t> roots;  ///< increasing
};

/// No two objects' DAG tables overlap in the `dag` view, and no two groups of the file (of one
/// object or two) share chunk bytes: each table is parsed once and each chunk decoded once (a
/// file whose 20,000 clusters shared one chunk used to decode it 20,000 times).
void check_disjoint(const JsonReader& r, const std::vector<ParsedObject>& parsed) {
    struct Range {
        std::uint64_t begin, end;
        std::size_t object, group;
    };
    std::vector<Range> tables, chunks;
    for (std::size_t o = 0; o < parsed.size(); ++o) {
        const ParsedObject& p = parsed[o];
        tables.push_back({p.dag_offset, p.dag_offset + p.out.dag_bytes, o, 0});
        for (std::size_t g = 0; g < p.table.groups.size(); ++g) {
            const format::DagGroup& group = p.table.groups[g];
            chunks.push_back(
                {group.chunk_offset, std::uint64_t{group.chunk_offset} + group.chunk_length, o, g});
        }
    }
    const auto first_overlap = [](std::vector<Range>& ranges) -> const Range* {
        std::sort(ranges.begin(), ranges.end(),
                  [](const Range& a, const Range& b) { return a.begin < b.begin; });
        for (std::size_t i = 1; i < ranges.size(); ++i) {
            if (ranges[i].begin < ranges[i - 1].end) {
                return &ranges[i];
            }
        }
        return nullptr;
    };
    if (const Range* t = first_overlap(tables)) {
        r.fail(parsed[t->object].where + "/dag",
               "its DAG table at byte " + std::to_string(t->begin) +
                   " overlaps another object's (each object has a table of its own)");
    }
    if (const Range* c = first_overlap(chunks)) {
        r.fail(parsed[c->object].where + "/dag",
               "two groups' chunks overlap at byte " + std::to_string(c->begin) +
                   " of the chunks buffer view (group " + std::to_string(c->group) +
                   "; each group has a chunk of its own)");
    }
}

Graph check_graph(const JsonReader& r, const ParsedObject& p) {
    const auto fail = [&](const std::string& what) { r.fail(p.where + "/dag", what); };
    const format::DagTable& t = p.table;
    Graph graph;
    graph.producer.assign(t.clusters, -1);
    graph.consumer.assign(t.clusters, -1);
    graph.level.assign(t.clusters, 0);
    for (std::size_t g = 0; g < t.groups.size(); ++g) {
        const format::DagGroup& group = t.groups[g];
        const std::string gs = "group " + std::to_string(g);
        for (const std::uint32_t c : group.consumed) {
            if (graph.consumer[c] >= 0) {
                fail(gs + " consumes cluster " + std::to_string(c) + ", consumed by group " +
                     std::to_string(graph.consumer[c]) + " already");
            }
            graph.consumer[c] = static_cast<std::int32_t>(g);
            // groups come children first: a cluster produced later is caught there
            const std::int32_t below = graph.producer[c];
            if (graph.level[c] >= group.level) {
                fail(gs + " (level " + std::to_string(group.level) + ") consumes cluster " +
                     std::to_string(c) + " of level " + std::to_string(graph.level[c]) +
                     ", expected a lower level");
            }
            const double under = below < 0 ? p.full_resolution_error : p.errors[std::size_t(below)];
            if (!(p.errors[g] >= under)) {
                r.fail(p.where + "/errors/" + std::to_string(g),
                       "error " + std::to_string(p.errors[g]) + " below the error " +
                           std::to_string(under) + " of what it replaces: errors must be monotone");
            }
            if (below >= 0) {
                const double fine = format::fine_error(p.errors[g], group.fine);
                const double fine_under = format::fine_error(p.errors[std::size_t(below)],
                                                             t.groups[std::size_t(below)].fine);
                if (!(fine >= fine_under)) {
                    fail(gs + "'s bound against the finest level " + std::to_string(fine) +
                         " (fine " + std::to_string(group.fine) + ") is below the bound " +
                         std::to_string(fine_under) + " of group " + std::to_string(below) +
                         ": bounds must be monotone");
                }
            }
            if (below >= 0) {
                const auto& a = group.sphere;
                const auto& b = t.groups[std::size_t(below)].sphere;
                const double d =
                    std::hypot(double(a[0]) - b[0], double(a[1]) - b[1], double(a[2]) - b[2]);
                if (d + b[3] > a[3] * (1.0 + 1e-6) + 1e-9) {
                    fail(gs + "'s sphere does not contain the sphere of group " +
                         std::to_string(below) + " below it");
                }
            }
        }
        for (const std::uint32_t c : group.produced) {
            if (graph.producer[c] >= 0 || graph.consumer[c] >= 0) {
                fail(gs + " produces cluster " + std::to_string(c) +
                     ", which is produced or consumed earlier (groups come children first)");
            }
            graph.producer[c] = static_cast<std::int32_t>(g);
            graph.level[c] = group.level;
        }
    }
    // chunk ranges: inside the view (overlaps anywhere in the file: check_disjoint)
    for (std::size_t g = 0; g < t.groups.size(); ++g) {
        const std::uint64_t begin = t.groups[g].chunk_offset;
        const std::uint64_t end = begin + t.groups[g].chunk_length;
        if (end > p.chunks.size()) {
            fail("group " + std::to_string(g) + "'s chunk [" + std::to_string(begin) + ", " +
                 std::to_string(end) + ") leaves the chunks buffer view of " +
                 std::to_string(p.chunks.size()) + " bytes");
        }
    }
    for (std::uint32_t c = 0; c < t.clusters; ++c) {
        if (graph.consumer[c] < 0) {
            graph.roots.push_back(c);
        }
    }
    if (graph.roots.size() > format::kMaxChunkClusters) {
        fail(std::to_string(graph.roots.size()) +
             " root clusters, more than the base's _CLUSTER holds");
    }
    return graph;
}

// ---- decode ---------------------------------------------------------------------------------

/// The object's vertices, merged by exact position, and the grid check.
class VertexIndex {
public:
    VertexIndex(MultiresMesh& model, double step) : model_(model), step_(step) {}

    /// The object's vertex at `p` (added when new); false when `p` is off the grid.
    bool add(const std::array<float, 3>& p, std::uint32_t& id) {
        for (const float x : p) {
            const double q = x / step_;
            if (q != std::nearbyint(q)) {
                return false;
            }
        }
        const auto [it, added] = ids_.emplace(p, static_cast<std::uint32_t>(ids_.size()));
        if (added) {
            model_.positions.push_back({p[0], p[1], p[2]});
        }
        id = it->second;
        return true;
    }

private:
    MultiresMesh& model_;
    double step_;
    std::map<std::array<float, 3>, std::uint32_t> ids_;
};

/// Splits a decoded mesh into `clusters` (triangles by `_CLUSTER`, object vertex ids); returns
/// the object id of every decoded vertex.
std::vector<std::uint32_t> add_clusters(const JsonReader& r,
                                        const std::string& where,
                                        const detail::DecodedChunk& d,
                                        const std::vector<std::uint32_t>& clusters,
                                        VertexIndex& index,
                                        MultiresMesh& model) {
    std::vector<std::uint32_t> id(d.positions.size());
    for (std::size_t v = 0; v < id.size(); ++v) {
        if (!index.add(d.positions[v], id[v])) {
            r.fail(where, "a position is off the grid of step " + std::to_string(model.grid_step));
        }
    }
    std::vector<std::vector<std::array<std::uint32_t, 3>>> triangles(clusters.size());
    for (std::size_t t = 0; t < d.triangles.size(); ++t) {
        const auto& tri = d.triangles[t];
        const std::uint32_t k = d.triangle_cluster.empty() ? 0 : d.triangle_cluster[t];
        triangles[k].push_back({id[tri[0]], id[tri[1]], id[tri[2]]});
    }
    for (std::size_t k = 0; k < clusters.size(); ++k) {
        if (triangles[k].empty()) {
            r.fail(where, "cluster " + std::to_string(clusters[k]) + " (_CLUSTER " +
                              std::to_string(k) + ") has no triangle");
        }
        MultiresCluster& out = model.clusters[clusters[k]];
        // local vertex lists increasing by id, as MultiresCluster promises
        for (const auto& t : triangles[k]) {
            out.vertices.insert(out.vertices.end(), t.begin(), t.end());
        }
        std::sort(out.vertices.begin(), out.vertices.end());
        out.vertices.erase(std::unique(out.vertices.begin(), out.vertices.end()),
                           out.vertices.end());
        for (const auto& t : triangles[k]) {
            std::array<std::uint32_t, 3> local{};
            for (int i = 0; i < 3; ++i) {
                local[i] = static_cast<std::uint32_t>(
                    std::lower_bound(out.vertices.begin(), out.vertices.end(), t[i]) -
                    out.vertices.begin());
            }
            out.triangles.push_back(local);
        }
    }
    return id;
}

/// Every vertex of `clusters` inside `sphere` (scene frame) after `to_scene`.
bool contains_vertices(const MultiresMesh& model,
                       const std::vector<std::uint32_t>& clusters,
                       const std::array<float, 4>& sphere,
                       const std::array<double, 16>& m) {
    const double slack = double(sphere[3]) * 1e-6 + 1e-9;
    for (const std::uint32_t c : clusters) {
        for (const std::uint32_t v : model.clusters[c].vertices) {
            const Vec3 p = model.positions[v];
            double d2 = 0.0;
            for (int k = 0; k < 3; ++k) {
                const double s =
                    m[12 + k] + m[k] * p.x + m[4 + k] * p.y + m[8 + k] * p.z - sphere[k];
                d2 += s * s;
            }
            if (std::sqrt(d2) > double(sphere[3]) + slack) {
                return false;
            }
        }
    }
    return true;
}

/// The decoded model: base, then each group's chunk, each decoded once.
ProgressiveFileObject decode_object(const JsonReader& r, ParsedObject& p, const Graph& graph) {
    ProgressiveFileObject object = std::move(p.out);
    MultiresMesh& model = object.model;
    model.grid_step = p.grid_step;
    model.full_resolution_error_px = p.full_resolution_error;
    model.clusters.resize(p.table.clusters);
    for (std::uint32_t c = 0; c < p.table.clusters; ++c) {
        model.clusters[c].producer = graph.producer[c];
        model.clusters[c].consumer = graph.consumer[c];
        model.clusters[c].level = graph.level[c];
    }
    VertexIndex index(model, p.grid_step);
    const auto decode = [&](std::string_view bytes, const detail::DracoAttributeIds& ids,
                            std::size_t clusters, const std::string& where) {
        try {
            return detail::decode_draco_chunk(bytes, ids, static_cast<std::uint32_t>(clusters),
                                              std::numeric_limits<std::size_t>::max());
        } catch (const Error& e) {
            r.fail(where, e.what());
        }
    };
    const std::string base_where = p.where + " (base mesh)";
    if (p.base.ids.cluster < 0 && graph.roots.size() != 1) {
        r.fail(base_where, std::to_string(graph.roots.size()) +
                               " root clusters but no _CLUSTER attribute, expected one root");
    }
    const detail::DecodedChunk base =
        decode(p.base.bytes, p.base.ids, graph.roots.size(), base_where);
    if (base.points != p.base.points || 3 * base.triangles.size() != p.base.indices) {
        r.fail(base_where, "Draco decoded " + std::to_string(base.points) + " points and " +
                               std::to_string(base.triangles.size()) +
                               " triangles, the accessors say " + std::to_string(p.base.points) +
                               " and " + std::to_string(p.base.indices / 3));
    }
    add_clusters(r, base_where, base, graph.roots, index, model);
    for (std::size_t g = 0; g < p.table.groups.size(); ++g) {
        const format::DagGroup& group = p.table.groups[g];
        const std::string where = p.where + " (group " + std::to_string(g) + "'s chunk)";
        const detail::DecodedChunk d =
            decode(p.chunks.substr(group.chunk_offset, group.chunk_length),
                   {int(format::kChunkPositionId), int(format::kChunkClusterId),
                    int(format::kChunkSlotId), -1},
                   group.consumed.size(), where);
        const std::vector<std::uint32_t> id =
            add_clusters(r, where, d, group.consumed, index, model);
        std::vector<std::uint32_t> coarse;
        try {
            coarse = detail::resolve_slots(d.positions, d.triangles, d.slots);
        } catch (const Error& e) {
            r.fail(where, e.what());
        }
        std::map<std::uint32_t, std::uint32_t> coarse_of;
        for (std::size_t v = 0; v < coarse.size(); ++v) {
            coarse_of[id[v]] = id[coarse[v]];
        }
        for (const std::uint32_t c : group.consumed) {
            MultiresCluster& cluster = model.clusters[c];
            for (const std::uint32_t v : cluster.vertices) {
                cluster.coarse_vertices.push_back(coarse_of.at(v));
            }
        }
        MultiresGroup out;
        out.level = group.level;
        out.consumed = group.consumed;
        out.produced = group.produced;
        out.error_px = p.errors[g];
        out.fine_error_px = format::fine_error(p.errors[g], group.fine);
        out.bounds = {{group.sphere[0], group.sphere[1], group.sphere[2]}, group.sphere[3]};
        model.groups.push_back(std::move(out));
        object.level_bytes.resize(std::max<std::size_t>(object.level_bytes.size(), group.level), 0);
        object.level_bytes[group.level - 1] += group.chunk_length;
    }
    // coarse vertices are vertices of the produced clusters; spheres hold their clusters
    for (std::size_t g = 0; g < model.groups.size(); ++g) {
        const MultiresGroup& group = model.groups[g];
        std::vector<std::uint32_t> kept;
        for (const std::uint32_t c : group.produced) {
            kept.insert(kept.end(), model.clusters[c].vertices.begin(),
                        model.clusters[c].vertices.end());
        }
        std::sort(kept.begin(), kept.end());
        for (const std::uint32_t c : group.consumed) {
            for (const std::uint32_t v : model.clusters[c].coarse_vertices) {
                if (!std::binary_search(kept.begin(), kept.end(), v)) {
                    r.fail(p.where + " (group " + std::to_string(g) + ")",
                           "a slot leads to a vertex that is not in the group's produced clusters");
                }
            }
        }
        if (!contains_vertices(model, group.consumed, p.table.groups[g].sphere, object.to_scene) ||
            !contains_vertices(model, group.produced, p.table.groups[g].sphere, object.to_scene)) {
            r.fail(p.where + "/dag", "group " + std::to_string(g) +
                                         "'s sphere does not contain its clusters' vertices");
        }
    }
    return object;
}

/// The JSON text and the BIN chunk (empty when there is none) of a GLB container (glTF 2.0
/// section 4.4); all of `bytes` as JSON when it is not one.
std::pair<std::string_view, std::string_view> glb_chunks(std::string_view bytes,
                                                         const std::string& name,
                                                         bool is_glb) {
    std::string_view json_text = bytes;
    std::string_view bin;
    if (!is_glb) {
        return {json_text, bin};
    }
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
    if (le32(bytes, 16) != format::kGlbJsonChunk || json_length > bytes.size() - 20) {
        throw Error(ErrorCode::InvalidInput,
                    name + ": the first GLB chunk (at byte 12) is not a JSON chunk that fits");
    }
    json_text = bytes.substr(20, json_length);
    const std::uint64_t next = 20 + json_length;
    if (next + 8 <= bytes.size()) {
        const std::uint64_t bin_length = le32(bytes, next);
        if (le32(bytes, next + 4) != format::kGlbBinChunk || bin_length > bytes.size() - next - 8) {
            throw Error(ErrorCode::InvalidInput, name + ": the GLB chunk at byte " +
                                                     std::to_string(next) +
                                                     " is not a BIN chunk that fits");
        }
        bin = bytes.substr(next + 8, bin_length);
    }
    return {json_text, bin};
}

/// Parses the objects of the scene: nodes with the extension below a root, each with the
/// matrices above it.
std::vector<ParsedObject> parse_objects(const JsonReader& r, const Json& json, const Data& data) {
    std::vector<ParsedObject> parsed;
    const Json& nodes = r.array(json, "nodes", "");
    const Json& scenes = r.array(json, "scenes", "");
    const std::size_t scene = r.index_or(json, "scene", "", scenes.size(), 0, "scene");
    if (scenes.empty()) {
        r.fail("/scenes", "no scene");
    }
    const std::string sw = "/scenes/" + std::to_string(scene);
    const Json& roots = r.array(r.object(scenes[scene], sw), "nodes", sw);
    const FileViews views = parse_file_extension(r, data);
    // objects: nodes with the extension below a root, the matrices between them multiplied
    // (strata writes root "patient" -> "storage" -> objects); each node visited once
    std::vector<char> visited(nodes.size(), 0);
    for (std::size_t i = 0; i < roots.size(); ++i) {
        const std::size_t root =
            r.index(roots[i], sw + "/nodes/" + std::to_string(i), nodes.size(), "node");
        const std::string rw = "/nodes/" + std::to_string(root);
        const std::array<double, 16> patient =
            r.numbers<16>(r.object(nodes[root], rw), "matrix", rw, kIdentity);
        std::vector<std::pair<std::size_t, std::array<double, 16>>> stack{{root, kIdentity}};
        while (!stack.empty()) {
            const auto [n, above] = stack.back();
            stack.pop_back();
            const std::string nw = "/nodes/" + std::to_string(n);
            if (visited[n] != 0) {
                r.fail(nw, "reached twice, expected a tree of nodes (one parent each)");
            }
            visited[n] = 1;
            const Json& node = r.object(nodes[n], nw);
            const Json* extensions = JsonReader::find(node, "extensions");
            if (n != root && extensions != nullptr &&
                JsonReader::find(*extensions, key(format::kExtension)) != nullptr) {
                parsed.push_back(parse_object(r, data, views, n, patient, above));
                continue;
            }
            const std::array<double, 16> here =
                n == root ? kIdentity
                          : multiply(above, r.numbers<16>(node, "matrix", nw, kIdentity));
            const Json& children = r.array(node, "children", nw, false);
            for (std::size_t k = children.size(); k-- > 0;) {
                stack.push_back({r.index(children[k], nw + "/children/" + std::to_string(k),
                                         nodes.size(), "node"),
                                 here});
            }
        }
    }
    return parsed;
}

ProgressiveFile read_document(std::string_view bytes,
                              const std::string& name,
                              const std::function<std::string(const std::string&)>& load_buffer) {
    const bool is_glb = bytes.size() >= 4 && le32(bytes, 0) == format::kGlbMagic;
    const auto [json_text, bin] = glb_chunks(bytes, name, is_glb);
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
    const JsonReader r(name, json);
    r.object(json, "");
    const Json& asset = r.object(json, "asset", "");
    if (r.string(asset, "version", "/asset") != "2.0") {
        r.fail("/asset/version", "expected \"2.0\"");
    }
    ProgressiveFile file;
    file.generator = r.string(asset, "generator", "/asset");
    const Data data = load_data(r, bin, is_glb, load_buffer);
    file.total_bytes = bytes.size();
    if (!is_glb) {
        for (const std::string& b : data.buffers) {
            file.total_bytes += b.size();
        }
    }
    // parse every object, then check every graph, then decode
    std::vector<ParsedObject> parsed = parse_objects(r, json, data);
    if (parsed.empty()) {
        throw Error(ErrorCode::Unsupported,
                    name + ": no node uses STRATA_progressive_mesh; not a progressive strata file");
    }
    check_disjoint(r, parsed);
    std::vector<Graph> graphs;
    for (const ParsedObject& p : parsed) {
        graphs.push_back(check_graph(r, p));
    }
    for (std::size_t i = 0; i < parsed.size(); ++i) {
        file.objects.push_back(decode_object(r, parsed[i], graphs[i]));
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

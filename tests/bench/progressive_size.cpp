// Size of the progressive glTF against single-rate Draco and gltfpack (issue 7), side by side in
// one run, plus the cluster-size sweep of DESIGN.md section 4.
//
//   progressive_size [--case SPEC]... [--sweep-case SPEC]... [--sweep 256,512,1024,2048,4096]
//                    [--cluster-triangles N] [--keep-fraction F] [--gltfpack EXE] [--work DIR]
//
// --keep-fraction: MultiresOptions::keep_fraction of every model (default its default), to
// compare ladders: the main table then shows the uniform-error cuts' triangles and the chunk
// bytes a viewer has loaded to show them.
// SPEC: `phantom:NAME` (make_phantom) or `stack:PATH` (read_slice_stack); every non-zero label is
// an object, as in `strata build`. A spec given both as --case and --sweep-case is reconstructed
// once.
//
// For each --case: `reconstruct` (default options, --cluster-triangles) and, like `strata build`,
// write_progressive_gltf of every object on a grid into WORK/model.glb (ProgressiveOptions
// defaults: Draco level 7, 10-bit normals). Its bytes: total (the .glb: what a full download,
// hence full resolution, needs), base (JSON + the root clusters, uncompressed: the first frame),
// and the Draco chunks per level, read back from the file's JSON (bufferView lengths).
// Peers, on the same full-resolution surface (the level-0 cut of each model: the same triangles
// and grid positions as the level-0 clusters):
//   Draco   single-rate: each object's level-0 mesh as one Draco mesh, encoded exactly as our
//           chunks are (draco::ExpertEncoder, Edgebreaker, speed 10 - 7 = 3, POSITION predicted
//           by constrained multi-parallelogram with explicit quantization on the model's grid in
//           the same storage frame: x, y px, z in slices; origin = the mesh's lowest grid point,
//           range = step * (2^bits - 1), bits the fewest that span the mesh; NORMAL the
//           area-weighted full-resolution normals (our level 0s), 10-bit octahedral). Lossless on
//           the grid, like ours. Reported: raw Draco bytes (POSITION + NORMAL, and POSITION only)
//           and a minimal .glb wrapping the POSITION + NORMAL meshes (KHR_draco_mesh_compression;
//           node matrices, one material per object).
//   gltfpack (npm `gltfpack`, meshoptimizer's packer as WASM) on WORK/scene.glb, the plain
//           full-resolution scene `strata build` writes (exporters/scene_gltf.h: float LPS mm,
//           float normals, 32/16-bit indices): `-cc` (meshopt compression, higher ratio; default
//           14-bit positions, 8-bit normals) and `-cc -vp B`, B the bits that give our grid's
//           in-plane resolution: gltfpack quantizes all positions of a scene on one grid of
//           (largest extent) / (2^B - 1), so B = ceil(log2(extent_mm / (px_mm / 16) + 1)),
//           capped at gltfpack's 16. Not lossless on our grid (its origin is not ours), but at
//           least as fine.
// For each --sweep-case and cluster size: the models rebuilt from the same surfaces with
// MultiresOptions::cluster_triangles = size (build_multires_mesh, as reconstruct does), written
// the same way; total, base, level-0 chunks, chunk count, mean chunk, and the clustering cost:
// the level-0 clusters encoded as separate POSITION + NORMAL Draco meshes over the single-rate
// POSITION + NORMAL bytes.
//
// Breakdown of the chunks (at the --case cluster size): every chunk is re-encoded with
// POSITION only, POSITION + NORMAL, and all three attributes (the last must equal the file's
// chunk bytes, checked), which splits the Draco bytes into positions (with connectivity),
// normals and _COARSE_POSITION; the fixed cost of a chunk is that of a one-triangle chunk.
//
// Prints the tables on stdout; progress on stderr. Exit 0, 1 on failures, 2 on bad arguments.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <map>
#include <optional>
#include <spawn.h>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>
#include <zlib.h>

#include <draco/compression/decode.h>
#include <draco/mesh/mesh.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/report.h"
#include "exporters/detail/draco_chunk.h"
#include "exporters/detail/gltf_common.h"
#include "exporters/progressive_gltf.h"
#include "exporters/scene_gltf.h"
#include "input/read_slice_stack.h"
#include "input/slice_stack.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "simplify/multires_dag.h"
#include "simplify/slice_error.h"

extern char** environ;

namespace strata {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitBadInput = 2;
constexpr int kGridFraction = 16;     // our grid: 1/16 px in plane (quantize stage)
constexpr int kGltfpackMaxBits = 16;  // gltfpack -vp accepts 1..16
constexpr double kInfinity = std::numeric_limits<double>::infinity();

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Arguments {
    std::vector<std::string> cases;
    std::vector<std::string> sweep_cases;
    std::vector<std::size_t> sweep_sizes{256, 512, 1024, 2048, 4096};
    std::size_t cluster_triangles = MultiresOptions{}.cluster_triangles;
    double keep_fraction = MultiresOptions{}.keep_fraction;
    std::string gltfpack;
    std::filesystem::path work;
};

std::string usage() {
    return "usage: progressive_size [--case phantom:NAME | --case stack:PATH]...\n"
           "                        [--sweep-case SPEC]... [--sweep 256,512,1024,2048,4096]\n"
           "                        [--cluster-triangles N] [--keep-fraction F] [--gltfpack EXE]\n"
           "                        [--work DIR]\n";
}

std::size_t parse_count(const std::string& text, const std::string& what) {
    std::size_t used = 0;
    unsigned long value = 0;
    try {
        value = std::stoul(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != text.size() || value == 0) {
        throw Error{ErrorCode::InvalidInput,
                    what + ": '" + text + "', expected a positive integer"};
    }
    return value;
}

Arguments parse_arguments(int argc, char** argv) {
    Arguments args;
    auto value = [&](int& i) -> std::string {
        if (i + 1 >= argc) {
            throw Error{ErrorCode::InvalidInput, std::string(argv[i]) + " needs a value"};
        }
        return argv[++i];
    };
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        if (arg == "--case") {
            args.cases.push_back(value(i));
        } else if (arg == "--sweep-case") {
            args.sweep_cases.push_back(value(i));
        } else if (arg == "--sweep") {
            args.sweep_sizes.clear();
            std::stringstream list(value(i));
            for (std::string item; std::getline(list, item, ',');) {
                args.sweep_sizes.push_back(parse_count(item, "--sweep"));
            }
        } else if (arg == "--cluster-triangles") {
            args.cluster_triangles = parse_count(value(i), "--cluster-triangles");
        } else if (arg == "--keep-fraction") {
            const std::string text = value(i);
            std::size_t used = 0;
            try {
                args.keep_fraction = std::stod(text, &used);
            } catch (const std::exception&) {
                used = 0;
            }
            if (used == 0 || used != text.size() || !(args.keep_fraction > 0.0) ||
                !(args.keep_fraction < 1.0)) {
                throw Error{ErrorCode::InvalidInput,
                            "--keep-fraction: '" + text + "', expected a number in (0, 1)"};
            }
        } else if (arg == "--gltfpack") {
            args.gltfpack = value(i);
        } else if (arg == "--work") {
            args.work = value(i);
        } else if (arg == "-h" || arg == "--help") {
            std::cout << usage();
            std::exit(kExitOk);
        } else {
            throw Error{ErrorCode::InvalidInput, "unknown argument '" + arg + "'\n" + usage()};
        }
    }
    if (args.cases.empty() && args.sweep_cases.empty()) {
        args.cases.push_back("phantom:torus");
    }
    return args;
}

double seconds_since(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string read_bytes(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw Error{ErrorCode::Io, path.string() + ": cannot read"};
    }
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), std::streamsize(bytes.size()));
    if (!out) {
        throw Error{ErrorCode::Io, path.string() + ": cannot write"};
    }
}

/// zlib (deflate) at level 9: what gzip / HTTP compression would send, within a few bytes.
std::size_t deflated_size(const std::string& bytes) {
    uLongf size = compressBound(uLong(bytes.size()));
    std::string out(size, '\0');
    if (compress2(reinterpret_cast<Bytef*>(out.data()), &size,
                  reinterpret_cast<const Bytef*>(bytes.data()), uLong(bytes.size()), 9) != Z_OK) {
        throw Error{ErrorCode::Internal, "zlib compress2 failed"};
    }
    return size;
}

// ---------------------------------------------------------------------------------------------
// Cases

struct Case {
    std::string spec;
    std::string name;
    SliceStack stack;
};

Case load_case(const std::string& spec) {
    const std::size_t colon = spec.find(':');
    if (colon == std::string::npos) {
        throw Error{ErrorCode::InvalidInput,
                    "case '" + spec + "': expected phantom:NAME or stack:PATH"};
    }
    const std::string kind = spec.substr(0, colon);
    const std::string what = spec.substr(colon + 1);
    Case c;
    c.spec = spec;
    if (kind == "phantom") {
        c.stack = make_phantom(what).stack;
        c.name = what;
    } else if (kind == "stack") {
        Report report;
        c.stack = read_slice_stack(what, ReadOptions{}, report);
        std::filesystem::path path(what);
        std::string name = path.filename().string();
        if (name.empty() || name == "slices") {  // a folder: name it after its parent
            name = path.parent_path().filename().string();
        }
        c.name = name.substr(0, name.find('.'));
    } else {
        throw Error{ErrorCode::InvalidInput,
                    "case '" + spec + "': unknown kind '" + kind + "', expected phantom or stack"};
    }
    complete_label_table(c.stack);
    return c;
}

/// The writer's storage frame: x negated when the slice frame mirrors (exporters/
/// progressive_gltf.cpp, storage_frame); triangles are then reversed.
bool frame_mirrors(const SliceFrame& frame) {
    const auto& l = frame.linear;
    const double det = l[0] * (l[4] * l[8] - l[5] * l[7]) - l[1] * (l[3] * l[8] - l[5] * l[6]) +
                       l[2] * (l[3] * l[7] - l[4] * l[6]);
    return det < 0.0;
}

/// The node matrix of an object (storage frame -> LPS mm, column-major), as the writer makes it.
std::array<double, 16> storage_matrix(const SliceFrame& frame) {
    const double flip = frame_mirrors(frame) ? -1.0 : 1.0;
    const std::array<double, 3> scale{flip, 1.0, frame.slice_spacing_px};
    std::array<double, 16> m{};
    for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) {
            m[4 * c + r] = frame.linear[3 * r + c] * scale[c];
        }
    }
    m[12] = frame.origin[0];
    m[13] = frame.origin[1];
    m[14] = frame.origin[2];
    m[15] = 1.0;
    return m;
}

// ---------------------------------------------------------------------------------------------
// Draco, encoded as the writer encodes its chunks

using Float3 = std::array<float, 3>;

/// One object's model in the writer's storage frame: grid points and normals.
struct StorageModel {
    const MultiresMesh* model = nullptr;
    std::vector<Float3> points;   ///< per model vertex, on the grid (x, y px; z in slices)
    std::vector<Float3> normals;  ///< per model vertex, unit, area-weighted over level 0
    /// per cluster, the writer's NORMAL (progressive_cluster_normals)
    std::vector<std::vector<Float3>> cluster_normals;
    bool reverse = false;  ///< triangles reversed (mirroring frame)
    double step = 0.0;
};

StorageModel storage_model(const MultiresMesh& model, const SliceFrame& frame) {
    StorageModel s;
    s.model = &model;
    s.reverse = frame_mirrors(frame);
    s.step = model.grid_step;
    const double flip = s.reverse ? -1.0 : 1.0;
    const double d = frame.slice_spacing_px;
    s.points.resize(model.positions.size());
    for (std::size_t v = 0; v < model.positions.size(); ++v) {
        const Vec3& p = model.positions[v];
        const double z = std::nearbyint(p.z / d / s.step) * s.step;
        s.points[v] = {detail::to_float(flip * p.x), detail::to_float(p.y), detail::to_float(z)};
    }
    s.cluster_normals = progressive_cluster_normals(model, s.points, s.reverse);
    // level 0: the full-resolution surface's normals, each vertex's in every level-0 cluster
    s.normals.assign(s.points.size(), Float3{0.0f, 0.0f, 1.0f});
    for (std::size_t c = 0; c < model.clusters.size(); ++c) {
        if (model.clusters[c].level == 0) {
            for (std::size_t i = 0; i < model.clusters[c].vertices.size(); ++i) {
                s.normals[model.clusters[c].vertices[i]] = s.cluster_normals[c][i];
            }
        }
    }
    return s;
}

/// A patch to encode: model vertex ids, optional collapse targets, and triangles over the ids'
/// indices, in the model's orientation (reversed here when the frame mirrors).
struct Patch {
    std::vector<std::uint32_t> vertices;
    std::vector<Float3> normals;        ///< per entry of `vertices`
    std::vector<std::uint32_t> coarse;  ///< empty: no _COARSE_POSITION
    std::vector<std::array<std::uint32_t, 3>> triangles;
};

/// Which attributes a re-encoding carries: POSITION; + NORMAL; + _COARSE_POSITION (as written).
enum class Attributes { Position, PositionNormal, All };

using Encoded = detail::DracoChunkBytes;

/// Draco bytes of `patch` with `attributes`, encoded by the writer's own chunk encoder
/// (detail::encode_draco_chunk) at the writer's default settings.
Encoded encode_patch(const StorageModel& s, const Patch& patch, Attributes attributes) {
    const ProgressiveOptions options;
    detail::DracoChunkInput input;
    input.step = s.step;
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) {
        input.positions.push_back(s.points[patch.vertices[i]]);
        if (attributes != Attributes::Position) {
            input.normals.push_back(patch.normals[i]);
        }
        if (attributes == Attributes::All && !patch.coarse.empty()) {
            input.coarse.push_back(s.points[patch.coarse[i]]);
        }
    }
    for (const auto& t : patch.triangles) {
        input.triangles.push_back({t[0], s.reverse ? t[2] : t[1], s.reverse ? t[1] : t[2]});
    }
    return detail::encode_draco_chunk(input, options.compression_level, options.normal_bits);
}

Patch cluster_patch(const StorageModel& s, std::uint32_t c) {
    const MultiresCluster& cluster = s.model->clusters[c];
    return {cluster.vertices, s.cluster_normals[c], cluster.coarse_vertices, cluster.triangles};
}

/// The level-0 surface of a model as one patch (the full-resolution mesh: the level-0 cut).
Patch full_patch(const StorageModel& s) {
    const MultiresMesh& model = *s.model;
    const TriMesh full = cut_mesh(model, select_cut_at_level(model, 0));
    // cut_mesh keeps model positions; find each vertex's model id by position (distinct vertices
    // never share a grid point)
    std::map<std::array<double, 3>, std::uint32_t> id;
    for (std::uint32_t v = 0; v < model.positions.size(); ++v) {
        const Vec3& p = model.positions[v];
        id.emplace(std::array{p.x, p.y, p.z}, v);
    }
    Patch patch;
    for (const Vec3& p : full.positions) {
        const auto it = id.find({p.x, p.y, p.z});
        if (it == id.end()) {
            throw Error{ErrorCode::Internal, "level-0 cut has a position the model lacks"};
        }
        patch.vertices.push_back(it->second);
        patch.normals.push_back(s.normals[it->second]);
    }
    patch.triangles = full.triangles;
    return patch;
}

/// Decoded point count and position bounds of a Draco mesh (for the .glb wrapper's accessors),
/// checking that every decoded position is a point of `s` (lossless on the grid).
struct DecodedInfo {
    std::uint32_t points = 0, faces = 0;
    Float3 min{}, max{};
};

DecodedInfo decode_info(const StorageModel& s, const Patch& patch, const Encoded& e) {
    draco::DecoderBuffer in;
    in.Init(e.bytes.data(), e.bytes.size());
    draco::Decoder decoder;
    auto decoded_or = decoder.DecodeMeshFromBuffer(&in);
    if (!decoded_or.ok()) {
        throw Error{ErrorCode::Internal,
                    std::string("Draco cannot decode: ") + decoded_or.status().error_msg()};
    }
    const std::unique_ptr<draco::Mesh> mesh = std::move(decoded_or).value();
    const draco::PointAttribute* dp = mesh->GetAttributeByUniqueId(e.position_id);
    if (dp == nullptr || mesh->num_faces() != patch.triangles.size()) {
        throw Error{ErrorCode::Internal, "Draco round trip lost positions or faces"};
    }
    std::vector<Float3> expected;
    for (std::uint32_t v : patch.vertices) {
        expected.push_back(s.points[v]);
    }
    std::sort(expected.begin(), expected.end());
    DecodedInfo info;
    info.points = mesh->num_points();
    info.faces = mesh->num_faces();
    info.min.fill(std::numeric_limits<float>::infinity());
    info.max.fill(-std::numeric_limits<float>::infinity());
    for (std::uint32_t i = 0; i < info.points; ++i) {
        Float3 p{};
        dp->ConvertValue<float, 3>(dp->mapped_index(draco::PointIndex(i)), p.data());
        if (!std::binary_search(expected.begin(), expected.end(), p)) {
            throw Error{ErrorCode::Internal, "single-rate Draco moved a position off the grid"};
        }
        for (int k = 0; k < 3; ++k) {
            info.min[k] = std::min(info.min[k], p[k]);
            info.max[k] = std::max(info.max[k], p[k]);
        }
    }
    return info;
}

/// A minimal .glb of single-rate Draco meshes (POSITION + NORMAL): root node "patient" with the
/// writer's matrix, one node per object with its storage matrix, mesh, material.
std::string draco_glb(const std::vector<std::string>& names,
                      const std::vector<std::array<double, 3>>& colours,
                      const std::vector<Encoded>& meshes,
                      const std::vector<DecodedInfo>& infos,
                      const std::array<double, 16>& matrix) {
    Json json;
    json["asset"] = {{"generator", "strata progressive_size"}, {"version", "2.0"}};
    json["extensionsUsed"] = {"KHR_draco_mesh_compression"};
    json["extensionsRequired"] = {"KHR_draco_mesh_compression"};
    json["scene"] = 0;
    json["scenes"] = Json::array({Json{{"nodes", Json::array({0})}}});
    json["nodes"] = Json::array();
    json["nodes"].push_back(
        {{"name", "patient"}, {"matrix", detail::kPatientToGltf}, {"children", Json::array()}});
    json["meshes"] = Json::array();
    json["materials"] = Json::array();
    json["accessors"] = Json::array();
    json["bufferViews"] = Json::array();
    std::string bin;
    for (std::size_t i = 0; i < meshes.size(); ++i) {
        const Encoded& e = meshes[i];
        const DecodedInfo& info = infos[i];
        const std::size_t a = json["accessors"].size();
        json["accessors"].push_back({{"componentType", 5126},
                                     {"count", info.points},
                                     {"type", "VEC3"},
                                     {"min", info.min},
                                     {"max", info.max}});
        json["accessors"].push_back(
            {{"componentType", 5126}, {"count", info.points}, {"type", "VEC3"}});
        json["accessors"].push_back({{"componentType", info.points <= 65535 ? 5123 : 5125},
                                     {"count", 3 * std::size_t{info.faces}},
                                     {"type", "SCALAR"}});
        json["bufferViews"].push_back(
            {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", e.bytes.size()}});
        bin += e.bytes;
        bin.resize((bin.size() + 3) / 4 * 4, '\0');
        json["materials"].push_back(
            {{"pbrMetallicRoughness",
              {{"baseColorFactor",
                {detail::srgb_to_linear(colours[i][0]), detail::srgb_to_linear(colours[i][1]),
                 detail::srgb_to_linear(colours[i][2]), 1.0}},
               {"metallicFactor", 0.0},
               {"roughnessFactor", 0.6}}}});
        Json primitive;
        primitive["attributes"] = {{"POSITION", a}, {"NORMAL", a + 1}};
        primitive["indices"] = a + 2;
        primitive["material"] = i;
        primitive["mode"] = 4;
        primitive["extensions"]["KHR_draco_mesh_compression"] = {
            {"bufferView", json["bufferViews"].size() - 1},
            {"attributes", {{"POSITION", e.position_id}, {"NORMAL", e.normal_id}}}};
        json["meshes"].push_back(
            {{"name", names[i]}, {"primitives", Json::array({std::move(primitive)})}});
        json["nodes"].push_back({{"name", names[i]}, {"mesh", i}, {"matrix", matrix}});
        json["nodes"][0]["children"].push_back(json["nodes"].size() - 1);
    }
    json["buffers"] = {{{"byteLength", bin.size()}}};
    std::string text = json.dump();
    text.resize((text.size() + 3) / 4 * 4, ' ');
    std::string out;
    const auto u32 = [&](std::size_t v) {
        for (int i = 0; i < 4; ++i) {
            out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
        }
    };
    u32(0x46546C67);
    u32(2);
    u32(12 + 8 + text.size() + 8 + bin.size());
    u32(text.size());
    u32(0x4E4F534A);
    out += text;
    u32(bin.size());
    u32(0x004E4942);
    out += bin;
    return out;
}

// ---------------------------------------------------------------------------------------------
// Our file

struct OursBytes {
    std::size_t total = 0, base = 0, json = 0, chunks = 0, chunk_count = 0;
    std::size_t level0_chunks = 0, level0_chunk_count = 0;
    std::size_t deflated = 0;
    std::uint32_t levels = 0;
    std::size_t root_triangles = 0;
    std::size_t clusters = 0;
    std::vector<std::size_t> level_bytes;      ///< Draco chunk bytes per level
    std::vector<std::size_t> level_clusters;   ///< clusters per level (roots included)
    std::vector<std::size_t> level_triangles;  ///< triangles of every cluster of a level
    /// Triangles of the uniform-error cuts (select_cut_by_error, all objects) at kCutErrorsPx:
    /// what a viewer draws for a given error, so fewer levels must not cost triangles here.
    std::vector<std::size_t> cut_triangles;
    /// Chunk bytes a viewer has loaded once it shows those cuts: the consumed clusters of every
    /// refined group (the base not counted).
    std::vector<std::size_t> cut_bytes;
};

constexpr std::array<double, 5> kCutErrorsPx{1.0, 2.0, 4.0, 8.0, 16.0};

/// Writes the progressive .glb of `models` (as `strata build` does) and reads its bytes back.
OursBytes write_ours(const std::filesystem::path& path,
                     const Case& c,
                     const std::vector<const MultiresMesh*>& models,
                     const std::vector<std::uint16_t>& labels,
                     const SliceFrame& frame) {
    std::vector<ProgressiveObject> objects;
    for (std::size_t i = 0; i < models.size(); ++i) {
        ProgressiveObject o;
        const auto label = std::find_if(c.stack.label_table.begin(), c.stack.label_table.end(),
                                        [&](const LabelInfo& l) { return l.value == labels[i]; });
        o.label = labels[i];
        if (label != c.stack.label_table.end()) {
            o.name = label->name;
            o.srgb = {label->color[0] / 255.0, label->color[1] / 255.0, label->color[2] / 255.0};
        }
        o.model = models[i];
        objects.push_back(o);
    }
    SceneInfo info;
    info.source = c.stack.source;
    const Vec3 spacing = c.stack.spacing_mm();
    info.spacing_mm = {spacing.x, spacing.y, spacing.z};
    info.generator = "strata 0.1.0";
    const ProgressiveStats stats = write_progressive_gltf(path, objects, frame, info);
    const std::string bytes = read_bytes(path);
    if (bytes.size() != stats.total_bytes) {
        throw Error{ErrorCode::Internal, path.string() + ": file size differs from the stats"};
    }
    OursBytes out;
    out.total = stats.total_bytes;
    out.base = stats.base_bytes;
    out.chunks = stats.chunk_bytes;
    out.chunk_count = stats.chunks;
    out.deflated = deflated_size(bytes);
    std::uint32_t json_length = 0;
    std::memcpy(&json_length, bytes.data() + 12, 4);
    out.json = json_length;
    const Json json = Json::parse(bytes.substr(20, json_length));
    std::size_t chunk_sum = 0;
    std::vector<std::vector<std::size_t>> cluster_bytes;  // per object, per cluster
    for (const Json& node : json["nodes"]) {
        if (!node.contains("extensions")) {
            continue;
        }
        const Json& ext = node["extensions"]["STRATA_progressive_mesh"];
        cluster_bytes.emplace_back();
        for (const Json& cluster : ext["clusters"]) {
            ++out.clusters;
            const std::uint32_t level = cluster["level"].get<std::uint32_t>();
            out.levels = std::max(out.levels, level + 1);
            cluster_bytes.back().push_back(0);
            if (cluster["mesh"] == node["mesh"]) {
                continue;
            }
            const Json& primitive =
                json["meshes"][cluster["mesh"].get<std::size_t>()]["primitives"][0];
            const std::size_t view =
                primitive["extensions"]["KHR_draco_mesh_compression"]["bufferView"];
            const std::size_t length = json["bufferViews"][view]["byteLength"];
            chunk_sum += length;
            cluster_bytes.back().back() = length;
            if (out.level_bytes.size() <= level) {
                out.level_bytes.resize(level + 1);
            }
            out.level_bytes[level] += length;
            if (level == 0) {
                out.level0_chunks += length;
                ++out.level0_chunk_count;
            }
        }
    }
    if (chunk_sum != out.chunks) {
        throw Error{ErrorCode::Internal, "chunk bytes in the file's JSON differ from the stats"};
    }
    for (const MultiresMesh* m : models) {
        for (std::uint32_t r : m->roots()) {
            out.root_triangles += m->clusters[r].triangles.size();
        }
        for (const MultiresCluster& cluster : m->clusters) {
            if (out.level_clusters.size() <= cluster.level) {
                out.level_clusters.resize(cluster.level + 1);
                out.level_triangles.resize(cluster.level + 1);
            }
            ++out.level_clusters[cluster.level];
            out.level_triangles[cluster.level] += cluster.triangles.size();
        }
    }
    out.level_bytes.resize(out.level_clusters.size());
    out.cut_triangles.assign(kCutErrorsPx.size(), 0);
    out.cut_bytes.assign(kCutErrorsPx.size(), 0);
    if (cluster_bytes.size() != models.size()) {
        throw Error{ErrorCode::Internal, "objects in the file's JSON differ from the models"};
    }
    for (std::size_t e = 0; e < kCutErrorsPx.size(); ++e) {
        for (std::size_t i = 0; i < models.size(); ++i) {
            for (const MultiresGroup& g : models[i]->groups) {
                if (g.error_px > kCutErrorsPx[e]) {
                    for (const std::uint32_t consumed : g.consumed) {
                        out.cut_bytes[e] += cluster_bytes[i].at(consumed);
                    }
                }
            }
        }
        for (const MultiresMesh* m : models) {
            for (const std::uint32_t cluster : select_cut_by_error(*m, kCutErrorsPx[e]).clusters) {
                out.cut_triangles[e] += m->clusters[cluster].triangles.size();
            }
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// gltfpack

/// Runs `exe args...` with stdout and stderr into `log`; returns the exit status.
int run_process(const std::string& exe,
                const std::vector<std::string>& args,
                const std::filesystem::path& log) {
    std::vector<std::string> words{exe};
    words.insert(words.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& w : words) {
        argv.push_back(w.data());
    }
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t pid = -1;
    const int status = posix_spawnp(&pid, exe.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (status != 0) {
        throw Error{ErrorCode::Io, "cannot run " + exe + ": " + std::strerror(status)};
    }
    int wstatus = 0;
    waitpid(pid, &wstatus, 0);
    return WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : 128;
}

struct PackResult {
    std::size_t bytes = 0;
    std::size_t deflated = 0;
    double seconds = 0.0;
};

std::optional<PackResult> gltfpack(const std::string& exe,
                                   const std::filesystem::path& input,
                                   const std::filesystem::path& output,
                                   const std::vector<std::string>& options,
                                   std::vector<std::string>& notes) {
    if (exe.empty()) {
        return std::nullopt;
    }
    std::vector<std::string> args{"-i", input.string(), "-o", output.string()};
    args.insert(args.end(), options.begin(), options.end());
    const std::filesystem::path log = output.string() + ".log";
    const auto start = Clock::now();
    const int status = run_process(exe, args, log);
    PackResult r;
    r.seconds = seconds_since(start);
    if (status != 0 || !std::filesystem::exists(output)) {
        notes.push_back("gltfpack " + output.filename().string() + " failed (exit " +
                        std::to_string(status) + "): " + read_bytes(log));
        return std::nullopt;
    }
    const std::string bytes = read_bytes(output);
    r.bytes = bytes.size();
    r.deflated = deflated_size(bytes);
    return r;
}

// ---------------------------------------------------------------------------------------------
// Tables

std::string fixed(double value, int digits) {
    if (!std::isfinite(value)) {
        return "-";
    }
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", digits, value);
    return text;
}

std::string pad(const std::string& text, int width, bool left = false) {
    const int fill = std::max(0, width - int(text.size()));
    return left ? text + std::string(fill, ' ') : std::string(fill, ' ') + text;
}

std::string ratio(double a, double b) {
    return b > 0 ? fixed(a / b, 2) : "-";
}

/// Bytes as kB with one decimal (1 kB = 1000 B).
std::string kb(std::size_t bytes) {
    return fixed(double(bytes) / 1000.0, 1);
}

struct MainRow {
    std::string name;
    std::size_t objects = 0, triangles = 0;
    OursBytes ours;
    std::size_t draco_pn = 0, draco_p = 0, draco_glb = 0, draco_glb_deflated = 0;
    std::size_t plain_glb = 0;
    std::optional<PackResult> pack14, pack_b;
    int bits_b = 0;
    double seconds_reconstruct = 0.0, seconds_write = 0.0;
};

struct Breakdown {
    std::string name;
    std::size_t chunks_p = 0, chunks_pn = 0, chunks_pnc = 0;  // every chunk re-encoded
    std::size_t l0_p = 0, l0_pn = 0, l0_pnc = 0;              // level-0 chunks only
    std::size_t one_triangle_chunk = 0;
    std::size_t l0_cluster_vertices = 0, full_vertices = 0;
    std::size_t base_binary = 0;
};

struct SweepRow {
    std::string name;
    std::size_t size = 0;
    OursBytes ours;
    std::size_t l0_pn_clustered = 0;
    std::size_t draco_pn = 0, draco_glb = 0;
    double seconds_build = 0.0;
};

void print_main(const std::vector<MainRow>& rows) {
    std::ostringstream out;
    out << "Size of the progressive glTF vs. single-rate Draco and gltfpack on the same "
           "full-resolution surfaces (issue 7). kB = 1000 bytes.\n"
           "ours: model.glb as `strata build` writes it. total = the file = bytes to full "
           "resolution (a full download); base = JSON + root clusters\n"
           "(uncompressed; the first frame); L0 = the level-0 Draco chunks alone (what full "
           "resolution needs beyond the base when a .gltf is streamed by range requests).\n"
           "Draco: single-rate, each object's full mesh, the same encoder settings and lossless "
           "grid quantization as our chunks; raw Draco bytes with\n"
           "POSITION+NORMAL (PN) and POSITION only (P), and glb = the PN meshes in a minimal .glb "
           "(what the ratio o/D uses).\n"
           "gltfpack: npm gltfpack on the plain full-resolution scene.glb (plain: its size); -cc "
           "default (14-bit positions, 8-bit normals) and -cc -vp B (B bits: our grid's\n"
           "in-plane resolution, px/16, over the scene's largest extent).\n";
    std::ostringstream header;
    header << pad("case", 22, true) << pad("obj", 4) << pad("tris", 8) << " |" << pad("total", 8)
           << pad("base", 7) << pad("L0", 8) << " |" << pad("D glb", 8) << pad("D PN", 8)
           << pad("D P", 8) << " |" << pad("plain", 8) << pad("gp -cc", 8) << pad("B", 3)
           << pad("gp -vpB", 8) << " |" << pad("o/D", 5) << pad("o/gpB", 6) << pad("b/tot", 6)
           << pad("L0/DPN", 7);
    out << header.str() << '\n' << std::string(header.str().size(), '-') << '\n';
    for (const MainRow& r : rows) {
        out << pad(r.name, 22, true) << pad(std::to_string(r.objects), 4)
            << pad(std::to_string(r.triangles), 8) << " |" << pad(kb(r.ours.total), 8)
            << pad(kb(r.ours.base), 7) << pad(kb(r.ours.level0_chunks), 8) << " |"
            << pad(kb(r.draco_glb), 8) << pad(kb(r.draco_pn), 8) << pad(kb(r.draco_p), 8) << " |"
            << pad(kb(r.plain_glb), 8) << pad(r.pack14 ? kb(r.pack14->bytes) : "-", 8)
            << pad(std::to_string(r.bits_b), 3) << pad(r.pack_b ? kb(r.pack_b->bytes) : "-", 8)
            << " |" << pad(ratio(double(r.ours.total), double(r.draco_glb)), 5)
            << pad(r.pack_b ? ratio(double(r.ours.total), double(r.pack_b->bytes)) : "-", 6)
            << pad(fixed(100.0 * double(r.ours.base) / double(r.ours.total), 1) + "%", 6)
            << pad(ratio(double(r.ours.level0_chunks), double(r.draco_pn)), 7) << '\n';
    }
    out << "o/D: our total over the Draco .glb (aim <= 1.5); o/gpB: over gltfpack -cc -vp B; "
           "b/tot: base over total (aim <= 5%); L0/DPN: our level-0 chunks over\n"
           "single-rate Draco PN (the cost of cutting full resolution into clusters, with "
           "_COARSE_POSITION).\n";
    out << "\nTransfer sizes (zlib -9 of each file, as HTTP gzip would send it), kB:\n";
    for (const MainRow& r : rows) {
        out << "  " << pad(r.name, 22, true) << " ours " << pad(kb(r.ours.deflated), 8)
            << "  Draco glb " << pad(kb(r.draco_glb_deflated), 8) << "  gltfpack -cc "
            << pad(r.pack14 ? kb(r.pack14->deflated) : "-", 8) << "  gltfpack -cc -vp B "
            << pad(r.pack_b ? kb(r.pack_b->deflated) : "-", 8) << "  (ours/gpB "
            << (r.pack_b ? ratio(double(r.ours.deflated), double(r.pack_b->deflated)) : "-")
            << ")\n";
    }
    out << "\nTimes (s): reconstruct / write model.glb / gltfpack -cc / gltfpack -cc -vp B:\n";
    for (const MainRow& r : rows) {
        out << "  " << pad(r.name, 22, true) << ' ' << fixed(r.seconds_reconstruct, 2) << " / "
            << fixed(r.seconds_write, 2) << " / " << (r.pack14 ? fixed(r.pack14->seconds, 2) : "-")
            << " / " << (r.pack_b ? fixed(r.pack_b->seconds, 2) : "-") << "; levels "
            << r.ours.levels << ", clusters " << r.ours.clusters << ", chunks "
            << r.ours.chunk_count << " (level 0: " << r.ours.level0_chunk_count
            << "), root triangles " << r.ours.root_triangles << '\n';
        out << "  " << pad("", 22) << " per level, triangles / clusters / chunk kB:";
        for (std::size_t l = 0; l < r.ours.level_clusters.size(); ++l) {
            out << (l == 0 ? " " : ", ") << l << ": " << r.ours.level_triangles[l] << " / "
                << r.ours.level_clusters[l] << " / " << kb(r.ours.level_bytes[l]);
        }
        out << '\n' << "  " << pad("", 22) << " uniform-error cuts, triangles at";
        for (std::size_t e = 0; e < kCutErrorsPx.size(); ++e) {
            out << (e == 0 ? " " : ", ") << kCutErrorsPx[e] << " px: " << r.ours.cut_triangles[e]
                << " (" << kb(r.ours.cut_bytes[e]) << " kB)";
        }
        out << '\n';
    }
    std::cout << out.str();
}

void print_breakdown(const std::vector<Breakdown>& rows, const std::vector<MainRow>& main) {
    std::ostringstream out;
    out << "\nWhere our bytes go (kB; every chunk re-encoded with fewer attributes, same "
           "settings; pos = POSITION with connectivity, nrm = + NORMAL,\n"
           "coarse = + _COARSE_POSITION; fixed = chunks x the bytes of a one-triangle chunk; "
           "dup = level-0 cluster vertices over full-mesh vertices).\n";
    std::ostringstream header;
    header << pad("case", 22, true) << " |" << pad("json", 7) << pad("base bin", 9) << " |"
           << pad("pos", 8) << pad("nrm", 8) << pad("coarse", 8) << pad("fixed", 7) << " |"
           << pad("L0 pos", 8) << pad("L0 nrm", 8) << pad("L0 crs", 8) << pad("lv>=1", 8) << " |"
           << pad("dup", 5) << pad("L0PN/DPN", 9) << pad("L0P/DP", 7);
    out << header.str() << '\n' << std::string(header.str().size(), '-') << '\n';
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const Breakdown& b = rows[i];
        const MainRow& r = main[i];
        const std::size_t chunks = r.ours.chunk_count;
        out << pad(b.name, 22, true) << " |" << pad(kb(r.ours.json), 7) << pad(kb(b.base_binary), 9)
            << " |" << pad(kb(b.chunks_p), 8) << pad(kb(b.chunks_pn - b.chunks_p), 8)
            << pad(kb(b.chunks_pnc - b.chunks_pn), 8) << pad(kb(chunks * b.one_triangle_chunk), 7)
            << " |" << pad(kb(b.l0_p), 8) << pad(kb(b.l0_pn - b.l0_p), 8)
            << pad(kb(b.l0_pnc - b.l0_pn), 8) << pad(kb(b.chunks_pnc - b.l0_pnc), 8) << " |"
            << pad(ratio(double(b.l0_cluster_vertices), double(b.full_vertices)), 5)
            << pad(ratio(double(b.l0_pn), double(r.draco_pn)), 9)
            << pad(ratio(double(b.l0_p), double(r.draco_p)), 7) << '\n';
    }
    out << "json: the glTF JSON (DAG, spheres, accessors of every chunk); base bin: the root "
           "clusters' float positions, normals and indices. One-triangle chunk: "
        << (rows.empty() ? 0 : rows.front().one_triangle_chunk)
        << " bytes. L0PN/DPN, L0P/DP: level-0 clusters as separate Draco meshes without "
           "_COARSE_POSITION over the single-rate mesh, with and without normals.\n";
    std::cout << out.str();
}

void print_sweep(const std::vector<SweepRow>& rows) {
    if (rows.empty()) {
        return;
    }
    std::ostringstream out;
    out << "\nCluster size sweep (MultiresOptions::cluster_triangles; the models rebuilt from "
           "the same surfaces). kB; total = bytes to full resolution.\n";
    std::ostringstream header;
    header << pad("case", 22, true) << pad("size", 6) << " |" << pad("lv", 3) << pad("chunks", 7)
           << pad("mean B", 7) << " |" << pad("total", 8) << pad("base", 7) << pad("L0", 8) << " |"
           << pad("o/D", 5) << pad("b/tot", 6) << pad("L0/DPN", 7) << pad("L0PN/DPN", 9) << " |"
           << pad("build s", 8);
    out << header.str() << '\n' << std::string(header.str().size(), '-') << '\n';
    for (const SweepRow& r : rows) {
        out << pad(r.name, 22, true) << pad(std::to_string(r.size), 6) << " |"
            << pad(std::to_string(r.ours.levels), 3) << pad(std::to_string(r.ours.chunk_count), 7)
            << pad(r.ours.chunk_count ? std::to_string(r.ours.chunks / r.ours.chunk_count) : "-", 7)
            << " |" << pad(kb(r.ours.total), 8) << pad(kb(r.ours.base), 7)
            << pad(kb(r.ours.level0_chunks), 8) << " |"
            << pad(ratio(double(r.ours.total), double(r.draco_glb)), 5)
            << pad(fixed(100.0 * double(r.ours.base) / double(r.ours.total), 1) + "%", 6)
            << pad(ratio(double(r.ours.level0_chunks), double(r.draco_pn)), 7)
            << pad(ratio(double(r.l0_pn_clustered), double(r.draco_pn)), 9) << " |"
            << pad(fixed(r.seconds_build, 2), 8) << '\n';
    }
    out << "mean B: mean Draco chunk (the streaming unit); L0PN/DPN: level-0 clusters as separate "
           "POSITION+NORMAL Draco meshes over the single-rate one (DESIGN.md's measure);\n"
           "build s: building the models of every object (simplify stage).\n";
    std::cout << out.str();
}

// ---------------------------------------------------------------------------------------------
// One case

struct Objects {
    std::vector<std::size_t> surfaces;  ///< indices into Reconstruction::surfaces
    std::vector<std::uint16_t> labels;
};

/// The surfaces `strata build` puts into the progressive scene: non-empty and on a grid.
Objects progressive_objects(const Reconstruction& result,
                            std::vector<std::string>& notes,
                            const std::string& name) {
    Objects o;
    for (std::size_t i = 0; i < result.surfaces.size() && i < result.models.size(); ++i) {
        if (result.surfaces[i].mesh.triangles.empty()) {
            continue;
        }
        if (!(result.models[i].grid_step > 0.0)) {
            notes.push_back(name + ": label " + std::to_string(result.surfaces[i].label) +
                            " is not on a grid; left out (as strata build does)");
            continue;
        }
        o.surfaces.push_back(i);
        o.labels.push_back(result.surfaces[i].label);
    }
    return o;
}

/// Single-rate Draco of every object's level-0 mesh; fills the row's Draco columns.
void single_rate_draco(const Case& c,
                       const std::vector<StorageModel>& storage,
                       const Objects& objects,
                       const SliceFrame& frame,
                       std::size_t& pn,
                       std::size_t& p,
                       std::string* glb) {
    std::vector<Encoded> encoded;
    std::vector<DecodedInfo> infos;
    std::vector<std::string> names;
    std::vector<std::array<double, 3>> colours;
    pn = p = 0;
    for (std::size_t i = 0; i < storage.size(); ++i) {
        const Patch full = full_patch(storage[i]);
        Encoded e = encode_patch(storage[i], full, Attributes::PositionNormal);
        pn += e.bytes.size();
        p += encode_patch(storage[i], full, Attributes::Position).bytes.size();
        if (glb != nullptr) {
            infos.push_back(decode_info(storage[i], full, e));
            encoded.push_back(std::move(e));
            const auto label =
                std::find_if(c.stack.label_table.begin(), c.stack.label_table.end(),
                             [&](const LabelInfo& l) { return l.value == objects.labels[i]; });
            names.push_back(label != c.stack.label_table.end()
                                ? label->name
                                : "label " + std::to_string(objects.labels[i]));
            colours.push_back(label != c.stack.label_table.end()
                                  ? std::array{label->color[0] / 255.0, label->color[1] / 255.0,
                                               label->color[2] / 255.0}
                                  : std::array{0.5, 0.5, 0.5});
        }
    }
    if (glb != nullptr) {
        *glb = draco_glb(names, colours, encoded, infos, storage_matrix(frame));
    }
}

/// Level-0 clusters as separate POSITION + NORMAL Draco meshes.
std::size_t level0_clustered_pn(const std::vector<StorageModel>& storage) {
    std::size_t bytes = 0;
    for (const StorageModel& s : storage) {
        for (std::uint32_t c = 0; c < s.model->clusters.size(); ++c) {
            if (s.model->clusters[c].level == 0) {
                bytes +=
                    encode_patch(s, cluster_patch(s, c), Attributes::PositionNormal).bytes.size();
            }
        }
    }
    return bytes;
}

std::string safe_stem(const std::string& name) {
    std::string stem = name;
    for (char& ch : stem) {
        if (!std::isalnum(static_cast<unsigned char>(ch))) {
            ch = '_';
        }
    }
    return stem;
}

void run_case(const std::string& spec,
              bool main_table,
              bool sweep,
              const Arguments& args,
              std::vector<MainRow>& main_rows,
              std::vector<Breakdown>& breakdowns,
              std::vector<SweepRow>& sweep_rows,
              std::vector<std::string>& notes) {
    Case c = load_case(spec);
    const std::filesystem::path work = args.work / safe_stem(c.name);
    std::filesystem::create_directories(work);
    std::cerr << "progressive_size: " << c.name << ": reconstructing\n";
    ReconstructOptions options;
    options.multires.cluster_triangles = args.cluster_triangles;
    options.multires.keep_fraction = args.keep_fraction;
    Report report;
    auto start = Clock::now();
    Reconstruction result = reconstruct(c.stack, options, report);
    const double seconds_reconstruct = seconds_since(start);
    for (const Warning& w : report.warnings) {
        if (w.stage != "triangulate") {  // note: slab fallbacks are the accuracy bench's business
            notes.push_back(c.name + ": warning (" + w.stage + ", " + w.where + "): " + w.message);
        }
    }
    const Objects objects = progressive_objects(result, notes, c.name);
    if (objects.surfaces.empty()) {
        throw Error{ErrorCode::InvalidInput, c.name + ": no surface to write"};
    }
    const SliceFrame frame = slice_frame(c.stack, result.slice_spacing_px);
    const double px_mm = frame.error_mm_per_px;

    auto storage_of = [&](const std::vector<MultiresMesh>& models) {
        std::vector<StorageModel> storage;
        for (std::size_t i : objects.surfaces) {
            storage.push_back(storage_model(models[i], frame));
        }
        return storage;
    };
    auto model_pointers = [&](const std::vector<MultiresMesh>& models) {
        std::vector<const MultiresMesh*> pointers;
        for (std::size_t i : objects.surfaces) {
            pointers.push_back(&models[i]);
        }
        return pointers;
    };

    // single-rate Draco depends only on the level-0 surface, the same for every cluster size
    std::size_t draco_pn = 0, draco_p = 0;
    std::string draco_file;
    {
        const std::vector<StorageModel> storage = storage_of(result.models);
        single_rate_draco(c, storage, objects, frame, draco_pn, draco_p, &draco_file);
        write_bytes(work / "draco.glb", draco_file);
    }

    if (main_table) {
        std::cerr << "progressive_size: " << c.name << ": writing model.glb and peers\n";
        MainRow row;
        row.name = c.name;
        row.objects = objects.surfaces.size();
        row.seconds_reconstruct = seconds_reconstruct;
        start = Clock::now();
        row.ours =
            write_ours(work / "model.glb", c, model_pointers(result.models), objects.labels, frame);
        row.seconds_write = seconds_since(start);
        row.draco_pn = draco_pn;
        row.draco_p = draco_p;
        row.draco_glb = draco_file.size();
        row.draco_glb_deflated = deflated_size(draco_file);

        // the plain full-resolution scene, as `strata build` writes OUT/scene.glb
        std::vector<SceneObject> scene;
        double lo[3] = {kInfinity, kInfinity, kInfinity};
        double hi[3] = {-kInfinity, -kInfinity, -kInfinity};
        for (std::size_t n = 0; n < objects.surfaces.size(); ++n) {
            const MultiresMesh& model = result.models[objects.surfaces[n]];
            const TriMesh full = cut_mesh(model, select_cut_at_level(model, 0));
            row.triangles += full.triangles.size();
            SceneObject o;
            o.label = objects.labels[n];
            const auto label = std::find_if(c.stack.label_table.begin(), c.stack.label_table.end(),
                                            [&](const LabelInfo& l) { return l.value == o.label; });
            if (label != c.stack.label_table.end()) {
                o.name = label->name;
                o.srgb = {label->color[0] / 255.0, label->color[1] / 255.0,
                          label->color[2] / 255.0};
            }
            o.mesh = surface_to_world(c.stack, result.slice_spacing_px, full);
            for (const Vec3& p : o.mesh.positions) {
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], p[k]);
                    hi[k] = std::max(hi[k], p[k]);
                }
            }
            scene.push_back(std::move(o));
        }
        SceneInfo info;
        info.source = c.stack.source;
        const Vec3 spacing = c.stack.spacing_mm();
        info.spacing_mm = {spacing.x, spacing.y, spacing.z};
        info.generator = "strata 0.1.0";
        const std::filesystem::path scene_file = work / "scene.glb";
        write_scene_gltf(scene_file, scene, info);
        row.plain_glb = std::filesystem::file_size(scene_file);
        const double extent = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
        row.bits_b = std::min(kGltfpackMaxBits,
                              int(std::ceil(std::log2(extent / (px_mm / kGridFraction) + 1.0))));
        std::cerr << "progressive_size: " << c.name << ": gltfpack\n";
        row.pack14 = gltfpack(args.gltfpack, scene_file, work / "packed_cc.glb", {"-cc"}, notes);
        row.pack_b = gltfpack(args.gltfpack, scene_file, work / "packed_cc_vp.glb",
                              {"-cc", "-vp", std::to_string(row.bits_b)}, notes);
        notes.push_back(c.name + ": scene extent " + fixed(extent, 1) + " mm, pixel " +
                        fixed(px_mm, 3) + " mm -> gltfpack -vp " + std::to_string(row.bits_b) +
                        " (step " + fixed(extent / (std::ldexp(1.0, row.bits_b) - 1.0), 4) +
                        " mm; ours " + fixed(px_mm / kGridFraction, 4) + " mm in plane)");

        // breakdown: every chunk re-encoded with fewer attributes
        std::cerr << "progressive_size: " << c.name << ": breakdown\n";
        Breakdown b;
        b.name = c.name;
        const std::vector<StorageModel> storage = storage_of(result.models);
        for (const StorageModel& s : storage) {
            b.full_vertices += full_patch(s).vertices.size();
            for (std::uint32_t id = 0; id < s.model->clusters.size(); ++id) {
                const MultiresCluster& cluster = s.model->clusters[id];
                if (cluster.level == 0) {
                    b.l0_cluster_vertices += cluster.vertices.size();
                }
                const Patch patch = cluster_patch(s, id);
                if (cluster.consumer < 0) {
                    // uncompressed: float positions and normals, 16/32-bit indices
                    b.base_binary +=
                        patch.vertices.size() * 24 +
                        patch.triangles.size() * 3 * (patch.vertices.size() <= 65535 ? 2 : 4);
                    if (cluster.level == 0) {
                        b.l0_p += encode_patch(s, patch, Attributes::Position).bytes.size();
                        b.l0_pn += encode_patch(s, patch, Attributes::PositionNormal).bytes.size();
                    }
                    continue;
                }
                const std::size_t bp = encode_patch(s, patch, Attributes::Position).bytes.size();
                const std::size_t bpn =
                    encode_patch(s, patch, Attributes::PositionNormal).bytes.size();
                const std::size_t bpnc = encode_patch(s, patch, Attributes::All).bytes.size();
                b.chunks_p += bp;
                b.chunks_pn += bpn;
                b.chunks_pnc += bpnc;
                if (cluster.level == 0) {
                    b.l0_p += bp;
                    b.l0_pn += bpn;
                    b.l0_pnc += bpnc;
                }
            }
        }
        if (b.chunks_pnc != row.ours.chunks) {
            notes.push_back(c.name + ": re-encoded chunks give " + std::to_string(b.chunks_pnc) +
                            " bytes, the file " + std::to_string(row.ours.chunks) +
                            ": the breakdown does not replicate the writer");
        }
        {
            // the fixed cost of a chunk: one triangle of the first model
            const StorageModel& s = storage.front();
            Patch one;
            const MultiresCluster& cluster = s.model->clusters.front();
            const auto& t = cluster.triangles.front();
            one.vertices = {cluster.vertices[t[0]], cluster.vertices[t[1]], cluster.vertices[t[2]]};
            one.normals = {s.normals[one.vertices[0]], s.normals[one.vertices[1]],
                           s.normals[one.vertices[2]]};
            one.coarse = one.vertices;
            one.triangles = {{0, 1, 2}};
            b.one_triangle_chunk = encode_patch(s, one, Attributes::All).bytes.size();
        }
        main_rows.push_back(row);
        breakdowns.push_back(b);
    }

    if (sweep) {
        for (const std::size_t size : args.sweep_sizes) {
            std::cerr << "progressive_size: " << c.name << ": cluster size " << size << '\n';
            // the models rebuilt as reconstruct builds them (src/pipeline/reconstruct.cpp)
            std::vector<MultiresMesh> models(result.surfaces.size());
            start = Clock::now();
            for (std::size_t i : objects.surfaces) {
                const ObjectSurface& surface = result.surfaces[i];
                const SliceErrorMeter meter(result.contours, result.fields, surface.label,
                                            result.slice_spacing_px);
                MultiresOptions multires = options.multires;
                multires.cluster_triangles = size;
                if (surface.verification.done && !surface.verification.ok()) {
                    multires.max_levels = 0;
                }
                models[i] = build_multires_mesh(
                    surface.mesh, meter, surface.contour_deviation_px + surface.grid_shift_px,
                    multires);
                models[i].grid_step = surface.grid_step;
            }
            SweepRow row;
            row.name = c.name;
            row.size = size;
            row.seconds_build = seconds_since(start);
            row.ours = write_ours(work / ("model_" + std::to_string(size) + ".glb"), c,
                                  model_pointers(models), objects.labels, frame);
            row.l0_pn_clustered = level0_clustered_pn(storage_of(models));
            row.draco_pn = draco_pn;
            row.draco_glb = draco_file.size();
            sweep_rows.push_back(row);
        }
    }
}

int run(int argc, char** argv) {
    Arguments args = parse_arguments(argc, argv);
    bool remove_work = false;
    if (args.work.empty()) {
        args.work = std::filesystem::temp_directory_path() /
                    ("strata_progressive_size_" + std::to_string(getpid()));
        remove_work = true;
    }
    std::filesystem::create_directories(args.work);
    std::vector<std::string> specs = args.cases;
    for (const std::string& s : args.sweep_cases) {
        if (std::find(specs.begin(), specs.end(), s) == specs.end()) {
            specs.push_back(s);
        }
    }
    std::vector<MainRow> main_rows;
    std::vector<Breakdown> breakdowns;
    std::vector<SweepRow> sweep_rows;
    std::vector<std::string> notes;
    const auto start = Clock::now();
    for (const std::string& spec : specs) {
        const bool in_main =
            std::find(args.cases.begin(), args.cases.end(), spec) != args.cases.end();
        const bool in_sweep = std::find(args.sweep_cases.begin(), args.sweep_cases.end(), spec) !=
                              args.sweep_cases.end();
        const auto case_start = Clock::now();
        run_case(spec, in_main, in_sweep, args, main_rows, breakdowns, sweep_rows, notes);
        std::cerr << "progressive_size: " << spec << ": " << fixed(seconds_since(case_start), 1)
                  << " s\n";
    }
    if (remove_work) {
        std::filesystem::remove_all(args.work);
    }
    if (!main_rows.empty()) {
        print_main(main_rows);
        print_breakdown(breakdowns, main_rows);
    }
    print_sweep(sweep_rows);
    if (args.gltfpack.empty()) {
        notes.push_back("gltfpack not run (no --gltfpack)");
    }
    if (!notes.empty()) {
        std::cout << "\nNotes:\n";
        for (const std::string& note : notes) {
            std::cout << "  " << note << '\n';
        }
    }
    std::cout << "\nprogressive_size: " << fixed(seconds_since(start), 1) << " s in all\n";
    return kExitOk;
}

}  // namespace
}  // namespace strata

int main(int argc, char** argv) {
    try {
        return strata::run(argc, argv);
    } catch (const strata::Error& e) {
        std::cerr << "progressive_size: error: " << e.what() << '\n';
        const bool bad_input = e.code() == strata::ErrorCode::InvalidInput ||
                               e.code() == strata::ErrorCode::Unsupported;
        return bad_input ? strata::kExitBadInput : strata::kExitFailure;
    } catch (const std::exception& e) {
        std::cerr << "progressive_size: error: " << e.what() << '\n';
        return strata::kExitFailure;
    }
}

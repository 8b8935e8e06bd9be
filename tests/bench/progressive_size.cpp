// Size of the progressive glTF (STRATA_progressive_mesh version 3) against single-rate Draco and
// gltfpack, side by side in one run (issue 16), plus a sweep of the multiresolution parameters.
//
//   progressive_size [--case SPEC]... [--sweep-case SPEC]... [--sweep-keep 0.25,0.35]
//                    [--sweep-clusters 1024,2048] [--cluster-triangles N] [--keep-fraction F]
//                    [--root-triangles N] [--first-level-px E]
//                    [--gltfpack EXE] [--work DIR]
//
// SPEC: `phantom:NAME` (make_phantom) or `stack:PATH` (read_slice_stack); every non-zero label is
// an object, as in `strata build`.
//
// For each --case: `reconstruct` (default options, or --cluster-triangles / --keep-fraction /
// --root-triangles / --first-level-px: the first level within E px of every full-resolution
// vertex where its groups can still shrink, MultiresOptions::first_level_px) and,
// like `strata build`, write_progressive_gltf of every object on a grid into WORK/model.glb. Its
// bytes (ProgressiveStats): total (the .glb: a full download, i.e. full resolution); base (GLB
// header, JSON, DAG tables and base meshes: what a first frame needs) and its share; the JSON per
// object against the aim of 1 kB per object + 10 B per group.
// Peers, on the same full-resolution surface (the level-0 cut of each model):
//   Draco PN  single-rate Draco .glb: each object's level-0 mesh as one Draco mesh with POSITION
//             and NORMAL (area-weighted, 10-bit octahedral), encoded by the writer's own encoder
//             (detail::encode_draco_chunk: Edgebreaker, speed 3, POSITION by constrained
//             multi-parallelogram, lossless on the model's grid: the same quantization as ours),
//             in a minimal .glb (KHR_draco_mesh_compression, node matrices, one material each);
//   Draco P   the same without NORMAL (a viewer computing normals itself, as ours does);
//   gltfpack  npm gltfpack -cc (meshoptimizer, WASM) on the plain full-resolution scene.glb
//             (exporters/scene_gltf.h; its default 14-bit positions, 8-bit normals: lossy).
// For each --sweep-case and each (keep fraction, cluster triangles) pair: the models rebuilt from
// the same surfaces (build_multires_mesh, as reconstruct does) and written the same way: total /
// Draco PN, base share, triangles over all levels / level 0, chunks and their mean size.
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

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Arguments {
    std::vector<std::string> cases;
    std::vector<std::string> sweep_cases;
    std::vector<double> sweep_keep{0.25, 0.35};
    std::vector<std::size_t> sweep_clusters{1024, 2048};
    std::size_t cluster_triangles = MultiresOptions{}.cluster_triangles;
    double keep_fraction = MultiresOptions{}.keep_fraction;
    std::size_t root_triangles = MultiresOptions{}.root_triangles;
    double first_level_px = MultiresOptions{}.first_level_px;
    std::string gltfpack;
    std::filesystem::path work;
};

std::string usage() {
    return "usage: progressive_size [--case phantom:NAME | --case stack:PATH]...\n"
           "                        [--sweep-case SPEC]... [--sweep-keep 0.25,0.35]\n"
           "                        [--sweep-clusters 1024,2048] [--cluster-triangles N]\n"
           "                        [--keep-fraction F] [--root-triangles N] [--first-level-px E]\n"
           "                        [--gltfpack EXE] [--work DIR]\n";
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

/// A number in (0, below): below 1 (a fraction) or infinite (any finite positive number).
double parse_positive(const std::string& text,
                      const std::string& what,
                      double below = std::numeric_limits<double>::infinity()) {
    std::size_t used = 0;
    double value = 0.0;
    try {
        value = std::stod(text, &used);
    } catch (const std::exception&) {
        used = 0;
    }
    if (used == 0 || used != text.size() || !(value > 0.0) || !std::isfinite(value) ||
        !(value < below)) {
        throw Error{ErrorCode::InvalidInput, what + ": '" + text + "', expected " +
                                                 (below == 1.0 ? std::string("a number in (0, 1)")
                                                               : std::string("a positive number"))};
    }
    return value;
}

double parse_fraction(const std::string& text, const std::string& what) {
    return parse_positive(text, what, 1.0);
}

std::vector<std::string> split(const std::string& text) {
    std::vector<std::string> items;
    std::stringstream list(text);
    for (std::string item; std::getline(list, item, ',');) {
        items.push_back(item);
    }
    return items;
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
        } else if (arg == "--sweep-keep") {
            args.sweep_keep.clear();
            for (const std::string& item : split(value(i))) {
                args.sweep_keep.push_back(parse_fraction(item, "--sweep-keep"));
            }
        } else if (arg == "--sweep-clusters") {
            args.sweep_clusters.clear();
            for (const std::string& item : split(value(i))) {
                args.sweep_clusters.push_back(parse_count(item, "--sweep-clusters"));
            }
        } else if (arg == "--cluster-triangles") {
            args.cluster_triangles = parse_count(value(i), "--cluster-triangles");
        } else if (arg == "--keep-fraction") {
            args.keep_fraction = parse_fraction(value(i), "--keep-fraction");
        } else if (arg == "--root-triangles") {
            args.root_triangles = parse_count(value(i), "--root-triangles");
        } else if (arg == "--first-level-px") {
            args.first_level_px = parse_positive(value(i), "--first-level-px");
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

/// One object's model in the writer's storage frame: grid points and level-0 normals.
struct StorageModel {
    const MultiresMesh* model = nullptr;
    std::vector<Float3> points;   ///< per model vertex, on the grid (x, y px; z in slices)
    std::vector<Float3> normals;  ///< per model vertex, unit, area-weighted over level 0
    bool reverse = false;         ///< triangles reversed (mirroring frame)
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
    std::vector<Vec3> sum(s.points.size());
    const auto at = [&](std::uint32_t v) {
        return Vec3{s.points[v][0], s.points[v][1], s.points[v][2]};
    };
    for (const std::uint32_t c : select_cut_at_level(model, 0).clusters) {
        const MultiresCluster& cluster = model.clusters[c];
        for (const auto& t : cluster.triangles) {
            const std::uint32_t a = cluster.vertices[t[0]], b = cluster.vertices[t[1]],
                                e = cluster.vertices[t[2]];
            const Vec3 n = (s.reverse ? -1.0 : 1.0) * cross(at(b) - at(a), at(e) - at(a));
            for (const std::uint32_t v : {a, b, e}) {
                sum[v] = sum[v] + n;
            }
        }
    }
    s.normals.assign(s.points.size(), Float3{0.0f, 0.0f, 1.0f});
    for (std::size_t v = 0; v < sum.size(); ++v) {
        const double length = norm(sum[v]);
        if (length > 0.0) {
            const Vec3 n = (1.0 / length) * sum[v];
            s.normals[v] = {float(n.x), float(n.y), float(n.z)};
        }
    }
    return s;
}

/// A patch to encode: model vertex ids, their normals, triangles over the ids' indices, in the
/// model's orientation (reversed here when the frame mirrors).
struct Patch {
    std::vector<std::uint32_t> vertices;
    std::vector<Float3> normals;  ///< per entry of `vertices`
    std::vector<std::array<std::uint32_t, 3>> triangles;
};

using Encoded = detail::DracoChunkBytes;

/// Draco bytes of `patch` (with NORMAL when `normals`), encoded by the writer's own encoder
/// (detail::encode_draco_chunk) at the writer's default settings.
Encoded encode_patch(const StorageModel& s, const Patch& patch, bool normals) {
    const ProgressiveOptions options;
    detail::DracoChunkInput input;
    input.step = s.step;
    for (std::size_t i = 0; i < patch.vertices.size(); ++i) {
        input.positions.push_back(s.points[patch.vertices[i]]);
        if (normals) {
            input.normals.push_back(patch.normals[i]);
        }
    }
    for (const auto& t : patch.triangles) {
        input.triangles.push_back({t[0], s.reverse ? t[2] : t[1], s.reverse ? t[1] : t[2]});
    }
    return detail::encode_draco_chunk(input, options.compression_level, options.normal_bits);
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

/// A minimal .glb of single-rate Draco meshes (POSITION, NORMAL when encoded): root node "patient"
/// with the writer's matrix, one node per object with its storage matrix, mesh, material.
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
            {{"componentType", 5126}, {"count", info.points}, {"type", "VEC3"}});  // unused: P
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
        primitive["attributes"] = {{"POSITION", a}};
        if (e.normal_id >= 0) {
            primitive["attributes"]["NORMAL"] = a + 1;
        }
        primitive["indices"] = a + 2;
        primitive["material"] = i;
        primitive["mode"] = 4;
        primitive["extensions"]["KHR_draco_mesh_compression"] = {
            {"bufferView", json["bufferViews"].size() - 1},
            {"attributes", {{"POSITION", e.position_id}}}};
        if (e.normal_id >= 0) {
            primitive["extensions"]["KHR_draco_mesh_compression"]["attributes"]["NORMAL"] =
                e.normal_id;
        }
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

/// Single-rate Draco .glb of every object's level-0 mesh, with or without NORMAL.
std::string single_rate_draco(const Case& c,
                              const std::vector<StorageModel>& storage,
                              const Objects& objects,
                              const SliceFrame& frame,
                              bool normals) {
    std::vector<Encoded> encoded;
    std::vector<DecodedInfo> infos;
    std::vector<std::string> names;
    std::vector<std::array<double, 3>> colours;
    for (std::size_t i = 0; i < storage.size(); ++i) {
        const Patch full = full_patch(storage[i]);
        Encoded e = encode_patch(storage[i], full, normals);
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
    return draco_glb(names, colours, encoded, infos, storage_matrix(frame));
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

/// Ours, written as `strata build` writes it: the file's stats plus the DAG's shape.
struct Ours {
    ProgressiveStats stats;
    std::size_t triangles_all_levels = 0;  ///< every cluster's triangles
    std::size_t triangles_level0 = 0;
};

Ours write_ours(const std::filesystem::path& path,
                const Case& c,
                const std::vector<const MultiresMesh*>& models,
                const std::vector<std::uint16_t>& labels,
                const SliceFrame& frame) {
    std::vector<ProgressiveObject> objects;
    Ours out;
    for (std::size_t i = 0; i < models.size(); ++i) {
        ProgressiveObject o;
        o.label = labels[i];
        const auto label = std::find_if(c.stack.label_table.begin(), c.stack.label_table.end(),
                                        [&](const LabelInfo& l) { return l.value == o.label; });
        if (label != c.stack.label_table.end()) {
            o.name = label->name;
            o.srgb = {label->color[0] / 255.0, label->color[1] / 255.0, label->color[2] / 255.0};
        }
        o.model = models[i];
        objects.push_back(o);
        for (const MultiresCluster& cluster : models[i]->clusters) {
            out.triangles_all_levels += cluster.triangles.size();
            out.triangles_level0 += cluster.level == 0 ? cluster.triangles.size() : 0;
        }
    }
    SceneInfo info;
    info.source = c.stack.source;
    const Vec3 spacing = c.stack.spacing_mm();
    info.spacing_mm = {spacing.x, spacing.y, spacing.z};
    info.generator = "strata progressive_size";
    out.stats = write_progressive_gltf(path, objects, frame, info);
    return out;
}

/// Where the chunks' bytes go: every group's chunk re-encoded as the writer encodes it with
/// POSITION only, + _CLUSTER, + _SLOT (the last is the file's chunk, checked by the caller).
struct ChunkBreakdown {
    std::size_t position = 0, cluster = 0, slot = 0;
};

ChunkBreakdown chunk_breakdown(const StorageModel& s) {
    const MultiresMesh& model = *s.model;
    const ProgressiveOptions options;
    ChunkBreakdown out;
    for (const MultiresGroup& group : model.groups) {
        std::vector<std::uint32_t> vertices;
        for (const std::uint32_t c : group.consumed) {
            vertices.insert(vertices.end(), model.clusters[c].vertices.begin(),
                            model.clusters[c].vertices.end());
        }
        std::sort(vertices.begin(), vertices.end());
        vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
        const auto local = [&](std::uint32_t v) {
            return static_cast<std::uint32_t>(
                std::lower_bound(vertices.begin(), vertices.end(), v) - vertices.begin());
        };
        detail::DracoChunkInput in;
        in.step = s.step;
        std::vector<std::uint32_t> coarse(vertices.size());
        for (const std::uint32_t v : vertices) {
            in.positions.push_back(s.points[v]);
        }
        for (std::uint32_t k = 0; k < group.consumed.size(); ++k) {
            const MultiresCluster& cluster = model.clusters[group.consumed[k]];
            for (std::size_t i = 0; i < cluster.vertices.size(); ++i) {
                coarse[local(cluster.vertices[i])] = local(cluster.coarse_vertices[i]);
            }
            for (const auto& t : cluster.triangles) {
                const std::uint32_t a = local(cluster.vertices[t[0]]);
                const std::uint32_t b = local(cluster.vertices[t[1]]);
                const std::uint32_t c = local(cluster.vertices[t[2]]);
                in.triangles.push_back(s.reverse ? std::array{a, c, b} : std::array{a, b, c});
                in.triangle_cluster.push_back(k);
            }
        }
        const std::vector<std::uint32_t> clusters = in.triangle_cluster;
        in.triangle_cluster.clear();
        out.position +=
            detail::encode_draco_chunk(in, options.compression_level, options.normal_bits)
                .bytes.size();
        in.triangle_cluster = clusters;
        out.cluster +=
            detail::encode_draco_chunk(in, options.compression_level, options.normal_bits)
                .bytes.size();
        in.slots = detail::encode_slots(in.positions, in.triangles, coarse);
        out.slot += detail::encode_draco_chunk(in, options.compression_level, options.normal_bits)
                        .bytes.size();
    }
    return out;
}

struct MainRow {
    std::string name;
    std::size_t objects = 0;
    std::size_t triangles = 0;  ///< full resolution
    Ours ours;
    std::size_t draco_pn = 0, draco_p = 0;  ///< single-rate .glb bytes
    std::size_t draco_p_raw = 0;            ///< the Draco P meshes alone, without the .glb
    std::optional<PackResult> pack;
    ChunkBreakdown chunks;
};

struct SweepRow {
    std::string name;
    double keep = 0.0;
    std::size_t cluster_triangles = 0;
    Ours ours;
    std::size_t draco_pn = 0;
    double seconds = 0.0;
};

void print_main(const std::vector<MainRow>& rows) {
    std::cout << "Progressive .glb (version 3) against single-rate peers of the same surfaces; "
                 "kB = 1000 B\n";
    std::cout << pad("case", 24, true) << pad("objs", 5) << pad("groups", 7) << pad("triangles", 10)
              << pad("ours kB", 9) << pad("Draco PN", 9) << pad("x", 6) << pad("Draco P", 9)
              << pad("x", 6) << pad("gltfpack", 9) << pad("x", 6) << pad("base kB", 8)
              << pad("base %", 7) << pad("JSON B", 8) << pad("B/obj", 6) << pad("aim B", 7) << '\n';
    for (const MainRow& r : rows) {
        const ProgressiveStats& s = r.ours.stats;
        const std::size_t aim = 1000 * s.objects + 10 * s.groups;
        std::cout << pad(r.name, 24, true) << pad(std::to_string(s.objects), 5)
                  << pad(std::to_string(s.groups), 7) << pad(std::to_string(r.triangles), 10)
                  << pad(kb(s.total_bytes), 9) << pad(kb(r.draco_pn), 9)
                  << pad(ratio(double(s.total_bytes), double(r.draco_pn)), 6)
                  << pad(kb(r.draco_p), 9)
                  << pad(ratio(double(s.total_bytes), double(r.draco_p)), 6)
                  << pad(r.pack ? kb(r.pack->bytes) : "-", 9)
                  << pad(r.pack ? ratio(double(s.total_bytes), double(r.pack->bytes)) : "-", 6)
                  << pad(kb(s.base_bytes), 8)
                  << pad(fixed(100.0 * double(s.base_bytes) / double(s.total_bytes), 1), 7)
                  << pad(std::to_string(s.json_bytes), 8)
                  << pad(std::to_string(s.json_bytes / std::max<std::size_t>(1, s.objects)), 6)
                  << pad(std::to_string(aim), 7) << '\n';
    }
    std::cout << "  x: ours / peer. Draco PN: single-rate Draco .glb, POSITION + NORMAL, same grid "
                 "quantization; Draco P: the same without NORMAL; gltfpack: -cc on scene.glb.\n"
                 "  base: GLB header + JSON + DAG tables + base meshes (a first frame's bytes); "
                 "aim B: 1000 per object + 10 per group.\n";
    std::cout << "\nWhere the bytes go (kB): chunks re-encoded with POSITION only (welded, one per "
                 "group), + _CLUSTER, + _SLOT (= the file's chunks); single-rate Draco P raw\n";
    std::cout << pad("case", 24, true) << pad("P", 9) << pad("+CLUSTER", 9) << pad("+SLOT", 9)
              << pad("slot %", 7) << pad("base kB", 8) << pad("JSON kB", 8) << pad("Draco P", 9)
              << '\n';
    for (const MainRow& r : rows) {
        const ProgressiveStats& s = r.ours.stats;
        std::cout << pad(r.name, 24, true) << pad(kb(r.chunks.position), 9)
                  << pad(kb(r.chunks.cluster), 9) << pad(kb(r.chunks.slot), 9)
                  << pad(fixed(100.0 * double(r.chunks.slot - r.chunks.cluster) /
                                   double(s.total_bytes),
                               1),
                         7)
                  << pad(kb(s.base_bytes), 8) << pad(kb(s.json_bytes), 8)
                  << pad(kb(r.draco_p_raw), 9) << '\n';
    }
}

void print_sweep(const std::vector<SweepRow>& rows) {
    if (rows.empty()) {
        return;
    }
    std::cout << "\nSweep of keep fraction and cluster size (models rebuilt from the same "
                 "surfaces)\n";
    std::cout << pad("case", 24, true) << pad("keep", 6) << pad("cluster", 8) << pad("kB", 9)
              << pad("x PN", 6) << pad("base %", 7) << pad("chunks", 7) << pad("mean kB", 8)
              << pad("tris/L0", 8) << pad("s", 6) << '\n';
    for (const SweepRow& r : rows) {
        const ProgressiveStats& s = r.ours.stats;
        std::cout << pad(r.name, 24, true) << pad(fixed(r.keep, 2), 6)
                  << pad(std::to_string(r.cluster_triangles), 8) << pad(kb(s.total_bytes), 9)
                  << pad(ratio(double(s.total_bytes), double(r.draco_pn)), 6)
                  << pad(fixed(100.0 * double(s.base_bytes) / double(s.total_bytes), 1), 7)
                  << pad(std::to_string(s.chunks), 7)
                  << pad(s.chunks > 0 ? kb(s.chunk_bytes / s.chunks) : "-", 8)
                  << pad(ratio(double(r.ours.triangles_all_levels),
                               double(r.ours.triangles_level0)),
                         8)
                  << pad(fixed(r.seconds, 1), 6) << '\n';
    }
    std::cout << "  tris/L0: triangles of every level / level 0 (what refining all the way "
                 "decodes).\n";
}

/// The plain full-resolution scene, as `strata build` writes OUT/scene.glb, for gltfpack.
std::filesystem::path write_plain_scene(const Case& c,
                                        const Reconstruction& result,
                                        const Objects& objects,
                                        const std::filesystem::path& work,
                                        std::size_t& triangles) {
    std::vector<SceneObject> scene;
    for (std::size_t n = 0; n < objects.surfaces.size(); ++n) {
        const MultiresMesh& model = result.models[objects.surfaces[n]];
        const TriMesh full = cut_mesh(model, select_cut_at_level(model, 0));
        triangles += full.triangles.size();
        SceneObject o;
        o.label = objects.labels[n];
        const auto label = std::find_if(c.stack.label_table.begin(), c.stack.label_table.end(),
                                        [&](const LabelInfo& l) { return l.value == o.label; });
        if (label != c.stack.label_table.end()) {
            o.name = label->name;
            o.srgb = {label->color[0] / 255.0, label->color[1] / 255.0, label->color[2] / 255.0};
        }
        o.mesh = surface_to_world(c.stack, result.slice_spacing_px, full);
        scene.push_back(std::move(o));
    }
    SceneInfo info;
    info.source = c.stack.source;
    info.generator = "strata progressive_size";
    const std::filesystem::path file = work / "scene.glb";
    write_scene_gltf(file, scene, info);
    return file;
}

/// The models rebuilt from the reconstruction's surfaces with other multiresolution options.
std::vector<MultiresMesh> rebuild_models(const Reconstruction& result,
                                         const Objects& objects,
                                         const MultiresOptions& multires) {
    std::vector<MultiresMesh> models(result.surfaces.size());
    for (std::size_t i : objects.surfaces) {
        const ObjectSurface& surface = result.surfaces[i];
        const SliceErrorMeter meter(result.contours, result.fields, surface.label,
                                    result.slice_spacing_px);
        MultiresOptions options = multires;
        if (surface.verification.done && !surface.verification.ok()) {
            options.max_levels = 0;
        }
        models[i] = build_multires_mesh(
            surface.mesh, meter, surface.contour_deviation_px + surface.grid_shift_px, options);
        models[i].grid_step = surface.grid_step;
    }
    return models;
}

void run_case(const std::string& spec,
              bool main_table,
              bool sweep,
              const Arguments& args,
              std::vector<MainRow>& main_rows,
              std::vector<SweepRow>& sweep_rows,
              std::vector<std::string>& notes) {
    Case c = load_case(spec);
    const std::filesystem::path work = args.work / safe_stem(c.name);
    std::filesystem::create_directories(work);
    std::cerr << "progressive_size: " << c.name << ": reconstructing\n";
    ReconstructOptions options;
    options.multires.cluster_triangles = args.cluster_triangles;
    options.multires.keep_fraction = args.keep_fraction;
    options.multires.root_triangles = args.root_triangles;
    options.multires.first_level_px = args.first_level_px;
    Report report;
    Reconstruction result = reconstruct(c.stack, options, report);
    const Objects objects = progressive_objects(result, notes, c.name);
    if (objects.surfaces.empty()) {
        throw Error{ErrorCode::InvalidInput, c.name + ": no surface to write"};
    }
    const SliceFrame frame = slice_frame(c.stack, result.slice_spacing_px);
    const auto pointers = [&](const std::vector<MultiresMesh>& models) {
        std::vector<const MultiresMesh*> out;
        for (std::size_t i : objects.surfaces) {
            out.push_back(&models[i]);
        }
        return out;
    };
    std::vector<StorageModel> storage;
    for (std::size_t i : objects.surfaces) {
        storage.push_back(storage_model(result.models[i], frame));
    }
    const std::string draco_pn = single_rate_draco(c, storage, objects, frame, true);
    write_bytes(work / "draco.glb", draco_pn);
    if (main_table) {
        std::cerr << "progressive_size: " << c.name << ": model.glb and peers\n";
        MainRow row;
        row.name = c.name;
        row.objects = objects.surfaces.size();
        row.ours =
            write_ours(work / "model.glb", c, pointers(result.models), objects.labels, frame);
        row.draco_pn = draco_pn.size();
        const std::string draco_p = single_rate_draco(c, storage, objects, frame, false);
        write_bytes(work / "draco_p.glb", draco_p);
        row.draco_p = draco_p.size();
        for (const StorageModel& s : storage) {
            row.draco_p_raw += encode_patch(s, full_patch(s), false).bytes.size();
            const ChunkBreakdown b = chunk_breakdown(s);
            row.chunks.position += b.position;
            row.chunks.cluster += b.cluster;
            row.chunks.slot += b.slot;
        }
        if (row.chunks.slot != row.ours.stats.chunk_bytes) {
            notes.push_back(c.name + ": re-encoded chunks give " + std::to_string(row.chunks.slot) +
                            " bytes, the file " + std::to_string(row.ours.stats.chunk_bytes) +
                            ": the breakdown does not replicate the writer");
        }
        const std::filesystem::path scene =
            write_plain_scene(c, result, objects, work, row.triangles);
        row.pack = gltfpack(args.gltfpack, scene, work / "packed_cc.glb", {"-cc"}, notes);
        main_rows.push_back(row);
    }
    if (sweep) {
        for (const double keep : args.sweep_keep) {
            for (const std::size_t size : args.sweep_clusters) {
                std::cerr << "progressive_size: " << c.name << ": keep " << keep << ", cluster "
                          << size << '\n';
                MultiresOptions multires = options.multires;
                multires.keep_fraction = keep;
                multires.cluster_triangles = size;
                SweepRow row;
                row.name = c.name;
                row.keep = keep;
                row.cluster_triangles = size;
                const auto start = Clock::now();
                const std::vector<MultiresMesh> models = rebuild_models(result, objects, multires);
                row.seconds = seconds_since(start);
                row.ours =
                    write_ours(work / "sweep.glb", c, pointers(models), objects.labels, frame);
                row.draco_pn = draco_pn.size();
                sweep_rows.push_back(row);
            }
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
    std::vector<SweepRow> sweep_rows;
    std::vector<std::string> notes;
    const auto start = Clock::now();
    for (const std::string& spec : specs) {
        const bool in_main =
            std::find(args.cases.begin(), args.cases.end(), spec) != args.cases.end();
        const bool in_sweep = std::find(args.sweep_cases.begin(), args.sweep_cases.end(), spec) !=
                              args.sweep_cases.end();
        const auto case_start = Clock::now();
        run_case(spec, in_main, in_sweep, args, main_rows, sweep_rows, notes);
        std::cerr << "progressive_size: " << spec << ": " << fixed(seconds_since(case_start), 1)
                  << " s\n";
    }
    if (remove_work) {
        std::filesystem::remove_all(args.work);
    }
    if (!main_rows.empty()) {
        print_main(main_rows);
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

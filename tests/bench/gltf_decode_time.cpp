// Decode time of compressed glTF geometry, Draco against meshopt, side by side in one run
// (scripts/bench-lods.sh, issue 23):
//   gltf_decode_time [--seconds S] FILE.glb...
// For each .glb, every KHR_draco_mesh_compression primitive is decoded with Draco's decoder
// (draco::Decoder::DecodeMeshFromBuffer, then every attribute converted to float and the faces
// read, as a glTF loader must), and every EXT_meshopt_compression buffer view with
// meshoptimizer's decoders (meshopt_decodeVertexBuffer / meshopt_decodeIndexBuffer, then the
// view's filter: OCTAHEDRAL, QUATERNION or EXPONENTIAL, as gltfpack writes them). The whole file
// is decoded repeatedly until S seconds (default 0.5) have passed, at least 5 times; the median
// of the repetitions is printed, one line per file:
//   FILE  compression  bytes  triangles  decode_ms  Mtriangles_per_s
// Both decoders run single-threaded in this process, so the comparison is like for like.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <meshoptimizer.h>
#include <stdexcept>
#include <string>
#include <vector>

#include <draco/compression/decode.h>
#include <nlohmann/json.hpp>

namespace {

using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Glb {
    Json json;
    std::string bin;
};

Glb read_glb(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const auto u32 = [&](std::size_t at) {
        if (at + 4 > bytes.size()) {
            throw std::runtime_error(path + ": truncated .glb");
        }
        std::uint32_t v = 0;
        std::memcpy(&v, bytes.data() + at, 4);
        return v;
    };
    if (u32(0) != 0x46546C67u) {
        throw std::runtime_error(path + ": not a .glb");
    }
    Glb g;
    const std::uint32_t length = u32(12);
    g.json = Json::parse(bytes.substr(20, length));
    const std::size_t at = 20 + std::size_t(length);
    if (at + 8 <= bytes.size()) {
        g.bin = bytes.substr(at + 8, u32(at));
    }
    return g;
}

/// What one decode of the file does.
struct Work {
    struct Draco {
        std::size_t offset, length;
    };
    struct Meshopt {
        std::size_t offset, length, count, stride;
        bool indices;
        std::string filter;
    };
    std::vector<Draco> draco;
    std::vector<Meshopt> meshopt;
    std::size_t triangles = 0;
};

Work plan(const Glb& g) {
    Work w;
    const Json& views = g.json.value("bufferViews", Json::array());
    for (const Json& mesh : g.json.value("meshes", Json::array())) {
        for (const Json& p : mesh["primitives"]) {
            const Json& accessors = g.json["accessors"];
            if (p.contains("indices")) {
                w.triangles += accessors[p["indices"].get<int>()]["count"].get<std::size_t>() / 3;
            }
            if (p.contains("extensions") &&
                p["extensions"].contains("KHR_draco_mesh_compression")) {
                const Json& v =
                    views[p["extensions"]["KHR_draco_mesh_compression"]["bufferView"].get<int>()];
                w.draco.push_back(
                    {v.value("byteOffset", std::size_t{0}), v["byteLength"].get<std::size_t>()});
            }
        }
    }
    for (const Json& v : views) {
        if (!v.contains("extensions") || !v["extensions"].contains("EXT_meshopt_compression")) {
            continue;
        }
        const Json& e = v["extensions"]["EXT_meshopt_compression"];
        if (e.value("buffer", 0) != 0) {
            throw std::runtime_error("meshopt data outside the GLB's binary chunk");
        }
        const std::string mode = e["mode"];
        if (mode != "ATTRIBUTES" && mode != "TRIANGLES") {
            throw std::runtime_error("meshopt mode " + mode + " not measured");
        }
        w.meshopt.push_back({e.value("byteOffset", std::size_t{0}),
                             e["byteLength"].get<std::size_t>(), e["count"].get<std::size_t>(),
                             e["byteStride"].get<std::size_t>(), mode == "TRIANGLES",
                             e.value("filter", std::string("NONE"))});
    }
    return w;
}

/// One full decode; returns a checksum so nothing is optimised away.
std::uint64_t decode(const Glb& g, const Work& w) {
    std::uint64_t sum = 0;
    for (const Work::Draco& d : w.draco) {
        draco::DecoderBuffer in;
        in.Init(g.bin.data() + d.offset, d.length);
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&in);
        if (!decoded.ok()) {
            throw std::runtime_error("Draco: " + decoded.status().error_msg_string());
        }
        const auto mesh = std::move(decoded).value();
        std::vector<float> values;
        for (int a = 0; a < mesh->num_attributes(); ++a) {
            const draco::PointAttribute* att = mesh->attribute(a);
            const int n = att->num_components();
            values.resize(std::size_t(mesh->num_points()) * n);
            for (draco::PointIndex i(0); i < mesh->num_points(); ++i) {
                att->ConvertValue<float>(att->mapped_index(i), n,
                                         &values[std::size_t(i.value()) * n]);
            }
            sum += values.empty() ? 0 : static_cast<std::uint64_t>(values.back() * 1000.0f);
        }
        std::vector<std::uint32_t> faces(std::size_t(mesh->num_faces()) * 3);
        for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f) {
            for (int k = 0; k < 3; ++k) {
                faces[3 * std::size_t(f.value()) + k] = mesh->face(f)[k].value();
            }
        }
        sum += faces.empty() ? 0 : faces.back();
    }
    std::vector<unsigned char> out;
    for (const Work::Meshopt& m : w.meshopt) {
        out.resize(m.count * m.stride);
        const auto* src = reinterpret_cast<const unsigned char*>(g.bin.data() + m.offset);
        const int rc =
            m.indices ? meshopt_decodeIndexBuffer(out.data(), m.count, m.stride, src, m.length)
                      : meshopt_decodeVertexBuffer(out.data(), m.count, m.stride, src, m.length);
        if (rc != 0) {
            throw std::runtime_error("meshopt: a stream does not decode (codec version?)");
        }
        if (m.filter == "OCTAHEDRAL") {
            meshopt_decodeFilterOct(out.data(), m.count, m.stride);
        } else if (m.filter == "QUATERNION") {
            meshopt_decodeFilterQuat(out.data(), m.count, m.stride);
        } else if (m.filter == "EXPONENTIAL") {
            meshopt_decodeFilterExp(out.data(), m.count, m.stride);
        }
        sum += out.empty() ? 0 : out.back();
    }
    return sum;
}

}  // namespace

int main(int argc, char** argv) {
    double seconds = 0.5;
    std::vector<std::string> files;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        if (arg == "--seconds" && i + 1 < argc) {
            seconds = std::stod(argv[++i]);
        } else if (arg == "-h" || arg == "--help") {
            std::cout << "usage: gltf_decode_time [--seconds S] FILE.glb...\n";
            return 0;
        } else {
            files.push_back(arg);
        }
    }
    if (files.empty()) {
        std::cerr << "usage: gltf_decode_time [--seconds S] FILE.glb...\n";
        return 2;
    }
    int status = 0;
    std::uint64_t checksum = 0;
    for (const std::string& file : files) {
        try {
            const Glb g = read_glb(file);
            const Work w = plan(g);
            const char* kind = w.draco.empty() ? (w.meshopt.empty() ? "none" : "meshopt")
                                               : (w.meshopt.empty() ? "draco" : "both");
            if (w.draco.empty() && w.meshopt.empty()) {  // plain accessors: nothing to decode
                std::ifstream size(file, std::ios::binary | std::ios::ate);
                std::printf("%s none %lld %zu - -\n", file.c_str(),
                            static_cast<long long>(size.tellg()), w.triangles);
                continue;
            }
            std::vector<double> ms;
            const auto start = Clock::now();
            while (ms.size() < 5 ||
                   std::chrono::duration<double>(Clock::now() - start).count() < seconds) {
                const auto t0 = Clock::now();
                checksum += decode(g, w);
                ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
            }
            std::sort(ms.begin(), ms.end());
            const double median = ms[ms.size() / 2];
            std::ifstream size(file, std::ios::binary | std::ios::ate);
            std::printf("%s %s %lld %zu %.3f %.2f\n", file.c_str(), kind,
                        static_cast<long long>(size.tellg()), w.triangles, median,
                        median > 0 ? double(w.triangles) / median / 1000.0 : 0.0);
        } catch (const std::exception& e) {
            std::printf("%s error - - - -\n", file.c_str());
            std::cerr << "gltf_decode_time: " << file << ": " << e.what() << '\n';
            status = 1;
        }
    }
    std::cerr << "gltf_decode_time: checksum " << checksum << '\n';
    return status;
}

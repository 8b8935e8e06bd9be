#include "exporters/read_progressive_gltf.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "exporters/progressive_gltf.h"
#include "mesh/mesh_checks.h"
#include "phantom/catalogue.h"
#include "pipeline/reconstruct.h"
#include "support/test_paths.h"

namespace strata {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

struct Written {
    Reconstruction result;
    SliceFrame frame;
    fs::path glb;
    fs::path gltf;
};

/// The torus reconstructed, written as .glb and .gltf (frame: 0.8 mm pixels, mirrored in x).
const Written& torus() {
    static const Written written = [] {
        Written w;
        const Phantom phantom = make_phantom("torus");
        ReconstructOptions options;
        options.multires.cluster_triangles = 256;
        Report report;
        w.result = reconstruct(phantom.stack, options, report);
        w.frame.linear = {-0.8, 0, 0, 0, 0.8, 0, 0, 0, 0.8};
        w.frame.origin = {10.0, -20.0, 30.0};
        w.frame.slice_spacing_px = w.result.slice_spacing_px;
        w.frame.error_mm_per_px = 0.8;
        std::vector<ProgressiveObject> objects(1);
        objects[0].name = "torus";
        objects[0].label = 1;
        objects[0].srgb = {0.5, 0.5, 0.5};
        objects[0].model = &w.result.models.at(0);
        SceneInfo info;
        info.generator = "strata test";
        const fs::path dir = test::fresh_temp_dir("read_progressive");
        w.glb = dir / "torus.glb";
        w.gltf = dir / "torus.gltf";
        write_progressive_gltf(w.glb, objects, w.frame, info);
        write_progressive_gltf(w.gltf, objects, w.frame, info);
        return w;
    }();
    return written;
}

using Key = std::array<float, 3>;
using TriKey = std::array<Key, 3>;

/// Storage coordinates of a slice-space position (what the file holds).
Key storage(const Vec3& p, double d, double flip, double step) {
    return {static_cast<float>(flip * p.x), static_cast<float>(p.y),
            static_cast<float>(std::nearbyint(p.z / d / step) * step)};
}

TriKey canonical(TriKey t) {
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
}

/// Triangles of a mesh as position triples, canonical, sorted; reversed when `reverse`.
std::vector<TriKey> triangles(const TriMesh& mesh,
                              const std::function<Key(const Vec3&)>& key,
                              bool reverse) {
    std::vector<TriKey> out;
    for (const auto& t : mesh.triangles) {
        TriKey k{key(mesh.positions[t[0]]), key(mesh.positions[t[1]]), key(mesh.positions[t[2]])};
        if (reverse) {
            std::swap(k[1], k[2]);
        }
        out.push_back(canonical(k));
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// Error bounds are written rounded up to 7 significant digits.
void expect_written_bound(double read, double exact) {
    EXPECT_GE(read, exact);
    EXPECT_LE(read, exact * (1.0 + 1e-6));
}

void expect_same_model(const ProgressiveFile& file, const Written& w) {
    ASSERT_EQ(file.objects.size(), 1u);
    const ProgressiveFileObject& object = file.objects[0];
    const MultiresMesh& mem = w.result.models[0];
    const MultiresMesh& read = object.model;
    EXPECT_EQ(object.name, "torus");
    EXPECT_EQ(object.label, 1);
    EXPECT_EQ(file.generator, "strata test");
    ASSERT_EQ(read.clusters.size(), mem.clusters.size());
    ASSERT_EQ(read.groups.size(), mem.groups.size());
    EXPECT_EQ(read.positions.size(), mem.positions.size()) << "vertices merged or split";
    const double m_per_px = w.frame.error_mm_per_px / 1000.0;
    expect_written_bound(read.full_resolution_error_px, mem.full_resolution_error_px * m_per_px);
    for (std::size_t g = 0; g < mem.groups.size(); ++g) {
        EXPECT_EQ(read.groups[g].consumed, mem.groups[g].consumed);
        EXPECT_EQ(read.groups[g].produced, mem.groups[g].produced);
        EXPECT_EQ(read.groups[g].level, mem.groups[g].level);
        expect_written_bound(read.groups[g].error_px, mem.groups[g].error_px * m_per_px);
    }
    const double d = w.result.slice_spacing_px;
    const auto mem_key = [&](const Vec3& p) { return storage(p, d, -1.0, mem.grid_step); };
    const auto file_key = [](const Vec3& p) {
        return Key{static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
    };
    // every level cut and a ladder of error cuts: the same triangles, exactly
    const std::uint32_t levels = level_count(mem);
    ASSERT_EQ(level_count(read), levels);
    for (std::uint32_t level = 0; level < levels; ++level) {
        const MultiresCut a = select_cut_at_level(mem, level);
        const MultiresCut b = select_cut_at_level(read, level);
        EXPECT_EQ(a.clusters, b.clusters) << "level " << level;
        EXPECT_EQ(triangles(cut_mesh(mem, a), mem_key, true),
                  triangles(cut_mesh(read, b), file_key, false))
            << "level " << level;
        const TriMesh patient = file_cut_to_patient(object, b);
        const MeshReport check = check_mesh(patient);
        EXPECT_TRUE(is_closed_manifold(check)) << "level " << level;
        EXPECT_GT(check.signed_volume, 0.0) << "level " << level << ": faces inwards";
    }
    std::set<double> errors{mem.full_resolution_error_px};
    for (const MultiresGroup& g : mem.groups) {
        errors.insert(g.error_px);
    }
    for (auto it = errors.begin(); it != errors.end(); ++it) {
        const auto next = std::next(it);
        const double tau = next == errors.end() ? *it * 2.0 : (*it + *next) / 2.0;
        const MultiresCut a = select_cut_by_error(mem, tau);
        const MultiresCut b = select_cut_by_error(read, tau * m_per_px);
        EXPECT_EQ(a.clusters, b.clusters) << "tau " << tau;
        expect_written_bound(b.error_px, a.error_px * m_per_px);
    }
    // geomorph targets: the same vertex, found by position
    for (std::size_t c = 0; c < mem.clusters.size(); ++c) {
        const MultiresCluster& mc = mem.clusters[c];
        const MultiresCluster& rc = read.clusters[c];
        ASSERT_EQ(rc.vertices.size(), mc.vertices.size());
        ASSERT_EQ(rc.coarse_vertices.size(), mc.coarse_vertices.size());
        std::set<std::pair<Key, Key>> expected, got;
        for (std::size_t i = 0; i < mc.coarse_vertices.size(); ++i) {
            expected.insert({mem_key(mem.positions[mc.vertices[i]]),
                             mem_key(mem.positions[mc.coarse_vertices[i]])});
            got.insert({file_key(read.positions[rc.vertices[i]]),
                        file_key(read.positions[rc.coarse_vertices[i]])});
        }
        EXPECT_EQ(expected, got) << "cluster " << c;
    }
}

TEST(ReadProgressiveGltf, GlbRoundTripGivesTheSameCuts) {
    const ProgressiveFile file = read_progressive_gltf(torus().glb);
    expect_same_model(file, torus());
    EXPECT_EQ(file.total_bytes, fs::file_size(torus().glb));
    EXPECT_GT(file.objects[0].base_bytes, 0u);
    EXPECT_FALSE(file.objects[0].level_bytes.empty());
}

TEST(ReadProgressiveGltf, GltfRoundTripGivesTheSameCuts) {
    expect_same_model(read_progressive_gltf(torus().gltf), torus());
}

/// The .glb's JSON and BIN, to corrupt and repack.
struct Glb {
    Json json;
    std::string bin;
};

Glb unpack(const std::string& bytes) {
    std::uint32_t json_length = 0, bin_length = 0;
    std::memcpy(&json_length, bytes.data() + 12, 4);
    std::memcpy(&bin_length, bytes.data() + 20 + json_length, 4);
    return {Json::parse(bytes.substr(20, json_length)), bytes.substr(28 + json_length, bin_length)};
}

std::string pack(const Glb& glb) {
    std::string json = glb.json.dump();
    json.resize((json.size() + 3) / 4 * 4, ' ');
    std::string out(12, '\0');
    const auto put = [&](std::uint32_t v) {
        char b[4];
        std::memcpy(b, &v, 4);
        out.append(b, 4);
    };
    put(static_cast<std::uint32_t>(json.size()));
    put(0x4E4F534A);
    out += json;
    put(static_cast<std::uint32_t>(glb.bin.size()));
    put(0x004E4942);
    out += glb.bin;
    const std::uint32_t header[3] = {0x46546C67, 2, static_cast<std::uint32_t>(out.size())};
    std::memcpy(out.data(), header, 12);
    return out;
}

void expect_rejected(const std::string& bytes, const std::string& fragment) {
    try {
        read_progressive_gltf(bytes, "corrupt.glb", [](const std::string&) -> std::string {
            throw Error(ErrorCode::Io, "no external buffers here");
        });
        ADD_FAILURE() << "accepted; expected an error with '" << fragment << "'";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
}

TEST(ReadProgressiveGltf, CorruptFilesAreRejectedWithWhatAndWhere) {
    const std::string good = test::read_file(torus().glb);
    ASSERT_NO_THROW(read_progressive_gltf(good, "good.glb", nullptr));
    expect_rejected(good.substr(0, good.size() - 100), "GLB header says");
    expect_rejected(good.substr(0, 10), "shorter than its 20-byte header");
    std::string bytes = good;
    bytes[20] = '#';
    expect_rejected(bytes, "not glTF JSON");

    const Glb glb = unpack(good);
    ASSERT_EQ(pack(glb).size(), good.size());
    const auto mutated = [&](const std::function<void(Glb&)>& change) {
        Glb g = glb;
        change(g);
        return pack(g);
    };
    const std::string ext = "/nodes/1/extensions/STRATA_progressive_mesh";
    const auto at = [&](Json& j, const std::string& pointer) -> Json& {
        return j[Json::json_pointer(ext + pointer)];
    };
    const std::size_t last = glb.json[Json::json_pointer(ext + "/groups")].size() - 1;
    // errors: a top group below its children
    expect_rejected(
        mutated([&](Glb& g) { at(g.json, "/groups/" + std::to_string(last) + "/error") = 0.0; }),
        "errors must be monotone");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/groups/0/error") = -1.0; }),
                    "expected a finite number >= 0");
    // links: an index out of range, a cluster consumed twice, a cycle (children not first)
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/groups/0/consumed/0") = 1000000; }),
                    "out of range");
    expect_rejected(
        mutated([&](Glb& g) {
            at(g.json, "/groups/1/consumed").push_back(at(g.json, "/groups/0/consumed/0"));
        }),
        "consumed twice");
    expect_rejected(mutated([&](Glb& g) {
                        std::swap(at(g.json, "/groups/0"),
                                  at(g.json, "/groups/" + std::to_string(last)));
                    }),
                    "");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/clusters/0/sphere/3") = -1.0; }),
                    "negative radius");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/clusters/0").erase("sphere"); }),
                    "expected [x, y, z, radius]");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "").erase("gridStep"); }), "gridStep");
    // data: a view past its buffer, an accessor past its view, a truncated Draco chunk,
    // a base index out of range
    expect_rejected(mutated([&](Glb& g) { g.json["bufferViews"][0]["byteLength"] = 1u << 30; }),
                    "out of range");
    expect_rejected(mutated([&](Glb& g) {
                        const int base = g.json["nodes"][1]["mesh"];
                        const int accessor =
                            g.json["meshes"][base]["primitives"][0]["attributes"]["POSITION"];
                        g.json["accessors"][accessor]["count"] = 1u << 20;
                    }),
                    "do not fit buffer view");
    expect_rejected(
        mutated([&](Glb& g) {
            for (Json& mesh : g.json["meshes"]) {
                Json& p = mesh["primitives"][0];
                if (p.contains("extensions")) {
                    g.json["accessors"][p["attributes"]["POSITION"].get<int>()]["count"] = 3;
                    return;
                }
            }
        }),
        "Draco decoded");
    expect_rejected(mutated([&](Glb& g) {
                        for (Json& mesh : g.json["meshes"]) {
                            Json& p = mesh["primitives"][0];
                            if (p.contains("extensions")) {
                                const int view =
                                    p["extensions"]["KHR_draco_mesh_compression"]["bufferView"];
                                g.json["bufferViews"][view]["byteLength"] = 7;
                                return;
                            }
                        }
                    }),
                    "Draco cannot decode");
    expect_rejected(mutated([&](Glb& g) {
                        const int base = g.json["nodes"][1]["mesh"];
                        const int accessor = g.json["meshes"][base]["primitives"][0]["indices"];
                        const std::size_t view = g.json["accessors"][accessor]["bufferView"];
                        const std::size_t offset = g.json["bufferViews"][view]["byteOffset"];
                        g.bin[offset] = static_cast<char>(0xFF);
                        g.bin[offset + 1] = static_cast<char>(0x7F);
                    }),
                    "triangle index");
    expect_rejected(
        mutated([&](Glb& g) { g.json["nodes"][1]["extensions"].erase("STRATA_progressive_mesh"); }),
        "not a progressive strata file");
}

TEST(ReadProgressiveGltf, GltfBuffersMustBeFilesBesideIt) {
    const fs::path dir = test::fresh_temp_dir("read_progressive_uri");
    Json json = Json::parse(test::read_file(torus().gltf));
    for (const auto& entry : fs::directory_iterator(torus().gltf.parent_path())) {
        if (entry.path().extension() == ".bin" &&
            entry.path().stem().string().starts_with("torus")) {
            fs::copy_file(entry.path(), dir / entry.path().filename());
        }
    }
    const auto write_and_read = [&](const std::string& uri) {
        Json j = json;
        j["buffers"][0]["uri"] = uri;
        std::ofstream(dir / "t.gltf") << j.dump();
        return read_progressive_gltf(dir / "t.gltf");
    };
    EXPECT_NO_THROW(write_and_read("torus.bin"));
    for (const std::string uri :
         {"../torus.bin", "/etc/passwd", "data:application/octet-stream;base64,AAAA"}) {
        try {
            write_and_read(uri);
            ADD_FAILURE() << uri << " accepted";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("not a relative file name"), std::string::npos)
                << e.what();
        }
    }
    try {
        write_and_read("missing.bin");
        ADD_FAILURE() << "missing buffer file accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Io) << e.what();
    }
}

}  // namespace
}  // namespace strata

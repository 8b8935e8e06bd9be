#include "exporters/read_progressive_gltf.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "exporters/progressive_format.h"
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

/// Error bounds are written rounded up to 3 significant digits.
void expect_written_bound(double read, double exact) {
    EXPECT_GE(read, exact);
    EXPECT_LE(read, exact * (1.0 + 1e-2));
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
        // errors are written rounded up to 3 significant digits: skip a bound that falls between
        // an exact error and its written value (the file rightly refines that group, memory not)
        const bool ambiguous = std::any_of(errors.begin(), errors.end(), [&](double e) {
            return e <= tau && format::round_up_decimal(e * m_per_px, 3) > tau * m_per_px;
        });
        if (ambiguous) {
            continue;
        }
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

/// The .glb with one change to its JSON or BIN.
struct Mutator {
    Glb glb;
    std::string ext = "/nodes/2/extensions/STRATA_progressive_mesh";  ///< the object's
    std::string file_ext = "/extensions/STRATA_progressive_mesh";     ///< version, views

    std::string operator()(const std::function<void(Glb&)>& change) const {
        Glb g = glb;
        change(g);
        return pack(g);
    }

    /// Offset in the BIN of one of the file's buffer views ("dag", "chunks").
    std::size_t view(const Glb& g, const std::string& name) const {
        const int v = g.json[Json::json_pointer(file_ext + "/" + name)];
        return g.json["bufferViews"][v].value("byteOffset", std::size_t{0});
    }

    /// Offset in the BIN of the object's DAG table.
    std::size_t table(const Glb& g) const {
        return view(g, "dag") + g.json[Json::json_pointer(ext + "/dag")].get<std::size_t>();
    }
};

void put32(std::string& bytes, std::size_t at, std::uint32_t v) {
    std::memcpy(bytes.data() + at, &v, 4);
}

std::uint32_t get32(const std::string& bytes, std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
}

TEST(ReadProgressiveGltf, CorruptFilesAreRejectedWithWhatAndWhere) {
    const std::string good = test::read_file(torus().glb);
    ASSERT_NO_THROW(read_progressive_gltf(good, "good.glb", nullptr));
    expect_rejected(good.substr(0, good.size() - 100), "GLB header says");
    expect_rejected(good.substr(0, 10), "shorter than its 20-byte header");
    std::string bytes = good;
    bytes[20] = '#';
    expect_rejected(bytes, "not glTF JSON");

    const Mutator mutated{unpack(good)};
    ASSERT_EQ(pack(mutated.glb).size(), good.size());
    const std::string& ext = mutated.ext;
    const auto at = [&](Json& j, const std::string& pointer) -> Json& {
        return j[Json::json_pointer(ext + pointer)];
    };
    const std::size_t groups = mutated.glb.json[Json::json_pointer(ext + "/errors")].size();
    ASSERT_GT(groups, 2u);
    // errors: a top group below its children; negative; one missing
    expect_rejected(
        mutated([&](Glb& g) { at(g.json, "/errors/" + std::to_string(groups - 1)) = 0.0; }),
        "errors must be monotone");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/errors/0") = -1.0; }),
                    "expected a finite number >= 0");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/errors").erase(0); }),
                    "expected errors.length");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "").erase("gridStep"); }), "gridStep");
    // the table: magic, an id out of range, a cluster consumed twice, children not first,
    // a negative radius, a chunk outside its view
    expect_rejected(mutated([&](Glb& g) { g.bin[mutated.table(g)] = 'X'; }), "no \"SDAG\" magic");
    const std::size_t lists = 16 + 32 * groups;
    expect_rejected(mutated([&](Glb& g) {
                        g.bin[mutated.table(g) + lists] = static_cast<char>(0xFF);
                        g.bin[mutated.table(g) + lists + 1] = static_cast<char>(0xFF);
                    }),
                    "expected < clusterCount");
    expect_rejected(mutated([&](Glb& g) {
                        // group 1's first consumed id := group 0's first consumed id
                        const std::size_t t = mutated.table(g);
                        const std::size_t ids0 = get32(g.bin, t + 16 + 24) & 0xFFFF;
                        const std::size_t produced0 = get32(g.bin, t + 16 + 24) >> 16;
                        const std::size_t first1 = t + lists + 2 * (ids0 + produced0);
                        g.bin[first1] = g.bin[t + lists];
                        g.bin[first1 + 1] = g.bin[t + lists + 1];
                    }),
                    "consumed by group 0 already");
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t t = mutated.table(g);
                        float r = -1.0f;
                        std::memcpy(g.bin.data() + t + 16 + 12, &r, 4);
                    }),
                    "negative radius");
    // (the chunk placed last in the view: a longer one before it would overlap the next)
    std::size_t last_placed = 0;
    for (std::size_t k = 1; k < groups; ++k) {
        const std::size_t t = mutated.table(mutated.glb);
        if (get32(mutated.glb.bin, t + 16 + 32 * k + 16) >
            get32(mutated.glb.bin, t + 16 + 32 * last_placed + 16)) {
            last_placed = k;
        }
    }
    expect_rejected(mutated([&](Glb& g) {
                        put32(g.bin, mutated.table(g) + 16 + 32 * last_placed + 20, 1u << 30);
                    }),
                    "leaves the chunks buffer view");
    // chunks shared by every group (a small file that would decode one chunk many times)
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t t = mutated.table(g);
                        for (std::size_t k = 1; k < groups; ++k) {
                            put32(g.bin, t + 16 + 32 * k + 16, get32(g.bin, t + 16 + 16));
                            put32(g.bin, t + 16 + 32 * k + 20, get32(g.bin, t + 16 + 20));
                        }
                    }),
                    "chunks overlap");
    // a truncated chunk
    expect_rejected(mutated([&](Glb& g) { put32(g.bin, mutated.table(g) + 16 + 20, 7); }),
                    "not a Draco bitstream");
    // the base: accessors that disagree with the Draco data
    expect_rejected(mutated([&](Glb& g) {
                        const int base = g.json["nodes"][2]["mesh"];
                        for (const auto& [name, a] :
                             g.json["meshes"][base]["primitives"][0]["attributes"].items()) {
                            g.json["accessors"][a.get<int>()]["count"] = 3;
                        }
                    }),
                    "the accessors say");
    expect_rejected(mutated([&](Glb& g) { g.json["bufferViews"][0]["byteLength"] = 1u << 30; }),
                    "out of range");
    // version 1 and files without the extension
    try {
        read_progressive_gltf(
            mutated([&](Glb& g) { g.json[Json::json_pointer(mutated.file_ext + "/version")] = 1; }),
            "v1.glb", nullptr);
        ADD_FAILURE() << "a version 1 extension accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Unsupported);
        EXPECT_NE(std::string(e.what()).find("version"), std::string::npos) << e.what();
    }
    expect_rejected(
        mutated([&](Glb& g) { g.json["nodes"][2]["extensions"].erase("STRATA_progressive_mesh"); }),
        "not a progressive strata file");
    try {
        read_progressive_gltf(
            mutated([&](Glb& g) { g.json["extensions"].erase("STRATA_progressive_mesh"); }),
            "no_file_extension.glb", nullptr);
        ADD_FAILURE() << "a file without the top-level extension accepted";
    } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::Unsupported);
        EXPECT_NE(std::string(e.what()).find("rebuild it"), std::string::npos) << e.what();
    }
    // tables: a second object naming the first one's table (parsed and decoded twice); an
    // offset off the 4-byte grid or beyond the view; the node tree: a node reached twice
    expect_rejected(mutated([&](Glb& g) {
                        g.json["nodes"].push_back(g.json["nodes"][2]);
                        g.json["nodes"][1]["children"].push_back(g.json["nodes"].size() - 1);
                    }),
                    "overlaps another object's");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/dag") = 2; }), "expected a multiple of 4");
    expect_rejected(mutated([&](Glb& g) { at(g.json, "/dag") = 1u << 20; }), "/dag");
    expect_rejected(mutated([&](Glb& g) { g.json["nodes"][1]["children"].push_back(1); }),
                    "reached twice");
}

// Issue 18: JSON fields of the wrong type were read with nlohmann's get<>(), whose type_error
// escaped as an internal error. Every field read says where (a JSON pointer) and what was expected.
TEST(ReadProgressiveGltf, FieldsOfTheWrongTypeNameTheirPointer) {
    const Mutator mutated{unpack(test::read_file(torus().glb))};
    const int base = mutated.glb.json["nodes"][2]["mesh"];
    const std::string primitive = "/meshes/" + std::to_string(base) + "/primitives/0";
    const int position = mutated.glb.json[Json::json_pointer(primitive + "/attributes/POSITION")];
    const int material = mutated.glb.json[Json::json_pointer(primitive + "/material")];
    const std::string m = "/materials/" + std::to_string(material);
    const std::string a = "/accessors/" + std::to_string(position);
    const std::vector<std::pair<std::string, Json>> cases = {
        {"/asset/version", 2.0},
        {"/asset/generator", 7},
        {"/nodes/2/name", 12},
        {m, 3},
        {m + "/pbrMetallicRoughness", 1},
        {m + "/pbrMetallicRoughness/baseColorFactor", "red"},
        {primitive + "/mode", "TRIANGLES"},
        {a + "/normalized", "no"},
        {a + "/count", "many"},
        {"/nodes/1/matrix", Json::object()},
        {"/nodes/2/matrix", Json::object()},
        {"/nodes/2/extras/label", "one"},
        {mutated.ext + "/errors", 0.5},
        {mutated.ext + "/dag", "0"},
        {"/bufferViews/0/byteOffset", -4},
        {"/buffers/0", Json::array()},
        {"/scenes/0/nodes", 0},
    };
    for (const auto& [pointer, value] : cases) {
        SCOPED_TRACE(pointer);
        const std::string bytes =
            mutated([&](Glb& g) { g.json[Json::json_pointer(pointer)] = value; });
        try {
            read_progressive_gltf(bytes, "typed.glb", nullptr);
            ADD_FAILURE() << "accepted";
        } catch (const Error& e) {
            EXPECT_EQ(e.code(), ErrorCode::InvalidInput) << e.what();
            EXPECT_NE(std::string(e.what()).find(pointer), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("expected"), std::string::npos) << e.what();
        }
    }
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

/// The fuzz target's structure-aware seeds (tests/fuzz/corpus/read_progressive), written when
/// STRATA_FUZZ_SEED_DIR is set: a small valid file and one variant per class of damage the reader
/// must refuse (fields of the wrong type, table corruptions, shared and oversized chunks, versions
/// 1 and 2, bounds not monotone), so that mutations start next to every check.
TEST(ReadProgressiveGltfSeeds, WritesFuzzSeeds) {
    const char* dir = std::getenv("STRATA_FUZZ_SEED_DIR");
    if (dir == nullptr) {
        GTEST_SKIP() << "STRATA_FUZZ_SEED_DIR not set";
    }
    Written w;
    const Phantom phantom = make_phantom("sphere");
    ReconstructOptions options;
    options.multires.cluster_triangles = 64;
    Report report;
    w.result = reconstruct(phantom.stack, options, report);
    w.frame.linear = {0.8, 0, 0, 0, 0.8, 0, 0, 0, 0.8};
    w.frame.slice_spacing_px = w.result.slice_spacing_px;
    w.frame.error_mm_per_px = 0.8;
    std::vector<ProgressiveObject> objects(1);
    objects[0].name = "s";
    objects[0].model = &w.result.models.at(0);
    const fs::path out(dir);
    write_progressive_gltf(out / "valid.glb", objects, w.frame, SceneInfo{});
    const Mutator mutated{unpack(test::read_file(out / "valid.glb"))};
    const auto seed = [&](const std::string& name, const std::function<void(Glb&)>& change) {
        std::ofstream(out / (name + ".glb"), std::ios::binary) << mutated(change);
    };
    const auto set = [&](const std::string& pointer, const Json& value) {
        return [=](Glb& g) { g.json[Json::json_pointer(pointer)] = value; };
    };
    seed("asset_version_number", set("/asset/version", 2));
    seed("generator_number", set("/asset/generator", 1));
    seed("node_name_number", set("/nodes/2/name", 1));
    seed("material_number", set("/materials/0", 1));
    seed("pbr_number", set("/materials/0/pbrMetallicRoughness", 1));
    seed("mode_string", set("/meshes/0/primitives/0/mode", "4"));
    seed("normalized_string", set("/accessors/0/normalized", "true"));
    seed("version_1", set(mutated.file_ext + "/version", 1));
    seed("version_2", set(mutated.file_ext + "/version", 2));
    seed("fine_not_monotone", [&](Glb& g) {
        const std::size_t t = mutated.table(g);
        const std::size_t last = get32(g.bin, t + 8) - 1;
        const std::size_t at = t + 16 + 32 * last + 28;
        put32(g.bin, at, get32(g.bin, at) & 0xFFFFu);
    });
    seed("errors_not_monotone", set(mutated.ext + "/errors/0", 1.0));
    seed("tables_shared", [&](Glb& g) {
        g.json["nodes"].push_back(g.json["nodes"][2]);
        g.json["nodes"][1]["children"].push_back(g.json["nodes"].size() - 1);
    });
    seed("node_cycle", [&](Glb& g) { g.json["nodes"][1]["children"].push_back(0); });
    seed("table_magic", [&](Glb& g) { g.bin[mutated.table(g)] = 'X'; });
    seed("table_counts", [&](Glb& g) { put32(g.bin, mutated.table(g) + 4, 1u << 31); });
    seed("chunks_shared", [&](Glb& g) {
        const std::size_t t = mutated.table(g);
        const std::size_t groups = get32(g.bin, t + 8);
        for (std::size_t k = 1; k < groups; ++k) {
            put32(g.bin, t + 16 + 32 * k + 16, get32(g.bin, t + 16 + 16));
            put32(g.bin, t + 16 + 32 * k + 20, get32(g.bin, t + 16 + 20));
        }
    });
    seed("chunk_declares_more", [&](Glb& g) {
        const std::size_t chunk = mutated.view(g, "chunks") + get32(g.bin, mutated.table(g) + 32);
        g.bin[chunk + 13] = static_cast<char>(0x7F);
    });
}

// Each side of the limits the reader checks in the DAG table and the extension's JSON (issue 24
// item 2): the file as written is on the valid side of each, one step further is refused.
TEST(ReadProgressiveGltf, TableAndExtensionFieldsEachSideOfTheirLimits) {
    const std::string good = test::read_file(torus().glb);
    ASSERT_NO_THROW(read_progressive_gltf(good, "good.glb", nullptr));
    const Mutator mutated{unpack(good)};
    const std::string& ext = mutated.ext;
    const std::size_t groups = mutated.glb.json[Json::json_pointer(ext + "/errors")].size();
    const std::size_t t0 = mutated.table(mutated.glb);
    ASSERT_EQ(get32(mutated.glb.bin, t0 + 12), 2u);  // idBytes as written
    ASSERT_GE(get32(mutated.glb.bin, t0 + 4), 1u);   // clusterCount
    // clusterCount >= 1; groupCount = errors.length; idBytes 2 or 4
    expect_rejected(mutated([&](Glb& g) { put32(g.bin, mutated.table(g) + 4, 0); }),
                    "clusterCount 0, expected >= 1");
    expect_rejected(
        mutated([&](Glb& g) { g.json[Json::json_pointer(ext + "/errors")].push_back(1.0); }),
        "groupCount " + std::to_string(groups) +
            ", expected errors.length = " + std::to_string(groups + 1));
    for (const std::uint32_t id_bytes : {1u, 3u}) {
        expect_rejected(mutated([&](Glb& g) { put32(g.bin, mutated.table(g) + 12, id_bytes); }),
                        "idBytes " + std::to_string(id_bytes) + ", expected 2 or 4");
    }
    // per group record: radius >= 0 (the smallest negative float is refused), chunk length >= 1,
    // counts >= 1, level >= 1
    const std::size_t r0 = 16;
    expect_rejected(mutated([&](Glb& g) {
                        const float r = -std::numeric_limits<float>::denorm_min();
                        std::memcpy(g.bin.data() + mutated.table(g) + r0 + 12, &r, 4);
                    }),
                    "group 0: negative radius");
    expect_rejected(mutated([&](Glb& g) { put32(g.bin, mutated.table(g) + r0 + 20, 0); }),
                    "group 0: empty chunk, expected >= 1 byte");
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t at = mutated.table(g) + r0 + 24;
                        put32(g.bin, at, get32(g.bin, at) & 0xFFFF0000u);  // consumed count 0
                    }),
                    "expected >= 1 each");
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t at = mutated.table(g) + r0 + 28;
                        put32(g.bin, at, 0);  // level 0, fine 0
                    }),
                    "group 0: level 0, expected >= 1");
    // the bound against the finest level (fine, the record's last uint16) monotone: the last
    // group (a parent) at fine 0 is below its children's
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t at = mutated.table(g) + r0 + 32 * (groups - 1) + 28;
                        put32(g.bin, at, get32(g.bin, at) & 0xFFFFu);
                    }),
                    "bounds must be monotone");
    // chunk ranges: the last chunk ends inside the chunks view (before its padding); a chunk
    // ending one byte past the view's end leaves it
    const int chunks_view = mutated.glb.json[Json::json_pointer(mutated.file_ext + "/chunks")];
    const std::size_t view_length = mutated.glb.json["bufferViews"][chunks_view]["byteLength"];
    std::size_t last = 0, end = 0;
    for (std::size_t g = 0; g < groups; ++g) {
        const std::size_t at = t0 + r0 + 32 * g;
        const std::size_t e =
            std::size_t(get32(mutated.glb.bin, at + 16)) + get32(mutated.glb.bin, at + 20);
        if (e > end) {
            end = e;
            last = g;
        }
    }
    ASSERT_LE(end, view_length);
    expect_rejected(mutated([&](Glb& g) {
                        const std::size_t at = mutated.table(g) + r0 + 32 * last + 20;
                        put32(g.bin, at, get32(g.bin, at) + std::uint32_t(view_length - end + 1));
                    }),
                    "leaves the chunks buffer view");
    // gridStep > 0; the extension's version exactly 3; asset.version "2.0"
    expect_rejected(mutated([&](Glb& g) { g.json[Json::json_pointer(ext + "/gridStep")] = 0.0; }),
                    "gridStep");
    for (const int version : {1, 2, 4}) {
        try {
            read_progressive_gltf(mutated([&](Glb& g) {
                                      g.json[Json::json_pointer(mutated.file_ext + "/version")] =
                                          version;
                                  }),
                                  "version.glb", nullptr);
            ADD_FAILURE() << "extension version " << version << " accepted";
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("/version: not 3"), std::string::npos) << e.what();
        }
    }
    expect_rejected(mutated([&](Glb& g) { g.json["asset"]["version"] = "2.1"; }),
                    "/asset/version: expected \"2.0\"");
}

}  // namespace
}  // namespace strata

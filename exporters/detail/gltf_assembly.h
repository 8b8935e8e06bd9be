#pragma once

// The JSON and binary chunk of a .glb being assembled by a writer that builds its own JSON
// (lod_gltf, meshopt_scene): buffer views, accessors and EXT_meshopt_compression primitives.

#include <cstddef>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "exporters/detail/meshopt_streams.h"

namespace strata::detail {

/// Buffer 0 is the GLB's binary chunk; with meshopt views, buffer 1 is the decoded data's
/// (fallback) buffer, which has no bytes (EXT_meshopt_compression's `fallback: true`).
class GltfAssembly {
public:
    using Json = nlohmann::ordered_json;

    Json json;
    std::string bin;

    /// Appends `bytes` to buffer 0 as a new view; returns its index.
    int add_view(const std::string& bytes) {
        Json view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
        append(bytes);
        json["bufferViews"].push_back(view);
        return static_cast<int>(json["bufferViews"].size() - 1);
    }

    /// A view of the decoded data whose bytes are the meshopt stream `s` in buffer 0.
    int add_meshopt_view(const MeshoptStream& s, bool indices) {
        const std::size_t length = std::size_t(s.count) * s.byte_stride;
        Json compressed = {{"buffer", 0},
                           {"byteOffset", bin.size()},
                           {"byteLength", s.bytes.size()},
                           {"byteStride", s.byte_stride},
                           {"mode", indices ? "TRIANGLES" : "ATTRIBUTES"},
                           {"count", s.count}};
        append(s.bytes);
        Json view = {{"buffer", 1}, {"byteOffset", fallback_bytes_}, {"byteLength", length}};
        if (!indices) {
            view["byteStride"] = s.byte_stride;
        }
        view["target"] = indices ? 34963 : 34962;  // ELEMENT_ARRAY_BUFFER : ARRAY_BUFFER
        view["extensions"]["EXT_meshopt_compression"] = compressed;
        fallback_bytes_ += (length + 3) / 4 * 4;
        json["bufferViews"].push_back(view);
        return static_cast<int>(json["bufferViews"].size() - 1);
    }

    int add_accessor(Json accessor) {
        json["accessors"].push_back(std::move(accessor));
        return static_cast<int>(json["accessors"].size() - 1);
    }

    /// One TRIANGLES primitive of `m` (POSITION uint16 or float, NORMAL snorm8, indices) with
    /// `material`.
    Json add_meshopt_primitive(const MeshoptMesh& m, int material) {
        const int pv = add_meshopt_view(m.positions, false);
        const int nv = add_meshopt_view(m.normals, false);
        const int iv = add_meshopt_view(m.indices, true);
        Json min = Json::array(), max = Json::array();
        for (int k = 0; k < 3; ++k) {
            min.push_back(m.min[k]);
            max.push_back(m.max[k]);
        }
        const int position = add_accessor({{"bufferView", pv},
                                           {"componentType", m.float_positions ? 5126 : 5123},
                                           {"count", m.positions.count},
                                           {"type", "VEC3"},
                                           {"min", min},
                                           {"max", max}});
        const int normal = add_accessor({{"bufferView", nv},
                                         {"componentType", 5120},  // BYTE
                                         {"normalized", true},
                                         {"count", m.normals.count},
                                         {"type", "VEC3"}});
        const int indices =
            add_accessor({{"bufferView", iv},
                          {"componentType", m.indices.byte_stride == 2 ? 5123 : 5125},
                          {"count", m.indices.count},
                          {"type", "SCALAR"}});
        return {{"attributes", {{"POSITION", position}, {"NORMAL", normal}}},
                {"indices", indices},
                {"material", material}};
    }

    /// Sets `buffers`: the binary chunk's length, and the fallback buffer when meshopt views
    /// were added.
    void finish_buffers() {
        json["buffers"] = Json::array({{{"byteLength", bin.size()}}});
        if (fallback_bytes_ > 0) {
            json["buffers"].push_back(
                {{"byteLength", fallback_bytes_},
                 {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}});
        }
    }

private:
    std::size_t fallback_bytes_ = 0;

    void append(const std::string& bytes) {
        bin += bytes;
        bin.resize((bin.size() + 3) / 4 * 4, '\0');
    }
};

}  // namespace strata::detail

#pragma once

// The GLB container (glTF 2.0 specification section 4.4) for writers that build their JSON
// themselves (tinygltf cannot write Draco or meshopt primitives).

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>

#include "core/error.h"
#include "exporters/progressive_format.h"

namespace strata::detail {

/// Header, JSON chunk (space padded to 4 bytes), BIN chunk (when `bin` is not empty; its length
/// must be a multiple of 4). \throw Error{Unsupported} when the file would exceed 4 GiB.
inline std::string glb_container(const std::filesystem::path& path,
                                 const std::string& json,
                                 const std::string& bin) {
    std::string padded_json = json;
    padded_json.resize((padded_json.size() + 3) / 4 * 4, ' ');
    const std::uint64_t total = 12 + 8 + padded_json.size() + (bin.empty() ? 0 : 8 + bin.size());
    if (total > std::numeric_limits<std::uint32_t>::max()) {
        throw Error(ErrorCode::Unsupported, path.string() + ": the scene needs " +
                                                std::to_string(total) +
                                                " bytes, more than a .glb holds (4 GiB)");
    }
    std::string out;
    out.reserve(total);
    const auto u32 = [&](std::uint32_t v) {
        for (int i = 0; i < 4; ++i) {
            out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
        }
    };
    u32(format::kGlbMagic);
    u32(2);
    u32(static_cast<std::uint32_t>(total));
    u32(static_cast<std::uint32_t>(padded_json.size()));
    u32(format::kGlbJsonChunk);
    out += padded_json;
    if (!bin.empty()) {
        u32(static_cast<std::uint32_t>(bin.size()));
        u32(format::kGlbBinChunk);
        out += bin;
    }
    return out;
}

}  // namespace strata::detail

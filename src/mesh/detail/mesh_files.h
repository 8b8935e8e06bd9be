#pragma once

// What the mesh file readers and writers share (mesh_io.cpp, read_ply.cpp); internal to
// strata_mesh.

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "core/types.h"
#include "mesh/tri_mesh.h"

namespace strata::mesh_detail {

using Triangle = std::array<std::uint32_t, 3>;
inline constexpr std::uint64_t kMaxVertices = std::numeric_limits<std::uint32_t>::max();

// ---------------------------------------------------------------------------------------------
// Common helpers

[[noreturn]] inline void fail(ErrorCode code,
                              const std::filesystem::path& path,
                              const std::string& what) {
    throw Error(code, path.string() + ": " + what);
}

template <class T>
inline T load_le(const char* p) {
    static_assert(std::is_unsigned_v<T>);
    T value = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i) {
        value =
            static_cast<T>(value | (static_cast<T>(static_cast<unsigned char>(p[i])) << (8 * i)));
    }
    return value;
}

template <class T>
inline void store_le(std::string& out, T value) {
    static_assert(std::is_unsigned_v<T>);
    for (std::size_t i = 0; i < sizeof(T); ++i) {
        out.push_back(static_cast<char>((value >> (8 * i)) & 0xFF));
    }
}

inline void store_f32(std::string& out, float value) {
    store_le(out, std::bit_cast<std::uint32_t>(value));
}

inline bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

/// Splits a line at blanks.
inline void split(std::string_view line, std::vector<std::string_view>& tokens) {
    tokens.clear();
    std::size_t i = 0;
    while (i < line.size()) {
        while (i < line.size() && is_space(line[i])) {
            ++i;
        }
        const std::size_t begin = i;
        while (i < line.size() && !is_space(line[i])) {
            ++i;
        }
        if (i > begin) {
            tokens.push_back(line.substr(begin, i - begin));
        }
    }
}

/// Reads a text file line by line, counting lines from 1.
class Lines {
public:
    explicit Lines(std::string_view text, std::size_t offset = 0, std::size_t first_line = 1)
        : text_(text), pos_(offset), next_number_(first_line) {}

    bool next(std::string_view& line) {
        if (pos_ >= text_.size()) {
            return false;
        }
        const std::size_t end = std::min(text_.find('\n', pos_), text_.size());
        line = text_.substr(pos_, end - pos_);
        if (!line.empty() && line.back() == '\r') {
            line.remove_suffix(1);
        }
        pos_ = end + 1;
        number_ = next_number_++;
        return true;
    }

    std::size_t number() const { return number_; }
    std::size_t offset() const { return std::min(pos_, text_.size()); }

private:
    std::string_view text_;
    std::size_t pos_ = 0;
    std::size_t next_number_ = 1;
    std::size_t number_ = 0;
};

inline std::string quote_token(std::string_view token) {
    constexpr std::size_t kMax = 40;
    std::string out = "'";
    for (char c : token.substr(0, kMax)) {
        out += (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7E) ? '?'
                                                                                              : c;
    }
    return out + (token.size() > kMax ? "...'" : "'");
}

inline std::optional<double> parse_double(std::string_view token) {
    if (!token.empty() && token.front() == '+') {
        token.remove_prefix(1);
    }
    double value = 0.0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size() || token.empty()) {
        return std::nullopt;
    }
    return value;
}

inline std::optional<std::int64_t> parse_int(std::string_view token) {
    if (!token.empty() && token.front() == '+') {
        token.remove_prefix(1);
    }
    std::int64_t value = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    if (ec != std::errc() || end != token.data() + token.size() || token.empty()) {
        return std::nullopt;
    }
    return value;
}

inline bool is_finite(const Vec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

/// Welds corners with exactly equal coordinates (0 and -0 are equal), first appearance first.
class Welder {
public:
    explicit Welder(TriMesh& mesh) : mesh_(mesh) {}

    std::uint32_t add(Vec3 p) {
        // note: + 0.0 turns -0.0 into +0.0 so both hash alike.
        const Key key{std::bit_cast<std::uint64_t>(p.x + 0.0),
                      std::bit_cast<std::uint64_t>(p.y + 0.0),
                      std::bit_cast<std::uint64_t>(p.z + 0.0)};
        const auto [it, inserted] =
            index_.try_emplace(key, static_cast<std::uint32_t>(mesh_.positions.size()));
        if (inserted) {
            mesh_.positions.push_back(p);
        }
        return it->second;
    }

private:
    using Key = std::array<std::uint64_t, 3>;
    struct Hash {
        std::size_t operator()(const Key& k) const {
            std::uint64_t h = 0x9E3779B97F4A7C15ull;
            for (std::uint64_t v : k) {
                h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
            }
            return static_cast<std::size_t>(h);
        }
    };
    TriMesh& mesh_;
    std::unordered_map<Key, std::uint32_t, Hash> index_;
};

/// PLY (ASCII or binary little/big endian): vertices x, y, z; faces fanned into triangles; an
/// optional integer face property 'label'. Every count is checked against the bytes there.
TriMesh read_ply(std::string_view data, const std::filesystem::path& path);

}  // namespace strata::mesh_detail

#include "exporters/detail/meshopt_streams.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <meshoptimizer.h>

#include "core/error.h"

namespace strata::detail {

namespace {

constexpr std::uint32_t kPositionStride16 = 8;  // three uint16 + pad: strides are multiples of 4
constexpr std::uint32_t kPositionStrideFloat = 12;
constexpr std::uint32_t kNormalStride = 4;  // three snorm8 + pad
constexpr std::size_t kMaxShortVertices = 65535;

[[noreturn]] void fail(ErrorCode code, const std::string& what) {
    throw Error(code, "meshopt: " + what);
}

std::int8_t snorm8(float x) {
    const float c = std::clamp(x, -1.0f, 1.0f);
    return static_cast<std::int8_t>(std::lround(c * 127.0f));
}

MeshoptStream encode_vertices(const std::vector<unsigned char>& raw,
                              std::uint32_t count,
                              std::uint32_t stride) {
    MeshoptStream s;
    s.count = count;
    s.byte_stride = stride;
    s.bytes.resize(meshopt_encodeVertexBufferBound(count, stride));
    const std::size_t size =
        meshopt_encodeVertexBuffer(reinterpret_cast<unsigned char*>(s.bytes.data()), s.bytes.size(),
                                   raw.data(), count, stride);
    if (size == 0) {
        fail(ErrorCode::Internal, "encoding a vertex stream failed");
    }
    s.bytes.resize(size);
    if (decode_meshopt_vertices(s.bytes, count, stride) != raw) {
        fail(ErrorCode::Internal, "a vertex stream does not decode to its input");
    }
    return s;
}

}  // namespace

std::vector<unsigned char> decode_meshopt_vertices(const std::string& bytes,
                                                   std::uint32_t count,
                                                   std::uint32_t byte_stride) {
    if (byte_stride == 0 || byte_stride % 4 != 0 || byte_stride > 256) {
        fail(ErrorCode::InvalidInput, "vertex stride " + std::to_string(byte_stride) +
                                          ", expected a multiple of 4 up to 256");
    }
    std::vector<unsigned char> out(std::size_t(count) * byte_stride);
    if (meshopt_decodeVertexBuffer(out.data(), count, byte_stride,
                                   reinterpret_cast<const unsigned char*>(bytes.data()),
                                   bytes.size()) != 0) {
        fail(ErrorCode::InvalidInput, "not a vertex stream of " + std::to_string(count) +
                                          " elements of " + std::to_string(byte_stride) + " bytes");
    }
    return out;
}

std::vector<std::uint32_t> decode_meshopt_indices(const std::string& bytes, std::uint32_t count) {
    if (count % 3 != 0) {
        fail(ErrorCode::InvalidInput,
             std::to_string(count) + " indices, expected a multiple of 3 (triangles)");
    }
    std::vector<std::uint32_t> out(count);
    if (meshopt_decodeIndexBuffer(out.data(), count, sizeof(std::uint32_t),
                                  reinterpret_cast<const unsigned char*>(bytes.data()),
                                  bytes.size()) != 0) {
        fail(ErrorCode::InvalidInput,
             "not an index stream of " + std::to_string(count) + " indices");
    }
    return out;
}

MeshoptMesh encode_meshopt_mesh(const MeshoptInput& in) {
    const bool use_float = !in.float_positions.empty();
    const std::size_t n = use_float ? in.float_positions.size() : in.grid_positions.size();
    if (n == 0 || in.triangles.empty()) {
        fail(ErrorCode::InvalidInput, "empty mesh, expected vertices and triangles");
    }
    if (in.normals.size() != n) {
        fail(ErrorCode::InvalidInput, std::to_string(in.normals.size()) + " normals for " +
                                          std::to_string(n) + " positions, expected one each");
    }
    if (n > std::numeric_limits<std::uint32_t>::max()) {
        fail(ErrorCode::InvalidInput, "more than 2^32 - 1 vertices");
    }
    std::vector<unsigned int> indices;
    indices.reserve(3 * in.triangles.size());
    for (std::size_t t = 0; t < in.triangles.size(); ++t) {
        for (const std::uint32_t v : in.triangles[t]) {
            if (v >= n) {
                fail(ErrorCode::InvalidInput, "triangle " + std::to_string(t) + " uses vertex " +
                                                  std::to_string(v) + ", expected < " +
                                                  std::to_string(n));
            }
            indices.push_back(v);
        }
    }
    // Cache order for the triangles, then first-use order for the vertices (gltfpack's order).
    meshopt_optimizeVertexCache(indices.data(), indices.data(), indices.size(), n);
    std::vector<unsigned int> remap(n);
    const std::size_t used =
        meshopt_optimizeVertexFetchRemap(remap.data(), indices.data(), indices.size(), n);
    for (unsigned int& i : indices) {
        i = remap[i];
    }

    MeshoptMesh out;
    out.float_positions = use_float;
    out.min.fill(std::numeric_limits<double>::infinity());
    out.max.fill(-std::numeric_limits<double>::infinity());
    const std::uint32_t stride = use_float ? kPositionStrideFloat : kPositionStride16;
    std::vector<unsigned char> positions(used * stride, 0);
    std::vector<unsigned char> normals(used * kNormalStride, 0);
    for (std::size_t v = 0; v < n; ++v) {
        const unsigned int r = remap[v];
        if (r == ~0u) {
            continue;  // unreferenced: dropped
        }
        for (int k = 0; k < 3; ++k) {
            double value = 0.0;
            if (use_float) {
                const float f = in.float_positions[v][k];
                std::memcpy(&positions[std::size_t(r) * stride + 4 * k], &f, 4);
                value = f;
            } else {
                const std::uint16_t q = in.grid_positions[v][k];
                std::memcpy(&positions[std::size_t(r) * stride + 2 * k], &q, 2);
                value = q;
            }
            out.min[k] = std::min(out.min[k], value);
            out.max[k] = std::max(out.max[k], value);
            normals[std::size_t(r) * kNormalStride + k] =
                static_cast<unsigned char>(snorm8(in.normals[v][k]));
        }
    }
    out.positions = encode_vertices(positions, static_cast<std::uint32_t>(used), stride);
    out.normals = encode_vertices(normals, static_cast<std::uint32_t>(used), kNormalStride);

    meshopt_encodeIndexVersion(1);
    out.indices.count = static_cast<std::uint32_t>(indices.size());
    out.indices.byte_stride = used <= kMaxShortVertices ? 2 : 4;
    out.indices.bytes.resize(meshopt_encodeIndexBufferBound(indices.size(), used));
    const std::size_t size =
        meshopt_encodeIndexBuffer(reinterpret_cast<unsigned char*>(out.indices.bytes.data()),
                                  out.indices.bytes.size(), indices.data(), indices.size());
    if (size == 0) {
        fail(ErrorCode::Internal, "encoding the index stream failed");
    }
    out.indices.bytes.resize(size);
    const std::vector<std::uint32_t> decoded =
        decode_meshopt_indices(out.indices.bytes, out.indices.count);
    // note: the index codec may rotate a triangle's corners (the winding stays)
    const auto rotated = [](const auto& v, std::size_t t) {
        std::array<std::uint32_t, 3> c{std::uint32_t(v[3 * t]), std::uint32_t(v[3 * t + 1]),
                                       std::uint32_t(v[3 * t + 2])};
        std::rotate(c.begin(), std::min_element(c.begin(), c.end()), c.end());
        return c;
    };
    bool same = decoded.size() == indices.size();
    for (std::size_t t = 0; same && t < indices.size() / 3; ++t) {
        same = rotated(decoded, t) == rotated(indices, t);
    }
    if (!same) {
        fail(ErrorCode::Internal, "the index stream does not decode to its input");
    }
    return out;
}

}  // namespace strata::detail

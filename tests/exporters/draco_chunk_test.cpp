#include "exporters/detail/draco_chunk.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include <draco/compression/decode.h>
#include <gtest/gtest.h>

#include "core/error.h"
#include "exporters/progressive_format.h"

namespace strata {
namespace {

using Float3 = std::array<float, 3>;

/// Decoded POSITION values of an encoded mesh, read with Draco directly.
std::vector<Float3> decode_positions(const detail::DracoChunkBytes& encoded) {
    draco::DecoderBuffer buffer;
    buffer.Init(encoded.bytes.data(), encoded.bytes.size());
    draco::Decoder decoder;
    auto mesh_or = decoder.DecodeMeshFromBuffer(&buffer);
    EXPECT_TRUE(mesh_or.ok()) << mesh_or.status().error_msg();
    if (!mesh_or.ok()) {
        return {};
    }
    const std::unique_ptr<draco::Mesh> mesh = std::move(mesh_or).value();
    const draco::PointAttribute* position = mesh->GetAttributeByUniqueId(encoded.position_id);
    std::vector<Float3> out;
    for (std::uint32_t i = 0; i < mesh->num_points(); ++i) {
        Float3 p{};
        position->ConvertValue<float, 3>(position->mapped_index(draco::PointIndex(i)), p.data());
        out.push_back(p);
    }
    return out;
}

/// A strip of `n` points near (83.66, 7.84) on the grid of `step`, triangulated.
detail::DracoChunkInput strip(double step, int n) {
    detail::DracoChunkInput in;
    in.step = step;
    const auto on_grid = [&](double v) { return std::round(v / step) * step; };
    for (int i = 0; i < n; ++i) {
        const double x = on_grid(83.6640625) + step * 5 * (i / 2);
        const double y = on_grid(7.8359375) + step * 3 * (i % 2) + step * (i % 3);
        in.positions.push_back({float(x), float(y), float(50.5 + step * i)});
    }
    for (std::uint32_t i = 0; i + 2 < std::uint32_t(n); ++i) {
        in.triangles.push_back(i % 2 == 0 ? std::array{i, i + 1, i + 2}
                                          : std::array{i + 1, i, i + 2});
    }
    return in;
}

// A grid of 1/128 px (the quantize stage's finest fallback) near small coordinates: Draco keeps
// the quantization origin and range as six-decimal text, so an origin of 7.8359375 came back as
// 7.835938 and decoded positions left the grid by one float step.
TEST(DracoChunk, FineGridsDecodeExactly) {
    for (const double step : {1.0 / 16.0, 1.0 / 128.0, 1.0 / 1024.0}) {
        SCOPED_TRACE("step " + std::to_string(step));
        const detail::DracoChunkInput in = strip(step, 12);
        const detail::DracoChunkBytes encoded = detail::encode_draco_chunk(in, 7, 10);
        const std::set<Float3> positions(in.positions.begin(), in.positions.end());
        const auto decoded = decode_positions(encoded);
        ASSERT_EQ(decoded.size(), in.positions.size());
        for (const auto& p : decoded) {
            EXPECT_TRUE(positions.count(p)) << p[0] << " " << p[1] << " " << p[2];
        }
    }
}

// Two clusters welded into one chunk: each border vertex is one position, split into one point
// per cluster for _CLUSTER only; the attributes carry the format's unique ids.
TEST(DracoChunk, ClustersAreWeldedAndTaggedPerTriangle) {
    detail::DracoChunkInput in = strip(1.0 / 16.0, 20);
    for (std::size_t t = 0; t < in.triangles.size(); ++t) {
        in.triangle_cluster.push_back(t < in.triangles.size() / 2 ? 0 : 1);
    }
    in.slots.assign(in.positions.size(), 0);
    const detail::DracoChunkBytes encoded = detail::encode_draco_chunk(in, 7, 10);
    EXPECT_EQ(encoded.position_id, int(format::kChunkPositionId));
    EXPECT_EQ(encoded.cluster_id, int(format::kChunkClusterId));
    EXPECT_EQ(encoded.slot_id, int(format::kChunkSlotId));
    EXPECT_EQ(detail::draco_declared_triangles(encoded.bytes), in.triangles.size());
    const detail::DecodedChunk d = detail::decode_draco_chunk(
        encoded.bytes, {encoded.position_id, encoded.cluster_id, encoded.slot_id, -1}, 2, 1000);
    EXPECT_EQ(d.positions.size(), in.positions.size()) << "welded: one vertex per position";
    EXPECT_EQ(d.points, in.positions.size() + 2) << "the 2 border vertices split for _CLUSTER";
    std::map<std::uint32_t, std::size_t> per_cluster;
    for (const std::uint32_t k : d.triangle_cluster) {
        ++per_cluster[k];
    }
    EXPECT_EQ(per_cluster[0], in.triangles.size() / 2);
    EXPECT_EQ(per_cluster[1], in.triangles.size() - in.triangles.size() / 2);
}

// The slot encoding on a random fan-like collapse: every vertex of a ring collapses into the
// centre or one of its survivors through connected runs; resolving gives the targets back.
TEST(DracoChunk, SlotsResolveToTheCollapseTargetsAfterDecoding) {
    // a triangulated grid of 9 x 9 points; survivors every third column, each other vertex
    // collapses into the survivor of its row at the left
    detail::DracoChunkInput in;
    in.step = 1.0 / 8.0;
    const int n = 9;
    for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
            in.positions.push_back({float(x * 0.5), float(y * 0.25), float((x * y) % 3) * 0.125f});
        }
    }
    const auto id = [&](int x, int y) { return std::uint32_t(y * n + x); };
    for (int y = 0; y + 1 < n; ++y) {
        for (int x = 0; x + 1 < n; ++x) {
            in.triangles.push_back({id(x, y), id(x + 1, y), id(x + 1, y + 1)});
            in.triangles.push_back({id(x, y), id(x + 1, y + 1), id(x, y + 1)});
        }
    }
    std::vector<std::uint32_t> coarse(in.positions.size());
    for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
            coarse[id(x, y)] = id(x - x % 3, y);
        }
    }
    in.slots = detail::encode_slots(in.positions, in.triangles, coarse);
    const detail::DracoChunkBytes encoded = detail::encode_draco_chunk(in, 7, 10);
    const detail::DecodedChunk d = detail::decode_draco_chunk(
        encoded.bytes, {encoded.position_id, -1, encoded.slot_id, -1}, 1, 1000);
    const std::vector<std::uint32_t> resolved =
        detail::resolve_slots(d.positions, d.triangles, d.slots);
    std::map<Float3, std::uint32_t> input_id;
    for (std::uint32_t v = 0; v < in.positions.size(); ++v) {
        input_id[in.positions[v]] = v;
    }
    for (std::size_t v = 0; v < d.positions.size(); ++v) {
        EXPECT_EQ(input_id.at(d.positions[resolved[v]]), coarse[input_id.at(d.positions[v])]);
    }
    // a slot past the neighbours, and a cycle, are refused
    std::vector<std::uint8_t> bad = d.slots;
    bad[1] = 200;
    EXPECT_THROW(detail::resolve_slots(d.positions, d.triangles, bad), Error);
    std::vector<std::uint8_t> cycle(d.positions.size(), 1);
    EXPECT_THROW(detail::resolve_slots(d.positions, d.triangles, cycle), Error);
}

// Issue 18 (memory bombs): a stream declaring far more triangles than its bytes can hold is
// refused from its header, before Draco allocates anything.
TEST(DracoChunk, DeclaredSizesAreCappedByTheBytes) {
    detail::DracoChunkInput in = strip(1.0 / 16.0, 12);
    const detail::DracoChunkBytes encoded = detail::encode_draco_chunk(in, 7, 10);
    // header: 11 bytes, traversal type, varint vertices, varint faces (1 byte each here)
    ASSERT_EQ(static_cast<unsigned char>(encoded.bytes[13]), in.triangles.size());
    std::string bomb = encoded.bytes;
    bomb.replace(13, 1, std::string("\xFF\xFF\xFF\xFF\x0F", 5));  // 2^32 - 1 triangles
    try {
        detail::decode_draco_chunk(bomb, {encoded.position_id, -1, -1, -1}, 1, 1u << 30);
        ADD_FAILURE() << "accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("declares"), std::string::npos) << e.what();
    }
    EXPECT_THROW(detail::decode_draco_chunk(encoded.bytes, {encoded.position_id, -1, -1, -1}, 1,
                                            in.triangles.size() - 1),
                 Error);
}

TEST(DracoChunk, ErrorsRoundUpToShortDecimals) {
    EXPECT_EQ(format::round_up_decimal(0.000424, 3), 0.000424);
    EXPECT_EQ(format::round_up_decimal(0.0004241, 3), 0.000425);
    EXPECT_EQ(format::round_up_decimal(0.0009999, 3), 0.001);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-8.0, -1.0);
    double previous = 0.0, previous_rounded = 0.0;
    for (int i = 0; i < 1000; ++i) {
        const double x = std::pow(10.0, u(rng));
        const double r = format::round_up_decimal(x, 3);
        EXPECT_GE(r, x);
        EXPECT_LE(r, x * 1.01);
        if (x >= previous) {
            EXPECT_GE(r, previous_rounded);
        }
        previous = x;
        previous_rounded = r;
    }
}

}  // namespace
}  // namespace strata

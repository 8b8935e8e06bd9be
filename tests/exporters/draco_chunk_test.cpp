#include "exporters/detail/draco_chunk.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <set>
#include <vector>

#include <draco/compression/decode.h>
#include <gtest/gtest.h>

namespace strata {
namespace {

using Float3 = std::array<float, 3>;

/// Decoded POSITION and _COARSE_POSITION values of an encoded chunk.
std::vector<std::pair<Float3, Float3>> decode(const detail::DracoChunkBytes& encoded) {
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
    const draco::PointAttribute* coarse = mesh->GetAttributeByUniqueId(encoded.coarse_id);
    std::vector<std::pair<Float3, Float3>> out;
    for (std::uint32_t i = 0; i < mesh->num_points(); ++i) {
        Float3 p{}, c{};
        position->ConvertValue<float, 3>(position->mapped_index(draco::PointIndex(i)), p.data());
        coarse->ConvertValue<float, 3>(coarse->mapped_index(draco::PointIndex(i)), c.data());
        out.push_back({p, c});
    }
    return out;
}

// A grid of 1/128 px (the quantize stage's finest fallback) near small coordinates: Draco keeps
// the quantization origin and range as six-decimal text, so an origin of 7.8359375 came back as
// 7.835938 and decoded positions left the grid by one float step.
TEST(DracoChunk, FineGridsDecodeExactly) {
    for (const double step : {1.0 / 16.0, 1.0 / 128.0, 1.0 / 1024.0}) {
        SCOPED_TRACE("step " + std::to_string(step));
        detail::DracoChunkInput in;
        in.step = step;
        // a strip of triangles on the grid, near (83.6640625, 7.8359375) (1/128 multiples)
        const auto on_grid = [&](double v) { return std::round(v / step) * step; };
        const int n = 12;
        for (int i = 0; i < n; ++i) {
            const double x = on_grid(83.6640625) + step * 5 * (i / 2);
            const double y = on_grid(7.8359375) + step * 3 * (i % 2) + step * (i % 3);
            in.positions.push_back({float(x), float(y), float(50.5 + step * i)});
        }
        for (int i = 0; i < n; ++i) {
            in.coarse.push_back(in.positions[std::size_t(i - i % 2)]);
        }
        for (std::uint32_t i = 0; i + 2 < n; ++i) {
            in.triangles.push_back(i % 2 == 0 ? std::array{i, i + 1, i + 2}
                                              : std::array{i + 1, i, i + 2});
        }
        const detail::DracoChunkBytes encoded = detail::encode_draco_chunk(in, 7, 10);
        const std::set<Float3> positions(in.positions.begin(), in.positions.end());
        const auto decoded = decode(encoded);
        ASSERT_EQ(decoded.size(), in.positions.size());
        for (const auto& [p, c] : decoded) {
            EXPECT_TRUE(positions.count(p)) << p[0] << " " << p[1] << " " << p[2];
            EXPECT_TRUE(positions.count(c)) << c[0] << " " << c[1] << " " << c[2];
        }
    }
}

}  // namespace
}  // namespace strata

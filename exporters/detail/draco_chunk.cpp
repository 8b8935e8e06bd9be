#include "exporters/detail/draco_chunk.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <draco/compression/expert_encode.h>
#include <draco/mesh/mesh.h>

#include "core/error.h"

namespace strata::detail {

namespace {

int bits_for(double extent_steps) {
    int bits = 1;
    while (bits < 24 && std::ldexp(1.0, bits) - 1.0 < extent_steps) {
        ++bits;
    }
    return bits;
}

}  // namespace

DracoChunkBytes encode_draco_chunk(const DracoChunkInput& in,
                                   int compression_level,
                                   int normal_bits) {
    const std::size_t n = in.positions.size();
    draco::Mesh mesh;
    mesh.set_num_points(static_cast<std::uint32_t>(n));
    const auto add = [&](draco::GeometryAttribute::Type type,
                         const std::vector<std::array<float, 3>>& values) {
        draco::GeometryAttribute attribute;
        attribute.Init(type, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3, 0);
        const int id = mesh.AddAttribute(attribute, true, static_cast<std::uint32_t>(n));
        for (std::size_t i = 0; i < n; ++i) {
            mesh.attribute(id)->SetAttributeValue(
                draco::AttributeValueIndex(static_cast<std::uint32_t>(i)), values[i].data());
        }
        return id;
    };
    const int position = add(draco::GeometryAttribute::POSITION, in.positions);
    const int normal = in.normals.empty() ? -1 : add(draco::GeometryAttribute::NORMAL, in.normals);
    const int coarse = in.coarse.empty() ? -1 : add(draco::GeometryAttribute::GENERIC, in.coarse);
    for (const auto& t : in.triangles) {
        mesh.AddFace({draco::PointIndex(t[0]), draco::PointIndex(t[1]), draco::PointIndex(t[2])});
    }

    // one quantization grid for positions and coarse positions: the lowest grid point and the
    // fewest bits that span both
    std::array<double, 3> lo{}, hi{};
    lo.fill(std::numeric_limits<double>::infinity());
    hi.fill(-std::numeric_limits<double>::infinity());
    for (const auto* values : {&in.positions, &in.coarse}) {
        for (const std::array<float, 3>& p : *values) {
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], double(p[k]));
                hi[k] = std::max(hi[k], double(p[k]));
            }
        }
    }
    double extent = 0.0;
    for (int k = 0; k < 3; ++k) {
        extent = std::max(extent, (hi[k] - lo[k]) / in.step);
    }
    const int bits = bits_for(extent);
    if (std::ldexp(1.0, bits) - 1.0 < extent) {
        throw Error(ErrorCode::InvalidInput,
                    "spans " + std::to_string(extent) +
                        " grid steps, more than 2^24 (float positions would lose the grid)");
    }
    const float origin[3] = {static_cast<float>(lo[0]), static_cast<float>(lo[1]),
                             static_cast<float>(lo[2])};
    const float range = static_cast<float>(in.step * (std::ldexp(1.0, bits) - 1.0));

    draco::ExpertEncoder encoder(mesh);
    encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    const int speed = 10 - std::clamp(compression_level, 0, 10);
    encoder.SetSpeedOptions(speed, speed);
    for (const int id : {position, coarse}) {
        if (id >= 0) {
            encoder.SetAttributeExplicitQuantization(id, bits, 3, origin, range);
            encoder.SetAttributePredictionScheme(
                id, draco::MESH_PREDICTION_CONSTRAINED_MULTI_PARALLELOGRAM);
        }
    }
    if (normal >= 0) {
        encoder.SetAttributeQuantization(normal, normal_bits);
    }
    draco::EncoderBuffer buffer;
    const draco::Status status = encoder.EncodeToBuffer(&buffer);
    if (!status.ok()) {
        throw Error(ErrorCode::Internal, "Draco encoding failed: " + status.error_msg_string());
    }
    DracoChunkBytes out;
    out.bytes.assign(buffer.data(), buffer.size());
    const auto unique_id = [&](int id) {
        return id < 0 ? -1 : static_cast<int>(mesh.attribute(id)->unique_id());
    };
    out.position_id = unique_id(position);
    out.normal_id = unique_id(normal);
    out.coarse_id = unique_id(coarse);
    return out;
}

}  // namespace strata::detail

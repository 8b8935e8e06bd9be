#include "exporters/detail/draco_chunk.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <draco/compression/expert_encode.h>
#include <draco/core/options.h>
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

// Draco keeps the quantization origin and range as decimal text with six decimals
// (draco::Options, std::to_string), so an origin of 7.8359375 comes back as 7.835938 and the
// decoded positions leave the grid. These read values back the way the encoder will.
bool survives_options(const float (&origin)[3]) {
    draco::Options options;
    options.SetVector("v", origin, 3);
    float back[3] = {};
    options.GetVector("v", 3, back);
    return back[0] == origin[0] && back[1] == origin[1] && back[2] == origin[2];
}

bool survives_options(float range) {
    draco::Options options;
    options.SetFloat("v", range);
    return options.GetFloat("v") == range;
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
    // The origin: the lowest grid point, moved down to a multiple of 1/64 when the grid is finer
    // (six decimals hold it exactly). The range: step * (2^bits - 1), with more bits where
    // Draco's text would round it.
    const double exact_step = std::max(in.step, 1.0 / 64.0);
    float origin[3] = {};
    double extent = 0.0;
    for (int k = 0; k < 3; ++k) {
        origin[k] = static_cast<float>(std::floor(lo[k] / exact_step) * exact_step);
        extent = std::max(extent, (hi[k] - origin[k]) / in.step);
    }
    int bits = bits_for(extent);
    const auto range_of = [&](int b) {
        return static_cast<float>(in.step * (std::ldexp(1.0, b) - 1.0));
    };
    while (bits < 24 && !survives_options(range_of(bits))) {
        ++bits;
    }
    if (std::ldexp(1.0, bits) - 1.0 < extent) {
        throw Error(ErrorCode::InvalidInput,
                    "spans " + std::to_string(extent) +
                        " grid steps, more than 2^24 (float positions would lose the grid)");
    }
    const float range = range_of(bits);
    if (!survives_options(origin) || !survives_options(range)) {
        throw Error(ErrorCode::Unsupported,
                    "the quantization origin (" + std::to_string(origin[0]) + ", " +
                        std::to_string(origin[1]) + ", " + std::to_string(origin[2]) +
                        ") or range " + std::to_string(range) +
                        " does not survive Draco's six-decimal options text (grid step " +
                        std::to_string(in.step) + ")");
    }

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

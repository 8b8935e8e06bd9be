#include "quantize/snap_to_grid.h"

#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "core/error.h"

namespace strata {

namespace {

/// Grid indices of a snapped vertex.
struct GridKey {
    std::int64_t x, y, z;
    bool operator==(const GridKey&) const = default;
};

struct GridKeyHash {
    std::size_t operator()(const GridKey& k) const {
        std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ULL;
        h ^= static_cast<std::uint64_t>(k.y) + 0x7F4A7C159E3779B9ULL + (h << 6) + (h >> 2);
        h ^= static_cast<std::uint64_t>(k.z) + 0x94D049BB133111EBULL + (h << 6) + (h >> 2);
        return static_cast<std::size_t>(h);
    }
};

bool is_power_of_two(double step) {
    int exponent = 0;
    return step > 0.0 && std::frexp(step, &exponent) == 0.5;
}

}  // namespace

bool snap_to_grid(
    const TriMesh& mesh, double slice_spacing_px, double step, GridSnap& out, std::string& why) {
    if (!is_power_of_two(step) || step > 0.5) {
        throw Error(ErrorCode::InvalidInput, "snap_to_grid: step " + std::to_string(step) +
                                                 " px, expected a power of two in (0, 1/2]");
    }
    if (!(slice_spacing_px > 0.0) || !std::isfinite(slice_spacing_px)) {
        throw Error(ErrorCode::InvalidInput, "snap_to_grid: slice spacing " +
                                                 std::to_string(slice_spacing_px) +
                                                 " px, expected a positive number");
    }
    const double d = slice_spacing_px;
    // note: |index| < 2^52 keeps index * step exact; far larger than any image
    constexpr double kMaxIndex = 4503599627370496.0;
    out = GridSnap{};
    out.step = step;
    out.mesh.triangles = mesh.triangles;
    out.mesh.labels = mesh.labels;
    out.mesh.positions.resize(mesh.positions.size());
    std::unordered_map<GridKey, std::uint32_t, GridKeyHash> used;
    used.reserve(mesh.positions.size());
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
        const Vec3 p = mesh.positions[v];
        const double qx = std::nearbyint(p.x / step);
        const double qy = std::nearbyint(p.y / step);
        const double slice = std::nearbyint(p.z / d);
        const bool on_plane = slice * d == p.z;
        const double qz = on_plane ? slice / step : std::nearbyint(p.z / d / step);
        if (!(std::abs(qx) < kMaxIndex && std::abs(qy) < kMaxIndex && std::abs(qz) < kMaxIndex)) {
            why = "vertex " + std::to_string(v) + " at (" + std::to_string(p.x) + ", " +
                  std::to_string(p.y) + ", " + std::to_string(p.z) + ") is off the grid's range";
            return false;
        }
        const double grid_slice = qz * step;  // exact: step is a power of two
        if (!on_plane && grid_slice == std::nearbyint(grid_slice)) {
            why = "vertex " + std::to_string(v) +
                  " between slice planes (z = " + std::to_string(p.z / d) +
                  " slices) would land on plane " +
                  std::to_string(static_cast<long long>(grid_slice));
            return false;
        }
        const Vec3 q{qx * step, qy * step, on_plane ? p.z : grid_slice * d};
        const GridKey key{static_cast<std::int64_t>(qx), static_cast<std::int64_t>(qy),
                          static_cast<std::int64_t>(qz)};
        const auto [it, inserted] = used.try_emplace(key, v);
        if (!inserted) {
            why = "vertices " + std::to_string(it->second) + " and " + std::to_string(v) +
                  " would share the grid point (" + std::to_string(q.x) + ", " +
                  std::to_string(q.y) + ", " + std::to_string(q.z) + ")";
            return false;
        }
        out.mesh.positions[v] = q;
        const double plane_shift = std::hypot(q.x - p.x, q.y - p.y);
        if (on_plane) {
            out.max_plane_shift_px = std::max(out.max_plane_shift_px, plane_shift);
        }
        out.max_shift_px = std::max(out.max_shift_px, std::hypot(plane_shift, q.z - p.z));
    }
    return true;
}

std::vector<Vec3> grid_frame_positions(const std::vector<Vec3>& positions,
                                       double slice_spacing_px,
                                       double grid_step) {
    std::vector<Vec3> out = positions;
    if (grid_step > 0.0) {
        for (Vec3& p : out) {
            p.z = std::nearbyint(p.z / slice_spacing_px / grid_step) * grid_step;
        }
    }
    return out;
}

}  // namespace strata

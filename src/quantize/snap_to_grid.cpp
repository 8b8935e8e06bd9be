#include "quantize/snap_to_grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/error.h"
#include "mesh/mesh_adjacency.h"

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

/// Rounding z to the nearest grid height can fold the surface where the grid is coarse in z
/// (a slab 6.4 px deep and a step of 1/16 slice: 0.4 px, against 1/16 px in x, y): a Steiner
/// point 0.3 px beside a contour goes up or down by up to 0.2 px. Each vertex between planes
/// that lies on a face of an edge folded over 90 degrees (its faces' normals) tries the grid
/// height on the other side of its unsnapped one, and keeps it when the squared excess over 90
/// degrees of the edges of its faces shrinks; its neighbours try in the next sweep. `alternative`
/// holds that other grid index per vertex (NaN: none, on a plane or it would land on one).
void unfold_rounding(GridSnap& out,
                     double d,
                     double step,
                     std::vector<double>& alternative,
                     std::unordered_map<GridKey, std::uint32_t, GridKeyHash>& used) {
    TriMesh& mesh = out.mesh;
    const std::size_t n = mesh.positions.size();
    const MeshAdjacency adjacency(mesh);
    auto unit_normal = [&](std::uint32_t f) { return unit_face_normal(mesh, f); };
    constexpr double kDegrees = 180.0 / 3.14159265358979323846;
    auto fold_excess = [&](const std::array<std::uint32_t, 3>& e) {
        const Vec3 a = unit_normal(e[0]);
        const Vec3 b = unit_normal(e[1]);
        if (e[2] != 2 || !(norm(a) > 0.0) || !(norm(b) > 0.0)) {
            return 0.0;
        }
        const double angle = std::acos(std::clamp(dot(a, b), -1.0, 1.0)) * kDegrees;
        return std::max(0.0, angle - 90.0);
    };
    auto cost = [&](const std::vector<std::uint64_t>& keys) {
        double sum = 0.0;
        for (const std::uint64_t key : keys) {
            const double excess = fold_excess(adjacency.edge(key));
            sum += excess * excess;
        }
        return sum;
    };
    std::vector<bool> active(n, false);
    for (const auto& [key, e] : adjacency.edges()) {
        if (fold_excess(e) > 0.0) {
            for (const std::uint32_t f : {e[0], e[1]}) {
                for (const std::uint32_t v : mesh.triangles[f]) {
                    active[v] = !std::isnan(alternative[v]);
                }
            }
        }
    }
    constexpr int kSweeps = 4;
    for (int sweep = 0; sweep < kSweeps; ++sweep) {
        std::vector<bool> next(n, false);
        bool any = false;
        for (std::uint32_t v = 0; v < n; ++v) {
            if (!active[v] || std::isnan(alternative[v])) {
                continue;
            }
            Vec3& p = mesh.positions[v];
            const double qx = std::nearbyint(p.x / step);
            const double qy = std::nearbyint(p.y / step);
            const double qz = std::nearbyint(p.z / d / step);
            const GridKey to{static_cast<std::int64_t>(qx), static_cast<std::int64_t>(qy),
                             static_cast<std::int64_t>(alternative[v])};
            if (used.count(to) != 0) {
                continue;
            }
            const std::vector<std::uint64_t> keys = adjacency.star_edges(v);
            const double before = cost(keys);
            const double z = p.z;
            p.z = alternative[v] * step * d;
            if (cost(keys) < before - 1e-9) {
                used.erase(GridKey{to.x, to.y, static_cast<std::int64_t>(qz)});
                used.emplace(to, v);
                alternative[v] = qz;
                any = true;
                for (const std::uint32_t f : adjacency.faces_around(v)) {
                    for (const std::uint32_t u : mesh.triangles[f]) {
                        if (u != v) {
                            next[u] = true;
                        }
                    }
                }
            } else {
                p.z = z;
            }
        }
        if (!any) {
            break;
        }
        active = std::move(next);
    }
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
    std::vector<double> alternative(mesh.positions.size(), std::nan(""));
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
        if (!on_plane) {
            // the grid height on the other side of p, unless it is a plane's
            const double other = p.z / d / step > qz ? qz + 1.0 : qz - 1.0;
            if (other * step != std::nearbyint(other * step)) {
                alternative[v] = other;
            }
        }
    }
    // Only between the surface's first and last slice planes: the stack ends' extensions (caps.cpp,
    // leaned with the object) keep their nearest heights.
    double low = HUGE_VAL;
    double high = -HUGE_VAL;
    for (const Vec3& p : mesh.positions) {
        if (std::nearbyint(p.z / d) * d == p.z) {
            low = std::min(low, p.z);
            high = std::max(high, p.z);
        }
    }
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
        if (!(mesh.positions[v].z > low && mesh.positions[v].z < high)) {
            alternative[v] = std::nan("");
        }
    }
    unfold_rounding(out, d, step, alternative, used);
    for (std::uint32_t v = 0; v < mesh.positions.size(); ++v) {
        const Vec3 p = mesh.positions[v];
        const Vec3 q = out.mesh.positions[v];
        const double plane_shift = std::hypot(q.x - p.x, q.y - p.y);
        if (std::nearbyint(p.z / d) * d == p.z) {
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

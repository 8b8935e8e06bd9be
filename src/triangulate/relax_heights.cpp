#include "triangulate/relax_heights.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "mesh/mesh_adjacency.h"

namespace strata {
namespace {

constexpr double kDegrees = 180.0 / 3.14159265358979323846;

class FoldRelaxer {
public:
    FoldRelaxer(TriMesh& mesh, const RelaxHeightsOptions& options)
        : mesh_(mesh), options_(options), adjacency_(mesh) {}

    /// The two faces of each edge of the faces around v (each edge once; edges without
    /// exactly two faces left out).
    std::vector<std::array<std::uint32_t, 2>> star_edge_faces(std::uint32_t v) const {
        std::vector<std::array<std::uint32_t, 2>> out;
        for (const std::uint64_t key : adjacency_.star_edges(v)) {
            const auto& e = adjacency_.edge(key);
            if (e[2] == 2) {
                out.push_back({e[0], e[1]});
            }
        }
        return out;
    }

    /// The faces around v.
    std::vector<std::uint32_t> star_faces(std::uint32_t v) const {
        return adjacency_.faces_around(v);
    }

    /// The unit normal of face f (zero for a face without area).
    Vec3 unit_normal(std::uint32_t f) const { return unit_face_normal(mesh_, f); }

    std::vector<std::uint32_t> neighbours(std::uint32_t v) const {
        std::vector<std::uint32_t> out;
        for (const std::uint32_t f : adjacency_.faces_around(v)) {
            for (const std::uint32_t u : mesh_.triangles[f]) {
                if (u != v) {
                    out.push_back(u);
                }
            }
        }
        std::sort(out.begin(), out.end());
        out.erase(std::unique(out.begin(), out.end()), out.end());
        return out;
    }

    bool touches_fold(std::uint32_t v) const {
        const double limit = std::cos(options_.unfold_angle_deg / kDegrees);
        for (const auto& e : star_edge_faces(v)) {
            const Vec3 a = unit_normal(e[0]);
            const Vec3 b = unit_normal(e[1]);
            if (norm(a) > 0.0 && norm(b) > 0.0 && dot(a, b) < limit) {
                return true;
            }
        }
        return false;
    }

private:
    TriMesh& mesh_;
    const RelaxHeightsOptions& options_;
    MeshAdjacency adjacency_;
};

}  // namespace

std::size_t relax_fold_heights(TriMesh& mesh,
                               const std::vector<FreeHeightVertex>& free,
                               const RelaxHeightsOptions& options) {
    if (free.empty() || !(options.fold_angle_deg > 0.0)) {
        return 0;
    }
    const FoldRelaxer relaxer(mesh, options);
    std::vector<std::int64_t> slot(mesh.positions.size(), -1);
    for (std::size_t i = 0; i < free.size(); ++i) {
        slot[free[i].id] = std::int64_t(i);
    }
    std::vector<double> z0(free.size());
    std::vector<bool> active(free.size(), false);
    for (std::size_t i = 0; i < free.size(); ++i) {
        z0[i] = mesh.positions[free[i].id].z;
        active[i] = relaxer.touches_fold(free[i].id);
    }
    std::vector<bool> moved(free.size(), false);
    // The cost of leaving the interpolated height: at the largest shift it equals an edge
    // (fold_angle + 3.5) degrees wide.
    const double stay = 100.0;
    for (unsigned sweep = 0; sweep < options.sweeps; ++sweep) {
        std::vector<bool> next(free.size(), false);
        bool any = false;
        for (std::size_t i = 0; i < free.size(); ++i) {
            if (!active[i]) {
                continue;
            }
            const FreeHeightVertex& fv = free[i];
            const double d = fv.z_high - fv.z_low;
            const double reach = options.max_shift * d;
            const double lo = std::max({fv.z_low + options.margin * d, z0[i] - reach, fv.z_min});
            const double hi = std::min({fv.z_high - options.margin * d, z0[i] + reach, fv.z_max});
            if (!(d > 0.0) || !(lo <= hi)) {
                continue;
            }
            // Only the faces around v move: the other faces' normals are fixed for this visit.
            const std::vector<std::uint32_t> moving = relaxer.star_faces(fv.id);
            const auto edges = relaxer.star_edge_faces(fv.id);
            std::vector<std::array<std::int32_t, 2>> slots(edges.size());  // -1: fixed
            std::vector<std::array<Vec3, 2>> fixed(edges.size());
            for (std::size_t e = 0; e < edges.size(); ++e) {
                for (int side = 0; side < 2; ++side) {
                    const std::uint32_t f = edges[e][std::size_t(side)];
                    const auto it = std::find(moving.begin(), moving.end(), f);
                    slots[e][std::size_t(side)] =
                        it == moving.end() ? -1 : std::int32_t(it - moving.begin());
                    fixed[e][std::size_t(side)] = relaxer.unit_normal(f);
                }
            }
            std::vector<Vec3> normals(moving.size());
            const double limit = std::cos(options.fold_angle_deg / kDegrees);
            double& z = mesh.positions[fv.id].z;
            const double start = z;
            auto cost = [&](double at) {
                z = at;
                for (std::size_t m = 0; m < moving.size(); ++m) {
                    normals[m] = relaxer.unit_normal(moving[m]);
                }
                double sum = 0.0;
                for (std::size_t e = 0; e < edges.size(); ++e) {
                    std::array<Vec3, 2> n = fixed[e];
                    for (std::size_t side = 0; side < 2; ++side) {
                        if (slots[e][side] >= 0) {
                            n[side] = normals[std::size_t(slots[e][side])];
                        }
                    }
                    if (!(norm(n[0]) > 0.0) || !(norm(n[1]) > 0.0)) {
                        continue;
                    }
                    // (cos(angle) below the limit) in degrees near 90: no acos per edge
                    const double over = (limit - dot(n[0], n[1])) * kDegrees;
                    sum += over > 0.0 ? over * over : 0.0;
                }
                const double shift = (at - z0[i]) / d;
                return sum + stay * shift * shift;
            };
            double best_z = start;
            double best = cost(start);
            constexpr int kSteps = 14;
            for (int s = 0; s <= kSteps; ++s) {
                const double at = lo + (hi - lo) * s / kSteps;
                const double c = cost(at);
                if (c < best - 1e-9) {
                    best = c;
                    best_z = at;
                }
            }
            // refine around the best candidate
            double step = (hi - lo) / kSteps;
            for (int r = 0; r < 4; ++r) {
                step *= 0.5;
                for (const double at : {best_z - step, best_z + step}) {
                    if (at < lo || at > hi) {
                        continue;
                    }
                    const double c = cost(at);
                    if (c < best - 1e-9) {
                        best = c;
                        best_z = at;
                    }
                }
            }
            z = best_z;
            if (best_z != start) {
                moved[i] = true;
                any = true;
                for (const std::uint32_t u : relaxer.neighbours(fv.id)) {
                    if (slot[u] >= 0) {
                        next[std::size_t(slot[u])] = true;
                    }
                }
            }
        }
        if (!any) {
            break;
        }
        active = std::move(next);
    }
    return std::size_t(std::count(moved.begin(), moved.end(), true));
}

}  // namespace strata

#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/types.h"
#include "mesh/tri_mesh.h"

namespace strata {

/// The faces around each vertex of a triangle mesh and the faces of each of its edges, for the
/// passes that walk a vertex's star to unfold the surface (relax_heights, snap_to_grid's
/// rounding). Built once from the triangles; positions may change afterwards.
class MeshAdjacency {
public:
    explicit MeshAdjacency(const TriMesh& mesh) : mesh_(mesh) {
        const std::size_t n = mesh.positions.size();
        first_.assign(n + 1, 0);
        for (const auto& t : mesh.triangles) {
            for (const std::uint32_t v : t) {
                ++first_[v + 1];
            }
        }
        for (std::size_t v = 0; v < n; ++v) {
            first_[v + 1] += first_[v];
        }
        faces_.resize(first_[n]);
        std::vector<std::size_t> fill(first_.begin(), first_.end() - 1);
        edges_.reserve(mesh.triangles.size() * 2);
        for (std::uint32_t f = 0; f < mesh.triangles.size(); ++f) {
            const auto& t = mesh.triangles[f];
            for (std::size_t i = 0; i < 3; ++i) {
                faces_[fill[t[i]]++] = f;
                auto [it, added] = edges_.try_emplace(edge_key(t[i], t[(i + 1) % 3]),
                                                      std::array<std::uint32_t, 3>{f, f, 0});
                if (!added) {
                    it->second[1] = f;
                }
                ++it->second[2];
            }
        }
    }

    /// The key of the undirected edge (a, b).
    static std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
        return a < b ? (std::uint64_t(a) << 32) | b : (std::uint64_t(b) << 32) | a;
    }

    /// The faces around v, in increasing order.
    std::vector<std::uint32_t> faces_around(std::uint32_t v) const {
        return {faces_.begin() + std::ptrdiff_t(first_[v]),
                faces_.begin() + std::ptrdiff_t(first_[v + 1])};
    }

    /// The keys of the edges of the faces around v, each once, in increasing order.
    std::vector<std::uint64_t> star_edges(std::uint32_t v) const {
        std::vector<std::uint64_t> keys;
        for (std::size_t i = first_[v]; i < first_[v + 1]; ++i) {
            const auto& t = mesh_.triangles[faces_[i]];
            for (std::size_t j = 0; j < 3; ++j) {
                keys.push_back(edge_key(t[j], t[(j + 1) % 3]));
            }
        }
        std::sort(keys.begin(), keys.end());
        keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
        return keys;
    }

    /// Edge `key`'s first and last face and its number of faces (an edge of the mesh).
    const std::array<std::uint32_t, 3>& edge(std::uint64_t key) const { return edges_.at(key); }

    /// Every edge: key -> first face, last face, number of faces.
    const std::unordered_map<std::uint64_t, std::array<std::uint32_t, 3>>& edges() const {
        return edges_;
    }

private:
    const TriMesh& mesh_;
    std::vector<std::size_t> first_;    ///< CSR offsets of each vertex's faces
    std::vector<std::uint32_t> faces_;  ///< faces per vertex
    std::unordered_map<std::uint64_t, std::array<std::uint32_t, 3>> edges_;
};

/// The unit normal of face f of `mesh` (zero for a face without area).
inline Vec3 unit_face_normal(const TriMesh& mesh, std::uint32_t f) {
    const auto& t = mesh.triangles[f];
    const Vec3 p0 = mesh.positions[t[0]];
    const Vec3 n = cross(mesh.positions[t[1]] - p0, mesh.positions[t[2]] - p0);
    const double length = norm(n);
    return length > 0.0 ? (1.0 / length) * n : Vec3{};
}

}  // namespace strata

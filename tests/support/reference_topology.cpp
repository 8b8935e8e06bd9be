// Independent cross-check of the reference labeller (triangulate/reference_topology.h): explicit
// boundary quad mesh of R made a closed 2-manifold by splitting edges and vertices as the
// connectivity rule says, then V - E + F per mesh component.
#include "support/reference_topology.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <limits>
#include <map>
#include <ostream>
#include <sstream>
#include <tuple>
#include <utility>

#include "core/error.h"

namespace strata::test {

using detail::check_topology_inputs;
using detail::label_mask;
using detail::sort_surfaces;
// ---------------------------------------------------------------------------------------------
// Brute force: explicit R, breadth-first labelling, boundary quad mesh, V - E + F.

namespace {

class BruteForce {
public:
    BruteForce(const std::vector<std::uint8_t>& mask, int width, int height, int depth)
        : n_{width + 2, height + 2, 2 * depth + 1} {
        volume_.assign(std::size_t(n_[0]) * n_[1] * n_[2], 0);
        for (int z = 0; z < n_[2]; ++z) {
            // note: written out again rather than shared with the fast labeller's streaming code.
            const int l = z - 1;
            for (int y = 1; y + 1 < n_[1]; ++y) {
                for (int x = 1; x + 1 < n_[0]; ++x) {
                    if (l < 0 || l > 2 * depth - 2) {
                        continue;
                    }
                    auto slice = [&](int k) {
                        return mask[(std::size_t(k) * height + (y - 1)) * width + (x - 1)] != 0;
                    };
                    const bool f = l % 2 == 0 ? slice(l / 2) : slice(l / 2) && slice(l / 2 + 1);
                    volume_[voxel({x, y, z})] = f ? 1 : 0;
                }
            }
        }
    }

    ReferenceTopology run() {
        label_components();
        collect_faces();
        collect_edges();
        collect_vertices();
        return summarise();
    }

private:
    using Coord = std::array<int, 3>;

    struct Face {
        std::size_t foreground_voxel;
        std::size_t background_voxel;
        int axis;
        Coord corner;  // lowest corner; the face lies in the plane coordinate[axis] = corner[axis]
        int normal;    // +1 if the foreground voxel is on the low side (normal along +axis)
    };

    std::size_t voxel(Coord c) const { return (std::size_t(c[2]) * n_[1] + c[1]) * n_[0] + c[0]; }
    std::size_t face_key(int axis, Coord c) const {
        return ((std::size_t(axis) * (n_[2] + 1) + c[2]) * (n_[1] + 1) + c[1]) * (n_[0] + 1) + c[0];
    }
    bool is_foreground(Coord c) const { return volume_[voxel(c)] != 0; }

    // Foreground: 8-connected in-plane, face-connected in z. Background: 6-connected.
    void label_components() {
        component_.assign(volume_.size(), -1);
        std::deque<Coord> queue;
        for (int z = 0; z < n_[2]; ++z) {
            for (int y = 0; y < n_[1]; ++y) {
                for (int x = 0; x < n_[0]; ++x) {
                    if (component_[voxel({x, y, z})] >= 0) {
                        continue;
                    }
                    const bool foreground = is_foreground({x, y, z});
                    const int id = foreground ? foreground_count_++ : background_count_++;
                    component_[voxel({x, y, z})] = id;
                    queue.push_back({x, y, z});
                    while (!queue.empty()) {
                        const Coord c = queue.front();
                        queue.pop_front();
                        for (int dz = -1; dz <= 1; ++dz) {
                            for (int dy = -1; dy <= 1; ++dy) {
                                for (int dx = -1; dx <= 1; ++dx) {
                                    const int steps = std::abs(dx) + std::abs(dy) + std::abs(dz);
                                    const bool adjacent =
                                        steps == 1 || (foreground && steps == 2 && dz == 0);
                                    const Coord d{c[0] + dx, c[1] + dy, c[2] + dz};
                                    if (!adjacent || d[0] < 0 || d[1] < 0 || d[2] < 0 ||
                                        d[0] >= n_[0] || d[1] >= n_[1] || d[2] >= n_[2]) {
                                        continue;
                                    }
                                    if (is_foreground(d) == foreground &&
                                        component_[voxel(d)] < 0) {
                                        component_[voxel(d)] = id;
                                        queue.push_back(d);
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
    }

    // One quad per face between a foreground and a background voxel.
    void collect_faces() {
        face_index_.assign(3 * std::size_t(n_[0] + 1) * (n_[1] + 1) * (n_[2] + 1), -1);
        for (int axis = 0; axis < 3; ++axis) {
            for (int z = 0; z < n_[2]; ++z) {
                for (int y = 0; y < n_[1]; ++y) {
                    for (int x = 0; x < n_[0]; ++x) {
                        const Coord low{x, y, z};
                        Coord high = low;
                        ++high[axis];
                        if (high[axis] >= n_[axis] || is_foreground(low) == is_foreground(high)) {
                            continue;
                        }
                        const bool low_foreground = is_foreground(low);
                        face_index_[face_key(axis, high)] = int(faces_.size());
                        faces_.push_back({voxel(low_foreground ? low : high),
                                          voxel(low_foreground ? high : low), axis, high,
                                          low_foreground ? 1 : -1});
                    }
                }
            }
        }
        parent_.resize(faces_.size());
        for (std::size_t f = 0; f < faces_.size(); ++f) {
            parent_[f] = int(f);
        }
    }

    // The face between two face-adjacent voxels (its lowest corner is the higher voxel).
    int face_between(Coord a, Coord b) const {
        const int axis = a[0] != b[0] ? 0 : (a[1] != b[1] ? 1 : 2);
        return face_index_[face_key(axis, a[axis] > b[axis] ? a : b)];
    }

    // The pairs of boundary faces that the surface joins across the grid edge along `axis` whose
    // low end is `c` (0, 1 or 2 pairs). Two pairs only where foreground and background alternate
    // around the edge: foreground connects there (in-plane 8-connectivity), so each background
    // voxel gets its own sheet.
    int edge_pairs(int axis, Coord c, std::array<std::pair<int, int>, 2>& out) const {
        const int u = (axis + 1) % 3;
        const int v = (axis + 2) % 3;
        std::array<Coord, 4> around{c, c, c, c};  // cyclic order around the edge
        around[0][u] -= 1;
        around[0][v] -= 1;
        around[1][v] -= 1;
        around[3][u] -= 1;
        std::array<int, 4> face{-1, -1, -1, -1};  // face[i] between around[i] and around[i+1]
        int boundary = 0;
        for (int i = 0; i < 4; ++i) {
            const Coord& a = around[i];
            const Coord& b = around[(i + 1) % 4];
            if (is_foreground(a) != is_foreground(b)) {
                face[i] = face_between(a, b);
                ++boundary;
            }
        }
        if (boundary == 0) {
            return 0;
        }
        if (boundary == 2) {
            std::array<int, 2> found{};
            int k = 0;
            for (int i = 0; i < 4; ++i) {
                if (face[i] >= 0) {
                    found[k++] = face[i];
                }
            }
            out[0] = {found[0], found[1]};
            return 1;
        }
        if (axis != 2) {
            std::ostringstream msg;
            msg << "reference_topology_brute_force: diagonal configuration across layers at "
                << "edge (" << c[0] << ", " << c[1] << ", " << c[2] << ") along axis " << axis;
            throw Error{ErrorCode::Internal, msg.str()};
        }
        int k = 0;
        for (int i = 0; i < 4; ++i) {
            if (!is_foreground(around[i])) {
                out[k++] = {face[(i + 3) % 4], face[i]};
            }
        }
        return 2;
    }

    // Whether the eight voxels around corner c are all foreground or all background.
    bool is_uniform_block(Coord c) const {
        const bool first = is_foreground({c[0] - 1, c[1] - 1, c[2] - 1});
        for (int b = 1; b < 8; ++b) {
            const Coord d{c[0] - 1 + (b & 1), c[1] - 1 + ((b >> 1) & 1), c[2] - 1 + (b >> 2)};
            if (is_foreground(d) != first) {
                return false;
            }
        }
        return true;
    }

    int find(int f) {
        while (parent_[f] != f) {
            parent_[f] = parent_[parent_[f]];
            f = parent_[f];
        }
        return f;
    }

    // Resolved edges: every grid edge with boundary faces gives one or two mesh edges.
    void collect_edges() {
        std::array<std::pair<int, int>, 2> pairs{};
        for (int axis = 0; axis < 3; ++axis) {
            const int u = (axis + 1) % 3;
            const int v = (axis + 2) % 3;
            Coord c{};
            for (c[2] = 0; c[2] <= n_[2]; ++c[2]) {
                for (c[1] = 0; c[1] <= n_[1]; ++c[1]) {
                    for (c[0] = 0; c[0] <= n_[0]; ++c[0]) {
                        if (c[axis] >= n_[axis] || c[u] < 1 || c[u] >= n_[u] || c[v] < 1 ||
                            c[v] >= n_[v]) {
                            continue;
                        }
                        const int count = edge_pairs(axis, c, pairs);
                        for (int k = 0; k < count; ++k) {
                            edge_faces_.push_back(pairs[k].first);
                            const int a = find(pairs[k].first);
                            const int b = find(pairs[k].second);
                            parent_[std::max(a, b)] = std::min(a, b);
                        }
                    }
                }
            }
        }
    }

    // Resolved vertices: around each grid corner, one mesh vertex per cycle of boundary faces
    // linked by the resolved edges through that corner.
    void collect_vertices() {
        std::array<std::pair<int, int>, 2> pairs{};
        Coord c{};
        for (c[2] = 1; c[2] < n_[2]; ++c[2]) {
            for (c[1] = 1; c[1] < n_[1]; ++c[1]) {
                for (c[0] = 1; c[0] < n_[0]; ++c[0]) {
                    if (is_uniform_block(c)) {
                        continue;
                    }
                    std::vector<int> local;  // boundary faces at this corner
                    std::vector<int> local_parent;
                    std::vector<int> degree;
                    auto slot = [&](int f) {
                        const auto it = std::find(local.begin(), local.end(), f);
                        if (it != local.end()) {
                            return int(it - local.begin());
                        }
                        local.push_back(f);
                        local_parent.push_back(int(local.size()) - 1);
                        degree.push_back(0);
                        return int(local.size()) - 1;
                    };
                    auto local_find = [&](int s) {
                        while (local_parent[s] != s) {
                            s = local_parent[s];
                        }
                        return s;
                    };
                    for (int axis = 0; axis < 3; ++axis) {
                        for (int side = 0; side < 2; ++side) {
                            Coord low = c;
                            low[axis] -= side;  // the edge from c going +axis, then going -axis
                            const int count = edge_pairs(axis, low, pairs);
                            for (int k = 0; k < count; ++k) {
                                const int a = slot(pairs[k].first);
                                const int b = slot(pairs[k].second);
                                ++degree[a];
                                ++degree[b];
                                const int ra = local_find(a);
                                const int rb = local_find(b);
                                local_parent[std::max(ra, rb)] = std::min(ra, rb);
                            }
                        }
                    }
                    for (std::size_t s = 0; s < local.size(); ++s) {
                        if (degree[s] != 2) {
                            std::ostringstream msg;
                            msg << "reference_topology_brute_force: face with " << degree[s]
                                << " links at corner (" << c[0] << ", " << c[1] << ", " << c[2]
                                << "), expected 2";
                            throw Error{ErrorCode::Internal, msg.str()};
                        }
                        if (local_find(int(s)) == int(s)) {
                            vertex_faces_.push_back(local[s]);
                        }
                    }
                }
            }
        }
    }

    ReferenceTopology summarise() {
        struct Mesh {
            std::int64_t vertices = 0, edges = 0, faces = 0;
            std::int64_t volume = 0;  // sum of z * n_z over faces normal to z
            int foreground = -1, background = -1;
        };
        std::vector<int> mesh_of(faces_.size(), -1);
        std::vector<Mesh> meshes;
        for (std::size_t f = 0; f < faces_.size(); ++f) {
            const int r = find(int(f));
            if (mesh_of[r] < 0) {
                mesh_of[r] = int(meshes.size());
                meshes.push_back({});
                meshes.back().foreground = component_[faces_[f].foreground_voxel];
                meshes.back().background = component_[faces_[f].background_voxel];
            }
            Mesh& mesh = meshes[mesh_of[r]];
            ++mesh.faces;
            if (faces_[f].axis == 2) {
                mesh.volume += std::int64_t(faces_[f].normal) * faces_[f].corner[2];
            }
            if (mesh.foreground != component_[faces_[f].foreground_voxel] ||
                mesh.background != component_[faces_[f].background_voxel]) {
                throw Error{ErrorCode::Internal,
                            "reference_topology_brute_force: a surface touches two solid or two "
                            "background components"};
            }
        }
        for (int f : edge_faces_) {
            ++meshes[mesh_of[find(f)]].edges;
        }
        for (int f : vertex_faces_) {
            ++meshes[mesh_of[find(f)]].vertices;
        }
        ReferenceTopology result;
        result.solid_components = foreground_count_;
        for (const Mesh& mesh : meshes) {
            const std::int64_t euler = mesh.vertices - mesh.edges + mesh.faces;
            if (euler > 2 || euler % 2 != 0 || 2 * mesh.edges != 4 * mesh.faces ||
                mesh.volume == 0) {
                std::ostringstream msg;
                msg << "reference_topology_brute_force: surface with V " << mesh.vertices << ", E "
                    << mesh.edges << ", F " << mesh.faces << ", volume " << mesh.volume;
                throw Error{ErrorCode::Internal, msg.str()};
            }
            result.surfaces.push_back(
                {static_cast<int>((2 - euler) / 2), mesh.volume < 0, mesh.foreground});
        }
        sort_surfaces(result);
        return result;
    }

    Coord n_;                           // padded size of R: x, y, layers
    std::vector<std::uint8_t> volume_;  // R, 1 = foreground
    std::vector<int> component_;        // per voxel: foreground or background component id
    int foreground_count_ = 0;
    int background_count_ = 0;
    std::vector<int> face_index_;  // per face key: index into faces_, or -1
    std::vector<Face> faces_;
    std::vector<int> parent_;        // union-find over faces_: mesh components
    std::vector<int> edge_faces_;    // one face per resolved edge
    std::vector<int> vertex_faces_;  // one face per resolved vertex
};

}  // namespace

ReferenceTopology reference_topology_brute_force(const std::vector<std::uint8_t>& mask,
                                                 int width,
                                                 int height,
                                                 int depth) {
    check_topology_inputs(mask, width, height, depth, "reference_topology_brute_force");
    if (width == 0 || height == 0 || depth == 0) {
        return {};
    }
    return BruteForce(mask, width, height, depth).run();
}

ReferenceTopology reference_topology_brute_force(const SliceStack& stack, std::uint16_t label) {
    return reference_topology_brute_force(
        label_mask(stack, label, "reference_topology_brute_force"), int(stack.width),
        int(stack.height), int(stack.depth));
}

}  // namespace strata::test

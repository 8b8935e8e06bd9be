#pragma once

// Hand-made triangle meshes with known topology and geometry, for mesh tests (pmp's
// algorithms/shapes.h in spirit). Closed shapes face outwards (counter-clockwise seen from
// outside) unless the name says otherwise. Header-only.

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <numbers>
#include <tuple>
#include <utility>

#include "mesh/tri_mesh.h"

namespace strata::test {

using Triangle = std::array<std::uint32_t, 3>;

/// Appends `part` to `mesh`, shifting its indices; labels are kept only if both have them.
inline void append(TriMesh& mesh, const TriMesh& part) {
    const auto offset = static_cast<std::uint32_t>(mesh.positions.size());
    mesh.positions.insert(mesh.positions.end(), part.positions.begin(), part.positions.end());
    for (Triangle t : part.triangles) {
        mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
    }
    mesh.labels.insert(mesh.labels.end(), part.labels.begin(), part.labels.end());
}

/// Merges vertices with exactly equal coordinates (first appearance wins, order kept) and drops
/// unreferenced ones.
inline TriMesh weld_exact(const TriMesh& mesh) {
    TriMesh out;
    out.labels = mesh.labels;
    std::map<std::tuple<double, double, double>, std::uint32_t> index;
    for (Triangle t : mesh.triangles) {
        Triangle r{};
        for (int k = 0; k < 3; ++k) {
            const Vec3 p = mesh.positions[t[k]];
            const auto [it, inserted] = index.try_emplace(
                {p.x, p.y, p.z}, static_cast<std::uint32_t>(out.positions.size()));
            if (inserted) {
                out.positions.push_back(p);
            }
            r[k] = it->second;
        }
        out.triangles.push_back(r);
    }
    return out;
}

/// Reverses the orientation of every triangle.
inline TriMesh flipped(TriMesh mesh) {
    for (Triangle& t : mesh.triangles) {
        std::swap(t[1], t[2]);
    }
    return mesh;
}

/// Applies `f` to every position.
inline TriMesh transformed(TriMesh mesh, const std::function<Vec3(Vec3)>& f) {
    for (Vec3& p : mesh.positions) {
        p = f(p);
    }
    return mesh;
}

inline TriMesh translated(TriMesh mesh, Vec3 offset) {
    return transformed(std::move(mesh), [&](Vec3 p) { return p + offset; });
}

/// Two triangles (a, b, c), (a, c, d) for a quad given counter-clockwise.
inline void add_quad(
    TriMesh& mesh, std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t d) {
    mesh.triangles.push_back({a, b, c});
    mesh.triangles.push_back({a, c, d});
}

/// The tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1): volume 1/6, area 1.5 + sqrt(3)/2.
inline TriMesh tetrahedron() {
    TriMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return mesh;
}

/// Corner offsets of the six cube faces, counter-clockwise seen from outside; corner bit 0 is
/// x, bit 1 y, bit 2 z. Order: -z, +z, -y, +y, -x, +x.
inline constexpr std::array<std::array<int, 4>, 6> kCubeFaces{{
    {0, 2, 3, 1},
    {4, 5, 7, 6},
    {0, 1, 5, 4},
    {2, 6, 7, 3},
    {0, 4, 6, 2},
    {1, 3, 7, 5},
}};
inline constexpr std::array<std::array<int, 3>, 6> kCubeFaceNormals{{
    {0, 0, -1},
    {0, 0, 1},
    {0, -1, 0},
    {0, 1, 0},
    {-1, 0, 0},
    {1, 0, 0},
}};

/// Axis-aligned cube [min, min + size]^3: 8 vertices, 12 triangles, volume size^3.
inline TriMesh cube(Vec3 min = {0, 0, 0}, double size = 1.0) {
    TriMesh mesh;
    for (int i = 0; i < 8; ++i) {
        mesh.positions.push_back(
            {min.x + (i & 1) * size, min.y + ((i >> 1) & 1) * size, min.z + ((i >> 2) & 1) * size});
    }
    for (const auto& f : kCubeFaces) {
        add_quad(mesh, f[0], f[1], f[2], f[3]);
    }
    return mesh;
}

/// Regular octahedron with vertices at +-1 on each axis: genus 0, volume 4/3.
inline TriMesh octahedron() {
    TriMesh mesh;
    // 0: +x, 1: -x, 2: +y, 3: -y, 4: +z, 5: -z
    mesh.positions = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int sx = 0; sx < 2; ++sx) {
        for (int sy = 0; sy < 2; ++sy) {
            for (int sz = 0; sz < 2; ++sz) {
                const std::uint32_t x = sx, y = 2 + sy, z = 4 + sz;
                if ((sx + sy + sz) % 2 == 0) {
                    mesh.triangles.push_back({x, y, z});
                } else {
                    mesh.triangles.push_back({x, z, y});
                }
            }
        }
    }
    return mesh;
}

/// Torus around the z axis as a `major` x `minor` quad grid (2 * major * minor triangles),
/// radii `major_radius` > `minor_radius`: genus 1.
inline TriMesh torus(int major = 12,
                     int minor = 8,
                     double major_radius = 2.0,
                     double minor_radius = 0.5) {
    TriMesh mesh;
    const double tau = 2.0 * std::numbers::pi;
    for (int i = 0; i < major; ++i) {
        for (int j = 0; j < minor; ++j) {
            const double u = tau * i / major, v = tau * j / minor;
            const double ring = major_radius + minor_radius * std::cos(v);
            mesh.positions.push_back(
                {ring * std::cos(u), ring * std::sin(u), minor_radius * std::sin(v)});
        }
    }
    auto id = [&](int i, int j) {
        return static_cast<std::uint32_t>((i % major) * minor + (j % minor));
    };
    for (int i = 0; i < major; ++i) {
        for (int j = 0; j < minor; ++j) {
            add_quad(mesh, id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
        }
    }
    return mesh;
}

/// Boundary surface of the unit voxels (x, y, z) in [0, nx) x [0, ny) x [0, nz) for which
/// `filled` holds, welded, outward-facing. Manifold when no two filled voxels touch only along
/// an edge or at a corner.
inline TriMesh voxel_surface(int nx,
                             int ny,
                             int nz,
                             const std::function<bool(int, int, int)>& filled) {
    auto inside = [&](int x, int y, int z) {
        return x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz && filled(x, y, z);
    };
    TriMesh soup;
    for (int z = 0; z < nz; ++z) {
        for (int y = 0; y < ny; ++y) {
            for (int x = 0; x < nx; ++x) {
                if (!inside(x, y, z)) {
                    continue;
                }
                for (int f = 0; f < 6; ++f) {
                    const auto& n = kCubeFaceNormals[f];
                    if (inside(x + n[0], y + n[1], z + n[2])) {
                        continue;
                    }
                    const auto base = static_cast<std::uint32_t>(soup.positions.size());
                    for (int corner : kCubeFaces[f]) {
                        soup.positions.push_back({double(x + (corner & 1)),
                                                  double(y + ((corner >> 1) & 1)),
                                                  double(z + ((corner >> 2) & 1))});
                    }
                    add_quad(soup, base, base + 1, base + 2, base + 3);
                }
            }
        }
    }
    return weld_exact(soup);
}

/// A one-voxel-thick slab (2 * holes + 1) x 3 x 1 with `holes` square holes through it:
/// a closed surface of genus `holes` (2: a double torus).
inline TriMesh slab_with_holes(int holes) {
    return voxel_surface(2 * holes + 1, 3, 1,
                         [](int x, int y, int) { return !(y == 1 && x % 2 == 1); });
}

/// Cube without its top face (2 triangles removed): open, 4 boundary edges.
inline TriMesh open_box() {
    TriMesh mesh = cube();
    mesh.triangles.erase(mesh.triangles.begin() + 2, mesh.triangles.begin() + 4);
    return mesh;
}

/// Unit cubes at the origin and at (1, 1, 0), welded: the edge (1,1,0)-(1,1,1) is shared by
/// 4 triangles (non-manifold edge).
inline TriMesh two_cubes_sharing_edge() {
    TriMesh mesh = cube();
    append(mesh, cube({1, 1, 0}));
    return weld_exact(mesh);
}

/// The tetrahedron and its point reflection through the origin, sharing only vertex (0,0,0):
/// a pinched, non-manifold vertex; all edges manifold.
inline TriMesh two_tetrahedra_sharing_vertex() {
    TriMesh mesh = tetrahedron();
    append(mesh, flipped(transformed(tetrahedron(), [](Vec3 p) { return -1.0 * p; })));
    return weld_exact(mesh);
}

/// Unit cube with triangle 0 reversed: its three edges are used twice in the same direction.
inline TriMesh cube_with_flipped_triangle() {
    TriMesh mesh = cube();
    std::swap(mesh.triangles[0][1], mesh.triangles[0][2]);
    return mesh;
}

/// Unit cubes at the origin and at (0.5, 0.5, 0.5): two components that cross each other.
inline TriMesh interpenetrating_cubes() {
    TriMesh mesh = cube();
    append(mesh, cube({0.5, 0.5, 0.5}));
    return mesh;
}

/// Cube of size 3 containing a unit cube at (1, 1, 1) that faces inwards (a cavity): no
/// intersection, enclosed volume 27 - 1 = 26.
inline TriMesh nested_cubes() {
    TriMesh mesh = cube({0, 0, 0}, 3.0);
    append(mesh, flipped(cube({1, 1, 1}, 1.0)));
    return mesh;
}

/// Unit cubes at the origin and at (2, 0, 0): disjoint.
inline TriMesh disjoint_cubes() {
    TriMesh mesh = cube();
    append(mesh, cube({2, 0, 0}));
    return mesh;
}

/// Unit cubes at the origin and at (1, 0, 0) with separate (unwelded) vertices: their faces at
/// x = 1 coincide, which counts as an intersection (the triangles share no vertex).
inline TriMesh face_touching_cubes() {
    TriMesh mesh = cube();
    append(mesh, cube({1, 0, 0}));
    return mesh;
}

/// One connected strip that folds through itself: the profile (0,0) -> (2,0) -> (1,1) ->
/// (1,-1) in the xz plane, extruded along y over [0, 1]. The first and last panels cross along
/// x = 1, z = 0. 8 vertices, 6 triangles, open.
inline TriMesh folded_strip() {
    TriMesh mesh;
    const std::array<std::array<double, 2>, 4> profile{{{0, 0}, {2, 0}, {1, 1}, {1, -1}}};
    for (const auto& p : profile) {
        mesh.positions.push_back({p[0], 0, p[1]});
        mesh.positions.push_back({p[0], 1, p[1]});
    }
    for (std::uint32_t i = 0; i + 1 < profile.size(); ++i) {
        add_quad(mesh, 2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1);
    }
    return mesh;
}

}  // namespace strata::test

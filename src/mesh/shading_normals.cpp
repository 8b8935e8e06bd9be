#include "mesh/shading_normals.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "core/error.h"

namespace strata {
namespace {

Vec3 unit_or_zero(Vec3 a) {
    const double n = norm(a);
    return n > 0.0 ? (1.0 / n) * a : Vec3{};
}

/// Interior angle at a between the edges to b and c (0 when an edge has zero length).
double corner_angle(Vec3 a, Vec3 b, Vec3 c) {
    const Vec3 u = unit_or_zero(b - a);
    const Vec3 w = unit_or_zero(c - a);
    if (u == Vec3{} || w == Vec3{}) {
        return 0.0;
    }
    return std::acos(std::clamp(dot(u, w), -1.0, 1.0));
}

}  // namespace

std::vector<Vec3> shading_normals(const TriMesh& mesh, unsigned rings) {
    const std::size_t n = mesh.positions.size();
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (const std::uint32_t v : mesh.triangles[t]) {
            if (v >= n) {
                throw Error(ErrorCode::InvalidInput,
                            "shading normals: triangle " + std::to_string(t) + " has vertex " +
                                std::to_string(v) + ", expected below " + std::to_string(n));
            }
        }
    }
    std::vector<Vec3> angle_weighted(n);
    for (const auto& tri : mesh.triangles) {
        const Vec3 p0 = mesh.positions[tri[0]];
        const Vec3 p1 = mesh.positions[tri[1]];
        const Vec3 p2 = mesh.positions[tri[2]];
        const Vec3 c = cross(p1 - p0, p2 - p0);
        if (c == Vec3{}) {
            continue;
        }
        const Vec3 nf = unit_or_zero(c);
        angle_weighted[tri[0]] = angle_weighted[tri[0]] + corner_angle(p0, p1, p2) * nf;
        angle_weighted[tri[1]] = angle_weighted[tri[1]] + corner_angle(p1, p2, p0) * nf;
        angle_weighted[tri[2]] = angle_weighted[tri[2]] + corner_angle(p2, p0, p1) * nf;
    }
    for (Vec3& a : angle_weighted) {
        a = unit_or_zero(a);
    }
    std::vector<Vec3> normals(n);
    if (rings == 0) {
        for (std::size_t v = 0; v < n; ++v) {
            normals[v] = angle_weighted[v] == Vec3{} ? Vec3{0.0, 0.0, 1.0} : angle_weighted[v];
        }
        return normals;
    }
    // Neighbours of every vertex (compressed rows, sorted, unique).
    std::vector<std::uint32_t> start(n + 1, 0);
    for (const auto& tri : mesh.triangles) {
        for (const std::uint32_t v : tri) {
            start[v + 1] += 2;
        }
    }
    for (std::size_t v = 0; v < n; ++v) {
        start[v + 1] += start[v];
    }
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    std::vector<std::uint32_t> adjacent(start[n]);
    for (const auto& tri : mesh.triangles) {
        for (int i = 0; i < 3; ++i) {
            const std::uint32_t v = tri[std::size_t(i)];
            adjacent[fill[v]++] = tri[std::size_t((i + 1) % 3)];
            adjacent[fill[v]++] = tri[std::size_t((i + 2) % 3)];
        }
    }
    std::vector<std::uint32_t> end(n);
    for (std::size_t v = 0; v < n; ++v) {
        const auto first = adjacent.begin() + start[v];
        std::sort(first, adjacent.begin() + start[v + 1]);
        end[v] =
            std::uint32_t(std::unique(first, adjacent.begin() + start[v + 1]) - adjacent.begin());
    }
    // Breadth-first to depth `rings`, marking visited vertices with the centre's stamp.
    std::vector<std::uint32_t> stamp(n, std::uint32_t(-1));
    std::vector<std::uint32_t> ring;
    for (std::size_t v = 0; v < n; ++v) {
        ring.assign(1, std::uint32_t(v));
        stamp[v] = std::uint32_t(v);
        std::size_t layer_begin = 0;
        for (unsigned depth = 0; depth < rings; ++depth) {
            const std::size_t layer_end = ring.size();
            for (std::size_t r = layer_begin; r < layer_end; ++r) {
                const std::uint32_t u = ring[r];
                for (std::uint32_t e = start[u]; e < end[u]; ++e) {
                    const std::uint32_t w = adjacent[e];
                    if (stamp[w] != std::uint32_t(v)) {
                        stamp[w] = std::uint32_t(v);
                        ring.push_back(w);
                    }
                }
            }
            layer_begin = layer_end;
        }
        std::sort(ring.begin(), ring.end());  // sum in vertex order
        Vec3 sum{};
        for (const std::uint32_t u : ring) {
            const double w =
                std::clamp((dot(angle_weighted[u], angle_weighted[v]) + 0.5) / 0.1, 0.0, 1.0);
            if (w > 0.0) {
                sum = sum + w * angle_weighted[u];
            }
        }
        Vec3 result = unit_or_zero(sum);
        if (result == Vec3{}) {
            result = angle_weighted[v];
        }
        normals[v] = result == Vec3{} ? Vec3{0.0, 0.0, 1.0} : result;
    }
    return normals;
}

}  // namespace strata

// Validity and topology checks for indexed triangle meshes.
//
// Everything local is found around each vertex in one pass over a vertex -> triangles table:
// the edges to higher-numbered neighbours with their uses and directions, the fans (a small
// union-find over the triangles at the vertex, joined through shared edges), and duplicate
// triangles (among those whose smallest vertex it is). Components come from a union-find over
// vertices. Euler characteristic and genus follow the usual definitions for closed orientable
// surfaces (chi = V - E + F = 2 - 2g), e.g. Edelsbrunner & Harer, "Computational Topology",
// 2010, section II.3. Volumes use the divergence theorem: the sum of the signed tetrahedra
// spanned by a reference point and each triangle.
#include "mesh/mesh_checks.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <string_view>
#include <utility>

namespace strata {

namespace {

constexpr std::size_t kMaxExamples = 5;
constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

/// Union-find with union by size and path halving.
class DisjointSets {
public:
    explicit DisjointSets(std::size_t n) : parent_(n), size_(n, 1) {
        std::iota(parent_.begin(), parent_.end(), std::uint32_t{0});
    }

    std::uint32_t find(std::uint32_t x) {
        while (parent_[x] != x) {
            parent_[x] = parent_[parent_[x]];
            x = parent_[x];
        }
        return x;
    }

    void unite(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) {
            return;
        }
        if (size_[a] < size_[b]) {
            std::swap(a, b);
        }
        parent_[b] = a;
        size_[a] += size_[b];
    }

private:
    std::vector<std::uint32_t> parent_;
    std::vector<std::uint32_t> size_;
};

/// A count of one kind of finding plus the first few examples, described lazily.
struct Finding {
    std::size_t count = 0;
    std::vector<std::string> examples;

    template <class Describe>
    void add(Describe&& describe) {
        if (examples.size() < kMaxExamples) {
            examples.push_back(describe());
        }
        ++count;
    }
};

/// "3 boundary edges (the surface is open), e.g. (0, 1), (1, 2), (2, 0)".
void describe(const Finding& finding,
              std::string_view singular,
              std::string_view plural,
              std::string_view explanation,
              std::vector<std::string>& out) {
    if (finding.count == 0) {
        return;
    }
    std::string line = std::to_string(finding.count) + " ";
    line += finding.count == 1 ? singular : plural;
    if (!explanation.empty()) {
        line += " ";
        line += explanation;
    }
    if (!finding.examples.empty()) {
        line += ", e.g. ";
        for (std::size_t i = 0; i < finding.examples.size(); ++i) {
            if (i > 0) {
                line += "; ";
            }
            line += finding.examples[i];
        }
        if (finding.count > finding.examples.size()) {
            line += "; ...";
        }
    }
    out.push_back(std::move(line));
}

std::string edge_text(std::uint32_t a, std::uint32_t b) {
    // note: appended piece by piece; "(" + std::string trips GCC 12's -Wrestrict (PR 105651).
    std::string text = "(";
    text += std::to_string(a);
    text += ", ";
    text += std::to_string(b);
    text += ")";
    return text;
}

std::string triangle_text(std::size_t t, const std::array<std::uint32_t, 3>& tri) {
    return "triangle " + std::to_string(t) + " (" + std::to_string(tri[0]) + ", " +
           std::to_string(tri[1]) + ", " + std::to_string(tri[2]) + ")";
}

bool is_finite(const Vec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

}  // namespace

MeshReport check_mesh(const TriMesh& mesh) {
    MeshReport report;
    const auto& positions = mesh.positions;
    const auto& triangles = mesh.triangles;
    const std::size_t vertex_count = positions.size();
    const std::size_t triangle_count = triangles.size();
    report.vertex_count = vertex_count;
    report.triangle_count = triangle_count;

    // note: indices are uint32, so more vertices than that cannot be referenced; the union-find
    // below indexes vertices with uint32 too.
    const std::size_t indexable = std::min<std::size_t>(vertex_count, kNone);

    Finding non_finite;
    for (std::size_t v = 0; v < vertex_count; ++v) {
        if (!is_finite(positions[v])) {
            non_finite.add([&] { return "vertex " + std::to_string(v); });
        }
    }

    // Classify triangles; only valid ones enter topology and geometry.
    Finding out_of_range;
    Finding repeated;
    std::vector<std::uint8_t> valid(triangle_count, 0);
    for (std::size_t t = 0; t < triangle_count; ++t) {
        const auto& tri = triangles[t];
        if (tri[0] >= indexable || tri[1] >= indexable || tri[2] >= indexable) {
            out_of_range.add([&] { return triangle_text(t, tri); });
        } else if (tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0]) {
            repeated.add([&] { return triangle_text(t, tri); });
        } else {
            valid[t] = 1;
        }
    }

    // Components: union-find over vertices through valid triangles.
    DisjointSets sets(indexable);
    std::vector<std::uint8_t> referenced(indexable, 0);
    for (std::size_t t = 0; t < triangle_count; ++t) {
        if (valid[t]) {
            const auto& tri = triangles[t];
            sets.unite(tri[0], tri[1]);
            sets.unite(tri[0], tri[2]);
            referenced[tri[0]] = referenced[tri[1]] = referenced[tri[2]] = 1;
        }
    }
    std::vector<std::uint32_t> component_of_root(indexable, kNone);
    std::vector<std::uint32_t> triangle_component(triangle_count, kNone);
    auto& components = report.components;
    for (std::size_t t = 0; t < triangle_count; ++t) {
        if (!valid[t]) {
            continue;
        }
        const std::uint32_t root = sets.find(triangles[t][0]);
        if (component_of_root[root] == kNone) {
            component_of_root[root] = static_cast<std::uint32_t>(components.size());
            components.emplace_back();
            components.back().first_triangle = static_cast<std::uint32_t>(t);
        }
        triangle_component[t] = component_of_root[root];
        ++components[component_of_root[root]].triangle_count;
    }
    auto vertex_component = [&](std::uint32_t v) { return component_of_root[sets.find(v)]; };

    Finding unreferenced;
    for (std::size_t v = 0; v < vertex_count; ++v) {
        if (v >= indexable || !referenced[v]) {
            unreferenced.add([&] { return "vertex " + std::to_string(v); });
        } else {
            ++components[vertex_component(static_cast<std::uint32_t>(v))].vertex_count;
        }
    }

    // One pass over the vertices: the triangles around a vertex v give, through their "spokes"
    // (v, w), every edge (v, w) with w > v and its uses, the fans at v (triangles joined
    // through a shared spoke) and, for triangles whose smallest vertex is v, duplicates.
    Finding boundary;
    Finding non_manifold_edges;
    Finding misoriented;
    Finding non_manifold_vertices;
    Finding duplicates;
    {
        std::vector<std::size_t> offsets(indexable + 1, 0);
        for (std::size_t t = 0; t < triangle_count; ++t) {
            if (valid[t]) {
                for (std::uint32_t v : triangles[t]) {
                    ++offsets[v + 1];
                }
            }
        }
        std::partial_sum(offsets.begin(), offsets.end(), offsets.begin());
        std::vector<std::uint32_t> incident(offsets.back());
        std::vector<std::size_t> fill(offsets.begin(), offsets.end() - 1);
        for (std::size_t t = 0; t < triangle_count; ++t) {
            if (valid[t]) {
                for (std::uint32_t v : triangles[t]) {
                    incident[fill[v]++] = static_cast<std::uint32_t>(t);  // increasing t
                }
            }
        }

        // Spoke key: neighbour << 32 | local triangle << 1 | (1 if the triangle walks v -> w);
        // vertex degrees stay far below the 2^31 local triangles this allows.
        std::vector<std::uint64_t> spokes;
        // Triangles whose smallest vertex is v: (middle << 32 | largest, triangle).
        std::vector<std::pair<std::uint64_t, std::uint32_t>> owned;
        std::vector<std::uint32_t> parent;
        auto find = [&](std::uint32_t x) {
            while (parent[x] != x) {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            return x;
        };
        auto local_of = [](std::uint64_t spoke) {
            return static_cast<std::uint32_t>((spoke & kNone) >> 1);
        };
        for (std::size_t vi = 0; vi < indexable; ++vi) {
            const auto v = static_cast<std::uint32_t>(vi);
            const std::size_t begin = offsets[v];
            const auto degree = static_cast<std::uint32_t>(offsets[v + 1] - begin);
            if (degree == 0) {
                continue;
            }
            MeshComponent& component = components[vertex_component(v)];
            spokes.clear();
            owned.clear();
            for (std::uint32_t i = 0; i < degree; ++i) {
                const auto& tri = triangles[incident[begin + i]];
                const int k = tri[0] == v ? 0 : (tri[1] == v ? 1 : 2);
                const std::uint64_t next = tri[(k + 1) % 3], prev = tri[(k + 2) % 3];
                spokes.push_back(next << 32 | std::uint64_t{i} << 1 | 1);
                spokes.push_back(prev << 32 | std::uint64_t{i} << 1);
                if (v < next && v < prev) {
                    owned.emplace_back(std::min(next, prev) << 32 | std::max(next, prev),
                                       incident[begin + i]);
                }
            }
            std::sort(spokes.begin(), spokes.end());
            parent.resize(degree);
            std::iota(parent.begin(), parent.end(), std::uint32_t{0});
            std::size_t fans = degree;
            for (std::size_t first = 0; first < spokes.size();) {
                const auto w = static_cast<std::uint32_t>(spokes[first] >> 32);
                std::size_t end = first;
                std::size_t forward = 0;
                for (; end < spokes.size() && (spokes[end] >> 32) == w; ++end) {
                    forward += spokes[end] & 1;
                    if (end > first) {
                        const std::uint32_t a = find(local_of(spokes[end]));
                        const std::uint32_t b = find(local_of(spokes[first]));
                        if (a != b) {
                            parent[a] = b;
                            --fans;
                        }
                    }
                }
                const std::size_t uses = end - first;
                auto triangle_of = [&](std::size_t spoke) {
                    return incident[begin + local_of(spokes[spoke])];
                };
                if (w > v) {
                    ++component.edge_count;
                    if (uses == 1) {
                        ++component.boundary_edge_count;
                        boundary.add([&] { return edge_text(v, w); });
                    } else if (uses > 2) {
                        ++component.non_manifold_edge_count;
                        non_manifold_edges.add([&] {
                            return edge_text(v, w) + " in " + std::to_string(uses) + " triangles";
                        });
                    } else if (forward != 1) {
                        ++component.misoriented_edge_count;
                        misoriented.add([&] {
                            return (forward == 2 ? edge_text(v, w) : edge_text(w, v)) +
                                   " in triangles " + std::to_string(triangle_of(first)) + " and " +
                                   std::to_string(triangle_of(first + 1));
                        });
                    }
                }
                first = end;
            }
            if (fans > 1) {
                ++component.non_manifold_vertex_count;
                non_manifold_vertices.add([&] {
                    return "vertex " + std::to_string(v) + " (" + std::to_string(fans) + " fans)";
                });
            }
            std::sort(owned.begin(), owned.end());
            for (std::size_t i = 1, first = 0; i < owned.size(); ++i) {
                if (owned[i].first != owned[first].first) {
                    first = i;
                    continue;
                }
                duplicates.add([&] {
                    return "triangle " + std::to_string(owned[i].second) + " repeats triangle " +
                           std::to_string(owned[first].second);
                });
            }
        }
    }

    // Area and volume, relative to one reference point per component for precision.
    Finding zero_area;
    {
        std::vector<Vec3> reference(components.size());
        for (std::size_t c = 0; c < components.size(); ++c) {
            const Vec3 p = positions[triangles[components[c].first_triangle][0]];
            reference[c] = is_finite(p) ? p : Vec3{};
        }
        for (std::size_t t = 0; t < triangle_count; ++t) {
            if (!valid[t]) {
                continue;
            }
            const auto& tri = triangles[t];
            const Vec3 &a = positions[tri[0]], &b = positions[tri[1]], &c = positions[tri[2]];
            if (!is_finite(a) || !is_finite(b) || !is_finite(c)) {
                continue;
            }
            MeshComponent& component = components[triangle_component[t]];
            const Vec3 r = reference[triangle_component[t]];
            const double area = 0.5 * norm(cross(b - a, c - a));
            if (area == 0.0) {
                zero_area.add([&] { return triangle_text(t, tri); });
            }
            component.area += area;
            component.signed_volume += dot(a - r, cross(b - r, c - r)) / 6.0;
        }
    }

    // Per-component topology and totals.
    for (MeshComponent& component : components) {
        component.euler_characteristic = static_cast<std::int64_t>(component.vertex_count) -
                                         static_cast<std::int64_t>(component.edge_count) +
                                         static_cast<std::int64_t>(component.triangle_count);
        const std::int64_t twice_genus = 2 - component.euler_characteristic;
        if (component.is_closed() && component.is_manifold() && component.is_oriented() &&
            twice_genus >= 0 && twice_genus % 2 == 0) {
            component.genus = static_cast<int>(twice_genus / 2);
        }
        report.edge_count += component.edge_count;
        report.euler_characteristic += component.euler_characteristic;
        report.signed_volume += component.signed_volume;
        report.area += component.area;
    }

    report.out_of_range_triangles = out_of_range.count;
    report.repeated_vertex_triangles = repeated.count;
    report.duplicate_triangles = duplicates.count;
    report.non_finite_vertices = non_finite.count;
    report.unreferenced_vertices = unreferenced.count;
    report.zero_area_triangles = zero_area.count;
    report.labels_size_mismatch = !mesh.labels.empty() && mesh.labels.size() != triangle_count;
    report.boundary_edges = boundary.count;
    report.non_manifold_edges = non_manifold_edges.count;
    report.non_manifold_vertices = non_manifold_vertices.count;
    report.misoriented_edges = misoriented.count;

    auto& problems = report.problems;
    const std::string range = "(vertex count " + std::to_string(vertex_count) + ")";
    describe(out_of_range, "triangle has a vertex index out of range",
             "triangles have a vertex index out of range", range, problems);
    describe(repeated, "triangle repeats a vertex", "triangles repeat a vertex", "", problems);
    describe(duplicates, "duplicate triangle", "duplicate triangles", "(same three vertices)",
             problems);
    describe(non_finite, "vertex has a non-finite coordinate",
             "vertices have a non-finite coordinate", "", problems);
    if (report.labels_size_mismatch) {
        problems.push_back("labels: " + std::to_string(mesh.labels.size()) +
                           " entries, expected 0 or " + std::to_string(triangle_count) +
                           " (one per triangle)");
    }
    describe(boundary, "boundary edge", "boundary edges", "(the surface is open)", problems);
    describe(non_manifold_edges, "non-manifold edge", "non-manifold edges",
             "(used by more than 2 triangles)", problems);
    describe(non_manifold_vertices, "non-manifold vertex", "non-manifold vertices",
             "(its triangles form more than one fan)", problems);
    describe(misoriented, "edge is used twice in the same direction",
             "edges are used twice in the same direction", "(inconsistent orientation)", problems);

    auto& notes = report.notes;
    if (triangle_count == 0) {
        notes.push_back("the mesh has no triangles");
    }
    describe(unreferenced, "unreferenced vertex", "unreferenced vertices", "", notes);
    describe(zero_area, "zero-area triangle", "zero-area triangles", "", notes);
    return report;
}

bool is_closed_manifold(const MeshReport& report) {
    return report.out_of_range_triangles == 0 && report.repeated_vertex_triangles == 0 &&
           report.duplicate_triangles == 0 && report.non_finite_vertices == 0 &&
           !report.labels_size_mismatch && report.boundary_edges == 0 &&
           report.non_manifold_edges == 0 && report.non_manifold_vertices == 0 &&
           report.misoriented_edges == 0;
}

std::vector<int> component_genera(const MeshReport& report) {
    std::vector<int> genera;
    genera.reserve(report.components.size());
    for (const MeshComponent& component : report.components) {
        genera.push_back(component.genus.value_or(-1));
    }
    return genera;
}

}  // namespace strata

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

/// Every kind of finding of check_mesh, in the order of its passes.
struct Findings {
    Finding non_finite;
    Finding out_of_range;
    Finding repeated;
    Finding unreferenced;
    Finding boundary;
    Finding non_manifold_edges;
    Finding misoriented;
    Finding non_manifold_vertices;
    Finding duplicates;
    Finding zero_area;
};

/// 1 for a triangle whose three indices are in range and distinct; only those enter topology and
/// geometry.
std::vector<std::uint8_t> classify_triangles(const TriMesh& mesh,
                                             std::size_t indexable,
                                             Findings& findings) {
    const auto& triangles = mesh.triangles;
    std::vector<std::uint8_t> valid(triangles.size(), 0);
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        const auto& tri = triangles[t];
        if (tri[0] >= indexable || tri[1] >= indexable || tri[2] >= indexable) {
            findings.out_of_range.add([&] { return triangle_text(t, tri); });
        } else if (tri[0] == tri[1] || tri[1] == tri[2] || tri[2] == tri[0]) {
            findings.repeated.add([&] { return triangle_text(t, tri); });
        } else {
            valid[t] = 1;
        }
    }
    return valid;
}

/// The connected components: a union-find over the vertices through the valid triangles.
struct ComponentMap {
    DisjointSets sets;
    std::vector<std::uint32_t> component_of_root;
    std::vector<std::uint32_t> triangle_component;  ///< kNone for an invalid triangle
    std::vector<std::uint8_t> referenced;           ///< per vertex: used by a valid triangle

    std::uint32_t of_vertex(std::uint32_t v) { return component_of_root[sets.find(v)]; }
};

/// Fills `components` (numbered by their first triangle) and their vertex and triangle counts.
ComponentMap find_components(const TriMesh& mesh,
                             const std::vector<std::uint8_t>& valid,
                             std::size_t indexable,
                             std::vector<MeshComponent>& components,
                             Findings& findings) {
    const auto& triangles = mesh.triangles;
    const std::size_t triangle_count = triangles.size();
    ComponentMap map{DisjointSets(indexable), std::vector<std::uint32_t>(indexable, kNone),
                     std::vector<std::uint32_t>(triangle_count, kNone),
                     std::vector<std::uint8_t>(indexable, 0)};
    for (std::size_t t = 0; t < triangle_count; ++t) {
        if (valid[t]) {
            const auto& tri = triangles[t];
            map.sets.unite(tri[0], tri[1]);
            map.sets.unite(tri[0], tri[2]);
            map.referenced[tri[0]] = map.referenced[tri[1]] = map.referenced[tri[2]] = 1;
        }
    }
    for (std::size_t t = 0; t < triangle_count; ++t) {
        if (!valid[t]) {
            continue;
        }
        const std::uint32_t root = map.sets.find(triangles[t][0]);
        if (map.component_of_root[root] == kNone) {
            map.component_of_root[root] = static_cast<std::uint32_t>(components.size());
            components.emplace_back();
            components.back().first_triangle = static_cast<std::uint32_t>(t);
        }
        map.triangle_component[t] = map.component_of_root[root];
        ++components[map.component_of_root[root]].triangle_count;
    }
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        if (v >= indexable || !map.referenced[v]) {
            findings.unreferenced.add([&] { return "vertex " + std::to_string(v); });
        } else {
            ++components[map.of_vertex(static_cast<std::uint32_t>(v))].vertex_count;
        }
    }
    return map;
}

/// The valid triangles around each vertex: `incident[offsets[v] .. offsets[v + 1])`, by
/// increasing triangle.
struct VertexTriangles {
    std::vector<std::size_t> offsets;
    std::vector<std::uint32_t> incident;
};

VertexTriangles vertex_triangles(const TriMesh& mesh,
                                 const std::vector<std::uint8_t>& valid,
                                 std::size_t indexable) {
    const auto& triangles = mesh.triangles;
    VertexTriangles table;
    table.offsets.assign(indexable + 1, 0);
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        if (valid[t]) {
            for (std::uint32_t v : triangles[t]) {
                ++table.offsets[v + 1];
            }
        }
    }
    std::partial_sum(table.offsets.begin(), table.offsets.end(), table.offsets.begin());
    table.incident.resize(table.offsets.back());
    std::vector<std::size_t> fill(table.offsets.begin(), table.offsets.end() - 1);
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        if (valid[t]) {
            for (std::uint32_t v : triangles[t]) {
                table.incident[fill[v]++] = static_cast<std::uint32_t>(t);  // increasing t
            }
        }
    }
    return table;
}

/// The local checks around one vertex v, from its triangles: through their "spokes" (v, w),
/// every edge (v, w) with w > v and its uses, the fans at v (triangles joined through a shared
/// spoke) and, for the triangles whose smallest vertex is v, duplicates. Reuses its buffers
/// from vertex to vertex.
class StarScan {
public:
    void scan(const TriMesh& mesh,
              const VertexTriangles& table,
              std::uint32_t v,
              MeshComponent& component,
              Findings& findings);

private:
    std::uint32_t find(std::uint32_t x) {
        while (parent_[x] != x) {
            parent_[x] = parent_[parent_[x]];
            x = parent_[x];
        }
        return x;
    }
    static std::uint32_t local_of(std::uint64_t spoke) {
        return static_cast<std::uint32_t>((spoke & kNone) >> 1);
    }

    // Spoke key: neighbour << 32 | local triangle << 1 | (1 if the triangle walks v -> w);
    // vertex degrees stay far below the 2^31 local triangles this allows.
    std::vector<std::uint64_t> spokes_;
    // Triangles whose smallest vertex is v: (middle << 32 | largest, triangle).
    std::vector<std::pair<std::uint64_t, std::uint32_t>> owned_;
    std::vector<std::uint32_t> parent_;  ///< union-find over the local triangles: the fans
};

void StarScan::scan(const TriMesh& mesh,
                    const VertexTriangles& table,
                    std::uint32_t v,
                    MeshComponent& component,
                    Findings& findings) {
    const std::size_t begin = table.offsets[v];
    const auto degree = static_cast<std::uint32_t>(table.offsets[v + 1] - begin);
    const auto& incident = table.incident;
    spokes_.clear();
    owned_.clear();
    for (std::uint32_t i = 0; i < degree; ++i) {
        const auto& tri = mesh.triangles[incident[begin + i]];
        const int k = tri[0] == v ? 0 : (tri[1] == v ? 1 : 2);
        const std::uint64_t next = tri[(k + 1) % 3], prev = tri[(k + 2) % 3];
        spokes_.push_back(next << 32 | std::uint64_t{i} << 1 | 1);
        spokes_.push_back(prev << 32 | std::uint64_t{i} << 1);
        if (v < next && v < prev) {
            owned_.emplace_back(std::min(next, prev) << 32 | std::max(next, prev),
                                incident[begin + i]);
        }
    }
    std::sort(spokes_.begin(), spokes_.end());
    parent_.resize(degree);
    std::iota(parent_.begin(), parent_.end(), std::uint32_t{0});
    std::size_t fans = degree;
    for (std::size_t first = 0; first < spokes_.size();) {
        const auto w = static_cast<std::uint32_t>(spokes_[first] >> 32);
        std::size_t end = first;
        std::size_t forward = 0;
        for (; end < spokes_.size() && (spokes_[end] >> 32) == w; ++end) {
            forward += spokes_[end] & 1;
            if (end > first) {
                const std::uint32_t a = find(local_of(spokes_[end]));
                const std::uint32_t b = find(local_of(spokes_[first]));
                if (a != b) {
                    parent_[a] = b;
                    --fans;
                }
            }
        }
        const std::size_t uses = end - first;
        auto triangle_of = [&](std::size_t spoke) {
            return incident[begin + local_of(spokes_[spoke])];
        };
        if (w > v) {
            ++component.edge_count;
            if (uses == 1) {
                ++component.boundary_edge_count;
                findings.boundary.add([&] { return edge_text(v, w); });
            } else if (uses > 2) {
                ++component.non_manifold_edge_count;
                findings.non_manifold_edges.add(
                    [&] { return edge_text(v, w) + " in " + std::to_string(uses) + " triangles"; });
            } else if (forward != 1) {
                ++component.misoriented_edge_count;
                findings.misoriented.add([&] {
                    return (forward == 2 ? edge_text(v, w) : edge_text(w, v)) + " in triangles " +
                           std::to_string(triangle_of(first)) + " and " +
                           std::to_string(triangle_of(first + 1));
                });
            }
        }
        first = end;
    }
    if (fans > 1) {
        ++component.non_manifold_vertex_count;
        findings.non_manifold_vertices.add(
            [&] { return "vertex " + std::to_string(v) + " (" + std::to_string(fans) + " fans)"; });
    }
    std::sort(owned_.begin(), owned_.end());
    for (std::size_t i = 1, first = 0; i < owned_.size(); ++i) {
        if (owned_[i].first != owned_[first].first) {
            first = i;
            continue;
        }
        findings.duplicates.add([&] {
            return "triangle " + std::to_string(owned_[i].second) + " repeats triangle " +
                   std::to_string(owned_[first].second);
        });
    }
}

/// Area and signed volume per component, relative to one reference point per component for
/// precision.
void measure_components(const TriMesh& mesh,
                        const std::vector<std::uint8_t>& valid,
                        const std::vector<std::uint32_t>& triangle_component,
                        std::vector<MeshComponent>& components,
                        Findings& findings) {
    const auto& positions = mesh.positions;
    const auto& triangles = mesh.triangles;
    std::vector<Vec3> reference(components.size());
    for (std::size_t c = 0; c < components.size(); ++c) {
        const Vec3 p = positions[triangles[components[c].first_triangle][0]];
        reference[c] = is_finite(p) ? p : Vec3{};
    }
    for (std::size_t t = 0; t < triangles.size(); ++t) {
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
            findings.zero_area.add([&] { return triangle_text(t, tri); });
        }
        component.area += area;
        component.signed_volume += dot(a - r, cross(b - r, c - r)) / 6.0;
    }
}

/// The counts, problems and notes of `report` from the findings.
void describe_findings(const TriMesh& mesh, const Findings& findings, MeshReport& report) {
    const std::size_t vertex_count = mesh.positions.size();
    const std::size_t triangle_count = mesh.triangles.size();
    report.out_of_range_triangles = findings.out_of_range.count;
    report.repeated_vertex_triangles = findings.repeated.count;
    report.duplicate_triangles = findings.duplicates.count;
    report.non_finite_vertices = findings.non_finite.count;
    report.unreferenced_vertices = findings.unreferenced.count;
    report.zero_area_triangles = findings.zero_area.count;
    report.labels_size_mismatch = !mesh.labels.empty() && mesh.labels.size() != triangle_count;
    report.boundary_edges = findings.boundary.count;
    report.non_manifold_edges = findings.non_manifold_edges.count;
    report.non_manifold_vertices = findings.non_manifold_vertices.count;
    report.misoriented_edges = findings.misoriented.count;

    auto& problems = report.problems;
    const std::string range = "(vertex count " + std::to_string(vertex_count) + ")";
    describe(findings.out_of_range, "triangle has a vertex index out of range",
             "triangles have a vertex index out of range", range, problems);
    describe(findings.repeated, "triangle repeats a vertex", "triangles repeat a vertex", "",
             problems);
    describe(findings.duplicates, "duplicate triangle", "duplicate triangles",
             "(same three vertices)", problems);
    describe(findings.non_finite, "vertex has a non-finite coordinate",
             "vertices have a non-finite coordinate", "", problems);
    if (report.labels_size_mismatch) {
        problems.push_back("labels: " + std::to_string(mesh.labels.size()) +
                           " entries, expected 0 or " + std::to_string(triangle_count) +
                           " (one per triangle)");
    }
    describe(findings.boundary, "boundary edge", "boundary edges", "(the surface is open)",
             problems);
    describe(findings.non_manifold_edges, "non-manifold edge", "non-manifold edges",
             "(used by more than 2 triangles)", problems);
    describe(findings.non_manifold_vertices, "non-manifold vertex", "non-manifold vertices",
             "(its triangles form more than one fan)", problems);
    describe(findings.misoriented, "edge is used twice in the same direction",
             "edges are used twice in the same direction", "(inconsistent orientation)", problems);

    auto& notes = report.notes;
    if (triangle_count == 0) {
        notes.push_back("the mesh has no triangles");
    }
    describe(findings.unreferenced, "unreferenced vertex", "unreferenced vertices", "", notes);
    describe(findings.zero_area, "zero-area triangle", "zero-area triangles", "", notes);
}

}  // namespace

MeshReport check_mesh(const TriMesh& mesh) {
    MeshReport report;
    report.vertex_count = mesh.positions.size();
    report.triangle_count = mesh.triangles.size();

    // note: indices are uint32, so more vertices than that cannot be referenced; the union-find
    // indexes vertices with uint32 too.
    const std::size_t indexable = std::min<std::size_t>(mesh.positions.size(), kNone);

    Findings findings;
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
        if (!is_finite(mesh.positions[v])) {
            findings.non_finite.add([&] { return "vertex " + std::to_string(v); });
        }
    }
    const std::vector<std::uint8_t> valid = classify_triangles(mesh, indexable, findings);
    auto& components = report.components;
    ComponentMap map = find_components(mesh, valid, indexable, components, findings);
    {
        const VertexTriangles table = vertex_triangles(mesh, valid, indexable);
        StarScan star;
        for (std::size_t vi = 0; vi < indexable; ++vi) {
            const auto v = static_cast<std::uint32_t>(vi);
            if (table.offsets[v + 1] > table.offsets[v]) {
                star.scan(mesh, table, v, components[map.of_vertex(v)], findings);
            }
        }
    }
    measure_components(mesh, valid, map.triangle_component, components, findings);

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
    describe_findings(mesh, findings, report);
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

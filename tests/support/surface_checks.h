#pragma once

// Independent validity checks of one label's full-resolution surface, for tests: the mesh core's
// manifold and orientation checks, the exact self-intersection test and the brute-force labeller
// of the reference volume R (support/reference_topology.h). None of it reads the pipeline's own
// verification (ObjectSurface::verification), which these checks are meant to cross-check.

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "input/slice_stack.h"
#include "mesh/mesh_checks.h"
#include "mesh/self_intersection.h"
#include "pipeline/reconstruct.h"
#include "support/reference_topology.h"

namespace strata::test {

/// (genus, is a cavity) of every surface of R for `label`, decreasing.
inline std::vector<std::pair<int, bool>> reference_genera(const SliceStack& stack,
                                                          std::uint16_t label) {
    const ReferenceTopology reference = reference_topology_brute_force(stack, label);
    std::vector<std::pair<int, bool>> genera;
    for (const ReferenceSurface& s : reference.surfaces) {
        genera.emplace_back(s.genus, s.is_cavity);
    }
    std::sort(genera.rbegin(), genera.rend());
    return genera;
}

/// What is wrong with `surface` (the surface of its label in `stack`): empty when it is a closed
/// oriented 2-manifold with positive volume, every component enclosing volume, the component
/// genera of R (brute force) and no self-intersection (exact), else the first problem found.
inline std::string independent_problem(const SliceStack& stack, const ObjectSurface& surface) {
    const MeshReport check = check_mesh(surface.mesh);
    if (!is_closed_manifold(check)) {
        return check.problems.empty() ? "not a closed manifold" : check.problems.front();
    }
    if (!(check.signed_volume > 0.0)) {
        return "faces inwards (volume " + std::to_string(check.signed_volume) + ")";
    }
    std::vector<std::pair<int, bool>> genera;  // (genus, faces inwards: a cavity)
    for (const MeshComponent& c : check.components) {
        if (c.signed_volume == 0.0) {
            return "a component encloses no volume";
        }
        genera.emplace_back(c.genus.value_or(-1), c.signed_volume < 0.0);
    }
    std::sort(genera.rbegin(), genera.rend());
    const std::vector<std::pair<int, bool>> expected = reference_genera(stack, surface.label);
    if (genera != expected) {
        return std::to_string(genera.size()) + " components, R has " +
               std::to_string(expected.size()) + " surfaces (or other genera or cavities)";
    }
    const SelfIntersections hits = find_self_intersections(surface.mesh, 1);
    if (!hits.is_free()) {
        return "self-intersections (" + std::to_string(hits.pairs.size()) + "+ pairs, " +
               std::to_string(hits.degenerate_triangles.size()) + " degenerate)";
    }
    return {};
}

/// Whether the independent checks reject `surface`.
inline bool independently_invalid(const SliceStack& stack, const ObjectSurface& surface) {
    return !independent_problem(stack, surface).empty();
}

}  // namespace strata::test

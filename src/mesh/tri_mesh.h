#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/types.h"

namespace strata {

/// An indexed triangle mesh: the output of triangulation and the input of simplification and
/// export. Triangles index `positions` (0-based); outward-facing triangles are counter-clockwise
/// seen from outside. Nothing is guaranteed by the type itself: `check_mesh` (mesh_checks.h) says
/// whether a given mesh is valid, closed, manifold and oriented.
struct TriMesh {
    std::vector<Vec3> positions;                          ///< one entry per vertex
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< one entry per triangle
    std::vector<std::uint16_t> labels;  ///< empty, or one label per triangle (material id)
};

}  // namespace strata

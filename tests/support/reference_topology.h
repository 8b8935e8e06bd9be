#pragma once

#include <cstdint>
#include <vector>

#include "input/slice_stack.h"
#include "triangulate/reference_topology.h"

namespace strata::test {

// The reference topology of R lives in the library (triangulate/reference_topology.h), which
// checks its own output with it; the tests cross-check it with this slow, simple labeller.
using strata::describe;
using strata::reference_topology;
using strata::ReferenceSurface;
using strata::ReferenceTopology;

/// Independent cross-check of reference_topology(), slow and simple: materialises R, labels it by
/// 3D breadth-first search, builds the boundary of R as a quad mesh (one quad per face between a
/// foreground and a background voxel), splits it into a closed 2-manifold (at an edge with
/// foreground on one diagonal and background on the other, the faces around each background
/// voxel are paired, since foreground connects there; vertices are split into one per cycle of
/// faces around them), and returns per mesh component genus = 1 - (V - E + F) / 2. Cavities are
/// the components whose enclosed signed volume is negative (normals point from foreground to
/// background). Memory and time O(size of R) with a large constant: for small stacks.
/// Same inputs, output convention and throws as reference_topology(); throws Error{Internal} if R
/// has a diagonal configuration across layers or the mesh is not a closed manifold (a bug).
ReferenceTopology reference_topology_brute_force(const std::vector<std::uint8_t>& mask,
                                                 int width,
                                                 int height,
                                                 int depth);

/// Same, for the pixels of `stack` equal to `label`.
ReferenceTopology reference_topology_brute_force(const SliceStack& stack, std::uint16_t label);

}  // namespace strata::test

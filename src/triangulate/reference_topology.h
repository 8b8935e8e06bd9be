#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "input/slice_stack.h"

namespace strata {

// Expected topology of a reconstructed surface, computed from the masks alone
// (docs/test-catalogue.md, "The reference volume R"). The reference volume R has 2K-1 layers: layer
// 2k is slice k, layer 2k+1 is slice k AND slice k+1; R is padded with background all round.
// Foreground is 8-connected in-plane and face-connected in z; background is 4-connected in-plane
// and face-connected in z (6-connected). The expected surface is the boundary of R.
//
// Why this pair of connectivities is sound on R (and what the labeller relies on): an AND layer
// is a subset of both neighbouring slice layers, so no 2x2 block spanning two layers holds two
// foreground voxels on one diagonal and two background voxels on the other. Hence any two
// foreground voxels of R that share a vertex or an edge are joined by the rule above within their
// 2x2x2 block: foreground connectivity equals 26-connectivity, and (26, 6) is a complementary
// pair. So:
// - the closed unit cubes of a foreground component X form a polyhedron P(X); distinct
//   components share no point;
// - the open complement of all foreground cubes has one component per background component Y, and
//   it deformation-retracts onto Y's voxel-centre complex K(Y) (vertices = voxels, edges =
//   face-adjacent pairs, squares = 2x2 planar blocks, cubes = 2x2x2 blocks, all inside Y);
// - every surface separates one foreground from one background component, the boundary between
//   a connected X and a connected Y is connected (a closed surface in R^3 separates), so surfaces
//   are exactly the adjacent (X, Y) pairs, and the adjacency graph of components is a tree rooted
//   at the outer background (the one holding the padding).
//
// Genus. For a compact 3-manifold M with boundary, chi(dM) = 2 chi(M). Cut the tree at the edge
// of surface S; the side away from the root is a component Z with everything it encloses, D(Z),
// a region whose boundary is S alone, so
//     genus(S) = 1 - chi(D(Z)),
// with chi(D(Z)) counted on closed cubes if Z is foreground (S is Z's outer surface) and on the
// voxel-centre complex if Z is background (S is a cavity of Z's parent). The labeller does not
// build D(Z): it counts chi(Z) for each component alone (chi(P(X)), chi(K(Y))) and uses that Z's
// own region M(Z) is bounded by S(Z) and the surfaces S(C) of its children C:
//     chi(S(Z)) = 2 chi(Z) - sum over children C of chi(S(C)),   genus(S(Z)) = 1 - chi(S(Z)) / 2.
// Examples: a voxel (chi 1): genus 0; a ring (chi 0): genus 1; a ball with a ball cavity: the
// cavity (chi(K) = 1) has chi(S) = 2, genus 0; the shell (chi(P) = 2, a thick sphere) has outer
// chi(S) = 2 * 2 - 2 = 2, genus 0.

/// One closed surface of the reference volume R.
struct ReferenceSurface {
    int genus = 0;            ///< genus of this closed surface (chi = 2 - 2 genus)
    bool is_cavity = false;   ///< false: outer surface of the solid; true: bounds a void inside it
    int solid_component = 0;  ///< the solid it bounds, an index into 0..solid_components-1

    friend bool operator==(const ReferenceSurface&, const ReferenceSurface&) = default;
};

/// Components and surfaces of R.
///
/// Solid components are numbered by their first voxel of R in raster order (layer, then row,
/// then column). `surfaces` is sorted by solid component, then the outer surface (exactly one per
/// solid) before the cavities, cavities by ascending genus: two results compare equal with ==
/// iff they describe the same topology with the same numbering.
struct ReferenceTopology {
    int solid_components = 0;
    std::vector<ReferenceSurface> surfaces;

    int surface_count() const { return static_cast<int>(surfaces.size()); }

    friend bool operator==(const ReferenceTopology&, const ReferenceTopology&) = default;
};

/// One line per topology: "2 solids, 3 surfaces: [0 outer g1] [0 cavity g0] [1 outer g0]".
std::string describe(const ReferenceTopology& topology);

/// Lets GoogleTest print results in failure messages.
void PrintTo(const ReferenceTopology& topology, std::ostream* os);

/// Reference topology of a binary stack: union-find over the runs (row intervals) of R, streamed
/// two layers at a time, with per-component Euler characteristics counted on the mixed 2x2x2
/// blocks (see the comment at the top of this header).
///
/// `mask` holds width * height * depth values, slice after slice, rows of `width`;
/// mask[(k * height + j) * width + i] != 0 is foreground at column i, row j of slice k.
/// Time is linear in the stack size (reading it) plus the number of runs; memory is O(runs of
/// two slices) plus O(provisional labels): 4096x4096x10 (T32) takes well under a second. An
/// empty mask or a zero dimension gives no solids.
/// Throws Error{InvalidInput} if a dimension is negative or the mask size is not
/// width * height * depth (the stack overload: labels size not width * height * depth);
/// Error{Unsupported} past 2^31 - 3 columns or rows or 2^30 slices; Error{Internal} if a
/// topological invariant fails (a bug).
ReferenceTopology reference_topology(const std::vector<std::uint8_t>& mask,
                                     int width,
                                     int height,
                                     int depth);

/// Same, for the pixels of `stack` equal to `label` (label 0 selects the background).
ReferenceTopology reference_topology(const SliceStack& stack, std::uint16_t label);

namespace detail {
/// Shared with the independent brute-force labeller of the tests: argument checks, the 0/1 mask
/// of one label, the canonical order of surfaces.
void check_topology_inputs(
    const std::vector<std::uint8_t>& mask, int width, int height, int depth, const char* who);
std::vector<std::uint8_t> label_mask(const SliceStack& stack, std::uint16_t label, const char* who);
void sort_surfaces(ReferenceTopology& topology);
}  // namespace detail

}  // namespace strata

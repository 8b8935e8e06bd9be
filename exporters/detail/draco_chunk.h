#pragma once

// Draco meshes of the progressive glTF (schema/README.md "Chunks", "The base mesh"), encoded and
// decoded with the format's settings: the writer's chunks and base meshes, the reader, and the
// size benchmark's single-rate re-encodings (tests/bench/progressive_size.cpp) all come through
// these functions, so the benchmark measures what the writer writes.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace strata::detail {

/// One Draco mesh to encode, in the storage frame. Vertices are distinct positions (welded); a
/// vertex used by triangles of two clusters is stored once, and Draco splits its point only for
/// `_CLUSTER`.
struct DracoChunkInput {
    std::vector<std::array<float, 3>> positions;          ///< one per vertex, on the grid of `step`
    std::vector<std::array<float, 3>> normals;            ///< unit, per vertex; empty: no NORMAL
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< vertex indices, file orientation
    std::vector<std::uint32_t> triangle_cluster;          ///< per triangle; empty: no `_CLUSTER`
    std::vector<std::uint8_t> slots;                      ///< per vertex; empty: no `_SLOT`
    double step = 0.0;                                    ///< grid step (storage units)
};

/// The encoded mesh and the Draco unique ids of its attributes (-1: absent). Attributes are
/// added in the order POSITION, `_CLUSTER`, `_SLOT`, NORMAL, so a chunk's ids are those of
/// format::kChunk*Id.
struct DracoChunkBytes {
    std::string bytes;
    int position_id = -1;
    int cluster_id = -1;
    int slot_id = -1;
    int normal_id = -1;
};

/// Edgebreaker at `compression_level` (0 fastest .. 10 smallest; speed 10 - level); POSITION
/// quantized losslessly on the grid (origin: the mesh's lowest grid point, moved down to a
/// multiple of 1/64 on finer grids; range: step * (2^bits - 1), bits the fewest that span it and
/// whose range survives Draco's six-decimal options text) and predicted by constrained
/// multi-parallelogram, which Draco itself picks only at its two slowest speeds (measured with
/// scripts/bench-size.sh on the torso: positions -12 % against parallelogram; every Draco decoder
/// build, the glTF-only one included, reads it); NORMAL octahedral with `normal_bits`, predicted
/// from the positions; `_CLUSTER` (uint8, uint16 above 256 clusters) with difference prediction
/// and `_SLOT` (uint8) without prediction (entropy coded as they are).
/// \throw Error{InvalidInput} when the mesh spans more than 2^24 grid steps (float positions
///        would lose the grid); Error{Unsupported} when the origin or range would not survive
///        Draco's options text; Error{Internal} when Draco fails.
DracoChunkBytes encode_draco_chunk(const DracoChunkInput& in,
                                   int compression_level,
                                   int normal_bits);

/// Which attributes to read from a decoded mesh (Draco unique ids, -1: not read).
struct DracoAttributeIds {
    int position = -1;
    int cluster = -1;
    int slot = -1;
    int normal = -1;
};

/// A decoded mesh, welded: points with one position are one vertex again.
struct DecodedChunk {
    std::size_t points = 0;                       ///< Draco points before welding
    std::vector<std::array<float, 3>> positions;  ///< per vertex, in order of first point
    std::vector<std::array<float, 3>> normals;    ///< per vertex (its first point's), if read
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< vertex indices
    std::vector<std::uint32_t> triangle_cluster;          ///< per triangle, if read
    std::vector<std::uint8_t> slots;                      ///< per vertex, if read
};

/// Most triangles a chunk may declare per byte of its data: far above what Draco reaches on
/// real surfaces (about 1 triangle per byte for strata's chunks, with positions), so a small
/// hostile stream cannot make the decoder allocate gigabytes.
inline constexpr std::size_t kMaxTrianglesPerByte = 16;

/// The triangle count a Draco Edgebreaker stream (bitstream 2.2, no metadata) declares, read
/// from its header without decoding. \throw Error{InvalidInput} for anything else.
std::size_t draco_declared_triangles(std::string_view bytes);

/// Decodes `bytes` (the declared triangle count first checked against `max_triangles` and
/// kMaxTrianglesPerByte), checks the attributes in `ids` (POSITION 3 components, `_CLUSTER` and
/// `_SLOT` 1, NORMAL 3), at most 3 points per triangle, every triangle's points of one `_CLUSTER`
/// value below `cluster_count`, one `_SLOT` per vertex, and welds the points by position.
/// \throw Error{InvalidInput} naming what is wrong (the caller adds where).
DecodedChunk decode_draco_chunk(std::string_view bytes,
                                const DracoAttributeIds& ids,
                                std::uint32_t cluster_count,
                                std::size_t max_triangles);

/// Lists of vertices, one per vertex, in one array: vertex v's are items[start[v]] to
/// items[start[v + 1]] (one allocation for a chunk's neighbours instead of one per vertex).
struct NeighbourLists {
    std::vector<std::uint32_t> start;  ///< per vertex, and one past the last
    std::vector<std::uint32_t> items;
    std::size_t size(std::uint32_t v) const { return start[v + 1] - start[v]; }
    std::uint32_t at(std::uint32_t v, std::size_t rank) const { return items[start[v] + rank]; }
};

/// The neighbours of every vertex, in the format's order (schema/README.md "Neighbour order"):
/// survivors first, then by squared edge length in binary64, then by position.
NeighbourLists ordered_neighbours(const std::vector<std::array<float, 3>>& positions,
                                  const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                  const std::vector<bool>& survivor);

/// The `_SLOT` of every vertex given where it collapses (`coarse[v]`, a vertex index; itself for
/// survivors). \throw Error{Internal} when a collapsed vertex has no neighbour one step closer
/// to its survivor within 255 ranks.
std::vector<std::uint8_t> encode_slots(const std::vector<std::array<float, 3>>& positions,
                                       const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                       const std::vector<std::uint32_t>& coarse);

/// The vertex every vertex collapses to, from the slots. \throw Error{InvalidInput} for a slot
/// beyond the vertex's neighbours or a chain of slots that never reaches a survivor.
std::vector<std::uint32_t> resolve_slots(const std::vector<std::array<float, 3>>& positions,
                                         const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                         const std::vector<std::uint8_t>& slots);

}  // namespace strata::detail

#pragma once

// One Draco refinement chunk of the progressive glTF, encoded with the format's settings: the
// writer's chunks and the size benchmark's re-encodings (tests/bench/progressive_size.cpp) come
// from this one function, so the benchmark measures what the writer writes.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace strata::detail {

/// The points and triangles of one chunk, in the storage frame (schema/README.md).
struct DracoChunkInput {
    std::vector<std::array<float, 3>> positions;  ///< on the grid of `step`
    std::vector<std::array<float, 3>> normals;    ///< unit, per position; empty: no NORMAL
    /// per position, on the grid; empty: no `_COARSE_POSITION` (a GENERIC attribute)
    std::vector<std::array<float, 3>> coarse;
    std::vector<std::array<std::uint32_t, 3>> triangles;  ///< indices, in the file's orientation
    double step = 0.0;                                    ///< grid step (storage units)
};

/// The encoded chunk and the Draco unique ids of its attributes (-1: absent).
struct DracoChunkBytes {
    std::string bytes;
    int position_id = -1;
    int normal_id = -1;
    int coarse_id = -1;
};

/// Edgebreaker at `compression_level` (0 fastest .. 10 smallest; speed 10 - level); POSITION and
/// `_COARSE_POSITION` quantized losslessly on the grid (origin: the chunk's lowest grid point,
/// moved down to a multiple of 1/64 on finer grids; range: step * (2^bits - 1), bits the fewest
/// that span it and whose range survives Draco's six-decimal options text) and predicted by
/// constrained multi-parallelogram, which Draco itself picks only at its two slowest speeds
/// (measured with scripts/bench-size.sh on the torso: positions -12 %, coarse positions -29 %
/// against parallelogram; every Draco decoder build, the glTF-only one included, reads it);
/// NORMAL octahedral with `normal_bits`, predicted from the positions.
/// \throw Error{InvalidInput} when the chunk spans more than 2^24 grid steps (float positions
///        would lose the grid); Error{Unsupported} when the origin or range would not survive
///        Draco's options text; Error{Internal} when Draco fails.
DracoChunkBytes encode_draco_chunk(const DracoChunkInput& in,
                                   int compression_level,
                                   int normal_bits);

}  // namespace strata::detail

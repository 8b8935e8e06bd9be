#pragma once

// The progressive glTF format (STRATA_progressive_mesh version 3, schema/README.md), defined once
// for C++: names, constants and the binary DAG table. The writer, the reader, the CLI, the size
// benchmark and the tests use these; the JavaScript side has its own single definition
// (web-viewer/).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace strata::format {

inline constexpr std::string_view kExtension = "STRATA_progressive_mesh";
inline constexpr std::string_view kDraco = "KHR_draco_mesh_compression";
inline constexpr int kVersion = 3;

// Scene structure: the root node (patient LPS mm -> glTF metres) and its one child, the storage
// frame (-> patient LPS mm) shared by every object node below it.
inline constexpr std::string_view kPatientNodeName = "patient";
inline constexpr std::string_view kStorageNodeName = "storage";

// Attribute names: glTF (base mesh) and the spec's names of the chunks' Draco attributes.
inline constexpr std::string_view kPosition = "POSITION";
inline constexpr std::string_view kNormal = "NORMAL";
inline constexpr std::string_view kCluster = "_CLUSTER";
inline constexpr std::string_view kSlot = "_SLOT";

// Draco unique ids of a chunk's attributes (the base mesh's ids are in its JSON; strata writes
// POSITION 0, _CLUSTER 1, NORMAL 2).
inline constexpr std::uint32_t kChunkPositionId = 0;
inline constexpr std::uint32_t kChunkClusterId = 1;
inline constexpr std::uint32_t kChunkSlotId = 2;

// glTF enums used by the format.
inline constexpr int kUnsignedByte = 5121;
inline constexpr int kUnsignedShort = 5123;
inline constexpr int kUnsignedInt = 5125;
inline constexpr int kFloat = 5126;
inline constexpr int kTriangles = 4;

// GLB container (glTF 2.0 section 4.4).
inline constexpr std::uint32_t kGlbMagic = 0x46546C67;      // "glTF"
inline constexpr std::uint32_t kGlbJsonChunk = 0x4E4F534A;  // "JSON"
inline constexpr std::uint32_t kGlbBinChunk = 0x004E4942;   // "BIN\0"

// The DAG table.
inline constexpr std::array<char, 4> kDagMagic{'S', 'D', 'A', 'G'};
inline constexpr std::size_t kDagHeaderBytes = 16;
inline constexpr std::size_t kGroupRecordBytes = 32;

/// Most clusters one chunk may hold (its `_CLUSTER` values), and most roots: the uint16 range.
inline constexpr std::size_t kMaxChunkClusters = 65536;

/// One group of the DAG table.
struct DagGroup {
    std::array<float, 4> sphere{};   ///< x, y, z, r: metres, scene frame
    std::uint32_t chunk_offset = 0;  ///< in the object's `chunks` buffer view
    std::uint32_t chunk_length = 0;
    std::uint16_t level = 0;  ///< level of the produced clusters, >= 1
    /// The bound against the finest level as a fraction of the group's error: fine_error().
    std::uint16_t fine = 0;
    std::vector<std::uint32_t> consumed;  ///< k-th: `_CLUSTER` value k in the chunk
    std::vector<std::uint32_t> produced;
};

/// The DAG table of one object.
struct DagTable {
    std::uint32_t clusters = 0;
    std::vector<DagGroup> groups;
};

/// The table's bytes (ids of 2 bytes when clusters <= 65535, else 4), padded to a multiple of 4.
/// \throw Error{InvalidInput} when a group lists more than 65535 clusters or an id >= clusters.
std::string encode_dag_table(const DagTable& table);

/// The length of the table at the start of `bytes` (header and group records read: magic, counts,
/// idBytes), padded to 4; the file's `dag` buffer view holds every object's table, each at the
/// byte offset its node names.
/// \throw Error{InvalidInput} "<where>: byte <offset>: <what>" when the header or the records do
///        not fit `bytes`, or the length would leave it.
std::size_t dag_table_length(std::string_view bytes, const std::string& where);

/// Parses and checks the table's layout (schema/README.md "The DAG table" and validation point
/// 2: magic, idBytes, exact length, counts, levels, reserved, finite spheres, ids in range).
/// `group_count` is the JSON's `errors.length`. Graph rules are checked separately.
/// \throw Error{InvalidInput} "<where>: byte <offset>: <what>, expected <...>".
DagTable parse_dag_table(std::string_view bytes, std::size_t group_count, const std::string& where);

/// The denominator of a group record's `fine` fraction.
inline constexpr double kFineDenominator = 65535.0;

/// A group's bound against the finest level: its (written) error times fine / 65535, evaluated
/// in this order in binary64 (as the JavaScript reader does, so both get the same number).
inline double fine_error(double error, std::uint16_t fine) {
    return error * double(fine) / kFineDenominator;
}

/// The smallest `fine` whose fine_error(error, fine) is at least `bound` (65535 when `bound` >=
/// `error`: the error itself bounds the distance to the finest level too).
std::uint16_t encode_fine(double bound, double error);

/// A bound rounded up to `digits` significant decimal digits, as a JSON reader parses it back
/// (monotone: x <= y gives round(x) <= round(y)). The format writes errors with 3.
double round_up_decimal(double x, int digits);

}  // namespace strata::format

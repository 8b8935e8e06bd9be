#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// One structure of a scene: a named, coloured surface.
struct SceneObject {
    std::string name;              ///< structure name (node, mesh and material name)
    std::uint16_t label = 0;       ///< label value in the source
    std::array<double, 3> srgb{};  ///< display colour, sRGB, each channel in [0, 1]
    TriMesh mesh;  ///< positions in patient LPS millimetres, outward triangles counter-clockwise
    /// shading_normals(mesh) when the caller has them already (one per vertex), else empty: the
    /// writers compute them (the same vectors either way).
    std::vector<Vec3> normals;
};

/// Where a scene comes from; copied into every object node's `extras`.
struct SceneInfo {
    std::string source;                  ///< input file or phantom name
    std::array<double, 3> spacing_mm{};  ///< voxel spacing (x, y, slice), millimetres
    std::string generator;               ///< glTF `asset.generator`, e.g. "strata 0.1.0"
};

/// How the scene's geometry is stored.
struct SceneGltfOptions {
    /// Compress every primitive with Draco (KHR_draco_mesh_compression, required by the file):
    /// Edgebreaker, positions and normals quantized; else plain float32 accessors.
    bool draco = false;
    int position_bits = 16;  ///< Draco quantization of positions (bits over the object's extent)
    int normal_bits = 12;    ///< Draco quantization of normals (octahedral bits)
    int draco_speed = 3;     ///< Draco encoder speed, 0 (smallest) .. 10 (fastest)
    /// Worker threads for the objects' Draco encodings (0: all cores); the file is the same for
    /// any count.
    unsigned threads = 1;
};

/// Writes `objects` as a plain (single-resolution) glTF 2.0 scene, binary `.glb` (one file) or
/// `.gltf` (JSON plus `<stem>.bin` beside it), chosen by the extension of `path`
/// (case-insensitive). Layout (docs/architecture.md section 5): one root node "patient" whose
/// `matrix` maps patient LPS millimetres to glTF metres (glTF X = left = +x, Y = superior = +z,
/// Z = anterior = -y, scale 0.001; a rotation, not a mirror), so vertex data stays in
/// millimetres; under it one node per object with one mesh (one TRIANGLES primitive: POSITION
/// as float32 with exact min/max, NORMAL as the unit shading normals of mesh/shading_normals.h,
/// indices UNSIGNED_SHORT when there are at most 65535 vertices, else UNSIGNED_INT) and one
/// material (sRGB colour linearised into `baseColorFactor`, metallic 0, roughness 0.6,
/// single-sided). Node `extras`: {"label", "source", "spacing_mm", "units": "mm"}; an empty name
/// becomes "label <value>". Objects without triangles are skipped; unreferenced vertices are kept
/// (a vertex whose normal is undefined, e.g. unreferenced or only in degenerate triangles, gets
/// +z). With `options.draco` the primitive is Draco-compressed instead (the accessors have no
/// buffer view and carry the decoded mesh's counts and bounds; Draco drops unreferenced
/// vertices and reorders the rest).
///
/// Atomic: everything is built in memory and written to temporary files that are renamed into
/// place, so on failure existing files are untouched and no partial file is left. Parent folders
/// are created. For `.gltf` the `.bin` is renamed first, then the `.gltf`.
/// \throw Error{Unsupported} for another extension or more than 2^32 - 1 vertices in an object;
///        Error{InvalidInput} if `objects` is empty or no object has a triangle, a triangle
///        index is out of range (the message names the object, triangle and index), a position
///        is not finite as float32, a colour channel is outside [0, 1] or the spacing is not
///        finite; Error{Io} if a file cannot be written; Error{Internal} if tinygltf fails.
void write_scene_gltf(const std::filesystem::path& path,
                      const std::vector<SceneObject>& objects,
                      const SceneInfo& info,
                      const SceneGltfOptions& options = {});

}  // namespace strata

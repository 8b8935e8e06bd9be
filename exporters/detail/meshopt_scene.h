#pragma once

// The single-rate scene (scene_gltf) with EXT_meshopt_compression: scene_gltf's option
// `meshopt` hands the whole file to this writer (issue 23).

#include <filesystem>
#include <vector>

#include "exporters/scene_gltf.h"

namespace strata::detail {

/// Writes `objects` as scene_gltf does (root "patient", one node, mesh and material per object,
/// the same names and extras), every primitive EXT_meshopt_compression-compressed with
/// KHR_mesh_quantization: positions as uint16 steps of one step per object (its box's longest
/// side / 65535; each coordinate to the nearest step, ties to even; the node matrix scales and
/// translates them back, so a position moves by at most half a step per axis, stated in the
/// node's extras as "quantization_step_mm"), the shading
/// normals of mesh/shading_normals.h as snorm8, indices as meshopt's index codec; unreferenced
/// vertices are dropped. `.glb` only; atomic. \throw Error{Unsupported} for another extension;
/// Error{InvalidInput} for empty scenes, bad indices, positions that are not finite or bad
/// colours; Error{Io} if the file cannot be written; Error{Internal} when meshopt fails.
void write_meshopt_scene(const std::filesystem::path& path,
                         const std::vector<SceneObject>& objects,
                         const SceneInfo& info);

}  // namespace strata::detail

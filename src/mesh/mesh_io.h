#pragma once

#include <filesystem>
#include <vector>

#include "mesh/tri_mesh.h"

namespace strata {

/// Writes a mesh as PLY, OBJ or STL, chosen by the extension of `path` (case-insensitive), and
/// atomically: an existing file is replaced only once the whole new file is written.
///
/// Precision: positions are stored as float32 in every format: binary little-endian PLY and
/// binary STL store the float32 bits (read back: exactly the float32 value), OBJ the shortest
/// decimal that rounds to the same float32 (at most 9 significant digits; read back: the
/// double nearest that decimal, which rounds to the same float32).
/// What is kept: PLY keeps vertex order, triangles and labels (face property `label`,
/// ushort); OBJ keeps vertex order and triangles; `normals` (empty, or one unit vector per
/// vertex, e.g. `shading_normals`) go to PLY as float vertex properties nx, ny, nz and to OBJ
/// as `vn` lines referenced by `f a//a b//b c//c`; STL keeps only the triangle corners (readers
/// weld equal corners again, so vertex order and unreferenced vertices are lost).
/// \throw Error{Unsupported} for another extension; Error{InvalidInput} if a triangle index is
///        out of range, labels are neither empty nor one per triangle, normals are neither empty
///        nor one per vertex or have a component outside [-1, 1], or a coordinate is not finite
///        as float32; Error{Io} if the file cannot be written (the old one is kept).
void write_mesh(const TriMesh& mesh,
                const std::filesystem::path& path,
                const std::vector<Vec3>& normals = {});

/// Reads a mesh written by `write_mesh` or by other tools, chosen by the extension of `path`:
/// - `.ply`: ASCII or binary little-endian; vertex x, y, z of any scalar type, faces as a list
///   property `vertex_indices` (or `vertex_index`), an optional integer face property `label`;
///   other elements and properties are skipped.
/// - `.obj`: `v` and `f` statements (`f 1 2 3`, `f 1/2 ...`, `f 1//3 ...`, `f 1/2/3 ...`,
///   negative relative indices); other known statements are ignored.
/// - `.stl`: binary or ASCII; corners with exactly equal coordinates become one vertex, in
///   order of first appearance.
/// Polygons with more than 3 corners (PLY, OBJ) are split into a fan around their first corner.
/// The result is not checked for topology (use `check_mesh`), but every index is in range and
/// every coordinate finite.
/// \throw Error{Unsupported} for another extension or an unsupported PLY format (big-endian);
///        Error{InvalidInput} for malformed, truncated or inconsistent files, saying where (line,
///        element or byte) and what was expected; Error{Io} if the file cannot be read.
TriMesh read_mesh(const std::filesystem::path& path);

}  // namespace strata

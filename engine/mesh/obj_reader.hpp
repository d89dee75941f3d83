// Reader for Wavefront .obj triangle surfaces: the static obstacle meshes of a scene.
//
// A deliberately small reader: "v x y z" and "f a b c ..." lines; polygons are triangulated as a
// fan around their first corner. Every other statement (vt, vn, o, g, s, usemtl, mtllib, l,
// comments) is ignored, since a static collision surface needs nothing else. What it does read it
// reads strictly: malformed or non-finite numbers, faces of fewer than 3 corners, bad or
// out-of-range indices (positive ones must name a vertex defined above, negative ones count back
// from the latest) and zero-area triangles throw MeshError naming the file and the line, e.g.
//   "meshes/bowl.obj: line 12: bad vertex reference "9" (8 vertices defined so far)".
// Memory stays proportional to the file: every vertex and triangle kept costs a line of text.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "engine/mesh/mesh_error.hpp"

namespace nexdyn {

struct ObjMesh {
  std::vector<double> positions;   // (num_vertices x 3) [m], every "v" line in file order
  std::vector<int32_t> triangles;  // (num_triangles x 3) 0-based vertex ids, winding of the file
};

// A triangle is degenerate when its area <= kDegenerateTriangleRelativeArea * (longest edge)^2:
// zero area up to round-off, for which no normal and no point-triangle distance is defined.
// Scale-free for the same reason as kDegenerateTetRelativeVolume in tet_mesh.hpp.
inline constexpr double kDegenerateTriangleRelativeArea = 1e-12;

bool is_degenerate_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c);

// Parses .obj text held in memory; source_name is used in error messages (a file name). Throws
// MeshError, also when the text has no face at all.
ObjMesh parse_obj(std::string_view text, std::string_view source_name);

// Reads the whole file, then parses it with parse_obj. MeshError also for an unreadable file.
ObjMesh read_obj(const std::filesystem::path& path);

}  // namespace nexdyn

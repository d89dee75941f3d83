// Triangle surfaces from files: the boundary of a body that is to be filled with tets (issue 21).
//
// A body may be given by its closed boundary surface instead of a tet mesh; the surface is read
// here, checked by checked_closed_surface (surface_check.hpp) and then tetrahedralised. Three
// formats cover what modelling tools, CAD exports and scanners write; the format is chosen by the
// file's extension (case-insensitive):
//  .obj  parse_obj (obj_reader.hpp): "v" and "f" lines, polygons fan-triangulated; the OBJ reader
//        itself refuses zero-area triangles, naming their line.
//  .stl  ASCII ("solid" ... "endsolid", several solids allowed, keywords in any case) or binary
//        (80-byte header, triangle count, 50 bytes per triangle). A binary file is recognised by
//        its size, exactly 84 + 50 n for the n in its header, since binary files whose header starts
//        with "solid" exist in the wild; otherwise a file that starts with "solid" and holds no NUL
//        byte is ASCII. STL stores every triangle's corners by value: corners with exactly equal
//        coordinates are welded into one vertex (-0 equals +0), vertices numbered in order of first
//        occurrence, so the result does not depend on anything but the file. Normals and the
//        attribute bytes are ignored (the winding gives the orientation).
//  .ply  "format ascii 1.0", "binary_little_endian 1.0" or "binary_big_endian 1.0"; any elements
//        and properties (the others are skipped), of which element "vertex" must have scalar x, y,
//        z and element "face" a list "vertex_indices" (or "vertex_index") of integers, 0-based
//        as PLY has them; polygons are fan-triangulated around their first corner.
// What is read is read strictly: a malformed, truncated or non-finite value, a bad index or a
// header that does not add up throws MeshError naming the file and the line (text) or the element
// (binary: "triangle 5 of 12", "face 3 of 6", counted from 1), e.g.
//   "parts/gear.ply: line 9: unknown property type \"floot\"".
// A file without a single triangle is an error. Nothing is allocated beyond what the file's size
// can justify, so a corrupt count fails cleanly (the fuzzers in tests/fuzz hold the readers to it).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

#include "engine/mesh/mesh_error.hpp"

namespace nexdyn {

struct TriangleSurface {
  std::vector<double> positions;   // (num_vertices x 3) [m]
  std::vector<int32_t> triangles;  // (num_triangles x 3), 0-based vertex ids, winding of the file

  int32_t num_vertices() const { return static_cast<int32_t>(positions.size() / 3); }
  int32_t num_triangles() const { return static_cast<int32_t>(triangles.size() / 3); }
};

// By extension, as above. Throws MeshError for an unreadable file, malformed contents, or an
// extension that is none of .obj, .stl and .ply (naming it and those).
TriangleSurface read_triangle_surface(const std::filesystem::path& path);

// The readers of file contents held in memory (the fuzzers feed them bytes); source_name names
// the file in messages.
TriangleSurface parse_stl(std::string_view bytes, std::string_view source_name);
TriangleSurface parse_ply(std::string_view bytes, std::string_view source_name);

// Limits shared by the readers: vertex ids are int32 and positions are indexed by 3 * id.
inline constexpr int64_t kMaxSurfaceVertices = int64_t{1} << 30;
inline constexpr int64_t kMaxSurfaceTriangles = (int64_t{1} << 31) / 3 - 1;

}  // namespace nexdyn

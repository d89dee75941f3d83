// read_triangle_surface: the file's extension picks the reader (see surface_reader.hpp); the
// readers themselves are obj_reader.cpp, stl_reader.cpp and ply_reader.cpp.
#include "engine/mesh/surface_reader.hpp"

#include <cctype>
#include <string>
#include <utility>

#include "engine/mesh/mesh_file.hpp"
#include "engine/mesh/obj_reader.hpp"
#include "engine/mesh/text_cursor.hpp"

namespace nexdyn {

TriangleSurface read_triangle_surface(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::string extension = path.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  // Decide before reading, so that a wrong extension is named even when the file is missing too.
  if (extension != ".obj" && extension != ".stl" && extension != ".ply") {
    const std::string shown =
        extension.empty() ? "no extension" : "extension \"" + excerpt(extension, HighBytes::replaced) + "\"";
    throw MeshError(name + ": unknown surface mesh format (" + shown + "; supported: .obj, .stl, .ply)");
  }
  const std::string bytes = read_mesh_file(path);
  if (extension == ".stl") return parse_stl(bytes, name);
  if (extension == ".ply") return parse_ply(bytes, name);
  ObjMesh obj = parse_obj(bytes, name);
  return {std::move(obj.positions), std::move(obj.triangles)};
}

}  // namespace nexdyn

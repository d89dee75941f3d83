// Gmsh 2.2 ASCII writer (see msh_writer.hpp).
#include "engine/mesh/msh_writer.hpp"

#include <cstdio>

namespace nexdyn {

std::string msh_document(const TetMesh& mesh) {
  std::string text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n";
  text.reserve(static_cast<size_t>(mesh.num_vertices()) * 64 + static_cast<size_t>(mesh.num_tets()) * 48);
  char line[160];
  auto append = [&](int n) { text.append(line, static_cast<size_t>(n)); };
  append(std::snprintf(line, sizeof line, "%d\n", mesh.num_vertices()));
  for (int32_t v = 0; v < mesh.num_vertices(); ++v)
    append(std::snprintf(line, sizeof line, "%d %.17g %.17g %.17g\n", v + 1, mesh.positions[3 * v],
                         mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]));
  text += "$EndNodes\n$Elements\n";
  append(std::snprintf(line, sizeof line, "%d\n", mesh.num_tets()));
  // "tag type(4 = linear tet) 2 tags (physical, elementary) nodes".
  for (int32_t t = 0; t < mesh.num_tets(); ++t)
    append(std::snprintf(line, sizeof line, "%d 4 2 1 1 %d %d %d %d\n", t + 1, mesh.tets[4 * t] + 1,
                         mesh.tets[4 * t + 1] + 1, mesh.tets[4 * t + 2] + 1, mesh.tets[4 * t + 3] + 1));
  text += "$EndElements\n";
  return text;
}

}  // namespace nexdyn

// Writing a TetMesh as a Gmsh .msh file (format 2.2, ASCII): the cache of tetrahedralised
// surfaces (DIR/meshes/NAME-CHECKSUM.msh) and the output of `nexdyn mesh`.
//
// 2.2 because every Gmsh, ParaView reader and our own msh_reader.hpp take it. Coordinates are
// written with 17 significant digits, so reading the file back gives the same doubles, and tets
// in the mesh's order with node tags id + 1: read_msh of the result is the same TetMesh.
#pragma once

#include "engine/mesh/tet_mesh.hpp"

#include <string>

namespace nexdyn {

std::string msh_document(const TetMesh& mesh);

}  // namespace nexdyn

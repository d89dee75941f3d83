// Reader for Gmsh .msh files (ASCII, format 2.2 and 4.1) into a TetMesh.
//
// Scenes name their meshes as .msh files, most of them from the IPC paper repository (MSH 4.1
// with IPC's nonstandard $Surface block). The reader keeps what a tet simulation needs and
// nothing else:
//  - only linear tets (element type 4); points, lines, triangles, quads and higher-order
//    elements are skipped, as are sections other than $MeshFormat/$Nodes/$Elements
//    ($PhysicalNames, $Entities, $Surface, $NodeData, ... are skipped to their $End line);
//  - node tags are arbitrary positive integers; nodes not used by any tet are dropped and the
//    rest renumbered 0..n-1 in increasing tag order (so a file with tags 1..N and no unused
//    nodes keeps its numbering: id = tag - 1);
//  - negatively oriented tets are flipped (last two vertices swapped), so the result satisfies
//    the TetMesh invariant.
// 4.1 node blocks may be parametric: the parametric coordinates after x y z are ignored.
// Every problem throws MeshError naming the file, the line and the node or element tag:
// binary files, MSH 1/3/4.0, truncated sections, non-finite coordinates, duplicate node tags,
// unknown node tags, tets with a repeated vertex, degenerate tets (kDegenerateTetRelativeVolume
// in tet_mesh.hpp), no tets at all, and counts the rest of the file cannot hold (a corrupt
// header never makes the reader allocate more than the file's size justifies).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>

#include "engine/mesh/mesh_error.hpp"
#include "engine/mesh/tet_mesh.hpp"

namespace nexdyn {

// What the reader repaired or left out, for `nexdyn check` style reports. Not an error.
struct MshReadStats {
  int64_t flipped_tets = 0;      // negatively oriented tets made positive
  int64_t skipped_elements = 0;  // elements that are not linear tets (points, lines, triangles...)
  int64_t unused_nodes = 0;      // nodes no tet uses, dropped
};

// Reads the whole file, then parses it with parse_msh. Throws MeshError (also for a missing or
// unreadable file). `stats`, when given, receives what was repaired or dropped.
TetMesh read_msh(const std::filesystem::path& path, MshReadStats* stats = nullptr);

// Parses .msh text held in memory; source_name is used in error messages (a file name).
TetMesh parse_msh(std::string_view text, std::string_view source_name,
                  MshReadStats* stats = nullptr);

}  // namespace nexdyn

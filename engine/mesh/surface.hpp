// Boundary surface of a tet mesh: the triangles, edges and vertices that contact works on.
//
// IPC only ever needs the boundary: point-triangle pairs (surface vertices x surface triangles)
// and edge-edge pairs (surface edges). A boundary face is a face used by exactly one tet; its
// winding is taken from that tet so that the right-hand normal points out of the body, which the
// divergence theorem then confirms (sum of centroid . normal * area / 3 = volume).
//
// Extraction is sort-based (bucket by smallest vertex id, then sort each small bucket), so the
// result is the same on every run and platform, and linear-ish in the tet count.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "engine/mesh/tet_mesh.hpp"

namespace nexdyn {

struct SurfaceMesh {
  // (num_triangles x 3) vertex ids, right-hand normal points out of the body; each triangle is
  // rotated so its smallest id comes first, and triangles are sorted by their ids.
  std::vector<int32_t> triangles;
  // (num_edges x 2) unique edges of the triangles, a < b, sorted lexicographically.
  std::vector<int32_t> edges;
  // sorted unique vertex ids used by the triangles.
  std::vector<int32_t> vertices;

  int32_t num_triangles() const { return static_cast<int32_t>(triangles.size() / 3); }
  int32_t num_edges() const { return static_cast<int32_t>(edges.size() / 2); }
};

// tets: (num_tets x 4) positively oriented, ids in [0, num_vertices), tets.size() <= INT32_MAX
// (as for TetMesh: 4 * num_tets fits in int32). Works on one body or on the
// engine's global tet buffer (the surface of several bodies is the union of their surfaces).
// Faces shared by more than two tets (non-manifold input) are not boundary faces and are dropped.
SurfaceMesh extract_surface(std::span<const int32_t> tets, int32_t num_vertices);
SurfaceMesh extract_surface(const TetMesh& mesh);

}  // namespace nexdyn

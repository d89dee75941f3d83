// TetMesh: a tetrahedral solid as two flat arrays, plus the orientation and volume helpers that
// every producer of tets (the .msh reader, the box mesher, scene transforms) shares.
//
// Why flat: the positions array is the DOF vector that Eigen and CHOLMOD see, and bodies are
// concatenated into the engine's global buffers by copying ranges (DESIGN §3). Why orientation
// matters: the elastic kernels compute Dm = [x1-x0, x2-x0, x3-x0] and expect det(Dm) > 0 at rest,
// and the surface extractor derives outward winding from it. So "positively oriented" is an
// invariant of every TetMesh that leaves engine/mesh.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <vector>

namespace nexdyn {

struct TetMesh {
  std::vector<double> positions;  // (num_vertices x 3) packed xyz, rest positions, metres
  std::vector<int32_t> tets;      // (num_tets x 4) vertex ids, det[x1-x0, x2-x0, x3-x0] > 0

  int32_t num_vertices() const { return static_cast<int32_t>(positions.size() / 3); }
  int32_t num_tets() const { return static_cast<int32_t>(tets.size() / 4); }
};

// A tet is degenerate when |volume| <= kDegenerateTetRelativeVolume * (longest edge)^3.
// The measure is per element and scale-free: a regular tet has volume / edge^3 = 0.118, so the
// threshold only catches tets that are flat up to round-off (coplanar or coincident vertices),
// whose Dm would be singular or have a condition number beyond ~1e12. A threshold relative to the
// whole mesh (bbox diagonal^3) would instead flag legitimately small tets of a locally refined mesh
// and miss flat tets in a mesh of large coordinates.
inline constexpr double kDegenerateTetRelativeVolume = 1e-12;

// (1/6) det[x1-x0, x2-x0, x3-x0]: positive when x3 lies on the side of triangle (x0,x1,x2) that
// its right-hand normal points to.
double signed_tet_volume(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1,
                         const Eigen::Vector3d& x2, const Eigen::Vector3d& x3);

// Signed volume of tet `tet` of `mesh`.
double signed_tet_volume(const TetMesh& mesh, int32_t tet);

// Sum of signed tet volumes, summed in tet order (deterministic).
double mesh_volume(const TetMesh& mesh);

// |volume| / (longest edge)^3 of tet `tet`; 0 when all four vertices coincide.
double tet_relative_volume(const TetMesh& mesh, int32_t tet);

// Swaps the last two vertex ids of every tet with negative volume, which flips its orientation
// and leaves the vertex set alone. Degenerate tets (volume exactly 0) are left untouched; find
// them with find_degenerate_tet. Returns the number of tets flipped.
// The span overload works on global buffers: positions (num_vertices x 3), tets (num_tets x 4).
int32_t orient_tets_positively(std::span<const double> positions, std::span<int32_t> tets);
int32_t orient_tets_positively(TetMesh& mesh);

// Index of the first tet whose tet_relative_volume is <= relative_volume, or -1 when none is.
int32_t find_degenerate_tet(const TetMesh& mesh,
                            double relative_volume = kDegenerateTetRelativeVolume);

}  // namespace nexdyn

// Orientation and volume helpers of TetMesh (see tet_mesh.hpp for the invariants they keep).
#include "engine/mesh/tet_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <utility>

namespace nexdyn {
namespace {

Eigen::Vector3d vertex_position(std::span<const double> positions, int32_t v) {
  const std::size_t i = 3 * static_cast<std::size_t>(v);
  return {positions[i], positions[i + 1], positions[i + 2]};
}

double signed_volume_of(std::span<const double> positions, const int32_t* tet) {
  return signed_tet_volume(vertex_position(positions, tet[0]), vertex_position(positions, tet[1]),
                           vertex_position(positions, tet[2]), vertex_position(positions, tet[3]));
}

}  // namespace

double signed_tet_volume(const Eigen::Vector3d& x0, const Eigen::Vector3d& x1,
                         const Eigen::Vector3d& x2, const Eigen::Vector3d& x3) {
  // Differences first: the determinant of the edge vectors keeps the precision of the edge
  // lengths, not of the (possibly large) absolute coordinates.
  const Eigen::Vector3d a = x1 - x0;
  const Eigen::Vector3d b = x2 - x0;
  const Eigen::Vector3d c = x3 - x0;
  return a.dot(b.cross(c)) / 6.0;
}

double signed_tet_volume(const TetMesh& mesh, int32_t tet) {
  return signed_volume_of(mesh.positions, &mesh.tets[4 * static_cast<std::size_t>(tet)]);
}

double mesh_volume(const TetMesh& mesh) {
  double volume = 0.0;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) volume += signed_tet_volume(mesh, t);
  return volume;
}

double tet_relative_volume(const TetMesh& mesh, int32_t tet) {
  const int32_t* ids = &mesh.tets[4 * static_cast<std::size_t>(tet)];
  Eigen::Vector3d x[4];
  for (int k = 0; k < 4; ++k) x[k] = vertex_position(mesh.positions, ids[k]);
  double longest_squared = 0.0;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      longest_squared = std::max(longest_squared, (x[i] - x[j]).squaredNorm());
  if (longest_squared == 0.0) return 0.0;
  const double longest = std::sqrt(longest_squared);
  return std::abs(signed_tet_volume(x[0], x[1], x[2], x[3])) / (longest * longest * longest);
}

int32_t orient_tets_positively(std::span<const double> positions, std::span<int32_t> tets) {
  int32_t flipped = 0;
  for (std::size_t t = 0; 4 * t < tets.size(); ++t) {
    int32_t* ids = &tets[4 * t];
    if (signed_volume_of(positions, ids) < 0.0) {
      std::swap(ids[2], ids[3]);
      ++flipped;
    }
  }
  return flipped;
}

int32_t orient_tets_positively(TetMesh& mesh) {
  return orient_tets_positively(mesh.positions, mesh.tets);
}

int32_t find_degenerate_tet(const TetMesh& mesh, double relative_volume) {
  for (int32_t t = 0; t < mesh.num_tets(); ++t)
    if (tet_relative_volume(mesh, t) <= relative_volume) return t;
  return -1;
}

}  // namespace nexdyn

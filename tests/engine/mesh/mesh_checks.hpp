// Geometric and topological checks shared by the mesh tests: orientation, closedness,
// consistent winding, Euler characteristic per component, and the divergence-theorem volume.
// They recompute everything from the raw arrays so that a bug in extract_surface cannot hide
// behind the same bug in the check.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

#include "engine/mesh/surface.hpp"
#include "engine/mesh/tet_mesh.hpp"

namespace nexdyn::test {

inline Eigen::Vector3d vertex_at(const TetMesh& mesh, int32_t v) {
  return {mesh.positions[3 * v], mesh.positions[3 * v + 1], mesh.positions[3 * v + 2]};
}

inline int64_t count_non_positive_tets(const TetMesh& mesh) {
  int64_t count = 0;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) count += signed_tet_volume(mesh, t) <= 0.0;
  return count;
}

// Closed and consistently wound: every directed edge p->q of the triangles appears exactly once
// and its reverse q->p exactly once too (so every undirected edge has exactly two triangles,
// which traverse it in opposite directions).
inline bool is_closed_and_consistently_wound(const SurfaceMesh& surface) {
  std::vector<std::pair<int32_t, int32_t>> directed;
  for (std::size_t i = 0; i < surface.triangles.size(); i += 3)
    for (int k = 0; k < 3; ++k)
      directed.emplace_back(surface.triangles[i + k], surface.triangles[i + (k + 1) % 3]);
  std::sort(directed.begin(), directed.end());
  if (std::adjacent_find(directed.begin(), directed.end()) != directed.end()) return false;
  for (const auto& [p, q] : directed)
    if (!std::binary_search(directed.begin(), directed.end(), std::make_pair(q, p))) return false;
  return true;
}

// Number of connected components of the surface (vertices linked by triangle edges).
inline int count_components(const SurfaceMesh& surface, int32_t num_vertices) {
  std::vector<int32_t> parent(num_vertices);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int32_t v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (std::size_t i = 0; i < surface.triangles.size(); i += 3)
    for (int k = 1; k < 3; ++k) parent[find(surface.triangles[i + k])] = find(surface.triangles[i]);
  int components = 0;
  for (const int32_t v : surface.vertices) components += find(v) == v;
  return components;
}

inline int64_t euler_characteristic(const SurfaceMesh& surface) {
  return static_cast<int64_t>(surface.vertices.size()) - surface.num_edges() +
         surface.num_triangles();
}

// Divergence theorem with F(x) = x / 3 (div F = 1): volume = sum over triangles of
// (centroid . area-weighted normal) / 3, exact for flat triangles. Coordinates are taken relative
// to the first vertex so large offsets do not cancel catastrophically.
inline double divergence_volume(const TetMesh& mesh, const SurfaceMesh& surface) {
  const Eigen::Vector3d origin =
      vertex_at(mesh, surface.vertices.empty() ? 0 : surface.vertices[0]);
  double volume = 0.0;
  for (std::size_t i = 0; i < surface.triangles.size(); i += 3) {
    const Eigen::Vector3d a = vertex_at(mesh, surface.triangles[i]) - origin;
    const Eigen::Vector3d b = vertex_at(mesh, surface.triangles[i + 1]) - origin;
    const Eigen::Vector3d c = vertex_at(mesh, surface.triangles[i + 2]) - origin;
    const Eigen::Vector3d area_normal = 0.5 * (b - a).cross(c - a);
    volume += ((a + b + c) / 3.0).dot(area_normal) / 3.0;
  }
  return volume;
}

// Edges of the triangles, recomputed independently: (a < b), sorted, unique.
inline std::vector<int32_t> edges_of(const SurfaceMesh& surface) {
  std::vector<std::pair<int32_t, int32_t>> pairs;
  for (std::size_t i = 0; i < surface.triangles.size(); i += 3)
    for (int k = 0; k < 3; ++k) {
      const int32_t p = surface.triangles[i + k], q = surface.triangles[i + (k + 1) % 3];
      pairs.emplace_back(std::min(p, q), std::max(p, q));
    }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<int32_t> flat;
  for (const auto& [p, q] : pairs) flat.insert(flat.end(), {p, q});
  return flat;
}

}  // namespace nexdyn::test

// Closed triangle surfaces made in code, of any size, for the surface-check tests and benchmark
// (tests/engine/mesh/test_surface_input.cpp, bench/bench_surface_check.cpp).
//
// Two kinds that stress different parts of checked_closed_surface: a subdivided icosahedron (a
// smooth sphere, every neighbouring triangle clearly bent against the next), and a box whose faces
// are fine grids, optionally rotated. On the rotated box every pair of triangles around a vertex of
// a face lies in one plane up to the rounding of the rotation, so their orientation signs are
// decided by the exact fallback of the predicates: the slow path, as often as a mesh can ask for it.
#pragma once

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "engine/mesh/surface_reader.hpp"

namespace nexdyn::test {

// The unit sphere as an icosahedron subdivided `levels` times: 20 * 4^levels triangles, wound
// outward.
inline TriangleSurface icosphere(int levels) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  TriangleSurface s;
  for (const auto& p : std::vector<Eigen::Vector3d>{{-1, t, 0},
                                                    {1, t, 0},
                                                    {-1, -t, 0},
                                                    {1, -t, 0},
                                                    {0, -1, t},
                                                    {0, 1, t},
                                                    {0, -1, -t},
                                                    {0, 1, -t},
                                                    {t, 0, -1},
                                                    {t, 0, 1},
                                                    {-t, 0, -1},
                                                    {-t, 0, 1}}) {
    const Eigen::Vector3d q = p.normalized();
    s.positions.insert(s.positions.end(), {q.x(), q.y(), q.z()});
  }
  s.triangles = {0, 11, 5,  0, 5,  1, 0, 1, 7, 0, 7,  10, 0, 10, 11, 1, 5, 9, 5, 11,
                 4, 11, 10, 2, 10, 7, 6, 7, 1, 8, 3,  9,  4, 3,  4,  2, 3, 2, 6, 3,
                 6, 8,  3,  8, 9,  4, 9, 5, 2, 4, 11, 6,  2, 10, 8,  6, 7, 9, 8, 1};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int32_t, int32_t>, int32_t> midpoint;
    auto middle = [&](int32_t a, int32_t b) {
      const auto key = std::minmax(a, b);
      const auto found = midpoint.find(key);
      if (found != midpoint.end()) return found->second;
      const Eigen::Vector3d m =
          (Eigen::Vector3d::Map(&s.positions[3 * a]) + Eigen::Vector3d::Map(&s.positions[3 * b]))
              .normalized();
      s.positions.insert(s.positions.end(), {m.x(), m.y(), m.z()});
      return midpoint[key] = s.num_vertices() - 1;
    };
    std::vector<int32_t> finer;
    for (std::size_t k = 0; k < s.triangles.size(); k += 3) {
      const int32_t a = s.triangles[k], b = s.triangles[k + 1], c = s.triangles[k + 2];
      const int32_t ab = middle(a, b), bc = middle(b, c), ca = middle(c, a);
      finer.insert(finer.end(), {a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca});
    }
    s.triangles = std::move(finer);
  }
  return s;
}

// The box [-0.5, 0.5]^3 with each face an n x n grid of squares, two triangles each (12 n^2
// triangles, 6 n^2 + 2 vertices), wound outward, then turned by `rotation`.
inline TriangleSurface grid_box(int n, const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity()) {
  TriangleSurface s;
  std::map<std::array<int, 3>, int32_t> id_of;  // lattice point -> vertex id
  auto vertex = [&](std::array<int, 3> lattice) {
    const auto [it, inserted] = id_of.emplace(lattice, s.num_vertices());
    if (inserted) {
      const Eigen::Vector3d p = rotation * (Eigen::Vector3d(lattice[0], lattice[1], lattice[2]) / n -
                                            Eigen::Vector3d::Constant(0.5));
      s.positions.insert(s.positions.end(), {p.x(), p.y(), p.z()});
    }
    return it->second;
  };
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side)
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          // Corners in the order (i, j) (i+1, j) (i+1, j+1) (i, j+1) of the axes after `axis`:
          // normal +axis, so reversed on the low side.
          int32_t quad[4];
          const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
          for (int c = 0; c < 4; ++c) {
            std::array<int, 3> lattice;
            lattice[axis] = side * n;
            lattice[(axis + 1) % 3] = i + di[c];
            lattice[(axis + 2) % 3] = j + dj[c];
            quad[side ? c : 3 - c] = vertex(lattice);
          }
          s.triangles.insert(s.triangles.end(), {quad[0], quad[1], quad[2], quad[0], quad[2], quad[3]});
        }
  return s;
}

}  // namespace nexdyn::test

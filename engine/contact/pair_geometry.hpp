// Small helpers the contact files share to read a candidate pair's geometry out of the flat
// position array (num_vertices x 3) and the Model: a vertex's position, a pair's vertex ids, the
// mollifier threshold of an edge pair, a vertex's squared distance to an obstacle plane. For the
// .cpp files of engine/contact only.
#pragma once

#include "engine/contact/candidates.hpp"
#include "engine/model.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace nexdyn::pair_geometry {

// Candidate pairs per chunk of the parallel loops over one candidate list: fixed, so that chunked
// results (sums, minima) do not depend on the number of threads.
inline constexpr int64_t kPairGrain = 256;

inline Eigen::Vector3d point(const double* x, int32_t v) { return Eigen::Vector3d::Map(x + 3 * int64_t{v}); }

// eps_x of the mollifier of edges ea and eb (2 vertex ids each), from the rest shape.
inline double edge_edge_threshold(const Model& m, const int32_t* ea, const int32_t* eb) {
  const double* r = m.rest_positions.data();
  return edge_edge_mollifier_threshold(point(r, ea[0]), point(r, ea[1]), point(r, eb[0]), point(r, eb[1]));
}

// Squared signed distance of a vertex-plane pair's vertex to its plane; 0 on or behind the plane
// (counted as touching).
inline double vertex_plane_squared_distance(const Model& m, const double* x, const IndexPair& pair) {
  const ObstaclePlane& plane = m.obstacle_planes[pair.second];
  const double s = (point(x, pair.first) - plane.point).dot(plane.normal);
  return s > 0.0 ? s * s : 0.0;
}

// The squared gap between the bounding boxes of a pair's two primitives, vertices s[0, na) and
// s[na, 4) at x0 (and at x1 too when it is given: then the boxes hold the linear paths from x0
// to x1); 0 where the boxes overlap. No point of one primitive comes closer to the other than
// this, so a pair whose gap is beyond a distance of interest needs no distance kernel: the
// energy, active-set and CCD passes skip such pairs with a margin (kFarMargin) far above the
// kernels' rounding, so they decide as the kernels would. It costs a few comparisons where a
// distance costs branches, cross products and square roots, and most candidates of a landing
// pile are such pairs (they were found for a whole Newton step, or padded for its turns).
inline double box_gap_squared(const double* x0, const double* x1, const PairVertices& s, int na) {
  double gap2 = 0.0;
  for (int d = 0; d < 3; ++d) {
    double lo[2] = {x0[3 * int64_t{s[0]} + d], x0[3 * int64_t{s[na]} + d]};
    double hi[2] = {lo[0], lo[1]};
    for (int k = 0; k < 4; ++k) {
      const int side = k < na ? 0 : 1;
      for (const double* x : {x0, x1}) {
        if (!x) continue;
        const double c = x[3 * int64_t{s[k]} + d];
        lo[side] = std::min(lo[side], c);
        hi[side] = std::max(hi[side], c);
      }
    }
    const double gap = std::max({0.0, lo[1] - hi[0], lo[0] - hi[1]});
    gap2 += gap * gap;
  }
  return gap2;
}

// Relative margin of the skips above: a pair is skipped only when its box gap passes the
// distance of interest by this factor, far beyond the distance kernels' relative rounding.
inline constexpr double kFarMargin = 1.0 + 1e-6;

// How much closer the pair's primitives (vertices s[0, na) and s[na, 4)) can come as they move
// from x0 to x1 on straight lines: the largest motion of a vertex of one plus that of the other.
inline double closing_reach(const PairVertices& s, int na, const double* x0, const double* x1) {
  double side[2] = {0.0, 0.0};
  for (int k = 0; k < 4; ++k) {
    const double* a = x0 + 3 * int64_t{s[k]};
    const double* b = x1 + 3 * int64_t{s[k]};
    const double dx = b[0] - a[0], dy = b[1] - a[1], dz = b[2] - a[2];
    side[k >= na] = std::max(side[k >= na], dx * dx + dy * dy + dz * dz);
  }
  return std::sqrt(side[0]) + std::sqrt(side[1]);
}

// The PairVertices (candidates.hpp) of candidate i of the concatenated lists (vertex-triangle,
// then edge-edge, then vertex-plane).
inline PairVertices candidate_vertices(const Model& m, const ContactCandidates& c, int64_t i) {
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  if (i < nvt) return vertex_triangle_vertices(m, c.vertex_triangle[i]);
  if (i < nvt + nee) return edge_edge_vertices(m, c.edge_edge[i - nvt]);
  return vertex_plane_vertices(c.vertex_plane[i - nvt - nee]);
}

}  // namespace nexdyn::pair_geometry

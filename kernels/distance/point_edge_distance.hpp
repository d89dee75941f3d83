// Squared distance from a point to a segment (edge) with its closest-feature case, and the
// gradient / Hessian of the piece that is active (IPC, Li et al. 2020, sec. 4 and supplemental:
// a distance to a simplex is the distance to its closest sub-simplex, each smooth on its own).
// Used directly for 2D-like stencils and as the building block of the point-triangle and
// edge-edge classifications. DOFs [p, e0, e1]; a zero-length edge is the vertex e0.
#pragma once

#include "kernels/distance/distance_primitives.hpp"

#include <cstdint>

namespace nexdyn {

enum class PointEdgeCase : uint8_t { p_e0, p_e1, p_e };

// Closest feature of the segment [e0, e1] to p, from the parameter of the foot of the
// perpendicular, s = (p - e0) . e / |e|^2, compared without dividing (no NaN for e0 == e1).
// Within detail::kFeatureTie of an end, the end is the closest feature.
inline PointEdgeCase point_edge_case(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                     const Eigen::Vector3d& e1) {
  const Eigen::Vector3d e = e1 - e0;
  const double l2 = e.squaredNorm();
  if (!(l2 > 0.0)) return PointEdgeCase::p_e0;
  const double s_l2 = (p - e0).dot(e);
  if (s_l2 <= detail::kFeatureTie * l2) return PointEdgeCase::p_e0;
  if (s_l2 >= (1.0 - detail::kFeatureTie) * l2) return PointEdgeCase::p_e1;
  return PointEdgeCase::p_e;
}

inline double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                  const Eigen::Vector3d& e1, PointEdgeCase c) {
  switch (c) {
    case PointEdgeCase::p_e0: return point_point_distance(p, e0);
    case PointEdgeCase::p_e1: return point_point_distance(p, e1);
    case PointEdgeCase::p_e: return point_line_distance(p, e0, e1);
  }
  return 0.0;
}

inline double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                  const Eigen::Vector3d& e1) {
  return point_edge_distance(p, e0, e1, point_edge_case(p, e0, e1));
}

inline Vector9d point_edge_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                             const Eigen::Vector3d& e1, PointEdgeCase c) {
  switch (c) {
    case PointEdgeCase::p_e0:
      return detail::scatter_gradient<2, 3>(point_point_distance_gradient(p, e0), {0, 1});
    case PointEdgeCase::p_e1:
      return detail::scatter_gradient<2, 3>(point_point_distance_gradient(p, e1), {0, 2});
    case PointEdgeCase::p_e: return point_line_distance_gradient(p, e0, e1);
  }
  return Vector9d::Zero();
}

inline Vector9d point_edge_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                             const Eigen::Vector3d& e1) {
  return point_edge_distance_gradient(p, e0, e1, point_edge_case(p, e0, e1));
}

inline Matrix9d point_edge_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                            const Eigen::Vector3d& e1, PointEdgeCase c) {
  switch (c) {
    case PointEdgeCase::p_e0:
      return detail::scatter_hessian<2, 3>(point_point_distance_hessian(p, e0), {0, 1});
    case PointEdgeCase::p_e1:
      return detail::scatter_hessian<2, 3>(point_point_distance_hessian(p, e1), {0, 2});
    case PointEdgeCase::p_e: return point_line_distance_hessian(p, e0, e1);
  }
  return Matrix9d::Zero();
}

inline Matrix9d point_edge_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                            const Eigen::Vector3d& e1) {
  return point_edge_distance_hessian(p, e0, e1, point_edge_case(p, e0, e1));
}

}  // namespace nexdyn

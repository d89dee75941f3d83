// Squared distance from a point to a triangle by closest-feature classification (IPC, Li et al.
// 2020, sec. 4: the point-triangle distance is the distance to the closest of the triangle's
// vertices, edges or its plane, each a smooth function). DOFs [p, t0, t1, t2]; the edges are
// e0 = (t0, t1), e1 = (t1, t2), e2 = (t2, t0).
//
// Classification: |p - (t0 + u e_1 + v e_2)|^2 is a convex quadratic in (u, v). If its
// unconstrained minimiser (the projection onto the plane) lies inside the triangle (more than
// detail::kFeatureTie from its boundary in barycentric terms), the plane is the closest feature.
// Otherwise the constrained minimum lies on the triangle's boundary, so it is the smallest of the
// three point-segment distances, each classified by point_edge_case. This needs no Voronoi-region
// table and handles degenerate (collinear) triangles by skipping the plane.
#pragma once

#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/point_edge_distance.hpp"

#include <cstdint>

namespace nexdyn {

enum class PointTriangleCase : uint8_t { p_t0, p_t1, p_t2, p_e0, p_e1, p_e2, p_t };

namespace detail {
// A triangle with |n|^2 <= kTriangleDegenerate |e_1|^2 |e_2|^2 (sin^2 of its angle at t0) is
// treated as a segment: the plane is ill defined and its distance is within ~1e-20 L^2 of the
// edges' anyway.
inline constexpr double kTriangleDegenerate = 1e-20;
}  // namespace detail

inline PointTriangleCase point_triangle_case(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                             const Eigen::Vector3d& t1,
                                             const Eigen::Vector3d& t2) {
  const Eigen::Vector3d e1 = t1 - t0;
  const Eigen::Vector3d e2 = t2 - t0;
  const double a = e1.squaredNorm();
  const double c = e2.squaredNorm();
  const double det = e1.cross(e2).squaredNorm();  // = a c - b^2, without cancellation
  if (det > detail::kTriangleDegenerate * a * c) {
    const Eigen::Vector2d uv = detail::in_plane_coordinates(p - t0, e1, e2);
    const double u = uv(0), v = uv(1);
    constexpr double tie = detail::kFeatureTie;
    if (u > tie && v > tie && u + v < 1.0 - tie) return PointTriangleCase::p_t;
  }
  // Boundary: the closest of the three edges; ties keep the first (the distances are equal).
  const PointEdgeCase c0 = point_edge_case(p, t0, t1);
  const PointEdgeCase c1 = point_edge_case(p, t1, t2);
  const PointEdgeCase c2 = point_edge_case(p, t2, t0);
  const double d0 = point_edge_distance(p, t0, t1, c0);
  const double d1 = point_edge_distance(p, t1, t2, c1);
  const double d2 = point_edge_distance(p, t2, t0, c2);
  int edge = 0;
  PointEdgeCase ec = c0;
  double dmin = d0;
  if (d1 < dmin) { edge = 1; ec = c1; dmin = d1; }
  if (d2 < dmin) { edge = 2; ec = c2; }
  // Edge k runs from corner k to corner (k + 1) % 3.
  constexpr PointTriangleCase kInterior[3] = {PointTriangleCase::p_e0, PointTriangleCase::p_e1,
                                              PointTriangleCase::p_e2};
  constexpr PointTriangleCase kCorner[3] = {PointTriangleCase::p_t0, PointTriangleCase::p_t1,
                                            PointTriangleCase::p_t2};
  switch (ec) {
    case PointEdgeCase::p_e: return kInterior[edge];
    case PointEdgeCase::p_e0: return kCorner[edge];
    case PointEdgeCase::p_e1: return kCorner[(edge + 1) % 3];
  }
  return PointTriangleCase::p_t;
}

inline double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                      const Eigen::Vector3d& t1, const Eigen::Vector3d& t2,
                                      PointTriangleCase c) {
  switch (c) {
    case PointTriangleCase::p_t0: return point_point_distance(p, t0);
    case PointTriangleCase::p_t1: return point_point_distance(p, t1);
    case PointTriangleCase::p_t2: return point_point_distance(p, t2);
    case PointTriangleCase::p_e0: return point_line_distance(p, t0, t1);
    case PointTriangleCase::p_e1: return point_line_distance(p, t1, t2);
    case PointTriangleCase::p_e2: return point_line_distance(p, t2, t0);
    case PointTriangleCase::p_t: return point_plane_distance(p, t0, t1, t2);
  }
  return 0.0;
}

inline double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                      const Eigen::Vector3d& t1, const Eigen::Vector3d& t2) {
  return point_triangle_distance(p, t0, t1, t2, point_triangle_case(p, t0, t1, t2));
}

inline Vector12d point_triangle_distance_gradient(const Eigen::Vector3d& p,
                                                  const Eigen::Vector3d& t0,
                                                  const Eigen::Vector3d& t1,
                                                  const Eigen::Vector3d& t2, PointTriangleCase c) {
  using detail::scatter_gradient;
  switch (c) {
    case PointTriangleCase::p_t0:
      return scatter_gradient<2, 4>(point_point_distance_gradient(p, t0), {0, 1});
    case PointTriangleCase::p_t1:
      return scatter_gradient<2, 4>(point_point_distance_gradient(p, t1), {0, 2});
    case PointTriangleCase::p_t2:
      return scatter_gradient<2, 4>(point_point_distance_gradient(p, t2), {0, 3});
    case PointTriangleCase::p_e0:
      return scatter_gradient<3, 4>(point_line_distance_gradient(p, t0, t1), {0, 1, 2});
    case PointTriangleCase::p_e1:
      return scatter_gradient<3, 4>(point_line_distance_gradient(p, t1, t2), {0, 2, 3});
    case PointTriangleCase::p_e2:
      return scatter_gradient<3, 4>(point_line_distance_gradient(p, t2, t0), {0, 3, 1});
    case PointTriangleCase::p_t: return point_plane_distance_gradient(p, t0, t1, t2);
  }
  return Vector12d::Zero();
}

inline Vector12d point_triangle_distance_gradient(const Eigen::Vector3d& p,
                                                  const Eigen::Vector3d& t0,
                                                  const Eigen::Vector3d& t1,
                                                  const Eigen::Vector3d& t2) {
  return point_triangle_distance_gradient(p, t0, t1, t2, point_triangle_case(p, t0, t1, t2));
}

inline Matrix12d point_triangle_distance_hessian(const Eigen::Vector3d& p,
                                                 const Eigen::Vector3d& t0,
                                                 const Eigen::Vector3d& t1,
                                                 const Eigen::Vector3d& t2, PointTriangleCase c) {
  using detail::scatter_hessian;
  switch (c) {
    case PointTriangleCase::p_t0:
      return scatter_hessian<2, 4>(point_point_distance_hessian(p, t0), {0, 1});
    case PointTriangleCase::p_t1:
      return scatter_hessian<2, 4>(point_point_distance_hessian(p, t1), {0, 2});
    case PointTriangleCase::p_t2:
      return scatter_hessian<2, 4>(point_point_distance_hessian(p, t2), {0, 3});
    case PointTriangleCase::p_e0:
      return scatter_hessian<3, 4>(point_line_distance_hessian(p, t0, t1), {0, 1, 2});
    case PointTriangleCase::p_e1:
      return scatter_hessian<3, 4>(point_line_distance_hessian(p, t1, t2), {0, 2, 3});
    case PointTriangleCase::p_e2:
      return scatter_hessian<3, 4>(point_line_distance_hessian(p, t2, t0), {0, 3, 1});
    case PointTriangleCase::p_t: return point_plane_distance_hessian(p, t0, t1, t2);
  }
  return Matrix12d::Zero();
}

inline Matrix12d point_triangle_distance_hessian(const Eigen::Vector3d& p,
                                                 const Eigen::Vector3d& t0,
                                                 const Eigen::Vector3d& t1,
                                                 const Eigen::Vector3d& t2) {
  return point_triangle_distance_hessian(p, t0, t1, t2, point_triangle_case(p, t0, t1, t2));
}

}  // namespace nexdyn

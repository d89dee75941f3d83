// Squared distance between two segments (edges) by closest-feature classification (IPC, Li et al.
// 2020, sec. 4 and supplemental). DOFs [ea0, ea1, eb0, eb1].
//
// Classification: |ea0 + s ea - eb0 - t eb|^2 is a convex quadratic in (s, t). If the edges are
// not parallel and its unconstrained minimiser lies inside (0, 1)^2, the closest features are the
// two edge interiors (line-line distance). Otherwise the constrained minimum is on the boundary of
// the unit square, i.e. the smallest of the four point-segment distances (ea0, ea1 against edge b,
// eb0, eb1 against edge a), each classified by point_edge_case. For parallel edges this is exact
// (the minimum is attained at an endpoint), so they need no special case beyond skipping the
// singular 2x2 solve; zero-length edges reduce to point-edge and point-point.
//
// Nearly parallel edges in the ea_eb case have a line-line Hessian growing like 1 / |ea x eb|^2:
// the engine multiplies edge-edge barriers by the mollifier (edge_edge_mollifier.hpp).
#pragma once

#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/point_edge_distance.hpp"

#include <cstdint>

namespace nexdyn {

enum class EdgeEdgeCase : uint8_t {
  ea0_eb0, ea0_eb1, ea1_eb0, ea1_eb1,  // vertex-vertex
  ea_eb0, ea_eb1,                      // eb's vertex against ea's interior
  ea0_eb, ea1_eb,                      // ea's vertex against eb's interior
  ea_eb                                // interior-interior (line-line)
};

namespace detail {
// Edges with |ea x eb|^2 <= kEdgesParallel |ea|^2 |eb|^2 (sin^2 of their angle) are treated as
// parallel: skipping the interior case there changes the squared distance by at most about
// kEdgesParallel * L^2, while the 2x2 solve would be ill conditioned.
inline constexpr double kEdgesParallel = 1e-20;
}  // namespace detail

inline EdgeEdgeCase edge_edge_case(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                   const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1) {
  const Eigen::Vector3d ea = ea1 - ea0;
  const Eigen::Vector3d eb = eb1 - eb0;
  const double a = ea.squaredNorm();
  const double c = eb.squaredNorm();
  const double det = ea.cross(eb).squaredNorm();  // = a c - b^2, without cancellation
  if (det > detail::kEdgesParallel * a * c) {
    // Closest points ea0 + s ea and eb0 + t eb: eb0 - ea0 = s ea - t eb + (normal part).
    const Eigen::Vector2d st = detail::in_plane_coordinates(eb0 - ea0, ea, eb);
    const double s = st(0), t = -st(1);
    constexpr double tie = detail::kFeatureTie;
    if (s > tie && s < 1.0 - tie && t > tie && t < 1.0 - tie) return EdgeEdgeCase::ea_eb;
  }
  // Boundary of the parameter square: four point-segment problems; ties keep the first.
  const PointEdgeCase c0 = point_edge_case(ea0, eb0, eb1);
  const PointEdgeCase c1 = point_edge_case(ea1, eb0, eb1);
  const PointEdgeCase c2 = point_edge_case(eb0, ea0, ea1);
  const PointEdgeCase c3 = point_edge_case(eb1, ea0, ea1);
  const double d[4] = {point_edge_distance(ea0, eb0, eb1, c0),
                       point_edge_distance(ea1, eb0, eb1, c1),
                       point_edge_distance(eb0, ea0, ea1, c2),
                       point_edge_distance(eb1, ea0, ea1, c3)};
  int k = 0;
  for (int i = 1; i < 4; ++i) {
    if (d[i] < d[k]) k = i;
  }
  // Row k: the case for [endpoint 0, endpoint 1, interior] of the point-edge result.
  constexpr EdgeEdgeCase kMap[4][3] = {
      {EdgeEdgeCase::ea0_eb0, EdgeEdgeCase::ea0_eb1, EdgeEdgeCase::ea0_eb},
      {EdgeEdgeCase::ea1_eb0, EdgeEdgeCase::ea1_eb1, EdgeEdgeCase::ea1_eb},
      {EdgeEdgeCase::ea0_eb0, EdgeEdgeCase::ea1_eb0, EdgeEdgeCase::ea_eb0},
      {EdgeEdgeCase::ea0_eb1, EdgeEdgeCase::ea1_eb1, EdgeEdgeCase::ea_eb1}};
  const PointEdgeCase pc[4] = {c0, c1, c2, c3};
  return kMap[k][static_cast<int>(pc[k])];
}

inline double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                 const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                 EdgeEdgeCase c) {
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return point_point_distance(ea0, eb0);
    case EdgeEdgeCase::ea0_eb1: return point_point_distance(ea0, eb1);
    case EdgeEdgeCase::ea1_eb0: return point_point_distance(ea1, eb0);
    case EdgeEdgeCase::ea1_eb1: return point_point_distance(ea1, eb1);
    case EdgeEdgeCase::ea_eb0: return point_line_distance(eb0, ea0, ea1);
    case EdgeEdgeCase::ea_eb1: return point_line_distance(eb1, ea0, ea1);
    case EdgeEdgeCase::ea0_eb: return point_line_distance(ea0, eb0, eb1);
    case EdgeEdgeCase::ea1_eb: return point_line_distance(ea1, eb0, eb1);
    case EdgeEdgeCase::ea_eb: return line_line_distance(ea0, ea1, eb0, eb1);
  }
  return 0.0;
}

inline double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                 const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1) {
  return edge_edge_distance(ea0, ea1, eb0, eb1, edge_edge_case(ea0, ea1, eb0, eb1));
}

inline Vector12d edge_edge_distance_gradient(const Eigen::Vector3d& ea0,
                                             const Eigen::Vector3d& ea1,
                                             const Eigen::Vector3d& eb0,
                                             const Eigen::Vector3d& eb1, EdgeEdgeCase c) {
  using detail::scatter_gradient;
  switch (c) {
    case EdgeEdgeCase::ea0_eb0:
      return scatter_gradient<2, 4>(point_point_distance_gradient(ea0, eb0), {0, 2});
    case EdgeEdgeCase::ea0_eb1:
      return scatter_gradient<2, 4>(point_point_distance_gradient(ea0, eb1), {0, 3});
    case EdgeEdgeCase::ea1_eb0:
      return scatter_gradient<2, 4>(point_point_distance_gradient(ea1, eb0), {1, 2});
    case EdgeEdgeCase::ea1_eb1:
      return scatter_gradient<2, 4>(point_point_distance_gradient(ea1, eb1), {1, 3});
    case EdgeEdgeCase::ea_eb0:
      return scatter_gradient<3, 4>(point_line_distance_gradient(eb0, ea0, ea1), {2, 0, 1});
    case EdgeEdgeCase::ea_eb1:
      return scatter_gradient<3, 4>(point_line_distance_gradient(eb1, ea0, ea1), {3, 0, 1});
    case EdgeEdgeCase::ea0_eb:
      return scatter_gradient<3, 4>(point_line_distance_gradient(ea0, eb0, eb1), {0, 2, 3});
    case EdgeEdgeCase::ea1_eb:
      return scatter_gradient<3, 4>(point_line_distance_gradient(ea1, eb0, eb1), {1, 2, 3});
    case EdgeEdgeCase::ea_eb: return line_line_distance_gradient(ea0, ea1, eb0, eb1);
  }
  return Vector12d::Zero();
}

inline Vector12d edge_edge_distance_gradient(const Eigen::Vector3d& ea0,
                                             const Eigen::Vector3d& ea1,
                                             const Eigen::Vector3d& eb0,
                                             const Eigen::Vector3d& eb1) {
  return edge_edge_distance_gradient(ea0, ea1, eb0, eb1, edge_edge_case(ea0, ea1, eb0, eb1));
}

inline Matrix12d edge_edge_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                            const Eigen::Vector3d& eb0,
                                            const Eigen::Vector3d& eb1, EdgeEdgeCase c) {
  using detail::scatter_hessian;
  switch (c) {
    case EdgeEdgeCase::ea0_eb0:
      return scatter_hessian<2, 4>(point_point_distance_hessian(ea0, eb0), {0, 2});
    case EdgeEdgeCase::ea0_eb1:
      return scatter_hessian<2, 4>(point_point_distance_hessian(ea0, eb1), {0, 3});
    case EdgeEdgeCase::ea1_eb0:
      return scatter_hessian<2, 4>(point_point_distance_hessian(ea1, eb0), {1, 2});
    case EdgeEdgeCase::ea1_eb1:
      return scatter_hessian<2, 4>(point_point_distance_hessian(ea1, eb1), {1, 3});
    case EdgeEdgeCase::ea_eb0:
      return scatter_hessian<3, 4>(point_line_distance_hessian(eb0, ea0, ea1), {2, 0, 1});
    case EdgeEdgeCase::ea_eb1:
      return scatter_hessian<3, 4>(point_line_distance_hessian(eb1, ea0, ea1), {3, 0, 1});
    case EdgeEdgeCase::ea0_eb:
      return scatter_hessian<3, 4>(point_line_distance_hessian(ea0, eb0, eb1), {0, 2, 3});
    case EdgeEdgeCase::ea1_eb:
      return scatter_hessian<3, 4>(point_line_distance_hessian(ea1, eb0, eb1), {1, 2, 3});
    case EdgeEdgeCase::ea_eb: return line_line_distance_hessian(ea0, ea1, eb0, eb1);
  }
  return Matrix12d::Zero();
}

inline Matrix12d edge_edge_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                            const Eigen::Vector3d& eb0,
                                            const Eigen::Vector3d& eb1) {
  return edge_edge_distance_hessian(ea0, ea1, eb0, eb1, edge_edge_case(ea0, ea1, eb0, eb1));
}

}  // namespace nexdyn

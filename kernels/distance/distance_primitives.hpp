// Squared distances between the affine primitives of IPC contact (point, infinite line, plane of a
// triangle, analytic obstacle plane) with exact gradients and Hessians, on fixed-size Eigen types.
// IPC works on squared distances d = |.|^2 so that every piece is smooth where the closest
// features are unique (Li et al. 2020, "Incremental Potential Contact", sec. 4 and supplemental
// sec. 1; seed 001). The closest-feature dispatch for triangles and segments lives in
// point_edge_distance.hpp, point_triangle_distance.hpp and edge_edge_distance.hpp.
//
// One derivation serves point-line, point-plane and line-line (and point-point as the 0-parameter
// case). Each is d(x) = min_lambda f(x, lambda), f = |r|^2, with the difference vector
//   r(x, lambda) = sum_i w_i(lambda) x_i,   w(lambda) = w0 + B lambda   (K points, M parameters),
// affine in lambda and linear in the stacked points x. At the minimiser f_lambda = 0, so by the
// envelope theorem and the implicit function theorem
//   grad d = f_x = [2 w_i r]_i,
//   hess d = f_xx - f_xlambda f_lambdalambda^-1 f_lambdax,
//   f_xx = 2 (w w^T (x) I3),  f_lambdalambda = 2 D^T D with D = dr/dlambda = X B (3 x M),
//   d f_x_i / d lambda_m = 2 (B_im r + w_i D_m).
// This is exact (no truncation), needs only a 1x1 or 2x2 inverse, and was checked against central
// differences in tests/kernels/distance. The values themselves are computed with cross / triple
// products, which stay accurate for points far from the foot of the perpendicular.
//
// DOF order everywhere: [x0 y0 z0, x1 y1 z1, ...] in argument order.
// Preconditions: a non-degenerate line (e0 != e1), triangle (non-collinear corners) and pair of
// lines (not parallel). Degenerate inputs do not produce NaN: the parameter solve is skipped and
// the derivatives become those of |r(lambda = 0)|^2 (for point_line with e0 == e1 that is exactly
// the point-point distance to e0), but the dispatchers never call a primitive on such inputs.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()
#include <Eigen/LU>        // fixed-size inverse()

#include <cmath>

namespace nexdyn {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Vector9d = Eigen::Matrix<double, 9, 1>;
using Vector12d = Eigen::Matrix<double, 12, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;

namespace detail {

// Ties between closest features. A closest point whose parameter (barycentric coordinate, edge
// parameter) is within kFeatureTie of a lower-dimensional feature is classified as that feature:
// a point exactly over a triangle's corner is a point-point contact, not a point-plane one. Exact
// ties are common (bodies stacked on grids), and rounding puts the computed parameter a few ulp
// to either side, so without the margin the same contact would be classified at random. The
// squared distance changes by at most (kFeatureTie L)^2, and only the one-sided second
// derivative used at the tie changes; point-point and point-edge contacts can then be merged
// (engine/contact/barrier_potential.cpp).
inline constexpr double kFeatureTie = 1e-12;

// a b - c d to within about one ulp of the result (Kahan): the rounding error of c d is recovered
// exactly by a fused multiply-add, so no cancellation is left when a b and c d nearly agree.
inline double difference_of_products(double a, double b, double c, double d) {
  const double cd = c * d;
  const double cd_error = std::fma(-c, d, cd);  // cd - c d, exactly
  return std::fma(a, b, -cd) + cd_error;
}

// u x v with every component accurate to about one ulp of itself, also for nearly parallel u and
// v, whose plain cross product is only accurate to eps |u| |v| (relative eps / sin of the angle).
inline Eigen::Vector3d accurate_cross(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  return {difference_of_products(u.y(), v.z(), u.z(), v.y()),
          difference_of_products(u.z(), v.x(), u.x(), v.z()),
          difference_of_products(u.x(), v.y(), u.y(), v.x())};
}

// Coordinates (alpha, beta) of r = alpha u + beta v + gamma (u x v), for u and v not parallel: the
// foot of a point on a triangle's plane in the edge basis, or the closest points of two lines.
// Crossing r with v (or u) and projecting on n = u x v leaves one unknown each:
//   alpha = (r x v) . n / |n|^2,   beta = (u x r) . n / |n|^2.
// With n accurate to its own size, the error is about eps |r| / (|u| sin) for an angle theta
// between u and v. Cramer's rule on the normal equations, (|v|^2 u.r - (u.v) v.r) / (|u|^2 |v|^2 -
// (u.v)^2), loses eps |r| / (|u| sin^2) to cancellation in its numerator, and so does the triple
// product with a plain n when gamma is comparable to |r|: enough to put the closest point of
// edges 1e-6 rad from parallel on the wrong side of an edge's end, and to make the answer depend
// on whether the compiler fuses multiply-adds.
inline Eigen::Vector2d in_plane_coordinates(const Eigen::Vector3d& r, const Eigen::Vector3d& u,
                                            const Eigen::Vector3d& v) {
  const Eigen::Vector3d n = accurate_cross(u, v);
  const double n2 = n.squaredNorm();
  return {r.cross(v).dot(n) / n2, u.cross(r).dot(n) / n2};
}

// Minimiser of |X (w0 + B lambda)|^2 over lambda, and the pieces its derivatives need.
template <int K, int M>
struct AffineMinimum {
  Eigen::Vector3d r;                // difference vector at lambda*
  Eigen::Matrix<double, K, 1> w;    // point weights at lambda*
  Eigen::Matrix<double, 3, M> D;    // dr/dlambda
  Eigen::Matrix<double, M, M> A_inv;  // (D^T D)^-1, zero when singular
};

template <int K, int M>
inline AffineMinimum<K, M> affine_minimum(const Eigen::Matrix<double, 3, K>& X,
                                          const Eigen::Matrix<double, K, 1>& w0,
                                          const Eigen::Matrix<double, K, M>& B) {
  AffineMinimum<K, M> out;
  out.D = X * B;
  const Eigen::Matrix<double, M, M> A = out.D.transpose() * out.D;
  const double det = A.determinant();
  // Exactly singular only for a zero-length edge, a collinear triangle or exactly parallel lines;
  // the dispatchers route those to lower-dimensional features before calling.
  if (det > 0.0) {
    out.A_inv = A.inverse();
  } else {
    out.A_inv.setZero();
  }
  const Eigen::Vector3d r0 = X * w0;
  const Eigen::Matrix<double, M, 1> lambda = -out.A_inv * (out.D.transpose() * r0);
  out.w = w0 + B * lambda;
  out.r = X * out.w;
  return out;
}

template <int K, int M>
inline Eigen::Matrix<double, 3 * K, 1> affine_gradient(const AffineMinimum<K, M>& m) {
  Eigen::Matrix<double, 3 * K, 1> g;
  for (int i = 0; i < K; ++i) g.template segment<3>(3 * i) = 2.0 * m.w(i) * m.r;
  return g;
}

template <int K, int M>
inline Eigen::Matrix<double, 3 * K, 3 * K> affine_hessian(const AffineMinimum<K, M>& m,
                                                          const Eigen::Matrix<double, K, M>& B) {
  Eigen::Matrix<double, 3 * K, 3 * K> H;
  H.setZero();
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j) {
      H.template block<3, 3>(3 * i, 3 * j).diagonal().setConstant(2.0 * m.w(i) * m.w(j));
    }
  }
  Eigen::Matrix<double, 3 * K, M> G;  // f_xlambda
  for (int i = 0; i < K; ++i) {
    for (int k = 0; k < M; ++k) {
      G.template block<3, 1>(3 * i, k) = 2.0 * (B(i, k) * m.r + m.w(i) * m.D.col(k));
    }
  }
  // f_lambdalambda^-1 = (2 D^T D)^-1 = A_inv / 2.
  H.noalias() -= G * (0.5 * m.A_inv) * G.transpose();
  return H;
}

// Stencils: r = p - e0 - s (e1 - e0) for point-line, DOFs [p, e0, e1].
inline Eigen::Matrix<double, 3, 1> point_line_w0() { return {1.0, -1.0, 0.0}; }
inline Eigen::Matrix<double, 3, 1> point_line_B() { return {0.0, 1.0, -1.0}; }

// r = p - t0 - a (t1 - t0) - b (t2 - t0), DOFs [p, t0, t1, t2].
inline Eigen::Matrix<double, 4, 1> point_plane_w0() { return {1.0, -1.0, 0.0, 0.0}; }
inline Eigen::Matrix<double, 4, 2> point_plane_B() {
  Eigen::Matrix<double, 4, 2> B;
  B << 0.0, 0.0, 1.0, 1.0, -1.0, 0.0, 0.0, -1.0;
  return B;
}

// r = ea0 + s (ea1 - ea0) - eb0 - t (eb1 - eb0), DOFs [ea0, ea1, eb0, eb1].
inline Eigen::Matrix<double, 4, 1> line_line_w0() { return {1.0, 0.0, -1.0, 0.0}; }
inline Eigen::Matrix<double, 4, 2> line_line_B() {
  Eigen::Matrix<double, 4, 2> B;
  B << -1.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, -1.0;
  return B;
}

inline Eigen::Matrix<double, 3, 3> columns(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                           const Eigen::Vector3d& c) {
  Eigen::Matrix<double, 3, 3> X;
  X << a, b, c;
  return X;
}

inline Eigen::Matrix<double, 3, 4> columns(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                           const Eigen::Vector3d& c, const Eigen::Vector3d& d) {
  Eigen::Matrix<double, 3, 4> X;
  X << a, b, c, d;
  return X;
}

}  // namespace detail

// ------------------------------------------------------------------------------------------------
// Point-point: d = |p0 - p1|^2. DOFs [p0, p1].

inline double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1) {
  return (p0 - p1).squaredNorm();
}

inline Vector6d point_point_distance_gradient(const Eigen::Vector3d& p0,
                                              const Eigen::Vector3d& p1) {
  Vector6d g;
  g.head<3>() = 2.0 * (p0 - p1);
  g.tail<3>() = -g.head<3>();
  return g;
}

inline Matrix6d point_point_distance_hessian(const Eigen::Vector3d& /*p0*/,
                                             const Eigen::Vector3d& /*p1*/) {
  Matrix6d H;
  H.setZero();
  H.diagonal().setConstant(2.0);
  H.block<3, 3>(0, 3).diagonal().setConstant(-2.0);
  H.block<3, 3>(3, 0).diagonal().setConstant(-2.0);
  return H;
}

// ------------------------------------------------------------------------------------------------
// Point to the infinite line through e0, e1: d = |(p - e0) x (e1 - e0)|^2 / |e1 - e0|^2.
// DOFs [p, e0, e1]. e0 == e1 gives the point-point distance to e0 (value and derivatives).

inline double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                  const Eigen::Vector3d& e1) {
  const Eigen::Vector3d e = e1 - e0;
  const double l2 = e.squaredNorm();
  if (!(l2 > 0.0)) return (p - e0).squaredNorm();
  return (p - e0).cross(e).squaredNorm() / l2;
}

inline Vector9d point_line_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                             const Eigen::Vector3d& e1) {
  return detail::affine_gradient(detail::affine_minimum<3, 1>(
      detail::columns(p, e0, e1), detail::point_line_w0(), detail::point_line_B()));
}

inline Matrix9d point_line_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                            const Eigen::Vector3d& e1) {
  const auto B = detail::point_line_B();
  return detail::affine_hessian(
      detail::affine_minimum<3, 1>(detail::columns(p, e0, e1), detail::point_line_w0(), B), B);
}

// ------------------------------------------------------------------------------------------------
// Point to the plane through t0, t1, t2: d = ((p - t0) . n)^2 / |n|^2, n = (t1 - t0) x (t2 - t0).
// DOFs [p, t0, t1, t2]. The corners' order does not matter (the sign of n cancels).

inline double point_plane_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                   const Eigen::Vector3d& t1, const Eigen::Vector3d& t2) {
  const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
  const double n2 = n.squaredNorm();
  if (!(n2 > 0.0)) return (p - t0).squaredNorm();
  const double h = (p - t0).dot(n);
  return h * h / n2;
}

inline Vector12d point_plane_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                               const Eigen::Vector3d& t1,
                                               const Eigen::Vector3d& t2) {
  return detail::affine_gradient(detail::affine_minimum<4, 2>(
      detail::columns(p, t0, t1, t2), detail::point_plane_w0(), detail::point_plane_B()));
}

inline Matrix12d point_plane_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                              const Eigen::Vector3d& t1,
                                              const Eigen::Vector3d& t2) {
  const auto B = detail::point_plane_B();
  return detail::affine_hessian(
      detail::affine_minimum<4, 2>(detail::columns(p, t0, t1, t2), detail::point_plane_w0(), B),
      B);
}

// ------------------------------------------------------------------------------------------------
// Between the infinite lines through ea0, ea1 and eb0, eb1:
// d = ((eb0 - ea0) . n)^2 / |n|^2, n = (ea1 - ea0) x (eb1 - eb0). DOFs [ea0, ea1, eb0, eb1].
// Not defined for parallel lines (n = 0): there the minimiser is a whole line and the Hessian
// blows up like 1 / |n|^2 as n -> 0, which is why IPC multiplies edge-edge barriers by the
// mollifier of edge_edge_mollifier.hpp.

inline double line_line_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                 const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1) {
  const Eigen::Vector3d n = (ea1 - ea0).cross(eb1 - eb0);
  const double n2 = n.squaredNorm();
  if (!(n2 > 0.0)) return point_line_distance(ea0, eb0, eb1);
  const double h = (eb0 - ea0).dot(n);
  return h * h / n2;
}

inline Vector12d line_line_distance_gradient(const Eigen::Vector3d& ea0,
                                             const Eigen::Vector3d& ea1,
                                             const Eigen::Vector3d& eb0,
                                             const Eigen::Vector3d& eb1) {
  return detail::affine_gradient(detail::affine_minimum<4, 2>(
      detail::columns(ea0, ea1, eb0, eb1), detail::line_line_w0(), detail::line_line_B()));
}

inline Matrix12d line_line_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                            const Eigen::Vector3d& eb0,
                                            const Eigen::Vector3d& eb1) {
  const auto B = detail::line_line_B();
  return detail::affine_hessian(
      detail::affine_minimum<4, 2>(detail::columns(ea0, ea1, eb0, eb1), detail::line_line_w0(), B),
      B);
}

// ------------------------------------------------------------------------------------------------
// Point to an analytic obstacle plane {x : (x - origin) . normal = 0} with |normal| = 1 (the caller
// normalises once when loading the scene): d = ((p - origin) . normal)^2, gradient
// 2 ((p - origin) . normal) normal, Hessian 2 normal normal^T. Only p is a DOF. The sign of the
// signed distance is lost in d; the engine keeps points on the positive side through CCD.

inline double point_obstacle_plane_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& origin,
                                            const Eigen::Vector3d& normal) {
  const double h = (p - origin).dot(normal);
  return h * h;
}

inline Eigen::Vector3d point_obstacle_plane_distance_gradient(const Eigen::Vector3d& p,
                                                              const Eigen::Vector3d& origin,
                                                              const Eigen::Vector3d& normal) {
  return 2.0 * (p - origin).dot(normal) * normal;
}

inline Eigen::Matrix3d point_obstacle_plane_distance_hessian(const Eigen::Vector3d& /*p*/,
                                                             const Eigen::Vector3d& /*origin*/,
                                                             const Eigen::Vector3d& normal) {
  return 2.0 * normal * normal.transpose();
}

namespace detail {

// Places the derivatives of a K-point stencil into an N-point stencil: local point i -> idx[i].
template <int K, int N>
inline Eigen::Matrix<double, 3 * N, 1> scatter_gradient(const Eigen::Matrix<double, 3 * K, 1>& g,
                                                        const int (&idx)[K]) {
  Eigen::Matrix<double, 3 * N, 1> out;
  out.setZero();
  for (int i = 0; i < K; ++i) out.template segment<3>(3 * idx[i]) = g.template segment<3>(3 * i);
  return out;
}

template <int K, int N>
inline Eigen::Matrix<double, 3 * N, 3 * N> scatter_hessian(
    const Eigen::Matrix<double, 3 * K, 3 * K>& H, const int (&idx)[K]) {
  Eigen::Matrix<double, 3 * N, 3 * N> out;
  out.setZero();
  for (int i = 0; i < K; ++i) {
    for (int j = 0; j < K; ++j) {
      out.template block<3, 3>(3 * idx[i], 3 * idx[j]) = H.template block<3, 3>(3 * i, 3 * j);
    }
  }
  return out;
}

}  // namespace detail

}  // namespace nexdyn

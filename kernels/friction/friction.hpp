// Per-contact kernels of IPC's lagged, smoothed Coulomb friction (Li et al. 2020, "Incremental
// Potential Contact", sec. 5 and supplemental sec. 2; issue 4). Pure math on fixed-size Eigen
// types: no allocation, no threads, no exceptions.
//
// Lagging. Coulomb friction is not a potential: its direction and magnitude depend on the normal
// force and on the contact geometry, both functions of the unknown positions. IPC makes it one by
// freezing ("lagging") three things at positions x^t, the start of a lagging iteration (the first
// one is x^t = x_n, the start of the step):
//   - the closest-point parameters of each contact, hence the 3 x 3n matrix Gamma with
//     Gamma (v_stencil) = relative velocity of the two closest points,
//   - an orthonormal basis P (3 x 2) of the tangent plane at the contact (orthogonal to the
//     normal), so that T = Gamma^T P (3n x 2) maps stencil motion to tangential relative motion,
//   - the normal force magnitude lambda (friction_normal_force below).
// With those constant, the tangential relative displacement over the step u = T^T (x - x_n) is
// linear in x and the friction dissipation
//   D(x) = mu lambda f0(|u|)
// is a smooth (C1, piecewise C2) potential whose negative gradient is the friction force. The
// engine re-lags (recomputes bases and lambda at the new x^t and re-solves) as many times as it
// likes; one lagging iteration is IPC's default.
//
// Smoothing. Coulomb's law has a set-valued force at zero slip. IPC replaces the unit step of
// the force magnitude by f1, with eps_u = epsv h (epsv: the slip velocity below which contacts
// count as sticking, h: the time step):
//   f1(y) = -y^2 / eps_u^2 + 2 y / eps_u  for 0 <= y < eps_u,   1 for y >= eps_u,
// which is C1 at eps_u (f1 = 1, f1' = 0) and has f1(0) = 0, f1'(0) = 2 / eps_u: static friction
// becomes a very stiff, bounded spring of stiffness ~ 2 mu lambda / eps_u. f0 is its
// antiderivative with f0(eps_u) = eps_u (so that f0(y) = y, plain Coulomb dissipation, above):
//   f0(y) = -y^3 / (3 eps_u^2) + y^2 / eps_u + eps_u / 3  below eps_u,   y above.
// The force direction needs f1(y) / y, which is 1 / y above eps_u and 2 / eps_u - y / eps_u^2
// below: evaluated in that form it has no 0 / 0 at y = 0 and tends to 2 / eps_u.
//
// Static and kinetic coefficients. Real surfaces hold with mu_s and slide with mu_k <= mu_s. The
// force magnitude becomes g(y) = mu(y) f1(y) with
//   mu(y) = mu_s                                        for y <= eps_u (sticking),
//         = mu_s + (mu_k - mu_s) s(y / eps_u - 1)       for eps_u < y < 2 eps_u,
//         = mu_k                                        for y >= 2 eps_u,
// s(z) = 3 z^2 - 2 z^3 (C1). The transition sits above the sticking band, where f1 = 1, so a
// contact resists up to the full mu_s lambda before it slips (a transition inside the band
// would cap the static force near mu_k lambda). Its potential is F0(y) = int_0^y g, which is
// mu_s f0(y) in the band, then mu_s y + (mu_k - mu_s) eps_u S(y / eps_u - 1) with
// S(z) = z^3 - z^4 / 2, then mu_k y + (mu_s - mu_k) 3 eps_u / 2 past 2 eps_u. With mu_s = mu_k
// all of it is mu f0. Where mu falls with speed the potential is not convex along the slip
// (g' = mu' < 0), and the projection below clamps that eigenvalue to 0.
//
// Derivatives. Since T is constant,
//   grad_x D = mu lambda T (f1(y) / y) u,
//   hess_x D = mu lambda T M T^T,   M = (f1'(y) y - f1(y)) / y^3 u u^T + (f1(y) / y) I  (2 x 2).
// With u_hat = u / y this is M = f1'(y) u_hat u_hat^T + (f1(y) / y) (I - u_hat u_hat^T): its
// eigenvectors are u_hat and its perpendicular, with eigenvalues f1'(y) (along the slip) and
// f1(y) / y (across it), and M = (2 / eps_u) I at y = 0. The PSD projection of M is therefore
// the clamp of these two numbers at zero, in closed form; no eigensolver is needed. For this f1
// both are >= 0 (f1' = 2 (eps_u - y) / eps_u^2 >= 0 in the band, 0 above; f1 / y > 0), so the
// clamp only removes rounding and hess_x D = mu lambda T M T^T is PSD exactly as it stands.
// Smoothness: f1 is C1 at eps_u, so D is C2 and M is continuous there; f1'' (hence the third
// derivative of D) jumps at y = eps_u, and M depends on the direction of u near y = 0 (it is
// continuous at 0, not differentiable). Newton does not mind; finite-difference checks of the
// Hessian stay off y = eps_u and y = 0, where central differences lose their second order.
//
// Stencils and DOF orders (as in kernels/distance): point-point [p0, p1], point-edge [p, e0, e1],
// point-triangle [p, t0, t1, t2], edge-edge [ea0, ea1, eb0, eb1], vertex-plane [v] against a
// static obstacle plane. Gamma = w^T (x) I3 for a weight vector w with sum_i w_i = 0 (zero for
// vertex-plane, whose plane is fixed): the relative position of the closest points is
// r = sum_i w_i x_i, the same r as the distance kernels' detail::affine_minimum (side A minus
// side B):
//   point-point     w = [1, -1]
//   point-edge      w = [1, -(1 - a), -a]               a: edge parameter of the closest point
//   point-triangle  w = [1, -(1 - b1 - b2), -b1, -b2]   b1, b2: barycentric of the projection
//   edge-edge       w = [1 - g1, g1, -(1 - g2), -g2]    g1, g2: parameters on ea and eb
//   vertex-plane    w = [1]
// so T = Gamma^T P has 3 x 2 blocks w_i P, and T M T^T has 3 x 3 blocks w_i w_j (P M P^T): the
// kernels keep (P, w) rather than the 12 x 2 T and form the Hessian from one 3 x 3 product.
// All stencil-sized values are padded to 4 points (12 DOFs); entries past 3 n are zero.
//
// Normals (the tangent plane is their orthogonal complement): the closest-point difference r for
// point-point and point-edge, the triangle normal for point-triangle, ea x eb for edge-edge
// (the closest-point difference for parallel edges), the plane normal for vertex-plane. Any
// orthonormal basis of the same plane gives the same D (D depends on |u| = |P^T Gamma dx| and
// P P^T is the plane's projector), so tangent_basis picks a cheap stable one.
#pragma once

#include "kernels/barrier/barrier.hpp"
#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/friction/friction_types.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace nexdyn {

// ------------------------------------------------------------------------------------------------
// Closest-point parameters at the lagged positions. They describe the interior case of each
// stencil kind (the engine's stencils are per closest feature); outside it the values are those
// of the infinite line or plane, still smooth and finite.

// a with e0 + a (e1 - e0) the foot of the perpendicular from p; 0 for a zero-length edge.
inline double point_edge_closest_parameter(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                           const Eigen::Vector3d& e1) {
  const Eigen::Vector3d e = e1 - e0;
  const double l2 = e.squaredNorm();
  if (!(l2 > 0.0)) return 0.0;
  return (p - e0).dot(e) / l2;
}

// (b1, b2) with t0 + b1 (t1 - t0) + b2 (t2 - t0) the projection of p onto the triangle's plane;
// for a degenerate (collinear) triangle, the closest point on the edge t0 t1 (b2 = 0).
inline Eigen::Vector2d point_triangle_closest_parameters(const Eigen::Vector3d& p,
                                                         const Eigen::Vector3d& t0,
                                                         const Eigen::Vector3d& t1,
                                                         const Eigen::Vector3d& t2) {
  const Eigen::Vector3d e1 = t1 - t0;
  const Eigen::Vector3d e2 = t2 - t0;
  const double a = e1.squaredNorm();
  const double c = e2.squaredNorm();
  const double det = e1.cross(e2).squaredNorm();  // a c - b^2 without cancellation
  if (!(det > detail::kTriangleDegenerate * a * c)) {
    return {point_edge_closest_parameter(p, t0, t1), 0.0};
  }
  return detail::in_plane_coordinates(p - t0, e1, e2);
}

// (g1, g2) with ea0 + g1 (ea1 - ea0) and eb0 + g2 (eb1 - eb0) the closest points of the two
// lines. Parallel edges (sin^2 of the angle <= detail::kEdgesParallel) have a segment of closest
// points; there g1 is the middle of the part of ea facing eb (the end of ea nearest to eb if none
// does) and g2 the foot of the perpendicular from that point onto eb, clamped to the edge, so the
// contact point is central rather than arbitrary and both parameters lie in [0, 1].
inline Eigen::Vector2d edge_edge_closest_parameters(const Eigen::Vector3d& ea0,
                                                    const Eigen::Vector3d& ea1,
                                                    const Eigen::Vector3d& eb0,
                                                    const Eigen::Vector3d& eb1) {
  const Eigen::Vector3d ea = ea1 - ea0;
  const Eigen::Vector3d eb = eb1 - eb0;
  const double a = ea.squaredNorm();
  const double c = eb.squaredNorm();
  const double det = ea.cross(eb).squaredNorm();
  const Eigen::Vector3d w = ea0 - eb0;
  const double b = ea.dot(eb);
  const double d = ea.dot(w);
  if (det > detail::kEdgesParallel * a * c) {
    // eb0 - ea0 = g1 ea - g2 eb + (normal part).
    const Eigen::Vector2d g = detail::in_plane_coordinates(-w, ea, eb);
    return {g(0), -g(1)};
  }
  double g1 = 0.0;
  if (a > 0.0) {
    // eb's ends in ea's parameter, then the overlap with [0, 1].
    const double s0 = -d / a;       // (eb0 - ea0) . ea / a
    const double s1 = (b - d) / a;  // (eb1 - ea0) . ea / a
    const double lo = std::max(0.0, std::min(s0, s1));
    const double hi = std::min(1.0, std::max(s0, s1));
    g1 = lo <= hi ? 0.5 * (lo + hi) : std::clamp(0.5 * (s0 + s1), 0.0, 1.0);
  }
  const double g2 = c > 0.0 ? std::clamp((w + g1 * ea).dot(eb) / c, 0.0, 1.0) : 0.0;
  return {g1, g2};
}

// ------------------------------------------------------------------------------------------------
// Tangent plane.

// An orthonormal basis [t1, t2] of the plane orthogonal to `normal` (any length > 0). t1 is the
// normal crossed with the coordinate axis least aligned with it, which keeps |n x axis| >=
// sqrt(2/3) |n|, so no near-zero normalisation. A zero normal (touching or degenerate geometry,
// which IPC never evaluates) gives the xy-plane rather than NaN.
inline Eigen::Matrix<double, 3, 2> tangent_basis(const Eigen::Vector3d& normal) {
  Eigen::Matrix<double, 3, 2> P;
  const double n2 = normal.squaredNorm();
  if (!(n2 > 0.0)) {
    P << 1.0, 0.0, 0.0, 1.0, 0.0, 0.0;
    return P;
  }
  const Eigen::Vector3d n = normal / std::sqrt(n2);
  int k = 0;
  n.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d t1 = n.cross(Eigen::Vector3d::Unit(k)).normalized();
  P.col(0) = t1;
  P.col(1) = n.cross(t1);
  return P;
}

// A vector orthogonal to v (v != 0), for normals of touching point-edge contacts.
inline Eigen::Vector3d any_perpendicular(const Eigen::Vector3d& v) {
  int k = 0;
  v.cwiseAbs().minCoeff(&k);
  return v.cross(Eigen::Vector3d::Unit(k));
}

// ------------------------------------------------------------------------------------------------
// Lagged bases per stencil kind, from the positions x^t at the start of the lagging iteration.

inline FrictionBasis point_point_friction_basis(const Eigen::Vector3d& p0,
                                                const Eigen::Vector3d& p1) {
  FrictionBasis f;
  f.w << 1.0, -1.0, 0.0, 0.0;
  f.P = tangent_basis(p0 - p1);
  f.num_points = 2;
  return f;
}

inline FrictionBasis point_edge_friction_basis(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                               const Eigen::Vector3d& e1) {
  const double a = point_edge_closest_parameter(p, e0, e1);
  FrictionBasis f;
  f.w << 1.0, -(1.0 - a), -a, 0.0;
  const Eigen::Vector3d e = e1 - e0;
  Eigen::Vector3d n = p - (e0 + a * e);
  // A point on the edge's line has no closest-point direction: any normal of the edge will do.
  if (!(n.squaredNorm() > 1e-24 * e.squaredNorm()) && e.squaredNorm() > 0.0) {
    n = any_perpendicular(e);
  }
  f.P = tangent_basis(n);
  f.num_points = 3;
  return f;
}

inline FrictionBasis point_triangle_friction_basis(const Eigen::Vector3d& p,
                                                   const Eigen::Vector3d& t0,
                                                   const Eigen::Vector3d& t1,
                                                   const Eigen::Vector3d& t2) {
  const Eigen::Vector2d b = point_triangle_closest_parameters(p, t0, t1, t2);
  FrictionBasis f;
  f.w << 1.0, -(1.0 - b(0) - b(1)), -b(0), -b(1);
  Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
  // Degenerate triangle: the closest-point difference, as for point-edge.
  if (!(n.squaredNorm() > 0.0)) n = p - (t0 + b(0) * (t1 - t0));
  f.P = tangent_basis(n);
  f.num_points = 4;
  return f;
}

inline FrictionBasis edge_edge_friction_basis(const Eigen::Vector3d& ea0,
                                              const Eigen::Vector3d& ea1,
                                              const Eigen::Vector3d& eb0,
                                              const Eigen::Vector3d& eb1) {
  const Eigen::Vector2d g = edge_edge_closest_parameters(ea0, ea1, eb0, eb1);
  FrictionBasis f;
  f.w << 1.0 - g(0), g(0), -(1.0 - g(1)), -g(1);
  const Eigen::Vector3d ea = ea1 - ea0;
  const Eigen::Vector3d eb = eb1 - eb0;
  Eigen::Vector3d n = ea.cross(eb);
  if (!(n.squaredNorm() > detail::kEdgesParallel * ea.squaredNorm() * eb.squaredNorm())) {
    // Parallel: the direction between the chosen closest points, orthogonal to both edges when
    // they overlap; for collinear touching edges, any normal of the edges.
    n = (1.0 - g(0)) * ea0 + g(0) * ea1 - (1.0 - g(1)) * eb0 - g(1) * eb1;
    if (!(n.squaredNorm() > 1e-24 * ea.squaredNorm()) && ea.squaredNorm() > 0.0) {
      n = any_perpendicular(ea);
    }
  }
  f.P = tangent_basis(n);
  f.num_points = 4;
  return f;
}

// A vertex against a static obstacle plane with the given normal (any length > 0).
inline FrictionBasis vertex_plane_friction_basis(const Eigen::Vector3d& plane_normal) {
  FrictionBasis f;
  f.w << 1.0, 0.0, 0.0, 0.0;
  f.P = tangent_basis(plane_normal);
  f.num_points = 1;
  return f;
}

// Dispatch on the kind. X holds the stencil's lagged positions in DOF order (columns past n
// unused); plane_normal is used by vertex_plane only. A mollified edge-edge stencil whose closest
// features are not the two interiors should be passed as the point-edge or point-point stencil
// of those features (with w scattered back onto its 4 vertices by the caller), or as edge_edge,
// whose parameters are then those of the two infinite lines.
inline FrictionBasis friction_basis(FrictionStencil kind, const Eigen::Matrix<double, 3, 4>& X,
                                    const Eigen::Vector3d& plane_normal) {
  switch (kind) {
    case FrictionStencil::vertex_plane: return vertex_plane_friction_basis(plane_normal);
    case FrictionStencil::point_point: return point_point_friction_basis(X.col(0), X.col(1));
    case FrictionStencil::point_edge:
      return point_edge_friction_basis(X.col(0), X.col(1), X.col(2));
    case FrictionStencil::point_triangle:
      return point_triangle_friction_basis(X.col(0), X.col(1), X.col(2), X.col(3));
    case FrictionStencil::edge_edge:
      return edge_edge_friction_basis(X.col(0), X.col(1), X.col(2), X.col(3));
  }
  return vertex_plane_friction_basis(plane_normal);
}

// Gamma (3 x 12, zero past 3 n): stencil velocity -> relative velocity of the closest points.
inline Eigen::Matrix<double, 3, 12> relative_velocity_jacobian(const FrictionBasis& f) {
  Eigen::Matrix<double, 3, 12> G;
  G.setZero();
  for (int i = 0; i < 4; ++i) G.block<3, 3>(0, 3 * i).diagonal().setConstant(f.w(i));
  return G;
}

// T = Gamma^T P (12 x 2, zero past 3 n): stencil displacement -> tangential relative one.
inline Eigen::Matrix<double, 12, 2> tangent_jacobian(const FrictionBasis& f) {
  Eigen::Matrix<double, 12, 2> T;
  for (int i = 0; i < 4; ++i) T.block<3, 2>(3 * i, 0) = f.w(i) * f.P;
  return T;
}

// ------------------------------------------------------------------------------------------------
// Lagged normal force.

// Magnitude of the contact force of a barrier kappa b(d) on the squared distance d, along the
// (unsquared) distance s = sqrt(d): lambda = -d/ds kappa b(s^2) = -kappa b'(d) 2 sqrt(d) >= 0.
// dhat2 is the squared activation distance (the `dhat` of barrier.hpp); 0 for d >= dhat2. The
// engine multiplies by the stencil's multiplicity (and the mollifier of a mollified edge-edge
// pair) and evaluates it once per lagging iteration, at x^t. lambda grows like
// 2 kappa dhat2 / sqrt(d) as d -> 0; d <= 0 (touching or crossing, never evaluated by IPC)
// returns +inf, like barrier().
inline double friction_normal_force(double d, double dhat2, double kappa) {
  if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
  if (d >= dhat2) return 0.0;
  return -kappa * barrier_first_derivative(d, dhat2) * 2.0 * std::sqrt(d);
}

// ------------------------------------------------------------------------------------------------
// The smoothed friction magnitude and its antiderivative (see the top), y = |u| >= 0.

inline double friction_f0(double y, double eps_u) {
  if (y >= eps_u) return y;
  return y * y * (1.0 / eps_u - y / (3.0 * eps_u * eps_u)) + eps_u / 3.0;
}

inline double friction_f1(double y, double eps_u) {
  if (y >= eps_u) return 1.0;
  return y * (2.0 - y / eps_u) / eps_u;
}

inline double friction_f1_derivative(double y, double eps_u) {
  if (y >= eps_u) return 0.0;
  return 2.0 * (eps_u - y) / (eps_u * eps_u);
}

// f1(y) / y, without the 0 / 0 at y = 0 (limit 2 / eps_u).
inline double friction_f1_over_y(double y, double eps_u) {
  if (y >= eps_u) return 1.0 / y;
  return (2.0 - y / eps_u) / eps_u;
}

// ------------------------------------------------------------------------------------------------
// The friction potential of one contact. dx is the stencil's displacement over the step,
// x - x_prev (x_prev: positions at the start of the time step), padded to 12 (entries past 3 n
// ignored). mu: friction coefficient of the contact's material pair, lambda: its lagged normal
// force, eps_u = epsv h.

// u = T^T dx, the tangential relative displacement of the closest points (slip speed |u| / h).
inline Eigen::Vector2d tangential_displacement(const FrictionBasis& f, const Vector12d& dx) {
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  for (int i = 0; i < f.num_points; ++i) r += f.w(i) * dx.segment<3>(3 * i);
  return f.P.transpose() * r;
}

// The friction magnitude g(y) = mu(y) f1(y) of a contact and its relatives, y = |u| >= 0.
struct FrictionMagnitude {
  double potential;     // F0(y) = int_0^y g (plus the constant mu_s eps_u / 3 of f0)
  double over_y;        // g(y) / y (limit 2 mu_s / eps_u at 0)
  double derivative;    // g'(y)
};

inline FrictionMagnitude friction_magnitude(double y, const FrictionCoefficients& c, double eps_u) {
  if (y < eps_u || c.mu_s == c.mu_k) {
    const double mu = y < eps_u ? c.mu_s : c.mu_k;
    return {mu * friction_f0(y, eps_u), mu * friction_f1_over_y(y, eps_u), mu * friction_f1_derivative(y, eps_u)};
  }
  const double jump = c.mu_k - c.mu_s;
  if (y >= 2.0 * eps_u) return {c.mu_k * y - 1.5 * jump * eps_u, c.mu_k / y, 0.0};
  const double z = y / eps_u - 1.0;
  const double mu = c.mu_s + jump * z * z * (3.0 - 2.0 * z);
  return {c.mu_s * y + jump * eps_u * z * z * z * (1.0 - 0.5 * z), mu / y, jump * 6.0 * z * (1.0 - z) / eps_u};
}

// D = lambda F0(|u|) (= mu lambda f0(|u|) for one coefficient).
inline double friction_energy(const FrictionBasis& f, const Vector12d& dx, const FrictionCoefficients& c,
                              double lambda, double eps_u) {
  return lambda * friction_magnitude(tangential_displacement(f, dx).norm(), c, eps_u).potential;
}

// grad D = lambda T (g(y) / y) u; zero past 3 n.
inline Vector12d friction_gradient(const FrictionBasis& f, const Vector12d& dx, const FrictionCoefficients& c,
                                   double lambda, double eps_u) {
  const Eigen::Vector2d u = tangential_displacement(f, dx);
  const Eigen::Vector3d t = (lambda * friction_magnitude(u.norm(), c, eps_u).over_y) * (f.P * u);
  Vector12d g;
  g.setZero();
  for (int i = 0; i < f.num_points; ++i) g.segment<3>(3 * i) = f.w(i) * t;
  return g;
}

// The friction force on each stencil vertex, -grad D (for reporting). It sums to zero over the
// stencil (sum_i w_i = 0) except for vertex-plane, whose reaction acts on the fixed plane. While
// sliding (|u| >= 2 eps_u) the vertices of side A (w_i > 0) together receive exactly
// -mu_k lambda P u / |u|: Coulomb's force, opposing the tangential relative displacement.
inline Vector12d friction_force(const FrictionBasis& f, const Vector12d& dx, const FrictionCoefficients& c,
                                double lambda, double eps_u) {
  return -friction_gradient(f, dx, c, lambda, eps_u);
}

// The 2 x 2 M of hess D = lambda T M T^T, PSD-projected in closed form: eigenvalue g'(y) along
// u_hat = u / y and g(y) / y across it, each clamped at 0 (with one coefficient both are >= 0
// and the clamp only removes rounding; with mu_k < mu_s, g' < 0 in the transition). y = 0:
// (2 mu_s / eps_u) I.
//
// majorize: g(y) / y along u_hat too (the larger of it and g'), i.e. (g(y) / y) I. While a
// contact slides, g' = 0: D grows linearly along the slip and the exact model does not see the
// kink at u = 0, so a Newton step that should bring the slip to rest carries it across. The
// quadratic with curvature g(y) / y in every direction lies on or above lambda F0 wherever
// g(y) / y does not increase with y (one coefficient, or mu_k <= mu_s): it touches D at u, and
// its minimum along any line is no further than the kink (the half-quadratic bound of iteratively
// reweighted least squares). FrictionPotential uses it for contacts whose slip has reversed.
inline Eigen::Matrix2d friction_tangent_hessian(const Eigen::Vector2d& u, const FrictionCoefficients& c,
                                                double eps_u, bool majorize = false) {
  const double y = u.norm();
  const FrictionMagnitude g = friction_magnitude(y, c, eps_u);
  const double across = std::max(0.0, g.over_y);
  Eigen::Matrix2d M = across * Eigen::Matrix2d::Identity();
  if (y > 0.0) {
    const double along = majorize ? std::max(g.derivative, across) : std::max(0.0, g.derivative);
    const Eigen::Vector2d u_hat = u / y;
    M.noalias() += (along - across) * (u_hat * u_hat.transpose());
  }
  return M;
}

// hess D = lambda T M T^T, built as 3 x 3 blocks w_i w_j (lambda P M P^T): exact where g' >= 0
// (T is constant) and PSD (M is). Zero past 3 n.
inline Matrix12d friction_hessian(const FrictionBasis& f, const Vector12d& dx, const FrictionCoefficients& c,
                                  double lambda, double eps_u, bool majorize = false) {
  const Eigen::Matrix2d M = friction_tangent_hessian(tangential_displacement(f, dx), c, eps_u, majorize);
  Eigen::Matrix3d A = lambda * (f.P * M * f.P.transpose());
  // Exactly symmetric, so that the assembled matrix is too (CHOLMOD reads one triangle).
  A = 0.5 * (A + A.transpose()).eval();
  Matrix12d H;
  H.setZero();
  for (int i = 0; i < f.num_points; ++i) {
    for (int j = 0; j < f.num_points; ++j) {
      H.block<3, 3>(3 * i, 3 * j) = (f.w(i) * f.w(j)) * A;
    }
  }
  return H;
}

// One coefficient mu (mu_s = mu_k): D = mu lambda f0(|u|).
inline double friction_energy(const FrictionBasis& f, const Vector12d& dx, double mu, double lambda, double eps_u) {
  return friction_energy(f, dx, FrictionCoefficients{mu, mu}, lambda, eps_u);
}
inline Vector12d friction_gradient(const FrictionBasis& f, const Vector12d& dx, double mu, double lambda,
                                   double eps_u) {
  return friction_gradient(f, dx, FrictionCoefficients{mu, mu}, lambda, eps_u);
}
inline Vector12d friction_force(const FrictionBasis& f, const Vector12d& dx, double mu, double lambda,
                                double eps_u) {
  return -friction_gradient(f, dx, FrictionCoefficients{mu, mu}, lambda, eps_u);
}
inline Matrix12d friction_hessian(const FrictionBasis& f, const Vector12d& dx, double mu, double lambda,
                                  double eps_u) {
  return friction_hessian(f, dx, FrictionCoefficients{mu, mu}, lambda, eps_u);
}
// M for mu = 1: eigenvalues f1'(y) along u and f1(y) / y across.
inline Eigen::Matrix2d friction_tangent_hessian(const Eigen::Vector2d& u, double eps_u) {
  return friction_tangent_hessian(u, FrictionCoefficients{1.0, 1.0}, eps_u);
}

}  // namespace nexdyn

// Barrier derivatives of one contact stencil: the energy w b(d(x)) of a pair whose squared
// distance d is that of its closest feature (point-point, point-line, point-plane, line-line, or a
// point against an analytic obstacle plane), its gradient, and its Hessian projected onto the PSD
// cone, as Newton's method on the incremental potential needs (IPC, Li et al. 2020, sec. 4-5;
// seed 001). Nearly parallel edge-edge pairs carry the mollifier m(x) (edge_edge_mollifier.hpp):
// E = w m b, by the product rule over all 12 DOFs.
//
// d and b follow kernels/distance and barrier.hpp: SQUARED distances, dhat2 = dhat^2, b = 0 for
// d >= dhat2. w is the stencil's weight (barrier stiffness times the number of pairs merged into
// it, engine/contact/barrier_potential.hpp). DOFs in argument order, [x0 y0 z0, x1 y1 z1, ...].
//
// The projections are exact, and cheap because the Hessians have known structure:
//   point-point, obstacle plane  closed-form eigenvalues (clamped directly);
//   point-line, point-plane,     the Hessian lives in a (3 + M)-dimensional subspace (M = 1 or 2
//   line-line                    parameters of the closest point), projected there;
//   mollified edge-edge          translations are in the null space: a 9x9 problem, not 12x12.
// Every stencil energy here except the obstacle plane's is translation invariant, so gradients
// sum to zero over the points and Hessians annihilate rigid translations (before and after the
// projection; tests/kernels/barrier/test_barrier_stencils.cpp).
//
// Each stencil has *_energy, *_gradient (returned) and *_gradient_hessian (gradient and projected
// Hessian written through Eigen::Ref, so that callers may pass a Map over their own buffers).
// Fixed-size Eigen types only; no allocation.
#pragma once

#include "kernels/barrier/barrier.hpp"
#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/projection/psd_projection.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>

namespace nexdyn {

// ---- closest features -------------------------------------------------------------------------

// The closest feature of a pair within its 4-point stencil (vertex-triangle: p, t0, t1, t2;
// edge-edge: ea0, ea1, eb0, eb1): the pair's squared distance is the point-point (n = 2),
// point-line (n = 3), point-plane or line-line (n = 4) distance of the stencil points
// idx[0..n), in that order.
struct ClosestFeature {
  int n;
  int idx[4];
};

inline ClosestFeature closest_feature(PointTriangleCase c) {
  switch (c) {
    case PointTriangleCase::p_t0: return {2, {0, 1}};
    case PointTriangleCase::p_t1: return {2, {0, 2}};
    case PointTriangleCase::p_t2: return {2, {0, 3}};
    case PointTriangleCase::p_e0: return {3, {0, 1, 2}};
    case PointTriangleCase::p_e1: return {3, {0, 2, 3}};
    case PointTriangleCase::p_e2: return {3, {0, 3, 1}};
    case PointTriangleCase::p_t: break;
  }
  return {4, {0, 1, 2, 3}};
}

inline ClosestFeature closest_feature(EdgeEdgeCase c) {
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return {2, {0, 2}};
    case EdgeEdgeCase::ea0_eb1: return {2, {0, 3}};
    case EdgeEdgeCase::ea1_eb0: return {2, {1, 2}};
    case EdgeEdgeCase::ea1_eb1: return {2, {1, 3}};
    case EdgeEdgeCase::ea_eb0: return {3, {2, 0, 1}};
    case EdgeEdgeCase::ea_eb1: return {3, {3, 0, 1}};
    case EdgeEdgeCase::ea0_eb: return {3, {0, 2, 3}};
    case EdgeEdgeCase::ea1_eb: return {3, {1, 2, 3}};
    case EdgeEdgeCase::ea_eb: break;
  }
  return {4, {0, 1, 2, 3}};
}

// ---- point against an analytic obstacle plane ---------------------------------------------------

// d = h^2 with h = (p - origin) . normal, |normal| = 1. The energy is +inf on or behind the plane
// (h <= 0: touching or crossed); the derivatives are those of b(h^2), meant for h > 0.
inline double point_obstacle_plane_barrier_energy(const Eigen::Vector3d& p, const Eigen::Vector3d& origin,
                                                  const Eigen::Vector3d& normal, double dhat2) {
  const double h = (p - origin).dot(normal);
  const double d = h > 0.0 ? h * h : 0.0;
  return d < dhat2 ? barrier(d, dhat2) : 0.0;
}

inline Eigen::Vector3d point_obstacle_plane_barrier_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& origin,
                                                             const Eigen::Vector3d& normal, double dhat2,
                                                             double weight) {
  const double h = (p - origin).dot(normal);
  const double b1 = weight * barrier_first_derivative(h * h, dhat2);
  return (2.0 * h * b1) * normal;
}

// The Hessian b'' g g^T + b' 2 n n^T = (4 h^2 b'' + 2 b') n n^T is rank one: projected by its sign.
inline void point_obstacle_plane_barrier_gradient_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& origin,
                                                          const Eigen::Vector3d& normal, double dhat2,
                                                          double weight, Eigen::Ref<Eigen::Vector3d> gradient,
                                                          Eigen::Ref<Eigen::Matrix3d> projected_hessian) {
  const double h = (p - origin).dot(normal);
  const double d = h * h;
  const double b1 = weight * barrier_first_derivative(d, dhat2);
  gradient = (2.0 * h * b1) * normal;
  const double b2 = weight * barrier_second_derivative(d, dhat2);
  const double lambda = std::max(0.0, 4.0 * d * b2 + 2.0 * b1);
  projected_hessian = lambda * normal * normal.transpose();
}

// ---- point-point --------------------------------------------------------------------------------

inline double point_point_barrier_energy(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double dhat2) {
  return barrier(point_point_distance(a, b), dhat2);
}

inline Vector6d point_point_barrier_gradient(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double dhat2,
                                             double weight) {
  const Eigen::Vector3d u = a - b;
  const double b1 = weight * barrier_first_derivative(u.squaredNorm(), dhat2);
  Vector6d gradient;
  gradient.head<3>() = 2.0 * b1 * u;
  gradient.tail<3>() = -2.0 * b1 * u;
  return gradient;
}

// With u = a - b the Hessian is [K -K; -K K], K = 4 b'' u u^T + 2 b' I, whose eigenvalues are
// twice K's (and 0): K has 4 b'' d + 2 b' along u and 2 b' across it, so the projection clamps
// those two numbers.
inline void point_point_barrier_gradient_hessian(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double dhat2,
                                                 double weight, Eigen::Ref<Vector6d> gradient,
                                                 Eigen::Ref<Matrix6d> projected_hessian) {
  const Eigen::Vector3d u = a - b;
  const double d = u.squaredNorm();
  const double b1 = weight * barrier_first_derivative(d, dhat2);
  gradient.head<3>() = 2.0 * b1 * u;
  gradient.tail<3>() = -2.0 * b1 * u;
  const double b2 = weight * barrier_second_derivative(d, dhat2);
  const double across = std::max(2.0 * b1, 0.0);
  const double along = std::max(4.0 * b2 * d + 2.0 * b1, 0.0);
  Eigen::Matrix3d K = ((along - across) / d) * u * u.transpose();
  K.diagonal().array() += across;
  projected_hessian << K, -K, -K, K;
}

// ---- affine closest features: point-line, point-plane, line-line --------------------------------

namespace detail {

// The gradient of w b(d) for an affine distance d = min_lambda |X (w0 + B lambda)|^2 of K points
// and M parameters (kernels/distance/distance_primitives.hpp): 2 w b' w_i r at point i. d is
// passed in from the closed-form distance, which is more accurate than |r|^2.
template <int K, int M>
Eigen::Matrix<double, 3 * K, 1> affine_barrier_gradient(const AffineMinimum<K, M>& m, double d, double dhat2,
                                                        double weight) {
  const double b1 = weight * barrier_first_derivative(d, dhat2);
  Eigen::Matrix<double, 3 * K, 1> gradient;
  for (int i = 0; i < K; ++i) gradient.template segment<3>(3 * i) = (2.0 * b1 * m.w(i)) * m.r;
  return gradient;
}

// The gradient and projected Hessian. The Hessian w (b'' g g^T + b' hess d) is V S V^T with
// V = [w (x) I3, B (x) r/|r|] (3K x (3 + M)): g = 2 w (x) r and
// hess d = 2 w w^T (x) I3 - G (D^T D)^-1 G^T / 2 with G = 2 (B (x) r + w (x) D) both lie in
// range(V), so it is zero outside that (3 + M)-dimensional subspace and its exact PSD projection
// is a (3 + M) x (3 + M) eigenproblem in an orthonormal basis Q = V L^-T of it (L L^T = V^T V),
// instead of a 3K x 3K one.
template <int K, int M>
void affine_barrier_gradient_hessian(const Eigen::Matrix<double, 3, K>& X, const Eigen::Matrix<double, K, 1>& w0,
                                     const Eigen::Matrix<double, K, M>& B, double d, double dhat2, double weight,
                                     Eigen::Ref<Eigen::Matrix<double, 3 * K, 1>> gradient,
                                     Eigen::Ref<Eigen::Matrix<double, 3 * K, 3 * K>> projected_hessian) {
  constexpr int R = 3 + M;
  using MatrixR = Eigen::Matrix<double, R, R>;
  const AffineMinimum<K, M> m = affine_minimum<K, M>(X, w0, B);
  const double b1 = weight * barrier_first_derivative(d, dhat2);
  for (int i = 0; i < K; ++i) gradient.template segment<3>(3 * i) = (2.0 * b1 * m.w(i)) * m.r;
  const double b2 = weight * barrier_second_derivative(d, dhat2);
  const double r_norm = m.r.norm();
  const Eigen::Vector3d r_hat = m.r / r_norm;
  Eigen::Matrix<double, 3 * K, R> V = Eigen::Matrix<double, 3 * K, R>::Zero();
  for (int i = 0; i < K; ++i) {
    V.template block<3, 3>(3 * i, 0).diagonal().setConstant(m.w(i));
    for (int k = 0; k < M; ++k) V.template block<3, 1>(3 * i, 3 + k) = B(i, k) * r_hat;
  }
  Eigen::Matrix<double, R, M> E;  // G = 2 V E
  E.template topRows<3>() = m.D;
  E.template bottomRows<M>() = r_norm * Eigen::Matrix<double, M, M>::Identity();
  MatrixR S = (-2.0 * b1) * E * m.A_inv * E.transpose();
  S.template topLeftCorner<3, 3>() += (4.0 * b2) * m.r * m.r.transpose();
  S.template topLeftCorner<3, 3>().diagonal().array() += 2.0 * b1;

  const Eigen::LLT<MatrixR> llt(V.transpose() * V);
  if (llt.info() != Eigen::Success) {  // V is full rank for d > 0; kept as a safety net
    Eigen::Matrix<double, 3 * K, 3 * K> full = V * S * V.transpose();
    full = 0.5 * (full + full.transpose()).eval();
    project_psd<3 * K>(full);
    projected_hessian = full;
    return;
  }
  const MatrixR L = llt.matrixL();
  MatrixR T = L.transpose() * S * L;
  T = 0.5 * (T + T.transpose()).eval();
  project_psd<R>(T);
  const Eigen::Matrix<double, 3 * K, R> Q = L.template triangularView<Eigen::Lower>().solve(V.transpose()).transpose();
  const Eigen::Matrix<double, 3 * K, R> QT = Q.lazyProduct(T);
  const Eigen::Matrix<double, 3 * K, 3 * K> full = QT.lazyProduct(Q.transpose());
  projected_hessian = 0.5 * (full + full.transpose());
}

}  // namespace detail

// Point p against the infinite line through e0, e1 (a point-edge closest feature).
inline double point_line_barrier_energy(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                        const Eigen::Vector3d& e1, double dhat2) {
  return barrier(point_line_distance(p, e0, e1), dhat2);
}

inline Vector9d point_line_barrier_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                            const Eigen::Vector3d& e1, double dhat2, double weight) {
  return detail::affine_barrier_gradient<3, 1>(
      detail::affine_minimum<3, 1>(detail::columns(p, e0, e1), detail::point_line_w0(), detail::point_line_B()),
      point_line_distance(p, e0, e1), dhat2, weight);
}

inline void point_line_barrier_gradient_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& e0,
                                                const Eigen::Vector3d& e1, double dhat2, double weight,
                                                Eigen::Ref<Vector9d> gradient, Eigen::Ref<Matrix9d> projected_hessian) {
  detail::affine_barrier_gradient_hessian<3, 1>(detail::columns(p, e0, e1), detail::point_line_w0(),
                                                detail::point_line_B(), point_line_distance(p, e0, e1), dhat2,
                                                weight, gradient, projected_hessian);
}

// Point p against the plane through t0, t1, t2 (a point-triangle interior).
inline double point_plane_barrier_energy(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                         const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, double dhat2) {
  return barrier(point_plane_distance(p, t0, t1, t2), dhat2);
}

inline Vector12d point_plane_barrier_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                              const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, double dhat2,
                                              double weight) {
  return detail::affine_barrier_gradient<4, 2>(
      detail::affine_minimum<4, 2>(detail::columns(p, t0, t1, t2), detail::point_plane_w0(),
                                   detail::point_plane_B()),
      point_plane_distance(p, t0, t1, t2), dhat2, weight);
}

inline void point_plane_barrier_gradient_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
                                                 const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, double dhat2,
                                                 double weight, Eigen::Ref<Vector12d> gradient,
                                                 Eigen::Ref<Matrix12d> projected_hessian) {
  detail::affine_barrier_gradient_hessian<4, 2>(detail::columns(p, t0, t1, t2), detail::point_plane_w0(),
                                                detail::point_plane_B(), point_plane_distance(p, t0, t1, t2),
                                                dhat2, weight, gradient, projected_hessian);
}

// The infinite lines through ea0, ea1 and eb0, eb1 (an edge-edge interior, not nearly parallel).
inline double line_line_barrier_energy(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                       const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double dhat2) {
  return barrier(line_line_distance(ea0, ea1, eb0, eb1), dhat2);
}

inline Vector12d line_line_barrier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                            const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double dhat2,
                                            double weight) {
  return detail::affine_barrier_gradient<4, 2>(
      detail::affine_minimum<4, 2>(detail::columns(ea0, ea1, eb0, eb1), detail::line_line_w0(),
                                   detail::line_line_B()),
      line_line_distance(ea0, ea1, eb0, eb1), dhat2, weight);
}

inline void line_line_barrier_gradient_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                               const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double dhat2,
                                               double weight, Eigen::Ref<Vector12d> gradient,
                                               Eigen::Ref<Matrix12d> projected_hessian) {
  detail::affine_barrier_gradient_hessian<4, 2>(detail::columns(ea0, ea1, eb0, eb1), detail::line_line_w0(),
                                                detail::line_line_B(), line_line_distance(ea0, ea1, eb0, eb1),
                                                dhat2, weight, gradient, projected_hessian);
}

// ---- nearly parallel edges: the mollified edge-edge barrier -------------------------------------

// Projects the Hessian H of a translation-invariant 4-point energy onto the PSD cone.
// Translation invariance means H (1 (x) I3) = 0: the three rigid translations of the stencil
// (all four points moved by one vector) are in H's null space, so in an orthonormal basis
// U (12 x 9) of their complement the projection is a 9x9 eigenproblem (about 2.4x cheaper than
// 12x12), and the translations keep their eigenvalue 0. For such an H the result is the exact PSD
// projection, and it annihilates translations too. H is left bit for bit as it is when it is PSD
// already (to a relative 1e-12 of its largest diagonal entry, in the basis U). H must be
// symmetric; its part along translations, if any, is dropped whenever it is projected.
void project_psd_translation_free(Matrix12d& H);

// E = w m(x) b(d(x)) for an edge-edge pair: d its squared distance by closest feature
// (edge_edge_distance.hpp), m the mollifier with threshold eps_x from the rest shape
// (edge_edge_mollifier.hpp). For nearly parallel edges, c = |ea x eb|^2 < eps_x, where m < 1.
inline double mollified_edge_edge_barrier_energy(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                 const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                                 double eps_x, double dhat2) {
  return barrier(edge_edge_distance(ea0, ea1, eb0, eb1), dhat2) * edge_edge_mollifier(ea0, ea1, eb0, eb1, eps_x);
}

// grad E = w (m b' grad d + b grad m), with d's closest feature classified at the given points.
// Out of line, as is the Hessian below (barrier_stencils.cpp): the product rule's roundings are
// then those of one compiled function, whatever the caller.
Vector12d mollified_edge_edge_barrier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                               const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x,
                                               double dhat2, double weight);
// The same with d's closest-feature case given: it must be edge_edge_case(ea0, ea1, eb0, eb1)
// (the contact active set keeps it from its own classification at the same points). Written
// into `gradient` (a stencil's slot in the caller's buffer: a returned vector went through the
// stack, and its stores could not be forwarded to the copy's wider loads).
void mollified_edge_edge_barrier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                          const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeCase ec,
                                          double eps_x, double dhat2, double weight, Eigen::Ref<Vector12d> gradient);

// hess E = w (m (b'' gd gd^T + b' hess d) + b' (gd gm^T + gm gd^T) + b hess m), projected with
// project_psd_translation_free; gd, gm: the gradients of d and m.
void mollified_edge_edge_barrier_gradient_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                  const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x,
                                                  double dhat2, double weight, Eigen::Ref<Vector12d> gradient,
                                                  Eigen::Ref<Matrix12d> projected_hessian);
// The same with the case given, as for the gradient.
void mollified_edge_edge_barrier_gradient_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                  const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                                  EdgeEdgeCase ec, double eps_x, double dhat2, double weight,
                                                  Eigen::Ref<Vector12d> gradient,
                                                  Eigen::Ref<Matrix12d> projected_hessian);

}  // namespace nexdyn

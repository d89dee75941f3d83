// Signed ("rotation-variant") SVD of a 3x3 deformation gradient, for per-tet hot loops; lane-wise
// (T = double or Double4, kernels/projection/simd4.hpp).
//
// F = U diag(sigma) V^T with U, V proper rotations (det = +1) and sigma_0 >= sigma_1 >= |sigma_2|;
// sigma_2 < 0 exactly when det F < 0. This is the convention of Irving, Teran & Fedkiw 2004
// ("Invertible finite elements") and Teran et al. 2005: isotropic energies written in sigma stay
// smooth through inversion, and the corotated rotation R = U V^T is always a proper rotation.
//
// Fast path (no iteration, no branch):
//   1. V and sigma^2 from the eigen-decomposition of F^T F (kernels/projection/sym_eigen3.hpp).
//   2. U from a Gram-Schmidt QR of B = F V: u0 = b0/|b0|, u1 = the part of b1 orthogonal to u0,
//      u2 = u0 x u1. The diagonal of R = U^T F V gives sigma, including the sign of sigma_2 (u2 is
//      forced right-handed, so sigma_2 = u2 . b2 carries the sign of det F). Computing sigma from
//      F V rather than as sqrt(eigenvalues) keeps small singular values accurate.
//   3. The off-diagonal of R is exactly what U diag(sigma) V^T misses of F. Errors of V inside a
//      cluster of nearly equal singular values barely show there (they are multiplied by the
//      cluster's width), which is why squaring F is acceptable. Where the off-diagonal exceeds
//      kSvdResidualTolerance * sigma_0 (two tiny singular values, say, or |F| outside ~1e+-150),
//      that lane is redone by the rare fallback: Eigen::JacobiSVD (one-sided Jacobi, accurate to
//      the last bit) with its signs fixed.
#pragma once

#include "kernels/projection/mat3.hpp"
#include "kernels/projection/simd4.hpp"
#include "kernels/projection/sym_eigen3.hpp"

#include <Eigen/Core>

namespace nexdyn {

template <typename T>
struct SignedSvd {
  Mat3<T> U;      // rotation, det = +1
  Vec3<T> sigma;  // signed singular values, sigma[0] >= sigma[1] >= |sigma[2]|
  Mat3<T> V;      // rotation, det = +1
};

// Eigen form of the same, for the element layer's callers and tests.
struct Svd3 {
  Eigen::Matrix3d U;
  Eigen::Vector3d sigma;
  Eigen::Matrix3d V;
};

// Relative size of the off-diagonal of U^T F V above which the fast path is rejected.
inline constexpr double kSvdResidualTolerance = 1e-13;

// Slow, accurate path (Eigen::JacobiSVD plus sign fix-up). Kept out of line: it is cold code.
// Non-finite F gives NaN everywhere.
void svd3_jacobi(const Eigen::Matrix3d& F, Svd3& out);

namespace detail {

inline void svd3_jacobi_lane(const Mat3<double>& F, SignedSvd<double>& out) {
  Svd3 s;
  svd3_jacobi(to_eigen(F), s);
  out = {to_mat3(s.U), to_vec3(s.sigma), to_mat3(s.V)};
}

// Redoes the lanes outside `keep` with the Jacobi SVD.
inline void svd3_repair_lanes(bool keep, const Mat3<double>& F, SignedSvd<double>& out) {
  if (!keep) svd3_jacobi_lane(F, out);
}
inline void svd3_repair_lanes(Mask4 keep, const Mat3<Double4>& F, SignedSvd<Double4>& out) {
  for (int l = 0; l < 4; ++l) {
    if (keep[l]) continue;
    Mat3<double> Fl;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) Fl(r, c) = F(r, c)[l];
    SignedSvd<double> sl;
    svd3_jacobi_lane(Fl, sl);
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r) {
        out.U(r, c)[l] = sl.U(r, c);
        out.V(r, c)[l] = sl.V(r, c);
      }
    for (int i = 0; i < 3; ++i) out.sigma[i][l] = sl.sigma[i];
  }
}

}  // namespace detail

// Signed SVD of F, lane-wise. Returns the lanes that took the fast path (for tests and
// statistics; the result is valid either way).
template <typename T>
inline simd::MaskOf<T> signed_svd(const Mat3<T>& F, SignedSvd<T>& out) {
  using simd::select;
  Vec3<T> eigenvalues;  // of F^T F, ascending
  Mat3<T> eigenvectors;
  sym_eigen3(transpose_times(F, F), eigenvalues, eigenvectors);

  // Descending order; V right-handed by construction of its last column.
  Mat3<T>& V = out.V;
  V.col[0] = eigenvectors.col[2];
  V.col[1] = eigenvectors.col[1];
  V.col[2] = cross(V.col[0], V.col[1]);

  const Mat3<T> B = F * V;
  const T zero = simd::splat<T>(0.0), one = simd::splat<T>(1.0);
  const T sigma0 = simd::sqrt(squared_norm(B.col[0]));
  // F == 0: every rotation is a valid U; start from e_x (the division below gives NaN there).
  Mat3<T>& U = out.U;
  U.col[0] = select(sigma0 > 0.0, B.col[0] * (1.0 / sigma0), Vec3<T>{{one, zero, zero}});
  const T r01 = dot(U.col[0], B.col[1]);
  const Vec3<T> w = B.col[1] - U.col[0] * r01;
  const T sigma1 = simd::sqrt(squared_norm(w));
  // Rank <= 1: the direction of u1 is arbitrary, any unit vector orthogonal to u0 will do.
  U.col[1] = select(sigma1 > 1e-200 * sigma0, w * (1.0 / sigma1),
                    detail::any_unit_orthogonal(U.col[0]));
  U.col[2] = cross(U.col[0], U.col[1]);
  const T r02 = dot(U.col[0], B.col[2]);
  const T r12 = dot(U.col[1], B.col[2]);
  out.sigma = {{sigma0, sigma1, dot(U.col[2], B.col[2])}};

  // NaN residuals (non-finite F) also fail the test and go to the fallback, which returns NaN.
  const T residual = simd::abs(r01) + simd::abs(r02) + simd::abs(r12);
  const auto fast = residual <= kSvdResidualTolerance * sigma0;
  if (!simd::all(fast)) detail::svd3_repair_lanes(fast, F, out);
  return fast;
}

// Eigen interface. Returns false when the fallback was used.
inline bool svd3(const Eigen::Matrix3d& F, Svd3& out) {
  SignedSvd<double> s;
  const bool fast = signed_svd(to_mat3(F), s);
  out = {to_eigen(s.U), to_eigen(s.sigma), to_eigen(s.V)};
  return fast;
}

}  // namespace nexdyn

// Eigen-decomposition of a symmetric 3x3 matrix, branch-free so that four can run side by side in
// SIMD lanes (T = double or Double4, see simd4.hpp), and accurate for repeated eigenvalues.
//
// Used by the 3x3 SVD (eigenvectors of F^T F, kernels/elasticity/svd3.hpp), by the PSD projection
// of 3x3 blocks (psd_projection.hpp) and through them by the elastic Hessian.
//
// Method (closed form + one exact 2x2 rotation, in the spirit of D. Eberly, "A Robust Eigensolver
// for 3x3 Symmetric Matrices", Geometric Tools 2014):
//   1. Shift by tr(A)/3 and scale by the largest entry: B = (A - shift I) / scale is traceless with
//      entries in [-1, 1] (no overflow) and eigenvalues spread over O(1) whatever A's magnitude.
//   2. The eigenvalues are 2 p cos(phi + 2 pi k / 3), p^2 = tr(B^2)/6, cos(3 phi) = r =
//      det(B)/(2 p^3). Only the most isolated one is used: the largest if r >= 0, else the
//      smallest; it is sign(r) 2 p c with c = cos(acos|r| / 3), the largest root of
//      4 c^3 - 3 c = |r|. Instead of acos and cos (slow, and no SIMD version in libm), c comes
//      from a cubic Hermite guess (error < 3e-4 on [0, 1]) and two Halley steps (error <= 1 ulp).
//      Near a double root the close pair is ill-determined by this formula, the isolated root is
//      not: its eigenvalue is at least ~0.7 away from the others after scaling.
//   3. Its eigenvector is the largest cross product of two rows of B - t I (rank 2, well
//      conditioned because of that gap).
//   4. The remaining pair is the eigen-decomposition of the 2x2 restriction of B to the plane
//      orthogonal to that vector, by one Jacobi rotation: exact for equal or clustered
//      eigenvalues, where closed-form eigenvector formulas break down.
// Eigen's SelfAdjointEigenSolver::computeDirect uses steps 1-3 for all three vectors and in Eigen
// 3.4 returns non-orthogonal vectors when two eigenvalues coincide; hence this file.
#pragma once

#include "kernels/projection/mat3.hpp"
#include "kernels/projection/simd4.hpp"

#include <Eigen/Core>

#include <limits>

namespace nexdyn {

namespace detail {

// Unit vector orthogonal to the unit vector v, built from its two largest components so the
// normalisation never divides by a small number.
template <typename T>
inline Vec3<T> any_unit_orthogonal(const Vec3<T>& v) {
  using simd::select;
  const T zero = simd::splat<T>(0.0);
  const auto x_larger = simd::abs(v[0]) > simd::abs(v[1]);
  const T inv_xz = 1.0 / simd::sqrt(v[0] * v[0] + v[2] * v[2]);
  const T inv_yz = 1.0 / simd::sqrt(v[1] * v[1] + v[2] * v[2]);
  const Vec3<T> from_xz{{-v[2] * inv_xz, zero, v[0] * inv_xz}};
  const Vec3<T> from_yz{{zero, v[2] * inv_yz, -v[1] * inv_yz}};
  return select(x_larger, from_xz, from_yz);
}

// c = cos(acos(s) / 3) for s in [0, 1]: the largest root of f(c) = 4 c^3 - 3 c - s.
template <typename T>
inline T cos_third_acos(const T& s) {
  // Cubic Hermite interpolation of c(s) between c(0) = sqrt(3)/2, c(1) = 1 with slopes
  // c'(0) = 1/6, c'(1) = 1/9 (dc/ds = 1 / f'(c)); max error 2.7e-4.
  constexpr double kC0 = 0.86602540378443864676, kC1 = 1.0, kD0 = 1.0 / 6.0, kD1 = 1.0 / 9.0;
  const T s2 = s * s, s3 = s2 * s;
  T c = (2.0 * s3 - 3.0 * s2 + 1.0) * kC0 + (s3 - 2.0 * s2 + s) * kD0 +
        (3.0 * s2 - 2.0 * s3) * kC1 + (s3 - s2) * kD1;
  // Halley's method, cubic convergence: 2.7e-4 -> 3e-11 -> 1 ulp. f' >= 6 on the branch.
  for (int step = 0; step < 2; ++step) {
    const T f = (4.0 * c * c - 3.0) * c - s;
    const T df = 12.0 * c * c - 3.0;
    const T ddf = 24.0 * c;
    c = c - (2.0 * f * df) / (2.0 * df * df - f * ddf);
  }
  return c;
}

// Sorts (lambda_i, v_i) so that lambda_i <= lambda_j, lane by lane.
template <typename T>
inline void order_pair(T& li, Vec3<T>& vi, T& lj, Vec3<T>& vj) {
  const auto swap = lj < li;
  const T l_lo = simd::select(swap, lj, li), l_hi = simd::select(swap, li, lj);
  const Vec3<T> v_lo = select(swap, vj, vi), v_hi = select(swap, vi, vj);
  li = l_lo;
  lj = l_hi;
  vi = v_lo;
  vj = v_hi;
}

}  // namespace detail

// Eigenvalues of the symmetric matrix A (only its upper triangle is read) in ascending order, and
// orthonormal eigenvectors as the columns of `vectors`, right-handed (det = +1).
// Accuracy: V diag(values) V^T reproduces A to a few ulps of max|A - tr(A)/3 I| + |tr(A)|/3.
// Non-finite input (or entries large enough for their sum to overflow) gives NaN.
template <typename T>
inline void sym_eigen3(const Mat3<T>& A, Vec3<T>& values, Mat3<T>& vectors) {
  using simd::select;
  const T shift = (A(0, 0) + A(1, 1) + A(2, 2)) * (1.0 / 3.0);
  T b00 = A(0, 0) - shift, b11 = A(1, 1) - shift, b22 = A(2, 2) - shift;
  T b01 = A(0, 1), b02 = A(0, 2), b12 = A(1, 2);
  const auto finite = simd::is_finite(shift + b01 + b02 + b12);
  const T scale = simd::max(simd::max(simd::max(simd::abs(b00), simd::abs(b11)),
                                      simd::max(simd::abs(b22), simd::abs(b01))),
                            simd::max(simd::abs(b02), simd::abs(b12)));
  const auto multiple_of_identity = scale == 0.0;
  // Lanes excluded above still run the arithmetic (on a harmless scale of 1) and are overwritten
  // at the end.
  const T inv_scale = 1.0 / select(multiple_of_identity, simd::splat<T>(1.0), scale);
  b00 = b00 * inv_scale, b11 = b11 * inv_scale, b22 = b22 * inv_scale;
  b01 = b01 * inv_scale, b02 = b02 * inv_scale, b12 = b12 * inv_scale;

  // Isolated root (step 2). After scaling tr(B^2) >= 1, so p >= 0.4.
  const T p2 = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (b01 * b01 + b02 * b02 + b12 * b12)) *
               (1.0 / 6.0);
  const T p = simd::sqrt(p2);
  const T det_b = b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) +
                  b02 * (b01 * b12 - b11 * b02);
  const T r = det_b / (2.0 * p2 * p);
  const T c = detail::cos_third_acos(simd::min(simd::abs(r), simd::splat<T>(1.0)));
  const T t_isolated = select(r < 0.0, -2.0 * p * c, 2.0 * p * c);

  // Its eigenvector (step 3): rows of B - t I span the plane orthogonal to it.
  const Vec3<T> r0{{b00 - t_isolated, b01, b02}};
  const Vec3<T> r1{{b01, b11 - t_isolated, b12}};
  const Vec3<T> r2{{b02, b12, b22 - t_isolated}};
  Vec3<T> v = cross(r0, r1);
  T n = squared_norm(v);
  const Vec3<T> c02 = cross(r0, r2), c12 = cross(r1, r2);
  const T n02 = squared_norm(c02), n12 = squared_norm(c12);
  const auto take02 = n02 > n;
  v = select(take02, c02, v);
  n = select(take02, n02, n);
  const auto take12 = n12 > n;
  v = select(take12, c12, v);
  n = select(take12, n12, n);
  v = v * (1.0 / simd::sqrt(n));

  // The other two (step 4): B restricted to span(e0, e1), diagonalised by one Jacobi rotation
  // (Numerical Recipes' stable tangent: |t| <= 1, no cancellation).
  const Vec3<T> e0 = detail::any_unit_orthogonal(v);
  const Vec3<T> e1 = cross(v, e0);
  const Vec3<T> Be0{{b00 * e0[0] + b01 * e0[1] + b02 * e0[2],
                     b01 * e0[0] + b11 * e0[1] + b12 * e0[2],
                     b02 * e0[0] + b12 * e0[1] + b22 * e0[2]}};
  const Vec3<T> Be1{{b00 * e1[0] + b01 * e1[1] + b02 * e1[2],
                     b01 * e1[0] + b11 * e1[1] + b12 * e1[2],
                     b02 * e1[0] + b12 * e1[1] + b22 * e1[2]}};
  const T m00 = dot(e0, Be0), m01 = dot(e0, Be1), m11 = dot(e1, Be1);
  const T theta = (m11 - m00) / (2.0 * m01);
  // theta = +-inf or NaN when m01 == 0 (already diagonal): t = 0 then. For huge finite theta,
  // theta^2 overflows to inf and t correctly becomes 0.
  T t = select(theta < 0.0, simd::splat<T>(-1.0), simd::splat<T>(1.0)) /
        (simd::abs(theta) + simd::sqrt(theta * theta + 1.0));
  t = select(m01 == 0.0, simd::splat<T>(0.0), t);
  const T cs = 1.0 / simd::sqrt(t * t + 1.0), sn = t * cs;

  T l0 = t_isolated, l1 = m00 - t * m01, l2 = m11 + t * m01;
  Vec3<T> v0 = v, v1 = e0 * cs - e1 * sn, v2 = e0 * sn + e1 * cs;
  detail::order_pair(l0, v0, l1, v1);
  detail::order_pair(l1, v1, l2, v2);
  detail::order_pair(l0, v0, l1, v1);

  values = {{l0 * scale + shift, l1 * scale + shift, l2 * scale + shift}};
  // The third vector is fixed up to sign by orthogonality; the cross product makes the basis
  // right-handed, which the SVD relies on (V must be a rotation).
  vectors = {{v0, v1, cross(v0, v1)}};

  const T shift_lanes = shift;
  values = select(multiple_of_identity, Vec3<T>{{shift_lanes, shift_lanes, shift_lanes}}, values);
  vectors = select(multiple_of_identity, identity3<T>(), vectors);
  const T nan = simd::splat<T>(std::numeric_limits<double>::quiet_NaN());
  values = select(finite, values, Vec3<T>{{nan, nan, nan}});
  vectors =
      select(finite, vectors, Mat3<T>{{{{nan, nan, nan}}, {{nan, nan, nan}}, {{nan, nan, nan}}}});
}

// Eigen interface (one matrix).
inline void sym_eigen3(const Eigen::Matrix3d& A, Eigen::Vector3d& values,
                       Eigen::Matrix3d& vectors) {
  Vec3<double> l;
  Mat3<double> v;
  sym_eigen3(to_mat3(A), l, v);
  values = to_eigen(l);
  vectors = to_eigen(v);
}

}  // namespace nexdyn

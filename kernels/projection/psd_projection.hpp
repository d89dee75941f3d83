// Projection of small symmetric matrices onto the positive semi-definite cone.
//
// Newton's method on the incremental potential (IPC, Li et al. 2020, sec. 5; seed 004 "IPC")
// needs a positive semi-definite Hessian so that the Newton direction is a descent direction.
// Per-element Hessians (contact stencils 6x6..12x12, elastic 9x9 in F-space) are made PSD before
// assembly by clamping negative eigenvalues: A+ = Q max(Lambda, 0) Q^T, the nearest PSD matrix in
// the Frobenius norm. Elastic tets use the cheaper analytic eigensystem (kernels/elasticity/); this
// brute-force version is the reference for it and the tool for stencils without a known
// eigensystem. psd_factor3 (3x3 blocks, lane-wise) returns a factor L with L L^T = A+ instead.
//
// project_psd takes fixed-size Eigen types only: SelfAdjointEigenSolver on them does not allocate.
#pragma once

#include "kernels/projection/sym_eigen3.hpp"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace nexdyn {

// Replaces the symmetric matrix A (both triangles must hold the same values) by its nearest PSD
// matrix, clamping eigenvalues below `min_eigenvalue` (>= 0) to it. Returns the number of clamped
// eigenvalues; when it is 0, A is left bit-for-bit untouched, so an already PSD Hessian keeps its
// exact values. The result is exactly symmetric.
template <int N>
int project_psd(Eigen::Matrix<double, N, N>& A, double min_eigenvalue = 0.0) {
  using Matrix = Eigen::Matrix<double, N, N>;
  using Vector = Eigen::Matrix<double, N, 1>;
  Vector values;
  Matrix vectors;
  if constexpr (N == 3) {
    sym_eigen3(A, values, vectors);  // closed form: ~5x faster than the QR iteration
  } else {
    Eigen::SelfAdjointEigenSolver<Matrix> solver(A);
    values = solver.eigenvalues();
    vectors = solver.eigenvectors();
  }
  int clamped = 0;
  for (int i = 0; i < N; ++i) {
    if (values[i] < min_eigenvalue) {
      values[i] = min_eigenvalue;
      ++clamped;
    }
  }
  if (clamped == 0) return 0;
  // Q diag(l) Q^T is symmetric only up to rounding; average with the transpose so downstream
  // code that reads one triangle (CHOLMOD) and code that reads both see the same matrix.
  const Matrix projected = vectors * values.asDiagonal() * vectors.transpose();
  A = 0.5 * (projected + projected.transpose());
  return clamped;
}

// The eigenvalues (ascending) and eigenvectors (columns, when asked for) of a symmetric matrix of
// any size, for tests and diagnostics. Eigen's dynamic-size solver, compiled once in
// psd_projection.cpp: every fixed size a test instantiated cost that test file about a minute of
// compiling (the solver's unrolled triangular loops), and these callers do not need the speed.
struct SymmetricEigen {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;  // empty unless asked for
};
SymmetricEigen symmetric_eigen(const Eigen::Ref<const Eigen::MatrixXd>& A, bool with_vectors = true);

// Smallest eigenvalue of a symmetric matrix (for tests and diagnostics).
template <int N>
double min_eigenvalue(const Eigen::Matrix<double, N, N>& A) {
  if constexpr (N == 3) {
    Eigen::Vector3d values;
    Eigen::Matrix3d vectors;
    sym_eigen3(A, values, vectors);
    return values[0];
  } else {
    return symmetric_eigen(A, false).values[0];
  }
}

// True when the symmetric matrix A shifted by shift = rel_tol * max_i A_ii has a Cholesky factor,
// so that (up to the rounding of the factorisation) no eigenvalue of A is below -shift. A cheap
// test, N^3 / 6 multiply-adds instead of an eigendecomposition, for callers whose matrices are
// often PSD already: such a matrix can be kept as it is.
template <int N>
bool cholesky_psd_test(const Eigen::Matrix<double, N, N>& A, double rel_tol) {
  double max_diagonal = 0.0;
  for (int i = 0; i < N; ++i) max_diagonal = std::max(max_diagonal, A(i, i));
  const double shift = rel_tol * max_diagonal;
  if (!(shift > 0.0)) return false;  // no positive diagonal, or NaN: leave it to the projection
  // Column-oriented Cholesky of A + shift I into the lower triangle of L.
  Eigen::Matrix<double, N, N> L;
  for (int j = 0; j < N; ++j) {
    double pivot = A(j, j) + shift;
    for (int k = 0; k < j; ++k) pivot -= L(j, k) * L(j, k);
    if (!(pivot > 0.0)) return false;
    const double root = std::sqrt(pivot);
    L(j, j) = root;
    for (int i = j + 1; i < N; ++i) {
      double value = A(i, j);
      for (int k = 0; k < j; ++k) value -= L(i, k) * L(j, k);
      L(i, j) = value / root;
    }
  }
  return true;
}

// True when every eigenvalue of the symmetric matrix A is >= -rel_tol * max|eigenvalue|.
template <int N>
bool is_psd(const Eigen::Matrix<double, N, N>& A, double rel_tol = 1e-10) {
  const Eigen::VectorXd values = symmetric_eigen(A, false).values;
  const double largest = std::max(std::abs(values[0]), std::abs(values[N - 1]));
  return values[0] >= -rel_tol * largest;
}

// A factor L with L L^T = A+, the PSD projection of the symmetric 3x3 matrix A, lane-wise
// (T = double or Double4). Writing the projected matrix as a product of factors keeps assembled
// Hessians PSD and exactly symmetric (kernels/elasticity/analytic_eigensystem.hpp). When A is
// positive definite (every Cholesky pivot > 0, the common case) L is its Cholesky factor, three
// square roots; lanes where it is not get L = Q diag(sqrt(max(lambda, 0))) from sym_eigen3.
template <typename T>
inline Mat3<T> psd_factor3(const Mat3<T>& A) {
  const T zero = simd::splat<T>(0.0);
  Mat3<T> L{{{{zero, zero, zero}}, {{zero, zero, zero}}, {{zero, zero, zero}}}};
  // Failed pivots produce inf/NaN in their lanes; those lanes are replaced below.
  L(0, 0) = simd::sqrt(A(0, 0));
  const T inv00 = 1.0 / L(0, 0);
  L(1, 0) = A(1, 0) * inv00;
  L(2, 0) = A(2, 0) * inv00;
  const T pivot1 = A(1, 1) - L(1, 0) * L(1, 0);
  L(1, 1) = simd::sqrt(pivot1);
  L(2, 1) = (A(2, 1) - L(2, 0) * L(1, 0)) / L(1, 1);
  const T pivot2 = A(2, 2) - L(2, 0) * L(2, 0) - L(2, 1) * L(2, 1);
  L(2, 2) = simd::sqrt(pivot2);
  const auto positive_definite = (A(0, 0) > 0.0) & (pivot1 > 0.0) & (pivot2 > 0.0);
  if (simd::all(positive_definite)) return L;
  Vec3<T> values;
  Mat3<T> vectors;
  sym_eigen3(A, values, vectors);
  Mat3<T> L_eigen;
  for (int k = 0; k < 3; ++k)
    L_eigen.col[k] = vectors.col[k] * simd::sqrt(simd::max(values[k], zero));
  return select(positive_definite, L, L_eigen);
}

inline Eigen::Matrix3d psd_factor3(const Eigen::Matrix3d& A) {
  return to_eigen(psd_factor3(to_mat3(A)));
}

// The sizes the contact stencils (and their tests) use are compiled once, in psd_projection.cpp: a fixed-size
// SelfAdjointEigenSolver is slow to compile (several minutes under the sanitizers per file that
// instantiates it), and a call costs nothing next to a 9x9 or 12x12 eigendecomposition.
extern template int project_psd<4>(Eigen::Matrix<double, 4, 4>&, double);
extern template int project_psd<5>(Eigen::Matrix<double, 5, 5>&, double);
extern template int project_psd<6>(Eigen::Matrix<double, 6, 6>&, double);
extern template int project_psd<9>(Eigen::Matrix<double, 9, 9>&, double);
extern template int project_psd<12>(Eigen::Matrix<double, 12, 12>&, double);

}  // namespace nexdyn

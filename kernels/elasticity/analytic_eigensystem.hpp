// PSD projection of the elastic Hessian through the analytic eigensystem of isotropic energies.
//
// For Psi(F) = Psi(sigma) (stvk, corotated, neohookean) the nine eigenvectors of dP/dF are known
// in closed form in the SVD frame F = U Sigma V^T (Teran, Sifakis, Irving & Fedkiw 2005, "Robust
// quasistatic finite elements and flesh simulation"; Smith, de Goes & Kim 2019, "Analytic
// eigensystems for isotropic distortion energies"):
//   scaling  Q = U diag(q) V^T, q an eigenvector of the 3x3 d2Psi/dsigma^2
//   flip     Q = U (e_i e_j^T + e_j e_i^T) V^T / sqrt 2, eigenvalue flip_ij
//   twist    Q = U (e_i e_j^T - e_j e_i^T) V^T / sqrt 2, eigenvalue twist_ij
// (eigenvalues from singular_value_derivatives, energy_density.hpp). Clamping the eigenvalues
// at zero gives the nearest PSD dP/dF without a 9x9 eigensolver.
//
// The tet Hessian is V B^T (dP/dF)+ B with B = dvec(F)/dx (9x12). Instead of forming B, every
// mode is mapped to x-space directly: B^T vec(u v^T) = u (x) (D v), where D (4x3) holds the shape
// function gradients (rows 1..3 = rows of Dm^-1, row 0 = minus their sum). With
// W = D V (4x3, one product per tet) a mode costs one or two 12-entry outer products. Each mode
// is scaled by sqrt(V eigenvalue), giving a 12x9 factor G with H = G G^T: the result is PSD and,
// computed as one triangle and mirrored, exactly symmetric.
//
// The tet-level functions are lane-wise (T = double or Double4); the 9x9 F-space matrices, for
// tests and rare callers, use Eigen.
#pragma once

#include "kernels/elasticity/energy_density.hpp"
#include "kernels/elasticity/svd3.hpp"
#include "kernels/projection/mat3.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "kernels/projection/simd4.hpp"

#include <Eigen/Core>

namespace nexdyn {

using Vector12d = Eigen::Matrix<double, 12, 1>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;
using Matrix43d = Eigen::Matrix<double, 4, 3>;

// ------------------------------------------------------------------------------------------------
// F-space (Eigen, one matrix)

namespace detail {

// vec(u v^T) for 3-vectors.
inline Vector9d outer9(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  Vector9d q;
  for (int b = 0; b < 3; ++b)
    for (int a = 0; a < 3; ++a) q[a + 3 * b] = u[a] * v[b];
  return q;
}

}  // namespace detail

// dP/dF from the eigensystem: exact when kProject is false, PSD-projected when true.
template <bool kProject>
inline Matrix9d isotropic_pk1_derivative(const Svd3& svd,
                                         const SingularValueDerivatives<double>& d) {
  const Eigen::Matrix3d& U = svd.U;
  const Eigen::Matrix3d& V = svd.V;
  Eigen::Matrix<double, 9, 3> S;  // scaling modes vec(u_m v_m^T)
  for (int m = 0; m < 3; ++m) S.col(m) = detail::outer9(U.col(m), V.col(m));
  Matrix9d H;
  if constexpr (kProject) {
    const Eigen::Matrix<double, 9, 3> SL = S * psd_factor3(to_eigen(d.d2psi));
    H.noalias() = SL * SL.transpose();
  } else {
    H.noalias() = S * to_eigen(d.d2psi) * S.transpose();
  }
  for (int p = 0; p < 3; ++p) {
    const int i = kSigmaPairs[p][0], j = kSigmaPairs[p][1];
    const Vector9d a = detail::outer9(U.col(i), V.col(j));
    const Vector9d b = detail::outer9(U.col(j), V.col(i));
    const double flip = kProject ? std::max(d.flip[p], 0.0) : d.flip[p];
    const double twist = kProject ? std::max(d.twist[p], 0.0) : d.twist[p];
    // 0.5 = (1/sqrt 2)^2, the normalisation of the flip and twist modes.
    H.noalias() += (0.5 * flip) * (a + b) * (a + b).transpose();
    H.noalias() += (0.5 * twist) * (a - b) * (a - b).transpose();
  }
  return H;
}

// ------------------------------------------------------------------------------------------------
// Tet level, lane-wise

// Shape-function gradients: dF = sum_k dx_k D_k^T with D_k = row k of D (4x3); rows 1..3 are the
// rows of Dm^-1, row 0 minus their sum (a translation leaves F unchanged). Stored as 4 rows.
template <typename T>
inline void shape_gradients(const Mat3<T>& Dm_inv, Vec3<T> D[4]) {
  for (int k = 1; k < 4; ++k) D[k] = {{Dm_inv(k - 1, 0), Dm_inv(k - 1, 1), Dm_inv(k - 1, 2)}};
  D[0] = -(D[1] + D[2] + D[3]);
}

// The 12x9 factor G (9 columns of 12) of the projected tet Hessian, H = G G^T = V B^T (dP/dF)+ B.
template <typename T>
inline void projected_tet_hessian_factor(const SignedSvd<T>& svd,
                                         const SingularValueDerivatives<T>& d,
                                         const Mat3<T>& Dm_inv, const T& volume, T G[9][12]) {
  // W = D V (4x3): w[k][m] = D_k . v_m; row 0 is minus the sum of the others.
  T w[4][3];
  for (int k = 1; k < 4; ++k)
    for (int m = 0; m < 3; ++m)
      w[k][m] = Dm_inv(k - 1, 0) * svd.V(0, m) + Dm_inv(k - 1, 1) * svd.V(1, m) +
                Dm_inv(k - 1, 2) * svd.V(2, m);
  for (int m = 0; m < 3; ++m) w[0][m] = -(w[1][m] + w[2][m] + w[3][m]);
  const Mat3<T>& U = svd.U;

  // Scaling modes: column m of (u_n (x) w_n) L, L L^T = V (d2Psi/dsigma^2)+.
  const Mat3<T> L = psd_factor3(d.d2psi) * simd::sqrt(volume);
  for (int m = 0; m < 3; ++m)
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a)
        G[m][3 * k + a] = U(a, 0) * w[k][0] * L(0, m) + U(a, 1) * w[k][1] * L(1, m) +
                          U(a, 2) * w[k][2] * L(2, m);

  // Flip and twist modes of pair (i, j): (u_i (x) w_j +/- u_j (x) w_i) sqrt(V max(l, 0) / 2).
  const T zero = simd::splat<T>(0.0);
  for (int p = 0; p < 3; ++p) {
    const int i = kSigmaPairs[p][0], j = kSigmaPairs[p][1];
    const T s_flip = simd::sqrt(0.5 * volume * simd::max(d.flip[p], zero));
    const T s_twist = simd::sqrt(0.5 * volume * simd::max(d.twist[p], zero));
    for (int k = 0; k < 4; ++k)
      for (int a = 0; a < 3; ++a) {
        const T ab = U(a, i) * w[k][j], ba = U(a, j) * w[k][i];
        G[3 + p][3 * k + a] = s_flip * (ab + ba);
        G[6 + p][3 * k + a] = s_twist * (ab - ba);
      }
  }
}

// Copies the upper triangle of the column-major 12x12 H onto its lower triangle.
template <typename T>
inline void mirror_upper_to_lower(T H[144]) {
  for (int j = 0; j < 12; ++j)
    for (int i = j + 1; i < 12; ++i) H[i + 12 * j] = H[j + 12 * i];
}

// H = G G^T (column-major 12x12). Only the upper triangle is summed, then mirrored: exactly
// symmetric, and 78 instead of 144 dot products.
template <typename T>
inline void symmetric_product(const T G[9][12], T H[144]) {
  for (int j = 0; j < 12; ++j)
    for (int i = 0; i <= j; ++i) {
      T sum = G[0][i] * G[0][j];
      for (int m = 1; m < 9; ++m) sum = sum + G[m][i] * G[m][j];
      H[i + 12 * j] = sum;
    }
  mirror_upper_to_lower(H);
}

// ------------------------------------------------------------------------------------------------
// Reference (Eigen): V B^T H9 B for any 9x9 H9 (exact Hessians in tests).

inline Matrix43d shape_gradients(const Eigen::Matrix3d& Dm_inv) {
  Matrix43d D;
  D.bottomRows<3>() = Dm_inv;
  D.row(0) = -Dm_inv.colwise().sum();
  return D;
}

inline Matrix12d tet_hessian_from_pk1_derivative(const Matrix9d& H9, const Eigen::Matrix3d& Dm_inv,
                                                 double volume) {
  const Matrix43d D = shape_gradients(Dm_inv);
  Eigen::Matrix<double, 9, 12> B = Eigen::Matrix<double, 9, 12>::Zero();
  for (int k = 0; k < 4; ++k)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) B(a + 3 * b, 3 * k + a) = D(k, b);
  return volume * (B.transpose() * H9 * B);
}

}  // namespace nexdyn

// Hyperelastic energy densities Psi(F), first Piola-Kirchhoff stress P = dPsi/dF and its exact
// derivative dP/dF for the four material models of seed 004 ("弹性能量模型"; Sifakis & Barbic,
// "FEM simulation of 3D deformable solids", SIGGRAPH 2012 course):
//   linear      Psi = mu tr(eps^2) + lambda/2 tr(eps)^2,        eps = (F + F^T)/2 - I
//   stvk        Psi = mu tr(E^2) + lambda/2 tr(E)^2,            E = (F^T F - I)/2
//   corotated   Psi = mu ||F - R||^2 + lambda/2 tr(R^T F - I)^2, F = R S, R from the signed SVD
//   neohookean  Psi = mu/2 (tr(F^T F) - 3) - mu ln J + lambda/2 (ln J)^2, J = det F;
//               Psi = +inf for J <= 0, so a line search never accepts an inverted tet.
// For the three rotation-invariant isotropic models the file also gives the derivatives of
// Psi(sigma) in the signed singular values, which kernels/elasticity/analytic_eigensystem.hpp turns
// into the PSD-projected Hessian.
//
// The energy, stress and singular-value derivatives are templates on the lane type T (double, or
// Double4 for four tets at once; kernels/projection/simd4.hpp), with Eigen overloads on top.
//
// Conventions: vec() is column-major (Eigen's storage), so entry (a, b) of a 3x3 matrix is
// component a + 3 b, and dP/dF(a + 3 b, c + 3 d) = dP_ab / dF_cd.
//
// Neo-Hookean with J <= 0: energy +inf; P, dP/dF and the singular-value derivatives are NaN. The
// engine must not ask for derivatives there (the line search never accepts such a state); NaN
// makes a violation loud instead of silently wrong.
#pragma once

#include "kernels/elasticity/material.hpp"
#include "kernels/elasticity/svd3.hpp"
#include "kernels/projection/mat3.hpp"
#include "kernels/projection/simd4.hpp"

#include <Eigen/Core>
#include <Eigen/LU>  // determinant(), inverse()

#include <cmath>
#include <limits>

namespace nexdyn {

using Matrix9d = Eigen::Matrix<double, 9, 9>;
using Vector9d = Eigen::Matrix<double, 9, 1>;

inline constexpr double kInfinity = std::numeric_limits<double>::infinity();
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ------------------------------------------------------------------------------------------------
// Psi(F) and P(F), lane-wise

// Corotated from a precomputed SVD (the Hessian reuses it): R = U V^T and R^T F = V Sigma V^T, so
// ||F - R||^2 = sum (sigma_i - 1)^2 and tr(R^T F - I) = sum sigma_i - 3, free of the cancellation
// in F - R.
template <typename T>
inline T corotated_energy_density_and_pk1(const Mat3<T>& F, const SignedSvd<T>& svd,
                                          const LameParameters& lame, Mat3<T>& P) {
  const Mat3<T> R = times_transpose(svd.U, svd.V);
  const T tr = svd.sigma[0] + svd.sigma[1] + svd.sigma[2] - 3.0;
  P = (F - R) * (2.0 * lame.mu) + R * (lame.lambda * tr);
  const Vec3<T> d{{svd.sigma[0] - 1.0, svd.sigma[1] - 1.0, svd.sigma[2] - 1.0}};
  return lame.mu * squared_norm(d) + 0.5 * lame.lambda * tr * tr;
}

// Psi(F), and P(F) into P: the hot loops call this.
template <MaterialModel M, typename T>
inline T energy_density_and_pk1(const Mat3<T>& F, const LameParameters& lame, Mat3<T>& P) {
  const double mu = lame.mu, lambda = lame.lambda;
  if constexpr (M == MaterialModel::linear) {
    // eps = (F + F^T)/2 - I, P = 2 mu eps + lambda tr(eps) I.
    Mat3<T> eps = (F + transpose(F)) * 0.5;
    for (int i = 0; i < 3; ++i) eps(i, i) = eps(i, i) - 1.0;
    const T tr = trace(eps);
    P = eps * (2.0 * mu);
    for (int i = 0; i < 3; ++i) P(i, i) = P(i, i) + lambda * tr;
    return mu * squared_norm(eps) + 0.5 * lambda * tr * tr;
  } else if constexpr (M == MaterialModel::stvk) {
    // E = (F^T F - I)/2; second Piola-Kirchhoff S = 2 mu E + lambda tr(E) I; P = F S.
    Mat3<T> E = transpose_times(F, F) * 0.5;
    for (int i = 0; i < 3; ++i) E(i, i) = E(i, i) - 0.5;
    const T tr = trace(E);
    Mat3<T> S = E * (2.0 * mu);
    for (int i = 0; i < 3; ++i) S(i, i) = S(i, i) + lambda * tr;
    P = F * S;
    return mu * squared_norm(E) + 0.5 * lambda * tr * tr;
  } else if constexpr (M == MaterialModel::corotated) {
    SignedSvd<T> svd;
    signed_svd(F, svd);
    return corotated_energy_density_and_pk1(F, svd, lame, P);
  } else {
    // P = mu (F - F^-T) + lambda ln J F^-T = mu F + (lambda ln J - mu) / J cof(F): the cofactor
    // needs no division and gives J as one dot product.
    const Mat3<T> C = cofactor(F);
    const T J = dot(F.col[0], C.col[0]);
    const auto valid = J > 0.0;
    const T log_J = simd::log(simd::select(valid, J, simd::splat<T>(1.0)));
    P = F * mu + C * ((lambda * log_J - mu) / J);
    const T psi = 0.5 * mu * (squared_norm(F) - 3.0) - mu * log_J + 0.5 * lambda * log_J * log_J;
    const T nan = simd::splat<T>(kNaN);
    P = select(valid, P, Mat3<T>{{{{nan, nan, nan}}, {{nan, nan, nan}}, {{nan, nan, nan}}}});
    return simd::select(valid, psi, simd::splat<T>(kInfinity));
  }
}

// Psi(F) alone (line search).
template <MaterialModel M, typename T>
inline T energy_density(const Mat3<T>& F, const LameParameters& lame) {
  if constexpr (M == MaterialModel::neohookean) {
    // J exactly as in energy_density_and_pk1, so both paths round alike; P is skipped.
    const T J = dot(F.col[0], cross(F.col[1], F.col[2]));
    const auto valid = J > 0.0;
    const T log_J = simd::log(simd::select(valid, J, simd::splat<T>(1.0)));
    const T psi = 0.5 * lame.mu * (squared_norm(F) - 3.0) - lame.mu * log_J +
                  0.5 * lame.lambda * log_J * log_J;
    return simd::select(valid, psi, simd::splat<T>(kInfinity));
  } else if constexpr (M == MaterialModel::corotated) {
    SignedSvd<T> svd;
    signed_svd(F, svd);
    const T tr = svd.sigma[0] + svd.sigma[1] + svd.sigma[2] - 3.0;
    const Vec3<T> d{{svd.sigma[0] - 1.0, svd.sigma[1] - 1.0, svd.sigma[2] - 1.0}};
    return lame.mu * squared_norm(d) + 0.5 * lame.lambda * tr * tr;
  } else {
    Mat3<T> P;
    return energy_density_and_pk1<M>(F, lame, P);  // P is dead code for the compiler
  }
}

// Eigen interface.
template <MaterialModel M>
inline double energy_density(const Eigen::Matrix3d& F, const LameParameters& lame) {
  return energy_density<M>(to_mat3(F), lame);
}

template <MaterialModel M>
inline Eigen::Matrix3d pk1(const Eigen::Matrix3d& F, const LameParameters& lame) {
  Mat3<double> P;
  energy_density_and_pk1<M>(to_mat3(F), lame, P);
  return to_eigen(P);
}

// ------------------------------------------------------------------------------------------------
// Derivatives in the signed singular values (rotation-invariant isotropic models only).
//
// The Hessian of an isotropic Psi(F) = Psi(sigma) has, in the frame F = U Sigma V^T, a fixed
// eigen-structure (Teran et al. 2005; Smith et al. 2019, "Analytic eigensystems for isotropic
// distortion energies"):
//   - a 3x3 block d2Psi/dsigma^2 acting on the "scaling" modes U diag(e_k) V^T;
//   - for each pair i < j, a 2x2 block on U (e_i e_j^T) V^T, U (e_j e_i^T) V^T with eigenvalues
//       flip  = (psi_i - psi_j) / (sigma_i - sigma_j)  on U (e_i e_j^T + e_j e_i^T) V^T / sqrt 2
//       twist = (psi_i + psi_j) / (sigma_i + sigma_j)  on U (e_i e_j^T - e_j e_i^T) V^T / sqrt 2
//     where psi_i = dPsi/dsigma_i.
// Both quotients are 0/0 at repeated (or opposite) singular values; below they are simplified by
// hand for each model so that no division by sigma_i -/+ sigma_j remains (except the corotated
// twist, whose singularity at sigma_i + sigma_j = 0 is genuine: R jumps there).

// Pairs (i, j) in the order used by `flip` and `twist`.
inline constexpr int kSigmaPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};

template <typename T>
struct SingularValueDerivatives {
  Vec3<T> dpsi;   // dPsi/dsigma_i
  Mat3<T> d2psi;  // d2Psi/(dsigma_i dsigma_j), symmetric
  Vec3<T> flip;   // per pair (0,1), (0,2), (1,2)
  Vec3<T> twist;  // per pair
};

// Denominator floor for the corotated twist eigenvalue, relative to 1 + |sigma|_max: it keeps
// the value finite (and huge) where sigma_i + sigma_j -> 0 instead of dividing by zero.
inline constexpr double kCorotatedTwistFloor = 1e-12;

// Neo-Hookean with sigma_0 sigma_1 sigma_2 <= 0 gives NaN.
template <MaterialModel M, typename T>
inline SingularValueDerivatives<T> singular_value_derivatives(const Vec3<T>& sigma,
                                                              const LameParameters& lame) {
  static_assert(M != MaterialModel::linear, "linear elasticity is not rotation invariant");
  const double mu = lame.mu, lambda = lame.lambda;
  SingularValueDerivatives<T> d;
  if constexpr (M == MaterialModel::stvk) {
    // psi_i = sigma_i (2 mu E_i + lambda tr E) = mu (sigma_i^3 - sigma_i) + lambda tr(E) sigma_i.
    Vec3<T> E;
    for (int i = 0; i < 3; ++i) E[i] = 0.5 * (sigma[i] * sigma[i] - 1.0);
    const T tr = E[0] + E[1] + E[2];
    for (int i = 0; i < 3; ++i) {
      d.dpsi[i] = sigma[i] * (2.0 * mu * E[i] + lambda * tr);
      for (int j = 0; j < 3; ++j) d.d2psi(i, j) = lambda * sigma[i] * sigma[j];
      d.d2psi(i, i) =
          d.d2psi(i, i) + 2.0 * mu * E[i] + lambda * tr + 2.0 * mu * sigma[i] * sigma[i];
    }
    for (int p = 0; p < 3; ++p) {
      const T si = sigma[kSigmaPairs[p][0]], sj = sigma[kSigmaPairs[p][1]];
      // (a^3 -/+ b^3) / (a -/+ b) = a^2 +/- a b + b^2.
      d.flip[p] = mu * (si * si + si * sj + sj * sj - 1.0) + lambda * tr;
      d.twist[p] = mu * (si * si - si * sj + sj * sj - 1.0) + lambda * tr;
    }
  } else if constexpr (M == MaterialModel::corotated) {
    // Psi = mu sum (sigma_i - 1)^2 + lambda/2 (sum sigma_i - 3)^2.
    const T tr = sigma[0] + sigma[1] + sigma[2] - 3.0;
    const T floor =
        kCorotatedTwistFloor *
        (1.0 + simd::max(simd::max(simd::abs(sigma[0]), simd::abs(sigma[1])), simd::abs(sigma[2])));
    for (int i = 0; i < 3; ++i) {
      d.dpsi[i] = 2.0 * mu * (sigma[i] - 1.0) + lambda * tr;
      for (int j = 0; j < 3; ++j)
        d.d2psi(i, j) = simd::splat<T>(i == j ? 2.0 * mu + lambda : lambda);
    }
    for (int p = 0; p < 3; ++p) {
      const T si = sigma[kSigmaPairs[p][0]], sj = sigma[kSigmaPairs[p][1]];
      d.flip[p] = simd::splat<T>(2.0 * mu);
      // (psi_i + psi_j)/(s_i + s_j) = 2 mu + (2 lambda tr - 4 mu) / (s_i + s_j); with the signed
      // SVD s_i + s_j >= 0 for i < j, so the floor only guards the genuine singularity.
      d.twist[p] = 2.0 * mu + (2.0 * lambda * tr - 4.0 * mu) / simd::max(si + sj, floor);
    }
  } else {  // neohookean
    // psi_i = mu sigma_i + (lambda ln J - mu) / sigma_i.
    const T J = sigma[0] * sigma[1] * sigma[2];
    const auto valid = J > 0.0;
    const T log_J = simd::log(simd::select(valid, J, simd::splat<T>(1.0)));
    const T nan = simd::splat<T>(kNaN);
    const T c = simd::select(valid, lambda * log_J - mu, nan);  // NaN spreads to every output
    const Vec3<T> inv{{1.0 / sigma[0], 1.0 / sigma[1], 1.0 / sigma[2]}};
    for (int i = 0; i < 3; ++i) {
      d.dpsi[i] = mu * sigma[i] + c * inv[i];
      for (int j = 0; j < 3; ++j) d.d2psi(i, j) = lambda * inv[i] * inv[j];
      d.d2psi(i, i) = d.d2psi(i, i) + mu - c * inv[i] * inv[i];
    }
    for (int p = 0; p < 3; ++p) {
      const T inv_ij = inv[kSigmaPairs[p][0]] * inv[kSigmaPairs[p][1]];
      // (1/a - 1/b)/(a - b) = -1/(a b) and (1/a + 1/b)/(a + b) = 1/(a b).
      d.flip[p] = mu - c * inv_ij;
      d.twist[p] = mu + c * inv_ij;
    }
  }
  return d;
}

// ------------------------------------------------------------------------------------------------
// Exact dP/dF. Closed forms in F for linear, StVK and neo-Hookean (independent of the SVD, which
// makes them a real check of the analytic eigensystem); corotated from its eigensystem
// (analytic_eigensystem.hpp) since dR/dF has no simpler form. Reference code: Eigen, one tet.

namespace detail {

template <MaterialModel M>
inline Matrix9d pk1_derivative_closed_form(const Eigen::Matrix3d& F, const LameParameters& lame) {
  const double mu = lame.mu, lambda = lame.lambda;
  Matrix9d H;
  if constexpr (M == MaterialModel::linear) {
    // dP = mu (dF + dF^T) + lambda tr(dF) I.
    H.setZero();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        H(a + 3 * b, a + 3 * b) += mu;
        H(a + 3 * b, b + 3 * a) += mu;
        if (a == b)
          for (int c = 0; c < 3; ++c) H(a + 3 * a, c + 3 * c) += lambda;
      }
  } else if constexpr (M == MaterialModel::stvk) {
    // dP = dF S + F (2 mu dE + lambda tr(dE) I), dE = (dF^T F + F^T dF)/2; column by column.
    Eigen::Matrix3d E = 0.5 * (F.transpose() * F);
    E.diagonal().array() -= 0.5;
    Eigen::Matrix3d S = 2.0 * mu * E;
    S.diagonal().array() += lambda * E.trace();
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d) {
        Eigen::Matrix3d dF = Eigen::Matrix3d::Zero();
        dF(c, d) = 1.0;
        const Eigen::Matrix3d dE = 0.5 * (dF.transpose() * F + F.transpose() * dF);
        Eigen::Matrix3d dS = 2.0 * mu * dE;
        dS.diagonal().array() += lambda * dE.trace();
        const Eigen::Matrix3d dP = dF * S + F * dS;
        H.col(c + 3 * d) = Eigen::Map<const Vector9d>(dP.data());
      }
  } else if constexpr (M == MaterialModel::neohookean) {
    // dP = mu dF + (mu - lambda ln J) F^-T dF^T F^-T + lambda tr(F^-1 dF) F^-T, entrywise
    // dP_ab/dF_cd = mu d_ac d_bd + (mu - lambda ln J) G_ad G_cb + lambda G_ab G_cd, G = F^-T.
    const double J = F.determinant();
    if (!(J > 0.0)) {
      H.setConstant(kNaN);
      return H;
    }
    const Eigen::Matrix3d G = to_eigen(cofactor(to_mat3(F))) / J;
    const double k = mu - lambda * std::log(J);
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d)
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            H(a + 3 * b, c + 3 * d) =
                k * G(a, d) * G(c, b) + lambda * G(a, b) * G(c, d) + (a == c && b == d ? mu : 0.0);
  }
  return H;
}

}  // namespace detail

}  // namespace nexdyn

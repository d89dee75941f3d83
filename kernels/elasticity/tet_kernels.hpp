// Per-tet elasticity kernels, lane-wise: energy, gradient and PSD-projected Hessian of linear
// tetrahedra for T = double (one tet: the element layer, elasticity.hpp) or T = Double4 (four tets
// per instruction: the range drivers, elasticity_range.cpp). One implementation serves both, so
// the finite-difference tests of the element layer test the code the engine runs.
//
// Tet conventions (seed 004, "有限元方法离散化"): corners x0..x3, Ds = [x1-x0, x2-x0, x3-x0],
// F = Ds Dm^-1, energy = volume Psi(F), gradient g[3 k + a] = volume (P D^T)(a, k) with D the
// shape-function gradients (analytic_eigensystem.hpp), Hessian = volume B^T (dP/dF)+ B.
// Outputs: gradient[12] as [x0 y0 z0 x1 ...], hessian[144] column-major 12x12.
#pragma once

#include "kernels/elasticity/analytic_eigensystem.hpp"
#include "kernels/elasticity/energy_density.hpp"
#include "kernels/elasticity/material.hpp"
#include "kernels/elasticity/svd3.hpp"
#include "kernels/projection/mat3.hpp"
#include "kernels/projection/simd4.hpp"

namespace nexdyn {

// One tet (or four) as the kernels read it.
template <typename T>
struct TetLanes {
  Vec3<T> x[4];    // current corner positions
  Mat3<T> Dm_inv;  // inverse rest edge matrix
  T volume;        // rest volume
};

template <typename T>
inline Mat3<T> deformation_gradient(const TetLanes<T>& tet) {
  const Mat3<T> Ds{{tet.x[1] - tet.x[0], tet.x[2] - tet.x[0], tet.x[3] - tet.x[0]}};
  return Ds * tet.Dm_inv;
}

namespace detail {

// gradient = volume vec(P D^T): corners 1..3 get the columns of volume P Dm^-T, corner 0 minus
// their sum (the four forces sum to zero up to rounding: translation invariance).
template <typename T>
inline void tet_gradient_from_pk1(const Mat3<T>& P, const TetLanes<T>& tet, T gradient[12]) {
  const Mat3<T> G = times_transpose(P * tet.volume, tet.Dm_inv);
  for (int a = 0; a < 3; ++a) {
    gradient[3 + a] = G(a, 0);
    gradient[6 + a] = G(a, 1);
    gradient[9 + a] = G(a, 2);
    gradient[a] = -(G(a, 0) + G(a, 1) + G(a, 2));
  }
}

// Linear elasticity's constant V B^T dP/dF B in closed form: with D_k the shape gradients,
// block (k, l) = V (mu (D_k . D_l) I + mu D_l D_k^T + lambda D_k D_l^T). Upper blocks, mirrored.
template <typename T>
inline void linear_tet_hessian(const TetLanes<T>& tet, const LameParameters& lame, T H[144]) {
  Vec3<T> D[4];
  shape_gradients(tet.Dm_inv, D);
  const T vmu = tet.volume * lame.mu, vlambda = tet.volume * lame.lambda;
  for (int l = 0; l < 4; ++l)
    for (int k = 0; k <= l; ++k) {
      const T diagonal = vmu * dot(D[k], D[l]);
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a) {
          T value = vmu * D[l][a] * D[k][c] + vlambda * D[k][a] * D[l][c];
          if (a == c) value = value + diagonal;
          H[(3 * k + a) + 12 * (3 * l + c)] = value;
        }
    }
  mirror_upper_to_lower(H);
}

}  // namespace detail

template <MaterialModel M, typename T>
inline T tet_energy_kernel(const TetLanes<T>& tet, const LameParameters& lame) {
  return tet.volume * energy_density<M>(deformation_gradient(tet), lame);
}

// Returns the energy. Inverted neo-Hookean lanes: energy +inf, gradient NaN.
template <MaterialModel M, typename T>
inline T tet_gradient_kernel(const TetLanes<T>& tet, const LameParameters& lame, T gradient[12]) {
  Mat3<T> P;
  const T psi = energy_density_and_pk1<M>(deformation_gradient(tet), lame, P);
  detail::tet_gradient_from_pk1(P, tet, gradient);
  return tet.volume * psi;
}

// Returns the energy; writes the gradient and the PSD-projected Hessian (exactly symmetric).
// Inverted neo-Hookean lanes: energy +inf, gradient and Hessian NaN.
template <MaterialModel M, typename T>
inline T tet_hessian_kernel(const TetLanes<T>& tet, const LameParameters& lame, T gradient[12],
                            T hessian[144]) {
  const Mat3<T> F = deformation_gradient(tet);
  Mat3<T> P;
  T psi;
  if constexpr (M == MaterialModel::linear) {
    psi = energy_density_and_pk1<M>(F, lame, P);
    detail::linear_tet_hessian(tet, lame, hessian);
  } else {
    SignedSvd<T> svd;
    signed_svd(F, svd);
    if constexpr (M == MaterialModel::corotated) {
      psi = corotated_energy_density_and_pk1(F, svd, lame, P);  // one SVD for both
    } else {
      psi = energy_density_and_pk1<M>(F, lame, P);
    }
    T G[9][12];
    projected_tet_hessian_factor(svd, singular_value_derivatives<M>(svd.sigma, lame), tet.Dm_inv,
                                 tet.volume, G);
    symmetric_product(G, hessian);
    if constexpr (M == MaterialModel::neohookean) {
      // No Hessian exists for an inverted tet; make the whole slab NaN, not only what the
      // singular values happened to poison.
      const auto valid = psi < kInfinity;
      if (!simd::all(valid))
        for (int i = 0; i < 144; ++i)
          hessian[i] = simd::select(valid, hessian[i], simd::splat<T>(kNaN));
    }
  }
  detail::tet_gradient_from_pk1(P, tet, gradient);
  return tet.volume * psi;
}

}  // namespace nexdyn

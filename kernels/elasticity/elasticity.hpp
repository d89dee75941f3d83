// Element layer of tetrahedral hyperelasticity: energy density, PK1 stress and its derivative
// (exact and PSD-projected) per material, and energy / gradient / projected Hessian of one linear
// tetrahedron (seed 004, "有限元方法离散化"; Sifakis & Barbic 2012).
//
// Tet conventions (shared with the engine's Model):
//   corners x0..x3 are the columns of x (3x4); the 12 DOFs are [x0 y0 z0 x1 y1 z1 ...];
//   Ds = [x1-x0, x2-x0, x3-x0], Dm likewise at rest, F = Ds Dm^-1, volume = det(Dm)/6 > 0;
//   energy = volume * Psi(F); gradient = volume * vec(P D^T) with D = shape_gradients(Dm^-1);
//   projected Hessian = volume * B^T (dP/dF)+ B, B = dvec(F)/dx.
//
// Every function is a template on the material and has a runtime-dispatch overload taking
// MaterialModel first, for tests and rare callers. The tet functions are thin Eigen adapters over
// the lane-wise kernels of tet_kernels.hpp with T = double: the range drivers
// (elasticity_range.hpp) run the very same kernels on four tets at once.
//
// Inversion: neo-Hookean energies are +inf for J <= 0 and the gradient / Hessian outputs are NaN
// there (see energy_density.hpp). The other models are finite for every F (the corotated Hessian
// becomes huge where two signed singular values cancel, sigma_i + sigma_j -> 0).
#pragma once

#include "kernels/elasticity/analytic_eigensystem.hpp"
#include "kernels/elasticity/energy_density.hpp"
#include "kernels/elasticity/material.hpp"
#include "kernels/elasticity/svd3.hpp"
#include "kernels/elasticity/tet_kernels.hpp"
#include "kernels/projection/mat3.hpp"

#include <Eigen/Core>
#include <Eigen/LU>  // determinant(), inverse()

namespace nexdyn {

using Matrix34d = Eigen::Matrix<double, 3, 4>;

// ------------------------------------------------------------------------------------------------
// dP/dF (energy_density<M> and pk1<M> are in energy_density.hpp)

template <MaterialModel M>
inline Matrix9d pk1_derivative(const Eigen::Matrix3d& F, const LameParameters& lame) {
  if constexpr (M == MaterialModel::corotated) {
    Svd3 svd;
    svd3(F, svd);
    return isotropic_pk1_derivative<false>(svd,
                                           singular_value_derivatives<M>(to_vec3(svd.sigma), lame));
  } else {
    return detail::pk1_derivative_closed_form<M>(F, lame);
  }
}

// Nearest PSD matrix to dP/dF (Frobenius norm). Linear elasticity's dP/dF is constant and PSD
// (for mu >= 0, 2 mu + 3 lambda >= 0) and returned as is.
template <MaterialModel M>
inline Matrix9d pk1_derivative_projected(const Eigen::Matrix3d& F, const LameParameters& lame) {
  if constexpr (M == MaterialModel::linear) {
    return detail::pk1_derivative_closed_form<M>(F, lame);
  } else {
    if constexpr (M == MaterialModel::neohookean) {
      if (!(F.determinant() > 0.0)) return Matrix9d::Constant(kNaN);
    }
    Svd3 svd;
    svd3(F, svd);
    return isotropic_pk1_derivative<true>(svd,
                                          singular_value_derivatives<M>(to_vec3(svd.sigma), lame));
  }
}

// ------------------------------------------------------------------------------------------------
// One tetrahedron

inline Eigen::Matrix3d deformation_gradient(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv) {
  Eigen::Matrix3d Ds;
  Ds.col(0) = x.col(1) - x.col(0);
  Ds.col(1) = x.col(2) - x.col(0);
  Ds.col(2) = x.col(3) - x.col(0);
  return Ds * Dm_inv;
}

// Rest-shape data of a tet from its rest edge matrix Dm = [X1-X0, X2-X0, X3-X0]: Dm^-1 and
// volume = det(Dm)/6, both written in every case (the volume signed, for the caller's message).
// Returns false when det(Dm) <= 0 (or is NaN): a degenerate or negatively oriented tet, which the
// mesh loader must reject or reorient (swap two corners); Dm_inv is then not finite or meaningless.
//
// Both are computed before the test, in one branch-free run: the determinant and the inverse's
// cofactors share products, and GCC fuses a product into an FMA only when all its uses are in the
// same basic block, so a branch between them would change the last bits of both.
inline bool tet_rest_shape_from_edges(const Eigen::Matrix3d& Dm, Eigen::Matrix3d& Dm_inv, double& volume) {
  const double det = Dm.determinant();
  volume = det / 6.0;
  Dm_inv = Dm.inverse();
  return det > 0.0;
}

// The same from the rest corners X (columns).
inline bool tet_rest_shape(const Matrix34d& X, Eigen::Matrix3d& Dm_inv, double& volume) {
  Eigen::Matrix3d Dm;
  Dm.col(0) = X.col(1) - X.col(0);
  Dm.col(1) = X.col(2) - X.col(0);
  Dm.col(2) = X.col(3) - X.col(0);
  return tet_rest_shape_from_edges(Dm, Dm_inv, volume);
}

namespace detail {

inline TetLanes<double> to_tet_lanes(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                                     double volume) {
  TetLanes<double> tet;
  for (int k = 0; k < 4; ++k) tet.x[k] = to_vec3(x.col(k));
  tet.Dm_inv = to_mat3(Dm_inv);
  tet.volume = volume;
  return tet;
}

}  // namespace detail

template <MaterialModel M>
inline double tet_energy(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv, double volume,
                         const LameParameters& lame) {
  return tet_energy_kernel<M>(detail::to_tet_lanes(x, Dm_inv, volume), lame);
}

// Returns the energy; writes the gradient (NaN for an inverted neo-Hookean tet, energy +inf).
template <MaterialModel M>
inline double tet_energy_gradient(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv, double volume,
                                  const LameParameters& lame, Vector12d& gradient) {
  return tet_gradient_kernel<M>(detail::to_tet_lanes(x, Dm_inv, volume), lame, gradient.data());
}

// Returns the energy; writes the gradient and the PSD-projected 12x12 Hessian (exactly symmetric).
// Energy and gradient are tet_energy_gradient's up to rounding (same formulas; the compiler may
// fuse multiply-adds differently in the two inlined copies). Inverted neo-Hookean tet: energy
// +inf, gradient and Hessian NaN.
template <MaterialModel M>
inline double tet_energy_gradient_hessian(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                                          double volume, const LameParameters& lame,
                                          Vector12d& gradient, Matrix12d& hessian_projected) {
  return tet_hessian_kernel<M>(detail::to_tet_lanes(x, Dm_inv, volume), lame, gradient.data(),
                               hessian_projected.data());
}

// The exact (unprojected) Hessian V B^T dP/dF B: a reference for tests, not for the solver.
template <MaterialModel M>
inline Matrix12d tet_hessian_exact(const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                                   double volume, const LameParameters& lame) {
  return tet_hessian_from_pk1_derivative(pk1_derivative<M>(deformation_gradient(x, Dm_inv), lame),
                                         Dm_inv, volume);
}

// ------------------------------------------------------------------------------------------------
// Runtime dispatch (elasticity.cpp): one switch, then the template above.

double energy_density(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame);
Eigen::Matrix3d pk1(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame);
Matrix9d pk1_derivative(MaterialModel model, const Eigen::Matrix3d& F, const LameParameters& lame);
Matrix9d pk1_derivative_projected(MaterialModel model, const Eigen::Matrix3d& F,
                                  const LameParameters& lame);
double tet_energy(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                  double volume, const LameParameters& lame);
double tet_energy_gradient(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                           double volume, const LameParameters& lame, Vector12d& gradient);
double tet_energy_gradient_hessian(MaterialModel model, const Matrix34d& x,
                                   const Eigen::Matrix3d& Dm_inv, double volume,
                                   const LameParameters& lame, Vector12d& gradient,
                                   Matrix12d& hessian_projected);
Matrix12d tet_hessian_exact(MaterialModel model, const Matrix34d& x, const Eigen::Matrix3d& Dm_inv,
                            double volume, const LameParameters& lame);

}  // namespace nexdyn

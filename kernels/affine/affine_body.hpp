// Affine bodies (Lan, Kaufman, Li, Jiang, Yang 2022, "Affine Body Dynamics: Fast, Stable and
// Intersection-free Simulation of Stiff Materials"): a stiff body as 12 coordinates,
//   q = (p, a1, a2, a3),   x(X) = p + A (X - c),   A = [a1^T; a2^T; a3^T] (rows a_i),
// where c is the body's centre of mass at rest and X a rest position. Every point's motion is
// linear in q, so a straight Newton step in q moves every vertex on a straight line and the
// CCD of deformable bodies applies unchanged.
//
// With rest positions taken about the centre of mass the mass matrix is block diagonal:
//   M = blockdiag(m I, S, S, S),   S = integral over the body of rho (X - c)(X - c)^T dV,
// so the kinetic energy is 1/2 m |p'|^2 + 1/2 sum_i a_i'^T S a_i', and gravity acts on p alone.
// The body keeps its shape by the orthogonality potential
//   E(A) = kappa V ||A A^T - I||_F^2,
// zero on rotations, whose Hessian has a closed-form eigensystem in the SVD frame of A (the
// energy is a function of the singular values sigma_k alone: sum_k (sigma_k^2 - 1)^2):
//   scaling  U e_k e_k^T V^T                    4 kappa V (3 sigma_k^2 - 1)
//   flip     U (e_k e_l^T + e_l e_k^T) V^T / sqrt2   4 kappa V (sigma_k^2 + sigma_k sigma_l + sigma_l^2 - 1)
//   twist    U (e_k e_l^T - e_l e_k^T) V^T / sqrt2   4 kappa V (sigma_k^2 - sigma_k sigma_l + sigma_l^2 - 1)
// (at rest the twists, the rotations, have eigenvalue 0), so its PSD projection clamps nine
// numbers instead of solving a 9x9 eigenproblem (kernels/elasticity/analytic_eigensystem.hpp).
//
// Vectors and matrices over A are in the order of q: a11, a12, a13, a21, ... (row by row).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace nexdyn {

using AffineVector9 = Eigen::Matrix<double, 9, 1>;
using AffineMatrix9 = Eigen::Matrix<double, 9, 9>;

// ||A A^T - I||_F^2, per unit of kappa V.
double orthogonality_energy(const Eigen::Matrix3d& A);
// Its gradient in q's order of A: 4 (A A^T - I) A, row by row.
AffineVector9 orthogonality_gradient(const Eigen::Matrix3d& A);
// Its Hessian in q's order, exact (project = false) or PSD-projected through the closed-form
// eigensystem above (project = true).
AffineMatrix9 orthogonality_hessian(const Eigen::Matrix3d& A, bool project);
// The Hessian Newton uses, whose line search turns the bodies (CoordinateMap::turn): the projected
// one with the twists' curvature that of a turn. A turn leaves the energy unchanged, but the
// exact twist value 4 (s_k^2 - s_k s_l + s_l^2 - 1) = 4 (s_k - s_l)^2 + 4 (s_k s_l - 1) holds the
// chord's curvature, 4 (s_k s_l - 1), first order in the body's stretch: under load it rivals
// the rotational inertia (a 5 cm stone: kappa V 4 (s_k s_l - 1) near S / h^2 at a stretch of
// 1e-5), so Newton's steps along turns came out several times too short and a loaded body
// crept through tens of full steps. The twists here take the Gauss-Newton value of the residual
// A A^T - I, 2 (s_k - s_l)^2: second order, and zero for a stretch without shear.
AffineMatrix9 orthogonality_hessian_for_turns(const Eigen::Matrix3d& A);

// A rigid body's mass properties, integrated exactly over tets (each tet's second moment is
// V / 20 (sum_i y_i y_i^T + (sum_i y_i)(sum_i y_i)^T) for its corners y_i about any point).
struct AffineMassProperties {
  double volume = 0.0;                                      // [m^3]
  Eigen::Vector3d center = Eigen::Vector3d::Zero();         // centre of mass (volume) [m]
  Eigen::Matrix3d second_moment = Eigen::Matrix3d::Zero();  // integral (X - c)(X - c)^T dV [m^5]
};
// Over the tets (4 vertex ids each) of positions (3 per vertex); inverted tets count negative.
AffineMassProperties affine_mass_properties(const std::vector<double>& positions, const std::vector<int32_t>& tets);

// The inertia tensor about the centre of mass, rho (tr(S) I - S), from S and the density.
Eigen::Matrix3d inertia_tensor(const Eigen::Matrix3d& second_moment, double density);

}  // namespace nexdyn

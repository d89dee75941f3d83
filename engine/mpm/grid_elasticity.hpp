// Elastic energy of MPM as a function of the grid's step displacement (seed 002, "MPM"; Gast et
// al. 2015, "Optimization integrator for large time steps"; Wang et al. 2020, "Hierarchical
// optimization time integration for CFL-rate MPM stepping"): the term s P(x) of the grid
// incremental potential, with the grid positions x_i^{n+1} = x_i^n + u_i as the unknowns.
//
// With the weights at the start of the step, each particle's deformation gradient is affine in u:
//   F_p(u) = (I + sum_i u_i (grad w_ip)^T) F_p^n = F_p^n + sum_i u_i g_ip^T,  g_ip = F_p^nT grad w_ip,
// so dF_p/du_i is the 3x9 map du -> du g_ip^T and, with P = dPsi/dF (PK1),
//   E_el(u)        = sum_p V_p^0 Psi(F_p(u))
//   dE_el/du_i     = sum_p V_p^0 P(F_p) g_ip           (the grid force is its negative)
//   d2E_el/du_i du_j = sum_p V_p^0 G_ip^T (dP/dF) G_jp,  G_ip = dvec(F)/du_i (9x3)
// and the Hessian is PSD when dP/dF is replaced by its PSD projection (kernels/elasticity/
// elasticity.hpp), since each particle's 81x81 block is then V B^T K+ B. The materials are the
// engine's, through the same Psi, P and dP/dF kernels as the tets.
//
// Derivatives are with respect to the dense grid's DOFs (3 per node, Grid::num_dofs()); nodes no
// particle reaches get zero rows. Reductions are deterministic: the energy is a chunked sum over
// particle ids, the gradient a coloured scatter (engine/mpm/transfer.hpp), the Hessian triplets
// concatenated in particle order.
#pragma once

#include "engine/model.hpp"
#include "engine/mpm/grid.hpp"
#include "engine/mpm/particles.hpp"
#include "engine/mpm/transfer.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <vector>

namespace nexdyn {

using Matrix81d = Eigen::Matrix<double, 81, 81>;
using Vector81d = Eigen::Matrix<double, 81, 1>;

// One particle's deformation gradient under the grid displacement u (num_dofs), with the stencil
// at its start-of-step position.
Eigen::Matrix3d particle_deformation_gradient(const Grid& grid, const BSplineStencil& stencil,
                                              const Eigen::Matrix3d& F_n, const double* u);

// E_el(u) = sum_p V_p^0 Psi(F_p(u)); +inf when a neo-Hookean particle is inverted.
double grid_elastic_energy(const Grid& grid, const Particles& particles,
                           const std::vector<Material>& materials, const double* u);

// Returns E_el(u) and writes its gradient (num_dofs, overwritten) by the coloured scatter over
// `bins` (bin_particles of the same particles). NaN entries where a neo-Hookean particle is
// inverted.
double grid_elastic_gradient(const Grid& grid, const Particles& particles, const ParticleBins& bins,
                             const std::vector<Material>& materials, const double* u, double* gradient);

// One particle's gradient (81: the 27 stencil nodes x 3, in for_each_stencil_node order) and
// Hessian (81x81) with respect to its stencil's displacements, projected or exact. Returns the
// energy V_p^0 Psi.
double particle_elastic_derivatives(const Grid& grid, const BSplineStencil& stencil,
                                    const Eigen::Matrix3d& F_n, double volume0, const Material& material,
                                    const double* u, bool projected, Vector81d& gradient, Matrix81d& hessian);

// The Hessian of E_el over all grid DOFs (num_dofs x num_dofs), PSD-projected per particle, or
// exact (projected = false: for tests). A reference assembly: the solver's slot-table assembly
// over active nodes is the next step (MPM_STATUS.md).
Eigen::SparseMatrix<double> grid_elastic_hessian(const Grid& grid, const Particles& particles,
                                                 const std::vector<Material>& materials, const double* u,
                                                 bool projected = true);

}  // namespace nexdyn

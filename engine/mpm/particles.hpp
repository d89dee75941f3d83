// Material points of the Material Point Method (issue 23; seed 002, "MPM"): the Lagrangian
// carriers of mass, volume, velocity, deformation and material, as flat per-particle arrays
// (structure of arrays, like the tet buffers of Model and State).
//
// A particle p carries its rest volume V_p^0 and mass m_p (both constant), its position x_p and
// velocity v_p, its deformation gradient F_p (updated from the grid motion, seed 002:
// F_p^{n+1} = (I + sum_i (x_i^{n+1} - x_i^n) (grad w_ip^n)^T) F_p^n) and its APIC affine velocity
// matrix C_p (Jiang et al. 2015, "The affine particle-in-cell method"): the particle's velocity
// field is v_p + C_p (x - x_p) near x_p. F and C are column-major 3x3 blocks, entry (a, b) at
// 9 p + a + 3 b, as Model::Dm_inv.
//
// Written by the sampler below (once, at scene load) and by the grid-to-particle transfer
// (engine/mpm/transfer.hpp) every step; everything else reads it.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace nexdyn {

struct Particles {
  std::vector<double> mass;       // (n) m_p [kg], constant
  std::vector<double> volume0;    // (n) V_p^0, rest volume [m^3], constant
  std::vector<double> x;          // (n x 3) position [m]
  std::vector<double> v;          // (n x 3) velocity [m/s]
  std::vector<double> F;          // (n x 9) deformation gradient, column-major [-]
  std::vector<double> C;          // (n x 9) APIC affine velocity matrix, column-major [1/s]
  std::vector<int32_t> material;  // (n) index into the scene's materials

  int64_t size() const { return static_cast<int64_t>(mass.size()); }
  int64_t num_dofs() const { return 3 * size(); }
  void resize(int64_t n);
  void reserve(int64_t n);
  // Appends one particle at rest shape (F = I, C = 0).
  void push_back(double mass_p, double volume_p, const Eigen::Vector3d& x_p,
                 const Eigen::Vector3d& v_p, int32_t material_p);

  Eigen::Map<const Eigen::Vector3d> position(int64_t p) const { return Eigen::Map<const Eigen::Vector3d>(&x[3 * p]); }
  Eigen::Map<const Eigen::Vector3d> velocity(int64_t p) const { return Eigen::Map<const Eigen::Vector3d>(&v[3 * p]); }
  Eigen::Map<const Eigen::Matrix3d> deformation(int64_t p) const { return Eigen::Map<const Eigen::Matrix3d>(&F[9 * p]); }
  Eigen::Map<const Eigen::Matrix3d> affine(int64_t p) const { return Eigen::Map<const Eigen::Matrix3d>(&C[9 * p]); }
};

// Samples the box [box_min, box_min + size] with K particles per grid cell per axis: each axis
// holds n_a = max(1, round(size_a / h)) cells of the box (the box is cut into n_a equal cells,
// which are grid cells when size_a is a multiple of h) and K n_a particles at the centres of equal
// sub-cells, so the particles tile the box exactly and each has volume = the product of the
// sub-cell edges and mass = density * volume. Particles are appended in x-fastest order, all with
// velocity `velocity`, F = I, C = 0. Returns the number appended.
int64_t sample_box_particles(Particles& particles, const Eigen::Vector3d& box_min,
                             const Eigen::Vector3d& size, double grid_spacing, int per_cell,
                             double density, const Eigen::Vector3d& velocity, int32_t material);

// Totals for tests and statistics: sum m_p, sum m_p v_p, and the APIC angular momentum about the
// origin, sum_p x_p x m_p v_p + m_p (h^2/4) eps : C_p^T (Jiang et al. 2015, eq. for L with
// B_p = C_p D_p and D_p = h^2/4 I for quadratic B-splines).
double total_mass(const Particles& particles);
Eigen::Vector3d total_momentum(const Particles& particles);
Eigen::Vector3d total_angular_momentum(const Particles& particles, double grid_spacing);

}  // namespace nexdyn

// Shared set-up of the MPM tests: random particles with random velocities, affine matrices and
// deformation gradients inside a grid.
#pragma once

#include "engine/model.hpp"
#include "engine/mpm/grid.hpp"
#include "engine/mpm/particles.hpp"
#include "kernels/elasticity/material.hpp"

#include <Eigen/Core>

#include <random>
#include <vector>

namespace nexdyn::test {

// n particles uniformly in [lo, hi]^3 with random mass in [0.5, 1.5], velocity in [-1, 1]^3,
// C in [-c_scale, c_scale]^9, F = I, material 0.
inline Particles random_particles(int64_t n, double lo, double hi, double c_scale, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> pos(lo, hi), unit(-1.0, 1.0), mass(0.5, 1.5);
  Particles particles;
  particles.reserve(n);
  for (int64_t p = 0; p < n; ++p) {
    const Eigen::Vector3d x(pos(rng), pos(rng), pos(rng));
    const Eigen::Vector3d v(unit(rng), unit(rng), unit(rng));
    particles.push_back(mass(rng), 1e-3, x, v, 0);
    for (int k = 0; k < 9; ++k) particles.C[9 * p + k] = c_scale * unit(rng);
  }
  return particles;
}

// Each F_p = scale I + perturbation (entries uniform in [-perturbation, perturbation]).
inline void perturb_deformation(Particles& particles, double scale, double perturbation, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int64_t p = 0; p < particles.size(); ++p)
    for (int k = 0; k < 9; ++k)
      particles.F[9 * p + k] = (k % 4 == 0 ? scale : 0.0) + perturbation * unit(rng);
}

inline Material test_material(MaterialModel model, double youngs = 1e5, double poisson = 0.3) {
  Material m;
  m.name = "test";
  m.model = model;
  m.youngs = youngs;
  m.poisson = poisson;
  m.density = 1000.0;
  m.lame = lame_from_young_poisson(youngs, poisson);
  return m;
}

}  // namespace nexdyn::test

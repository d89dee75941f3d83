// The particle cube of the MPM step benchmarks (bench_mpm_step, bench_mpm_cholmod): neo-Hookean
// (E 1e5 Pa, nu 0.3, 1000 kg/m^3), `cells`^3 grid cells of h = 2 cm with 8 particles each,
// squeezed 5% along x, under gravity, three empty cells of margin on each side.
#pragma once

#include "engine/mpm/mpm_model.hpp"
#include "kernels/elasticity/material.hpp"

namespace nexdyn::bench {

inline constexpr double kMpmSpacing = 0.02;  // h [m]

inline MpmModel squeezed_cube(int cells) {
  MpmModel m;
  m.grid_spacing = kMpmSpacing;
  m.domain_max = Eigen::Vector3d::Constant((cells + 6) * kMpmSpacing);
  m.gravity = Eigen::Vector3d(0, -9.81, 0);
  Material material;
  material.name = "rubber";
  material.model = MaterialModel::neohookean;
  material.youngs = 1e5;
  material.poisson = 0.3;
  material.density = 1000.0;
  material.lame = lame_from_young_poisson(1e5, 0.3);
  m.materials.push_back(material);
  sample_box_particles(m.initial, Eigen::Vector3d::Constant(3.0 * kMpmSpacing),
                       Eigen::Vector3d::Constant(cells * kMpmSpacing), kMpmSpacing, 2, 1000.0, Eigen::Vector3d::Zero(), 0);
  for (int64_t p = 0; p < m.initial.size(); ++p) m.initial.F[9 * p] = 0.95;
  m.particle_body.assign(static_cast<size_t>(m.initial.size()), 0);
  return m;
}

}  // namespace nexdyn::bench

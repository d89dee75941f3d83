// Particle storage, the box sampler and momentum totals (see particles.hpp).
#include "engine/mpm/particles.hpp"

#include <Eigen/Geometry>  // cross

#include <algorithm>
#include <cmath>

namespace nexdyn {

void Particles::resize(int64_t n) {
  const size_t m = static_cast<size_t>(n);
  mass.resize(m);
  volume0.resize(m);
  x.resize(3 * m);
  v.resize(3 * m);
  F.resize(9 * m);
  C.resize(9 * m);
  material.resize(m);
}

void Particles::reserve(int64_t n) {
  const size_t m = static_cast<size_t>(n);
  mass.reserve(m);
  volume0.reserve(m);
  x.reserve(3 * m);
  v.reserve(3 * m);
  F.reserve(9 * m);
  C.reserve(9 * m);
  material.reserve(m);
}

void Particles::push_back(double mass_p, double volume_p, const Eigen::Vector3d& x_p,
                          const Eigen::Vector3d& v_p, int32_t material_p) {
  mass.push_back(mass_p);
  volume0.push_back(volume_p);
  x.insert(x.end(), {x_p.x(), x_p.y(), x_p.z()});
  v.insert(v.end(), {v_p.x(), v_p.y(), v_p.z()});
  F.insert(F.end(), {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0});
  C.insert(C.end(), 9, 0.0);
  material.push_back(material_p);
}

int64_t sample_box_particles(Particles& particles, const Eigen::Vector3d& box_min,
                             const Eigen::Vector3d& size, double grid_spacing, int per_cell,
                             double density, const Eigen::Vector3d& velocity, int32_t material) {
  int64_t count[3];
  Eigen::Vector3d spacing;  // particle sub-cell edge per axis
  for (int a = 0; a < 3; ++a) {
    const int64_t cells = std::max<int64_t>(1, std::llround(size[a] / grid_spacing));
    count[a] = cells * per_cell;
    spacing[a] = size[a] / static_cast<double>(count[a]);
  }
  const double volume = spacing.prod();
  const double mass = density * volume;
  const int64_t n = count[0] * count[1] * count[2];
  particles.reserve(particles.size() + n);
  for (int64_t k = 0; k < count[2]; ++k)
    for (int64_t j = 0; j < count[1]; ++j)
      for (int64_t i = 0; i < count[0]; ++i) {
        const Eigen::Vector3d offset((static_cast<double>(i) + 0.5) * spacing[0],
                                     (static_cast<double>(j) + 0.5) * spacing[1],
                                     (static_cast<double>(k) + 0.5) * spacing[2]);
        particles.push_back(mass, volume, box_min + offset, velocity, material);
      }
  return n;
}

double total_mass(const Particles& particles) {
  double m = 0.0;
  for (double mp : particles.mass) m += mp;
  return m;
}

Eigen::Vector3d total_momentum(const Particles& particles) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int64_t i = 0; i < particles.size(); ++i) p += particles.mass[i] * particles.velocity(i);
  return p;
}

Eigen::Vector3d total_angular_momentum(const Particles& particles, double grid_spacing) {
  // The particle's own spin: m_p eps : B_p^T with B_p = C_p D_p, D_p = h^2/4 I; component a is
  // eps_abc B_cb, i.e. (B(2,1) - B(1,2), B(0,2) - B(2,0), B(1,0) - B(0,1)).
  const double d = 0.25 * grid_spacing * grid_spacing;
  Eigen::Vector3d L = Eigen::Vector3d::Zero();
  for (int64_t i = 0; i < particles.size(); ++i) {
    const double m = particles.mass[i];
    const Eigen::Matrix3d C = particles.affine(i);
    L += m * particles.position(i).cross(particles.velocity(i));
    L += m * d * Eigen::Vector3d(C(2, 1) - C(1, 2), C(0, 2) - C(2, 0), C(1, 0) - C(0, 1));
  }
  return L;
}

}  // namespace nexdyn

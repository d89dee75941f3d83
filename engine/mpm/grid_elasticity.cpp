// Elastic energy, gradient and Hessian with respect to grid displacements (see grid_elasticity.hpp).
#include "engine/mpm/grid_elasticity.hpp"

#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "kernels/elasticity/energy_density.hpp"

#include <Eigen/SparseCore>

#include <algorithm>

namespace nexdyn {

namespace {

constexpr int64_t kHessianGrain = 64;  // particles per chunk of the Hessian assembly

// g_ip = F_p^nT grad w_ip for the 27 nodes, and their node ids.
struct ParticleStencilMap {
  int64_t node[27];
  Eigen::Vector3d g[27];
};

ParticleStencilMap stencil_map(const Grid& grid, const BSplineStencil& s, const Eigen::Matrix3d& F_n) {
  ParticleStencilMap map;
  const Eigen::Matrix3d Ft = F_n.transpose();
  for_each_stencil_node(grid, s, [&](int64_t node, int o, double, const Eigen::Vector3d& grad) {
    map.node[o] = node;
    map.g[o] = Ft * grad;
  });
  return map;
}

Eigen::Matrix3d deformation_from_map(const ParticleStencilMap& map, const Eigen::Matrix3d& F_n, const double* u) {
  Eigen::Matrix3d F = F_n;
  for (int o = 0; o < 27; ++o) F += Eigen::Map<const Eigen::Vector3d>(&u[3 * map.node[o]]) * map.g[o].transpose();
  return F;
}

template <MaterialModel M>
double particle_derivatives(const ParticleStencilMap& map, const Eigen::Matrix3d& F, double volume0,
                            const LameParameters& lame, bool projected, Vector81d& gradient,
                            Matrix81d& hessian) {
  const double psi = energy_density<M>(F, lame);
  const Eigen::Matrix3d P = pk1<M>(F, lame);
  for (int o = 0; o < 27; ++o) gradient.segment<3>(3 * o) = volume0 * (P * map.g[o]);
  const Matrix9d K = projected ? pk1_derivative_projected<M>(F, lame) : pk1_derivative<M>(F, lame);
  // B = dvec(F)/du (9 x 81): B(a + 3 b, 3 o + c) = delta_ac g_o[b].
  Eigen::Matrix<double, 9, 81> B = Eigen::Matrix<double, 9, 81>::Zero();
  for (int o = 0; o < 27; ++o)
    for (int b = 0; b < 3; ++b)
      for (int a = 0; a < 3; ++a) B(a + 3 * b, 3 * o + a) = map.g[o][b];
  const Eigen::Matrix<double, 9, 81> KB = K * B;
  hessian.noalias() = volume0 * (B.transpose() * KB);
  // Exactly symmetric, as the solver's Cholesky expects.
  hessian = 0.5 * (hessian + hessian.transpose()).eval();
  return volume0 * psi;
}

}  // namespace

Eigen::Matrix3d particle_deformation_gradient(const Grid& grid, const BSplineStencil& stencil,
                                              const Eigen::Matrix3d& F_n, const double* u) {
  return deformation_from_map(stencil_map(grid, stencil, F_n), F_n, u);
}

double grid_elastic_energy(const Grid& grid, const Particles& particles,
                           const std::vector<Material>& materials, const double* u) {
  return deterministic_sum(particles.size(), [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p) {
      const BSplineStencil s = bspline_stencil(grid, &particles.x[3 * p]);
      const Eigen::Matrix3d F_n = particles.deformation(p);
      const Eigen::Matrix3d F = particle_deformation_gradient(grid, s, F_n, u);
      const Material& material = materials[particles.material[p]];
      sum += particles.volume0[p] * with_material_model(material.model, [&](auto m) {
        return energy_density<decltype(m)::value>(F, material.lame);
      });
    }
    return sum;
  });
}

double grid_elastic_gradient(const Grid& grid, const Particles& particles, const ParticleBins& bins,
                             const std::vector<Material>& materials, const double* u, double* gradient) {
  parallel_for(grid.num_dofs(), [&](int64_t begin, int64_t end) {
    std::fill(gradient + begin, gradient + end, 0.0);
  }, 65536);
  // Each particle's energy goes to its own slot, summed afterwards in particle order.
  std::vector<double> energy(static_cast<size_t>(particles.size()), 0.0);
  for_each_particle_coloured(bins, [&](int32_t p) {
    const BSplineStencil s = bspline_stencil(grid, &particles.x[3 * p]);
    const Eigen::Matrix3d F_n = particles.deformation(p);
    const ParticleStencilMap map = stencil_map(grid, s, F_n);
    const Eigen::Matrix3d F = deformation_from_map(map, F_n, u);
    const Material& material = materials[particles.material[p]];
    Eigen::Matrix3d P;
    energy[p] = particles.volume0[p] * with_material_model(material.model, [&](auto m) {
      Mat3<double> P3;
      const double psi = energy_density_and_pk1<decltype(m)::value>(to_mat3(F), material.lame, P3);
      P = to_eigen(P3);
      return psi;
    });
    const Eigen::Matrix3d VP = particles.volume0[p] * P;
    for (int o = 0; o < 27; ++o) Eigen::Map<Eigen::Vector3d>(&gradient[3 * map.node[o]]) += VP * map.g[o];
  });
  return deterministic_sum(particles.size(), [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p) sum += energy[p];
    return sum;
  });
}

double particle_elastic_derivatives(const Grid& grid, const BSplineStencil& stencil,
                                    const Eigen::Matrix3d& F_n, double volume0, const Material& material,
                                    const double* u, bool projected, Vector81d& gradient, Matrix81d& hessian) {
  const ParticleStencilMap map = stencil_map(grid, stencil, F_n);
  const Eigen::Matrix3d F = deformation_from_map(map, F_n, u);
  return with_material_model(material.model, [&](auto m) {
    return particle_derivatives<decltype(m)::value>(map, F, volume0, material.lame, projected, gradient, hessian);
  });
}

Eigen::SparseMatrix<double> grid_elastic_hessian(const Grid& grid, const Particles& particles,
                                                 const std::vector<Material>& materials, const double* u,
                                                 bool projected) {
  using Triplet = Eigen::Triplet<double, int64_t>;
  const int64_t n = particles.size();
  std::vector<std::vector<Triplet>> chunks(static_cast<size_t>((n + kHessianGrain - 1) / kHessianGrain));
  for_each_chunk(n, kHessianGrain, [&](int64_t c, int64_t begin, int64_t end) {
    std::vector<Triplet>& out = chunks[c];
    out.reserve(static_cast<size_t>(end - begin) * 81 * 81);
    Vector81d gradient;
    Matrix81d hessian;
    for (int64_t p = begin; p < end; ++p) {
      const BSplineStencil s = bspline_stencil(grid, &particles.x[3 * p]);
      const Eigen::Matrix3d F_n = particles.deformation(p);
      const ParticleStencilMap map = stencil_map(grid, s, F_n);
      const Eigen::Matrix3d F = deformation_from_map(map, F_n, u);
      const Material& material = materials[particles.material[p]];
      with_material_model(material.model, [&](auto m) {
        return particle_derivatives<decltype(m)::value>(map, F, particles.volume0[p], material.lame, projected,
                                                        gradient, hessian);
      });
      for (int oj = 0; oj < 27; ++oj)
        for (int d = 0; d < 3; ++d)
          for (int oi = 0; oi < 27; ++oi)
            for (int c = 0; c < 3; ++c)
              out.emplace_back(3 * map.node[oi] + c, 3 * map.node[oj] + d, hessian(3 * oi + c, 3 * oj + d));
    }
  });
  std::vector<Triplet> all;
  size_t total = 0;
  for (const auto& chunk : chunks) total += chunk.size();
  all.reserve(total);
  for (auto& chunk : chunks) {
    all.insert(all.end(), chunk.begin(), chunk.end());
    std::vector<Triplet>().swap(chunk);
  }
  Eigen::SparseMatrix<double> H(grid.num_dofs(), grid.num_dofs());
  H.setFromTriplets(all.begin(), all.end());
  return H;
}

}  // namespace nexdyn

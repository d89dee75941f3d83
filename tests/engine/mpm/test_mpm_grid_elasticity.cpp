// The elastic energy of MPM in the grid displacements (engine/mpm/grid_elasticity.hpp): gradient
// against central differences of the energy, exact Hessian against central differences of the
// gradient, the projected Hessian PSD everywhere and equal to the exact one where the material is
// convex, for neo-Hookean and corotated particles.
#include "engine/mpm/grid.hpp"
#include "engine/mpm/grid_elasticity.hpp"
#include "engine/mpm/particles.hpp"
#include "engine/mpm/transfer.hpp"
#include "tests/engine/mpm/mpm_test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Dense>

#include <cmath>
#include <random>
#include <vector>

using namespace nexdyn;

namespace {

struct Setup {
  Grid grid;
  Particles particles;
  ParticleBins bins;
  std::vector<int64_t> active;  // DOFs of the nodes the particles reach
  std::vector<double> u;        // a small random grid displacement
};

// A 3 x 3 x 3-cell box of particles (2 per cell per axis) with deformation gradients
// scale I + perturbation, and a random displacement of amplitude `amplitude` h.
Setup make_setup(double scale, double perturbation, double amplitude, uint32_t seed) {
  Setup s;
  s.grid = make_grid(0.1, Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  sample_box_particles(s.particles, Eigen::Vector3d(0.3, 0.3, 0.3), Eigen::Vector3d(0.3, 0.3, 0.3), 0.1, 2, 1000.0,
                       Eigen::Vector3d::Zero(), 0);
  test::perturb_deformation(s.particles, scale, perturbation, seed);
  REQUIRE(bin_particles(s.grid, s.particles, s.bins) == 0);
  particles_to_grid(s.particles, s.bins, s.grid);
  for (int64_t i = 0; i < s.grid.num_nodes(); ++i)
    if (s.grid.mass[i] > 0.0)
      for (int a = 0; a < 3; ++a) s.active.push_back(3 * i + a);
  std::mt19937 rng(seed + 1);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  s.u.assign(s.grid.num_dofs(), 0.0);
  for (int64_t k : s.active) s.u[k] = amplitude * s.grid.h * unit(rng);
  return s;
}

const MaterialModel kModels[] = {MaterialModel::neohookean, MaterialModel::corotated};

}  // namespace

TEST_CASE("mpm elastic energy: zero at rest, and F_p(u) matches the G2P update") {
  Setup s = make_setup(1.0, 0.0, 0.02, 5);
  const std::vector<Material> materials{test::test_material(MaterialModel::neohookean)};
  const std::vector<double> zero(s.grid.num_dofs(), 0.0);
  CHECK(grid_elastic_energy(s.grid, s.particles, materials, zero.data()) == doctest::Approx(0.0).epsilon(1e-14));
  // The F the energy sees at u is the F grid_to_particles writes for the same u.
  std::vector<Eigen::Matrix3d> F(s.particles.size());
  for (int64_t p = 0; p < s.particles.size(); ++p)
    F[p] = particle_deformation_gradient(s.grid, bspline_stencil(s.grid, &s.particles.x[3 * p]),
                                         s.particles.deformation(p), s.u.data());
  grid_to_particles(s.grid, s.grid.velocity.data(), s.u.data(), s.particles);
  for (int64_t p = 0; p < s.particles.size(); ++p)
    CHECK((Eigen::Matrix3d(s.particles.deformation(p)) - F[p]).norm() < 1e-14);
}

TEST_CASE("mpm elastic gradient matches central differences of the energy") {
  for (MaterialModel model : kModels) {
    CAPTURE(material_model_name(model));
    Setup s = make_setup(1.0, 0.1, 0.02, 7);
    const std::vector<Material> materials{test::test_material(model)};
    std::vector<double> gradient(s.grid.num_dofs());
    const double E = grid_elastic_gradient(s.grid, s.particles, s.bins, materials, s.u.data(), gradient.data());
    CHECK(E == doctest::Approx(grid_elastic_energy(s.grid, s.particles, materials, s.u.data())).epsilon(1e-13));
    const double eps = 1e-7 * s.grid.h;
    double worst = 0.0, norm = 0.0;
    std::vector<double> u = s.u;
    for (int64_t k : s.active) {
      u[k] = s.u[k] + eps;
      const double Ep = grid_elastic_energy(s.grid, s.particles, materials, u.data());
      u[k] = s.u[k] - eps;
      const double Em = grid_elastic_energy(s.grid, s.particles, materials, u.data());
      u[k] = s.u[k];
      worst = std::max(worst, std::abs((Ep - Em) / (2.0 * eps) - gradient[k]));
      norm = std::max(norm, std::abs(gradient[k]));
    }
    CHECK(norm > 0.0);
    CHECK(worst <= 1e-6 * norm);
    // Nodes no particle reaches get no force; the forces sum to zero (translation invariance).
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (int64_t i = 0; i < s.grid.num_nodes(); ++i) {
      if (s.grid.mass[i] == 0.0) CHECK(Eigen::Map<const Eigen::Vector3d>(&gradient[3 * i]).norm() == 0.0);
      total += Eigen::Map<const Eigen::Vector3d>(&gradient[3 * i]);
    }
    CHECK(total.norm() <= 1e-10 * norm);
  }
}

TEST_CASE("mpm elastic Hessian matches central differences of the gradient") {
  for (MaterialModel model : kModels) {
    CAPTURE(material_model_name(model));
    Setup s = make_setup(1.0, 0.1, 0.02, 13);
    const std::vector<Material> materials{test::test_material(model)};
    const Eigen::MatrixXd H = Eigen::MatrixXd(grid_elastic_hessian(s.grid, s.particles, materials, s.u.data(), false));
    const double eps = 1e-7 * s.grid.h;
    std::vector<double> u = s.u, gp(s.grid.num_dofs()), gm(s.grid.num_dofs());
    double worst = 0.0;
    for (int64_t k : s.active) {
      u[k] = s.u[k] + eps;
      grid_elastic_gradient(s.grid, s.particles, s.bins, materials, u.data(), gp.data());
      u[k] = s.u[k] - eps;
      grid_elastic_gradient(s.grid, s.particles, s.bins, materials, u.data(), gm.data());
      u[k] = s.u[k];
      for (int64_t r : s.active) worst = std::max(worst, std::abs((gp[r] - gm[r]) / (2.0 * eps) - H(r, k)));
    }
    const double scale = H.cwiseAbs().maxCoeff();
    CHECK(scale > 0.0);
    CHECK(worst <= 1e-6 * scale);
  }
}

TEST_CASE("mpm projected elastic Hessian is PSD, and exact where the material is convex") {
  for (MaterialModel model : kModels) {
    CAPTURE(material_model_name(model));
    const std::vector<Material> materials{test::test_material(model)};
    // The rows and columns of the active DOFs (the others are zero), read from the sparse matrix.
    auto active_block = [](const Setup& s, const Eigen::SparseMatrix<double>& H) {
      std::vector<int64_t> slot(static_cast<size_t>(H.rows()), -1);
      for (size_t k = 0; k < s.active.size(); ++k) slot[s.active[k]] = static_cast<int64_t>(k);
      const int64_t n = static_cast<int64_t>(s.active.size());
      Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
      int64_t outside = 0;  // entries off the active DOFs: there must be none
      for (int64_t col = 0; col < H.outerSize(); ++col)
        for (Eigen::SparseMatrix<double>::InnerIterator it(H, col); it; ++it) {
          if (slot[it.row()] < 0 || slot[col] < 0) ++outside;
          else A(slot[it.row()], slot[col]) = it.value();
        }
      CHECK(outside == 0);
      return A;
    };
    {
      // Far from rest (F up to 40% off the identity, displacements of 10% of h): indefinite
      // material, PSD after projection.
      Setup s = make_setup(1.0, 0.4, 0.1, 17);
      for (int64_t p = 0; p < s.particles.size(); ++p) REQUIRE(s.particles.deformation(p).determinant() > 0.2);
      const Eigen::MatrixXd A = active_block(s, grid_elastic_hessian(s.grid, s.particles, materials, s.u.data()));
      CHECK((A - A.transpose()).norm() == 0.0);
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A, Eigen::EigenvaluesOnly);
      CHECK(eig.eigenvalues().minCoeff() >= -1e-10 * eig.eigenvalues().maxCoeff());
      const Eigen::MatrixXd E = active_block(s, grid_elastic_hessian(s.grid, s.particles, materials, s.u.data(), false));
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig_exact(E, Eigen::EigenvaluesOnly);
      CHECK(eig_exact.eigenvalues().minCoeff() < -1e-6 * eig_exact.eigenvalues().maxCoeff());
    }
    {
      // Stretched by 5%, small perturbation: every particle's dP/dF is positive definite for
      // nu = 0.3 (both models), so projection changes nothing.
      Setup s = make_setup(1.05, 0.005, 0.002, 19);
      const Eigen::MatrixXd P = active_block(s, grid_elastic_hessian(s.grid, s.particles, materials, s.u.data()));
      const Eigen::MatrixXd E = active_block(s, grid_elastic_hessian(s.grid, s.particles, materials, s.u.data(), false));
      CHECK((P - E).norm() <= 1e-10 * E.norm());
    }
  }
}

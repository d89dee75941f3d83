// The "arap" material (as-rigid-as-possible, Psi = mu ||F - R||^2; Wang 2015, seed 004) is the
// corotated model with lambda = 0 (engine/scene/settings_readers.cpp). Checked here against an
// independent polar decomposition: the energy, the stress P = 2 mu (F - R), the exact dP/dF by
// finite differences of P, and the projected dP/dF: positive semi-definite everywhere, and equal
// to the exact one where that is already PSD.
#include "engine/simulation.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>
#include "kernels/projection/psd_projection.hpp"
#include <Eigen/SVD>

#include <random>

using namespace nexdyn;

namespace {

// R of F = R S by Eigen's SVD, with the reflection moved to the smallest singular value.
Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& F) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(F, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) *= -1.0;
  return U * V.transpose();
}

Eigen::Matrix3d random_f(std::mt19937_64& rng, double spread) {
  std::uniform_real_distribution<double> u(-spread, spread);
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  for (int i = 0; i < 9; ++i) F(i % 3, i / 3) += u(rng);
  return F;
}

}  // namespace

TEST_CASE("arap: energy, stress and both Hessians are those of mu ||F - R||^2") {
  const LameParameters arap{3.0e5, 0.0};
  std::mt19937_64 rng(22);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Matrix3d F = random_f(rng, k < 100 ? 0.3 : 0.9);
    CAPTURE(F);
    const Eigen::Matrix3d R = closest_rotation(F);
    const double psi = energy_density(MaterialModel::corotated, F, arap);
    CHECK(psi == doctest::Approx(arap.mu * (F - R).squaredNorm()).epsilon(1e-10).scale(arap.mu));
    const Eigen::Matrix3d P = pk1(MaterialModel::corotated, F, arap);
    CHECK((P - 2.0 * arap.mu * (F - R)).norm() <= 1e-9 * arap.mu);
    // Exact dP/dF against central differences of P.
    const Matrix9d H = pk1_derivative(MaterialModel::corotated, F, arap);
    for (int c = 0; c < 9; ++c) {
      Eigen::Matrix3d Fp = F, Fm = F;
      const double h = 1e-6;
      Fp(c % 3, c / 3) += h;
      Fm(c % 3, c / 3) -= h;
      const Eigen::Matrix3d dP = (pk1(MaterialModel::corotated, Fp, arap) - pk1(MaterialModel::corotated, Fm, arap)) / (2 * h);
      for (int r = 0; r < 9; ++r) CHECK(H(r, c) == doctest::Approx(dP(r % 3, r / 3)).epsilon(1e-5).scale(arap.mu));
    }
    // Projected: PSD; the same as the exact one when that has no negative eigenvalue.
    const Matrix9d Hp = pk1_derivative_projected(MaterialModel::corotated, F, arap);
    const double smallest_projected = symmetric_eigen(Hp, false).values.minCoeff();
    CHECK(smallest_projected >= -1e-9 * arap.mu);
    const double smallest_exact = symmetric_eigen(0.5 * (H + H.transpose()), false).values.minCoeff();
    if (smallest_exact >= 0.0) CHECK((Hp - H).norm() <= 1e-8 * arap.mu);
  }
}

TEST_CASE("arap: the scene model has lambda 0 and mu from youngs and poisson") {
  const Scene scene = test::scene_from_json(R"({
    "materials": { "a": { "model": "arap", "youngs": 1e6, "poisson": 0.25, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "a" } ]
  })", "arap_scene");
  const Material& m = scene.model.materials[0];
  CHECK(m.arap);
  CHECK(m.model == MaterialModel::corotated);
  CHECK(m.lame.lambda == 0.0);
  CHECK(m.lame.mu == doctest::Approx(1e6 / 2.5));
}

// The contact part of the Newton system against independent references: the gradient of the
// incremental potential with barrier against finite differences of its energy, the merged sparse
// Hessian against a dense sum of the element and contact blocks, and bitwise equality for 1 and
// 2 threads. (Candidates against the brute force: test_candidates.cpp.)
#include "engine/contact/barrier_potential.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/elastic_assembly.hpp"
#include "engine/incremental_potential.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <random>

using namespace nexdyn;

namespace {

// Two stacked boxes 0.01 m apart and a ground plane 0.02 m under the lower one: with
// dhat = 0.05 m many vertex-triangle, edge-edge (parallel ones too) and vertex-plane pairs are
// active.
Scene two_boxes() {
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.4, 0.4, 0.4], "cells": [2, 1, 2] }, "material": "a",
                  "translate": [0.03, 0.46, -0.02] } ]
  })", "contact_two_boxes");
  ObstaclePlane ground;
  ground.point = Eigen::Vector3d(0.0, -0.27, 0.0);
  ground.normal = Eigen::Vector3d::UnitY();
  scene.model.obstacle_planes.push_back(ground);
  return scene;
}

std::vector<double> perturbed(const std::vector<double>& x0, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<double> x = x0;
  for (double& xi : x) xi += u(rng);
  return x;
}

constexpr double kDhat = 0.05;

}  // namespace

TEST_CASE("incremental potential gradient with contact matches finite differences") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  ElasticAssembly elastic(model);
  BarrierPotential contact(model, kDhat);
  IncrementalPotential potential(model, elastic, &contact);
  const std::vector<double> x = perturbed(model.rest_positions, 2e-3, 3);
  const std::vector<double> x_tilde = perturbed(x, 1e-2, 4);
  potential.begin_step(x_tilde, 1e-4, 2e-4, true);
  potential.begin_solve(x.data());
  potential.prepare(x.data(), true);
  REQUIRE(contact.num_active() > 20);
  REQUIRE(std::isfinite(potential.energy(x.data())));
  std::vector<double> grad(model.num_dofs()), values(potential.pattern().nnz());
  potential.gradient_hessian(x.data(), grad.data(), values.data());

  const double h = 1e-7;
  double max_error = 0.0, max_grad = 0.0;
  std::vector<double> xp = x;
  for (int64_t i = 0; i < model.num_dofs(); ++i) {
    xp[i] = x[i] + h;
    const double ep = potential.energy(xp.data());
    xp[i] = x[i] - h;
    const double em = potential.energy(xp.data());
    xp[i] = x[i];
    max_error = std::max(max_error, std::abs((ep - em) / (2 * h) - grad[i]));
    max_grad = std::max(max_grad, std::abs(grad[i]));
  }
  CHECK(max_grad > 0.0);
  CHECK(max_error < 1e-5 * max_grad);
}

TEST_CASE("merged Newton matrix equals elastic plus contact blocks, on 1 and 2 threads") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  const std::vector<double> x = perturbed(model.rest_positions, 2e-3, 5);
  const std::vector<double> x_tilde = perturbed(x, 1e-2, 6);
  const double scale = 1e-4;

  auto assemble = [&](int threads, std::vector<double>& grad, std::vector<double>& values,
                      Eigen::MatrixXd* reference) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    ElasticAssembly elastic(model);
    BarrierPotential contact(model, kDhat);
    IncrementalPotential potential(model, elastic, &contact);
    potential.begin_step(x_tilde, scale, 2 * scale, true);
    potential.begin_solve(x.data());
    potential.prepare(x.data(), true);
    grad.assign(model.num_dofs(), 0.0);
    values.assign(potential.pattern().nnz(), 0.0);
    potential.gradient_hessian(x.data(), grad.data(), values.data());
    if (!reference) return;
    // Reference: s * elastic + mass diagonal + every contact slab added densely.
    std::vector<double> egrad(model.num_dofs()), evalues(elastic.pattern().nnz());
    elastic.gradient_hessian(x.data(), egrad.data(), evalues.data());
    Eigen::MatrixXd H = scale * test::dense_from(elastic.pattern(), evalues);
    for (int32_t v = 0; v < model.num_vertices; ++v)
      for (int d = 0; d < 3; ++d) H(3 * v + d, 3 * v + d) += model.mass[v];
    const std::vector<int32_t>& st = contact.stencils();
    const std::vector<double>& slabs = contact.local_hessians();
    for (int64_t k = 0; k < contact.num_active(); ++k)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          if (st[4 * k + a] < 0 || st[4 * k + b] < 0) continue;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c)
              H(3 * st[4 * k + a] + r, 3 * st[4 * k + b] + c) += slabs[144 * k + (3 * b + c) * 12 + 3 * a + r];
        }
    *reference = H;
    CHECK(potential.pattern().nnz() > elastic.pattern().nnz());  // contact added blocks
    const Eigen::MatrixXd assembled = test::dense_from(potential.pattern(), values);
    CHECK((assembled - H).cwiseAbs().maxCoeff() <= 1e-12 * H.cwiseAbs().maxCoeff());
    // Every contact slab is symmetric PSD after projection.
    for (int64_t k = 0; k < contact.num_active(); ++k) {
      const Eigen::Map<const Eigen::Matrix<double, 12, 12>> S(&slabs[144 * k]);
      CHECK((S - S.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + S.cwiseAbs().maxCoeff()));
      CHECK(Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>>(S).eigenvalues().minCoeff() >=
            -1e-9 * (1.0 + S.cwiseAbs().maxCoeff()));
    }
  };
  std::vector<double> g1, v1, g2, v2;
  Eigen::MatrixXd reference;
  assemble(1, g1, v1, &reference);
  assemble(2, g2, v2, nullptr);
  CHECK(g1 == g2);
  CHECK(v1 == v2);
}

TEST_CASE("CCD-capped step never crosses: the boxes pushed into each other stop apart") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  BarrierPotential contact(model, kDhat);
  const std::vector<double> x = model.rest_positions;
  std::vector<double> p(model.num_dofs(), 0.0);
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.vertex_body[v] == 1) p[3 * v + 1] = -0.5;  // would pass 0.49 m through the lower box
  const double alpha = contact.max_step(x.data(), p.data());
  // The gap is 0.01 m along a 0.5 m motion: contact at t = 0.02, the step stops short of it.
  CHECK(alpha > 0.0);
  CHECK(alpha < 0.02);
  CHECK(alpha > 0.015);
  std::vector<double> y(x.size());
  for (size_t i = 0; i < x.size(); ++i) y[i] = x[i] + alpha * p[i];
  contact.find_candidates(y.data(), nullptr);
  CHECK(std::isfinite(contact.energy(y.data())));
  CHECK(contact.min_squared_distance(y.data()) > 0.0);
  const BarrierPotential::Summary summary = contact.summarize(y.data());
  CHECK(summary.min_distance > 0.0);
  CHECK(summary.min_distance < 0.01 * 0.25);
}

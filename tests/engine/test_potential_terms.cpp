// The potential as a list of terms (engine/potential/potential_term.hpp): a term registered with one
// add_term line enters the energy, the group energies, the gradient and the Hessian's diagonal
// with its class's weight, and nothing else changes.
#include "engine/potential/incremental_potential.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

namespace nexdyn {
namespace {

// e(x) = k/2 |x_v - p|^2 for one vertex v: a spring to a fixed point, weight s.
class AnchorTerm final : public PotentialTerm {
 public:
  AnchorTerm(int32_t vertex, Eigen::Vector3d point, double k) : v_(vertex), p_(point), k_(k) {}
  const char* name() const override { return "anchor"; }
  TermScale scale() const override { return TermScale::potential; }
  TermHessian hessian() const override { return TermHessian::diagonal; }
  double energy(const double* x) const override { return 0.5 * k_ * (at(x) - p_).squaredNorm(); }
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t, double* out) override {
    if (group_of_vertex[v_] >= 0) out[group_of_vertex[v_]] += energy(x);
  }
  void add_gradient(const double* x, double weight, double* grad) override {
    Eigen::Vector3d::Map(grad + 3 * v_) += weight * k_ * (at(x) - p_);
  }
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override {
    add_gradient(x, weight, out.grad);
  }
  void add_diagonal(const double*, double weight, const CscPattern& pattern, double* values,
                    const ActiveSubset*) override {
    for (int d = 0; d < 3; ++d) values[pattern.diagonal[3 * v_ + d]] += weight * k_;
  }

 private:
  Eigen::Vector3d at(const double* x) const { return Eigen::Vector3d::Map(x + 3 * v_); }
  int32_t v_;
  Eigen::Vector3d p_;
  double k_;
};

struct Evaluation {
  double energy = 0.0;
  std::vector<double> grad, values, group;
};

Evaluation evaluate(IncrementalPotential& potential, const Model& model, const std::vector<double>& x,
                    const std::vector<double>& x_tilde, double s) {
  Evaluation e;
  potential.begin_step(x_tilde, weights_context(s, 2.0 * s, true));
  potential.begin_solve(x.data());
  potential.prepare(x.data(), true);
  e.energy = potential.energy(x.data());
  e.grad.assign(model.num_dofs(), 0.0);
  e.values.assign(potential.pattern().nnz(), 0.0);
  potential.gradient_hessian(x.data(), e.grad.data(), e.values.data());
  const std::vector<int32_t> one_group(model.num_vertices, 0);
  e.group.assign(1, 0.0);
  potential.group_energy(x.data(), one_group.data(), 1, e.group.data());
  return e;
}

}  // namespace

TEST_CASE("potential terms: a registered term enters E, its gradient and Hessian with its weight only") {
  const Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "a" } ]
  })", "potential_terms");
  const Model& model = scene.model;
  const std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 3);
  const std::vector<double> x_tilde = test::perturbed(x, 1e-2, 4);
  const double s = 1e-4, k = 3e5;
  const int32_t v = 5;
  const Eigen::Vector3d p(0.1, -0.2, 0.3);

  ElasticAssembly elastic_plain(model), elastic_anchored(model);
  StepHistory history_plain, history_anchored;
  IncrementalPotential plain(model, elastic_plain, history_plain);
  IncrementalPotential anchored(model, elastic_anchored, history_anchored);
  anchored.add_term(std::make_unique<AnchorTerm>(v, p, k));
  REQUIRE(anchored.terms().size() == 3);
  CHECK(std::string(anchored.terms()[0]->name()) == "inertia and gravity");
  CHECK(std::string(anchored.terms()[1]->name()) == "elasticity");
  CHECK(std::string(anchored.terms()[2]->name()) == "anchor");

  const Evaluation a = evaluate(plain, model, x, x_tilde, s);
  const Evaluation b = evaluate(anchored, model, x, x_tilde, s);
  const Eigen::Vector3d r = Eigen::Vector3d::Map(&x[3 * v]) - p;
  const double anchor_energy = 0.5 * k * r.squaredNorm();
  const double round_off = 1e-13 * (std::abs(a.energy) + s * anchor_energy);
  CHECK(std::abs((b.energy - a.energy) - s * anchor_energy) <= round_off);
  CHECK(std::abs(b.group[0] - b.energy) <= 1e-12 * std::abs(b.energy));

  const double grad_scale = *std::max_element(a.grad.begin(), a.grad.end(), [](double l, double m) {
    return std::abs(l) < std::abs(m);
  });
  for (int64_t i = 0; i < model.num_dofs(); ++i) {
    const double expected = i / 3 == v ? s * k * r[i % 3] : 0.0;
    CHECK(std::abs((b.grad[i] - a.grad[i]) - expected) <= 1e-13 * (std::abs(grad_scale) + std::abs(expected)));
  }
  REQUIRE(a.values.size() == b.values.size());
  const CscPattern& pattern = anchored.pattern();
  for (size_t q = 0; q < a.values.size(); ++q) {
    bool anchored_diagonal = false;
    for (int d = 0; d < 3; ++d) anchored_diagonal |= pattern.diagonal[3 * v + d] == static_cast<int64_t>(q);
    const double expected = anchored_diagonal ? s * k : 0.0;
    CHECK(std::abs((b.values[q] - a.values[q]) - expected) <= 1e-13 * (std::abs(a.values[q]) + expected));
  }
}

}  // namespace nexdyn

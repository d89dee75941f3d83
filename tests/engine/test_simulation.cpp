// The step driver with boundary conditions: the static preset against an analytic solution,
// prescribed rotations followed exactly, and failures reported instead of accepted.
#include "engine/simulation.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Geometry>
#include <cmath>

using namespace nexdyn;

TEST_CASE("static: a column hanging under its own weight stretches by rho g L^2 / (2 E)") {
  // Linear elasticity with nu = 0: the exact displacement is u(y) = rho g (L y - y^2 / 2) / E from
  // the clamped end, independent of the cross section, so the free end moves rho g L^2 / (2 E).
  const double rho = 1000.0, g = 9.81, L = 1.0, E = 1e6;
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 1, "steps": 1, "integrator": "static" },
    "solver": { "tolerance": 1e-12 },
    "materials": { "m": { "model": "linear", "youngs": 1e6, "poisson": 0.0, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.1, 1.0, 0.1], "cells": [2, 40, 2] }, "material": "m" } ],
    "boundary": [ { "box_min": [-1, 0.499, -1], "box_max": [1, 0.501, 1], "fix": true } ]
  })", "hanging");
  Simulation sim(scene);
  REQUIRE(sim.step().status == StepStatus::ok);
  double lowest = 0.0;
  for (int32_t v = 0; v < scene.model.num_vertices; ++v)
    if (scene.model.rest_positions[3 * v + 1] < -0.499)
      lowest = std::min(lowest, sim.state().x[3 * v + 1] - scene.model.rest_positions[3 * v + 1]);
  const double expected = -rho * g * L * L / (2 * E);
  CHECK(lowest == doctest::Approx(expected).epsilon(0.01));
  CHECK(sim.state().v[0] == 0.0);
}

TEST_CASE("prescribed rotation: the driven end follows R(omega t) exactly") {
  Scene scene = load_scene(test::scene_path("bar_twist.json"));
  Simulation sim(scene);
  const int steps = 25;
  for (int i = 0; i < steps; ++i) REQUIRE(sim.step().status == StepStatus::ok);
  const DirichletMotion& motion = scene.model.dirichlet_motions[1];
  const Eigen::AngleAxisd rotation(motion.angular_velocity * sim.state().time, motion.axis);
  int driven = 0;
  double worst = 0.0;
  for (int32_t v = 0; v < scene.model.num_vertices; ++v) {
    if (scene.model.dirichlet[v] != 1) continue;
    ++driven;
    const Eigen::Vector3d p0 = Eigen::Vector3d::Map(&scene.model.rest_positions[3 * v]);
    const Eigen::Vector3d expected = motion.center + rotation * (p0 - motion.center);
    worst = std::max(worst, (Eigen::Vector3d::Map(&sim.state().x[3 * v]) - expected).norm());
  }
  CHECK(driven == 7 * 7);
  CHECK(worst < 1e-12);
  // An eighth of a turn after 0.5 s twists the bar between its two held ends: it stores energy.
  StepStats stats;
  sim.measure(stats);
  CHECK(stats.elastic_energy > 0.0);
}

TEST_CASE("a step that cannot converge leaves the state untouched and says why") {
  Scene scene = test::scene_from_json(R"({
    "time": { "dt": 0.01 }, "solver": { "tolerance": 1e-14, "max_iterations": 1 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 0.1, 0.1], "cells": [10, 1, 1] }, "material": "m" } ],
    "boundary": [ { "box_min": [-0.51, -1, -1], "box_max": [-0.49, 1, 1], "fix": true } ]
  })", "noconverge");
  Simulation sim(scene);
  const std::vector<double> before = sim.state().x;
  const StepOutcome outcome = sim.step();
  CHECK(outcome.status == StepStatus::max_iterations);
  CHECK(outcome.message.find("tolerance") != std::string::npos);
  CHECK(sim.state().x == before);
  CHECK(sim.state().step == 0);
}

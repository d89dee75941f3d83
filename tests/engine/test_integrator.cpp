// Time integration against analytic solutions and conservation laws (DESIGN.md section 4).
//   - free fall: Newmark is exact for constant acceleration; implicit Euler lags by g h t / 2
//   - the cantilever (undamped elastic oscillation): Newmark keeps the total energy, Euler and
//     gamma > 1/2 dissipate it, central difference is stable below its limit and blows up above
#include "engine/integrator.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

using namespace nexdyn;

namespace {

std::string free_fall_scene(const std::string& integrator) {
  return R"({
    "name": "free_fall", "gravity": [0, -9.81, 0],
    "time": { "dt": 0.01, "steps": 100, "integrator": ")" + integrator + R"(" },
    "solver": { "tolerance": 1e-9 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.4, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [2, 2, 2] }, "material": "m",
                  "translate": [0, 10, 0], "velocity": [1, 2, 0] } ]
  })";
}

// Largest |x_i(t) - expected_i(t)| over all vertices and all steps.
template <typename Expected>
double max_free_fall_error(const std::string& integrator, Expected expected) {
  Scene scene = test::scene_from_json(free_fall_scene(integrator), "free_fall_" + integrator);
  Simulation sim(scene);
  double worst = 0.0;
  for (int step = 1; step <= 100; ++step) {
    REQUIRE(sim.step().status == StepStatus::ok);
    const double t = sim.state().time;
    for (int32_t v = 0; v < scene.model.num_vertices; ++v)
      for (int d = 0; d < 3; ++d) {
        const double x0 = scene.model.rest_positions[3 * v + d];
        worst = std::max(worst, std::abs(sim.state().x[3 * v + d] - expected(d, x0, t)));
      }
  }
  return worst;
}

constexpr double kG = 9.81, kDt = 0.01;
const double kV0[3] = {1.0, 2.0, 0.0};
const double kA[3] = {0.0, -kG, 0.0};

}  // namespace

TEST_CASE("free fall: newmark reproduces x0 + v0 t + g t^2 / 2 to round-off") {
  const double err = max_free_fall_error("newmark", [](int d, double x0, double t) {
    return x0 + kV0[d] * t + 0.5 * kA[d] * t * t;
  });
  CHECK(err < 1e-10);
}

TEST_CASE("free fall: implicit Euler's position error is g h t / 2") {
  // Backward Euler: v_n = v0 + g n h, x_n = x0 + v0 t + g h^2 n (n + 1) / 2 = exact + g h t / 2.
  const double err = max_free_fall_error("implicit_euler", [](int d, double x0, double t) {
    return x0 + kV0[d] * t + 0.5 * kA[d] * t * t + 0.5 * kA[d] * kDt * t;
  });
  CHECK(err < 1e-10);
  // And the error is real: the exact parabola is off by g h t / 2 = 0.04905 m at t = 1 s.
  const double err_vs_exact = max_free_fall_error("implicit_euler", [](int d, double x0, double t) {
    return x0 + kV0[d] * t + 0.5 * kA[d] * t * t;
  });
  CHECK(err_vs_exact == doctest::Approx(0.5 * kG * kDt * 1.0).epsilon(1e-6));
}

namespace {

struct EnergyHistory {
  double start = 0.0, min = 0.0, max = 0.0, last = 0.0, peak_kinetic = 0.0;
  bool failed = false;
  int steps_done = 0;
};

// The cantilever of scenes/cantilever.json (2 m x 0.2 m x 0.2 m neo-Hookean bar, E = 1e7 Pa,
// clamped at one end, sagging and swinging under gravity) on a coarser 20 x 2 x 2 mesh so that
// thousands of steps run in seconds.
constexpr const char* kCantilever = R"({
  "gravity": [0, -9.81, 0],
  "materials": { "rubber": { "model": "neohookean", "youngs": 1e7, "poisson": 0.3, "density": 1000 } },
  "bodies": [ { "box": { "size": [2.0, 0.2, 0.2], "cells": [20, 2, 2] }, "material": "rubber" } ],
  "boundary": [ { "box_min": [-1.001, -1, -1], "box_max": [-0.999, 1, 1], "fix": true } ]
})";

EnergyHistory cantilever_energy(const IntegratorParams& integrator, double dt, int steps) {
  Scene scene = test::scene_from_json(kCantilever, "cantilever");
  scene.time.integrator = integrator;
  scene.time.dt = dt;
  scene.solver.tolerance = 1e-7;
  Simulation sim(scene);
  StepStats s0;
  sim.measure(s0);
  EnergyHistory h;
  h.start = h.min = h.max = h.last = s0.total_energy;
  for (int i = 0; i < steps; ++i) {
    if (sim.step().status != StepStatus::ok) {
      h.failed = true;
      break;
    }
    const StepStats& s = sim.last_stats();
    if (!std::isfinite(s.total_energy)) {
      h.failed = true;
      break;
    }
    h.min = std::min(h.min, s.total_energy);
    h.max = std::max(h.max, s.total_energy);
    h.last = s.total_energy;
    h.peak_kinetic = std::max(h.peak_kinetic, s.kinetic_energy);
    h.steps_done = i + 1;
  }
  return h;
}

}  // namespace

TEST_CASE("cantilever: newmark conserves energy far above the explicit limit while Euler and gamma > 1/2 dissipate") {
  // dt = 0.01 s is more than 14 times the explicit (central difference) stability limit of this
  // mesh, which the central-difference case below brackets between 5e-4 and 7e-4 s.
  const EnergyHistory newmark = cantilever_energy(*integrator_preset("newmark"), 0.01, 1000);
  REQUIRE_FALSE(newmark.failed);
  REQUIRE(newmark.peak_kinetic > 0.0);
  MESSAGE("newmark energy drift " << (newmark.max - newmark.min) / newmark.peak_kinetic
                                  << " of peak kinetic energy " << newmark.peak_kinetic);
  CHECK((newmark.max - newmark.min) < 0.01 * newmark.peak_kinetic);

  const EnergyHistory euler = cantilever_energy(*integrator_preset("implicit_euler"), 0.01, 1000);
  REQUIRE_FALSE(euler.failed);
  const double euler_loss = euler.start - euler.last;
  MESSAGE("implicit Euler lost " << euler_loss / newmark.peak_kinetic << " of the peak kinetic energy");
  CHECK(euler_loss > 0.5 * newmark.peak_kinetic);

  IntegratorParams damped{"custom", 0.5, 0.3025, 0.6, false};  // beta = (gamma + 1/2)^2 / 4
  const EnergyHistory gamma = cantilever_energy(damped, 0.01, 1000);
  REQUIRE_FALSE(gamma.failed);
  const double gamma_loss = gamma.start - gamma.last;
  MESSAGE("gamma = 0.6 lost " << gamma_loss / newmark.peak_kinetic << " of the peak kinetic energy");
  CHECK(gamma_loss > 0.05 * newmark.peak_kinetic);
  CHECK(gamma_loss < euler_loss);
}

TEST_CASE("cantilever: central difference is stable below its limit and blows up above it") {
  const IntegratorParams central = *integrator_preset("central_difference");
  const EnergyHistory below = cantilever_energy(central, 5e-4, 1000);
  REQUIRE_FALSE(below.failed);
  REQUIRE(below.peak_kinetic > 0.0);
  CHECK((below.max - below.min) < 0.01 * below.peak_kinetic);

  const EnergyHistory above = cantilever_energy(central, 7e-4, 500);
  const bool blew_up = above.failed || (above.max - above.start) > 1e3 * std::max(below.peak_kinetic, 1e-12);
  CHECK(blew_up);
}

TEST_CASE("integrator presets carry the DESIGN.md parameters") {
  struct Row { const char* name; double alpha, beta, gamma; };
  const Row rows[] = {{"implicit_euler", 1, 0.5, 1},       {"newmark", 0.5, 0.25, 0.5},
                      {"newmark_linear", 0.5, 1.0 / 6, 0.5}, {"fox_goodwin", 0.5, 1.0 / 12, 0.5},
                      {"central_difference", 0.5, 0, 0.5},   {"symplectic_euler", 1, 0, 0}};
  for (const Row& r : rows) {
    const auto p = integrator_preset(r.name);
    REQUIRE(p);
    CHECK(p->alpha == r.alpha);
    CHECK(p->beta == r.beta);
    CHECK(p->gamma == r.gamma);
    CHECK(p->is_explicit() == (r.beta == 0.0));
  }
  CHECK(integrator_preset("static")->is_static);
  CHECK_FALSE(integrator_preset("leapfrog"));
}

TEST_CASE("symplectic Euler is x += h v_{n+1} with v_{n+1} = v_n + h a_n") {
  Scene scene = test::scene_from_json(free_fall_scene("symplectic_euler"), "symplectic");
  Simulation sim(scene);
  for (int n = 1; n <= 10; ++n) REQUIRE(sim.step().status == StepStatus::ok);
  // y_n = y0 + v0 t - g h^2 n (n + 1) / 2 for the same recursion as backward Euler here.
  const double t = 10 * kDt;
  const double y0 = scene.model.rest_positions[1];
  CHECK(sim.state().x[1] == doctest::Approx(y0 + 2.0 * t - 0.5 * kG * kDt * kDt * 10 * 11).epsilon(1e-12));
}

// Whole simulations against closed-form dynamics: the first bending frequency of a clamped
// cantilever against Euler-Bernoulli beam theory at three mesh resolutions (the discretisation
// error must shrink), and the small-angle period of a stiff bar swinging on a pin joint against
// the compound-pendulum formula. (The order of accuracy of the time integrators under dt halving
// is measured on the cantilever in test_integrator.cpp.)
#include "engine/integrator.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/cantilever_support.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

std::string number(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", value);
  return buf;
}

// The times at which the samples y(t_k) cross `level`, linearly interpolated.
std::vector<double> crossings(const std::vector<double>& t, const std::vector<double>& y, double level) {
  std::vector<double> at;
  for (size_t k = 1; k < y.size(); ++k) {
    const double a = y[k - 1] - level, b = y[k] - level;
    if ((a < 0.0) != (b < 0.0)) at.push_back(t[k - 1] + (t[k] - t[k - 1]) * a / (a - b));
  }
  return at;
}

// The period of an oscillation about `level` from its crossings: twice the mean spacing of the
// first and last of them (a whole number of half periods).
double period_from(const std::vector<double>& t, const std::vector<double>& y, double level) {
  const std::vector<double> at = crossings(t, y, level);
  REQUIRE(at.size() >= 3);
  return 2.0 * (at.back() - at.front()) / double(at.size() - 1);
}

// A rubber beam, 2 m x 0.2 m x 0.2 m, clamped at x = -1, under a gravity so weak that the
// tip moves 0.6 mm: linear elasticity in effect, while the step load sets it vibrating about
// its sagged shape.
std::string cantilever_json(int nx, int ny, const std::string& integrator) {
  const std::string cells = std::to_string(nx) + ", " + std::to_string(ny) + ", " + std::to_string(ny);
  return R"({
    "gravity": [0, -0.01, 0],
    "time": { "dt": 0.01, "integrator": ")" + integrator + R"(" },
    "solver": { "tolerance": 1e-9 },
    "materials": { "rubber": { "model": "neohookean", "youngs": 1e7, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [2.0, 0.2, 0.2], "cells": [)" + cells + R"(] }, "material": "rubber" } ],
    "boundary": [ { "box_min": [-1.001, -1, -1], "box_max": [-0.999, 1, 1], "fix": true } ]
  })";
}

// The cantilever's first bending frequency [rad/s], measured: the static sag (one step of the
// static integrator) is the level the tip oscillates about; Newmark, which neither damps nor (at
// omega dt = 0.05) shifts the period by more than (omega dt)^2 / 12 = 2e-4, runs three periods.
double measured_frequency(int nx, int ny) {
  Scene statics = test::scene_from_json(cantilever_json(nx, ny, "static"), "beam_static");
  Simulation sag(statics);
  REQUIRE(sag.step().status == StepStatus::ok);
  const double level = test::tip_y(statics.model, sag.state().x);

  Scene scene = test::scene_from_json(cantilever_json(nx, ny, "newmark"), "beam_dynamic");
  scene.time.energy_guard = false;
  Simulation sim(scene);
  std::vector<double> t = {0.0}, y = {test::tip_y(scene.model, sim.state().x)};
  for (int i = 0; i < 380; ++i) {
    REQUIRE(sim.step().status == StepStatus::ok);
    t.push_back(sim.state().time);
    y.push_back(test::tip_y(scene.model, sim.state().x));
  }
  return 2.0 * M_PI / period_from(t, y, level);
}

}  // namespace

TEST_CASE("cantilever: the first bending frequency approaches Euler-Bernoulli's under mesh refinement") {
  // Euler-Bernoulli, clamped-free: omega_1 = (1.8751)^2 sqrt(E I / (rho A L^4)), I = a^4 / 12.
  const double E = 1e7, rho = 1000.0, L = 2.0, a = 0.2;
  const double omega_eb = 1.875104 * 1.875104 * std::sqrt(E * (a * a * a * a / 12.0) / (rho * a * a * std::pow(L, 4)));
  double previous_error = 0.0;
  std::vector<double> omegas;
  for (const auto& [nx, ny] : {std::pair{10, 1}, std::pair{20, 2}, std::pair{40, 4}}) {
    CAPTURE(nx);
    const double omega = measured_frequency(nx, ny);
    omegas.push_back(omega);
    const double error = omega / omega_eb - 1.0;
    MESSAGE(nx << " x " << ny << " x " << ny << " cells: omega_1 = " << omega << " rad/s, Euler-Bernoulli "
                << omega_eb << " rad/s, " << 100.0 * error << "%");
    // Linear tets are too stiff in bending (shear locking): the error is positive and shrinks
    // with the cells across the section.
    CHECK(error > 0.0);
    if (previous_error > 0.0) CHECK(error < 0.6 * previous_error);
    previous_error = error;
  }
  // The error halves with the cell size (first order): Richardson's extrapolation from the two
  // finest meshes, 2 omega(h/2) - omega(h), estimates the converged model's frequency. That
  // differs from Euler-Bernoulli only by what beam theory leaves out: shear and rotary inertia
  // (Timoshenko: about -1% at L / a = 10) and the clamped face's Poisson constraint (stiffer); 2%
  // bounds both.
  const double extrapolated = 2.0 * omegas[2] - omegas[1];
  MESSAGE("extrapolated to zero cell size: ", extrapolated, " rad/s, ", 100.0 * (extrapolated / omega_eb - 1.0), "%");
  CHECK(std::abs(extrapolated / omega_eb - 1.0) < 0.02);
}

TEST_CASE("pendulum: a stiff bar on a pin swings with the compound pendulum's small-angle period") {
  // A 1 m bar hangs from a pin at its top end, started 0.05 rad from the vertical.
  const double theta0 = 0.05, L = 1.0;
  const double s = std::sin(theta0), c = std::cos(theta0);
  const std::string json = R"({
    "gravity": [0, -9.81, 0],
    "time": { "dt": 0.005, "integrator": "newmark" },
    "solver": { "tolerance": 1e-8 },
    "materials": { "stiff": { "model": "neohookean", "youngs": 1e9, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.05, 1, 0.05], "cells": [1, 8, 1] }, "material": "stiff",
                  "rotate_deg": [0, 0, )" + number(theta0 * 180.0 / M_PI) + R"(],
                  "translate": [)" + number(0.5 * L * s) + ", " + number(-0.5 * L * c) + R"(, 0] } ],
    "joints": [ { "type": "pin", "body": 0, "point": [0, 0, 0] } ]
  })";
  Scene scene = test::scene_from_json(json, "pendulum");
  scene.time.energy_guard = false;
  const Model& model = scene.model;
  // The rigid-body period of the discrete bar: its lumped masses give the moment of inertia about
  // the pin's axis (z) and the distance of the centre of mass, T = 2 pi sqrt(I / (m g d)).
  double mass = 0.0, inertia = 0.0;
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    const Eigen::Vector3d r = Eigen::Vector3d::Map(&model.rest_positions[3 * v]);
    mass += model.mass[v];
    moment += model.mass[v] * r;
    inertia += model.mass[v] * (r.x() * r.x() + r.y() * r.y());
  }
  const double d = (moment / mass).norm();
  const double period = 2.0 * M_PI * std::sqrt(inertia / (mass * 9.81 * d));

  Simulation sim(scene);
  std::vector<double> t = {0.0}, angle;
  auto angle_now = [&] {
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
    for (int32_t v = 0; v < model.num_vertices; ++v) com += model.mass[v] * Eigen::Vector3d::Map(&sim.state().x[3 * v]);
    return std::atan2(com.x(), -com.y());
  };
  angle.push_back(angle_now());
  CHECK(std::abs(angle[0] - theta0) < 1e-12);
  const int steps = static_cast<int>(std::ceil(2.6 * period / scene.time.dt));
  for (int i = 0; i < steps; ++i) {
    REQUIRE(sim.step().status == StepStatus::ok);
    t.push_back(sim.state().time);
    angle.push_back(angle_now());
  }
  const double measured = period_from(t, angle, 0.0);
  MESSAGE("period: measured ", measured, " s, compound pendulum ", period, " s (", 100.0 * (measured / period - 1.0), "%)");
  // What separates the two, each below 2e-4: the finite amplitude lengthens the period by
  // theta0^2 / 16 = 1.6e-4; Newmark's trapezoidal rule by (omega dt)^2 / 12 = 3e-5; the bar's
  // stretch under its weight, rho g L / E ~ 1e-5; the pin's augmented Lagrangian holds it to
  // solver.joint_tolerance. 1e-3 leaves room for their sum and no more.
  CHECK(std::abs(measured / period - 1.0) < 1e-3);
}

TEST_CASE("a spinning body in empty space keeps its momentum exactly and its angular momentum to the step's order") {
  // A soft box spun about a tilted axis with no gravity, contact or boundary. The elastic forces
  // of every tet sum to zero and have zero moment, so momentum is kept to rounding under every
  // scheme; the schemes keep angular momentum only up to their error (none of them is the
  // midpoint rule), so its drift must shrink as dt does: by about 4 for a second-order scheme
  // (measured: Newmark 5.1e-4 -> 1.5e-4, generalized-alpha 7.8e-4 -> 1.8e-4 over 0.2 s), by 2 for
  // a first-order one, which fails.
  auto drift = [](const std::string& integrator, double dt) {
    const int steps = static_cast<int>(std::lround(0.2 / dt));
    const Scene scene = test::scene_from_json(R"({"gravity": [0, 0, 0],
      "time": {"dt": )" + number(dt) + R"(, "integrator": ")" + integrator + R"("},
      "materials": {"m": {"model": "neohookean", "youngs": 2e5, "poisson": 0.3, "density": 1000}},
      "bodies": [{"box": {"size": [0.3, 0.1, 0.2], "cells": [6, 2, 4]}, "material": "m",
                  "velocity": [0.2, 0, 0], "angular_velocity": [1, 4, 2]}]})",
                                              "spin_" + integrator);
    Simulation simulation(scene);
    const Model& m = simulation.model();
    auto momenta = [&](Eigen::Vector3d& p, Eigen::Vector3d& L) {
      p.setZero();
      L.setZero();
      for (int32_t i = 0; i < m.num_vertices; ++i) {
        const Eigen::Vector3d x = Eigen::Vector3d::Map(&simulation.state().x[3 * i]);
        const Eigen::Vector3d v = Eigen::Vector3d::Map(&simulation.state().v[3 * i]);
        p += m.mass[i] * v;
        L += m.mass[i] * x.cross(v);
      }
    };
    Eigen::Vector3d p0, L0, p, L;
    momenta(p0, L0);
    for (int k = 0; k < steps; ++k) REQUIRE(simulation.step().ok());
    momenta(p, L);
    CHECK((p - p0).norm() <= 1e-12 * p0.norm());
    // stats.csv's columns hold the same sums.
    CHECK((simulation.last_stats().momentum - p).norm() <= 1e-14 * p.norm());
    CHECK((simulation.last_stats().angular_momentum - L).norm() <= 1e-14 * L.norm());
    return (L - L0).norm() / L0.norm();
  };
  for (const std::string integrator : {"newmark", "generalized_alpha"}) {
    const double coarse = drift(integrator, 0.01), fine = drift(integrator, 0.005);
    MESSAGE(integrator << ": angular momentum drift " << coarse << " at dt 0.01, " << fine << " at dt 0.005 over 0.2 s");
    CHECK(coarse < 2e-3);
    CHECK(fine < 0.4 * coarse);
  }
}

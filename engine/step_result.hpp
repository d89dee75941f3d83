// What a step hands back to whoever drives it (the run loop, the tests): how it ended
// (StepStatus, StepOutcome) and its row of stats.csv (StepStats, with its EnergyBalance). Every
// kind of simulation (tet bodies: simulation.hpp; particle bodies: mpm/mpm_simulation.hpp) speaks
// these, so the run loop (run.cpp) and the retry by halving (step_retry.hpp) serve them alike.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace nexdyn {

// How a step ended. The solvers never throw for a failure: every failure on their path, the linear
// solver's included, comes back as one of these with a sentence saying why, and the driver decides
// (a failed attempt is put back and retried as two halves, step_retry.hpp). The one exception that
// crosses them is StepStopped (stop_request.hpp), a request to abandon the step, which the step's
// driver turns into `stopped`.
enum class StepStatus {
  ok,
  max_iterations,         // Newton increment still above the tolerance
  line_search_failed,     // no step length decreased the energy
  factorization_failed,   // the Newton matrix is not positive definite (Cholesky refused it)
  non_finite,             // NaN/inf in the energy or gradient, or an inverted start
  boundary_collision,     // a moving boundary or obstacle cannot reach its prescribed position
  linear_solver_failed,   // CHOLMOD could not analyse, factorise or solve whatever the values:
                          // out of memory, a matrix too large for its indices, invalid input
  stopped,                // abandoned at a safe point on request (SIGINT, SIGTERM): the state is
                          // the step's start, as if it had not been attempted
};

inline std::string_view step_status_name(StepStatus s) {
  switch (s) {
    case StepStatus::ok: return "ok";
    case StepStatus::max_iterations: return "max_iterations";
    case StepStatus::line_search_failed: return "line_search_failed";
    case StepStatus::factorization_failed: return "factorization_failed";
    case StepStatus::non_finite: return "non_finite";
    case StepStatus::boundary_collision: return "boundary_collision";
    case StepStatus::linear_solver_failed: return "linear_solver_failed";
    case StepStatus::stopped: return "stopped";
  }
  return "?";
}

// The failed attempts of one step that advance_or_split (engine/step_retry.hpp) split in halves.
struct RetryLog {
  int retries = 0;
  std::string first_failure;  // the first one's status, message, and its dt and start time
};

struct StepOutcome {
  StepStatus status = StepStatus::ok;
  std::string message;          // empty when ok
  bool retry_may_help = true;   // false when no smaller step can help (particles left the grid)
  bool ok() const { return status == StepStatus::ok; }
};

// The energy balance of a step (issue 16): where the change of the total energy came from.
//
//   total_{n+1} - total_n = boundary_work - friction_dissipated - damping_dissipated + kappa_energy
//                           + integrator_energy
//
// total = kinetic + elastic + gravity + kappa B, the total_energy column of stats.csv.
// - boundary_work: what the held vertices (moving boundaries, kinematic obstacles) did on the
//   rest: the sum over held vertices of F . dx, F the force that keeps a held vertex on its path,
//   F = m a - f(x). Its inertia and gravity parts are exact (the held kinetic energy's change,
//   -m g . dx); the elastic force is averaged over the step's two ends (trapezoidal rule, as
//   Newmark treats it); contact and friction act at the end of the step, as they do in the
//   step (engine/potential/incremental_potential.hpp). Fixed vertices do no work.
// - friction_dissipated: grad D(x_{n+1}) . (x_{n+1} - x_n) over all vertices = sum over the
//   friction contacts of mu N f1(|u|) |u| >= 0, the lagged friction force times the slip.
// - damping_dissipated: dx^T D dx / h, the energy the Rayleigh damping force -D v took out over
//   the step: >= 0, and its exact work under implicit Euler and under Newmark on a linear problem
//   (Simulation::account_damping). stats.csv reports its running sum since the start.
// - kappa_energy: (kappa_{n+1} - kappa_n) B(x_{n+1}): the barrier energy that a raised barrier
//   stiffness added at the configuration it was raised in, not earned by any motion.
// - integrator_energy: the rest, what the time integration itself created (> 0) or took out
//   (< 0): Newmark's error on a nonlinear problem, generalized-alpha's and Euler's numerical
//   damping, and the impulsive contact treatment.
// Joint forces do no work in the exact problem; their augmented Lagrangian's small violation
// work is part of integrator_energy. The functions that book these are in energy_balance.hpp.
struct EnergyBalance {
  double boundary_work = 0.0;        // [J] put in by moving boundaries and obstacles
  double friction_dissipated = 0.0;  // [J] taken out by friction (>= 0)
  double damping_dissipated = 0.0;   // [J] taken out by Rayleigh damping (stats.csv: cumulative)
  double kappa_energy = 0.0;         // [J] put in by raising the barrier stiffness
  double integrator_energy = 0.0;    // [J] put in (> 0) or taken out (< 0) by the time integration

  EnergyBalance& operator+=(const EnergyBalance& o) {
    boundary_work += o.boundary_work;
    friction_dissipated += o.friction_dissipated;
    damping_dissipated += o.damping_dissipated;
    kappa_energy += o.kappa_energy;
    integrator_energy += o.integrator_energy;
    return *this;
  }
};

// One row of stats.csv (the README lists the columns; run.cpp writes them).
struct StepStats {
  int64_t step = 0;
  double time = 0.0;
  double kinetic_energy = 0.0;
  double elastic_energy = 0.0;
  double gravity_energy = 0.0;  // -sum m g . x
  double barrier_energy = 0.0;
  double total_energy = 0.0;
  Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
  int newton_iterations = 0;
  int64_t contacts = 0;
  double min_distance = 0.0;
  double wall_seconds = 0.0;
  std::optional<double> joint_violation;  // [m] max over joints; only with joints (extra column)
  int retries = 0;  // failed attempts of this step, each retried as two of half the dt
  std::string retried_because;  // why the first of them failed: "[status] message (a step of ...)"
  EnergyBalance balance;  // where the change of total_energy came from (columns after retries)
  int guarded_steps = 0;  // (sub)steps of this step the energy guard retook with implicit Euler
  int32_t sleeping_bodies = 0;  // bodies asleep at the end of the step (engine/sleeping.hpp)
  double damping_dissipated = 0.0;  // [J] taken out by Rayleigh damping since the start
  // [kg m^2/s] about the origin: sum m x cross v over the vertices (lumped masses); for particles
  // each particle's APIC spin as well (engine/mpm/particles.hpp). The last columns.
  Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();
};

}  // namespace nexdyn

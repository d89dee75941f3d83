// MPM scenes stepped with retries and measured (see mpm_simulation.hpp).
#include "engine/mpm/mpm_simulation.hpp"

#include "engine/parallel.hpp"
#include "engine/step_retry.hpp"
#include "kernels/elasticity/elasticity.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace nexdyn {

MpmSimulation::MpmSimulation(const Scene& scene) : scene_(scene), model_(*scene.mpm), stepper_(*scene.mpm) {
  settings_.integrator = scene.time.integrator;
  settings_.tolerance = scene.solver.tolerance;
  settings_.max_iterations = scene.solver.max_iterations;
  state_.particles = model_.initial;
  // The consistent start of generalized-alpha, abar^0 = a^0 (as Simulation's a_bar = a): the
  // particles start at rest shape (F = I), where the elastic force is zero, so a^0 = g. Starting
  // from abar = 0 instead took only gamma h g of the first step's gravity into the velocity: under
  // rho_inf 0.5 a body fell h g / 6 slower than free fall, for ever after.
  state_.history.a_bar.resize(state_.particles.x.size());
  for (size_t k = 0; k < state_.history.a_bar.size(); ++k) state_.history.a_bar[k] = model_.gravity[k % 3];
  StepStats start;
  measure(start);
  previous_total_ = start.total_energy;
}

StepOutcome MpmSimulation::step() {
  const auto start = std::chrono::steady_clock::now();
  RetryLog retries;
  step_iterations_ = 0;
  boundary_nodes_ = 0;
  const double t_next = state_.time + scene_.time.dt;
  StepOutcome outcome;
  try {
    outcome = advance_or_split(*this, state_.time, t_next, scene_.time.dt, 0, scene_.solver.substep_halvings, retries);
  } catch (const StepStopped& stop) {
    return stopped_outcome(stop);
  }
  if (!outcome.ok()) return outcome;
  ++state_.step;
  stats_ = StepStats{};
  stats_.step = state_.step;
  stats_.time = state_.time;
  stats_.newton_iterations = step_iterations_;
  stats_.retries = retries.retries;
  stats_.retried_because = std::move(retries.first_failure);
  {
    ProfileScope scope(&profile_, StepPhase::measure);
    measure(stats_);
  }
  stats_.contacts = boundary_nodes_;
  stats_.balance.integrator_energy = stats_.total_energy - previous_total_;
  previous_total_ = stats_.total_energy;
  stats_.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return outcome;
}

StepOutcome MpmSimulation::attempt(double t_start, double /*t_end*/, double dt, int level, const Snapshot& /*before*/) {
  if (level == fail_level_) return {StepStatus::max_iterations, "failed on purpose (test seam)"};
  const MpmStepResult result =
      stepper_.advance(state_.particles, state_.history, t_start, dt, settings_, &profile_);
  step_iterations_ += result.newton_iterations;
  pcg_iterations_ += result.pcg_iterations;
  if (!result.ok) return {result.status, result.message, result.retry_may_help};
  boundary_nodes_ = std::max(boundary_nodes_, result.boundary_nodes);
  return {};
}

void MpmSimulation::measure(StepStats& stats) const {
  const Particles& P = state_.particles;
  const int64_t n = P.size();
  const double h2_4 = 0.25 * model_.grid_spacing * model_.grid_spacing;
  const Eigen::Vector3d& g = model_.gravity;
  stats.kinetic_energy = deterministic_sum(n, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p)
      sum += 0.5 * P.mass[p] * (P.velocity(p).squaredNorm() + h2_4 * P.affine(p).squaredNorm());
    return sum;
  });
  stats.elastic_energy = deterministic_sum(n, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p) {
      const Material& m = model_.materials[P.material[p]];
      sum += P.volume0[p] * energy_density(m.model, P.deformation(p), m.lame);
    }
    return sum;
  });
  stats.gravity_energy = deterministic_sum(n, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p) sum -= P.mass[p] * g.dot(P.position(p));
    return sum;
  });
  stats.barrier_energy = 0.0;
  stats.total_energy = stats.kinetic_energy + stats.elastic_energy + stats.gravity_energy;
  stats.momentum = total_momentum(P);
  stats.angular_momentum = total_angular_momentum(P, model_.grid_spacing);
  stats.contacts = 0;
  stats.min_distance = std::numeric_limits<double>::infinity();
  for (int64_t p = 0; p < n; ++p)
    for (const MpmPlane& plane : model_.planes)
      stats.min_distance = std::min(stats.min_distance, plane.signed_distance(P.position(p)));
}

void MpmSimulation::adopt(const MpmState& state, double previous_total) {
  state_ = state;
  previous_total_ = previous_total;
}

}  // namespace nexdyn

// MPM scenes stepped with retries, measured and checkpointed (see mpm_simulation.hpp).
#include "engine/mpm/mpm_simulation.hpp"

#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity.hpp"

#include <chrono>
#include <cmath>
#include <limits>

namespace nexdyn {

namespace {
constexpr const char* kMpmCheckpointTag = "nexdyn mpm state 1";
}  // namespace

MpmSimulation::MpmSimulation(const Scene& scene) : scene_(scene), model_(*scene.mpm), stepper_(*scene.mpm) {
  settings_.integrator = scene.time.integrator;
  settings_.tolerance = scene.solver.tolerance;
  settings_.max_iterations = scene.solver.max_iterations;
  state_.particles = model_.initial;
  state_.history.a_bar.assign(state_.particles.x.size(), 0.0);
  StepStats start;
  measure(start);
  previous_total_ = start.total_energy;
}

StepOutcome MpmSimulation::step() {
  const auto start = std::chrono::steady_clock::now();
  int iterations = 0, retries = 0;
  int64_t boundary_nodes = 0;
  // On failure advance_or_split has put the state back as it was.
  const MpmStepResult result = advance_or_split(scene_.time.dt, 0, iterations, retries, boundary_nodes);
  if (!result.ok) return {result.status, result.message};
  ++state_.step;
  stats_ = StepStats{};
  stats_.step = state_.step;
  stats_.time = state_.time;
  stats_.newton_iterations = iterations;
  stats_.retries = retries;
  {
    ProfileScope scope(&profile_, StepPhase::measure);
    measure(stats_);
  }
  stats_.contacts = boundary_nodes;
  stats_.balance.integrator_energy = stats_.total_energy - previous_total_;
  previous_total_ = stats_.total_energy;
  stats_.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return {};
}

MpmStepResult MpmSimulation::advance_or_split(double dt, int level, int& iterations, int& retries,
                                              int64_t& boundary_nodes) {
  const MpmState before = state_;
  MpmStepResult result =
      stepper_.advance(state_.particles, state_.history, state_.time, dt, settings_, &profile_);
  iterations += result.newton_iterations;
  pcg_iterations_ += result.pcg_iterations;
  if (result.ok) {
    state_.time += dt;
    boundary_nodes = result.boundary_nodes;
    return result;
  }
  state_ = before;
  if (!result.retry_may_help || level >= scene_.solver.substep_halvings) return result;
  ++retries;
  for (int half = 0; half < 2; ++half) {
    MpmStepResult part = advance_or_split(0.5 * dt, level + 1, iterations, retries, boundary_nodes);
    if (!part.ok) {
      state_ = before;
      return part;
    }
  }
  return MpmStepResult{};
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
  stats.contacts = 0;
  stats.min_distance = std::numeric_limits<double>::infinity();
  for (int64_t p = 0; p < n; ++p)
    for (const MpmPlane& plane : model_.planes)
      stats.min_distance = std::min(stats.min_distance, plane.signed_distance(P.position(p)));
}

void MpmSimulation::save(CheckpointWriter& out) const {
  out.put_string(kMpmCheckpointTag);
  out.put(state_.step);
  out.put(state_.time);
  out.put(previous_total_);
  out.put_vector(state_.particles.x);
  out.put_vector(state_.particles.v);
  out.put_vector(state_.particles.F);
  out.put_vector(state_.particles.C);
  out.put_vector(state_.history.a_bar);
}

void MpmSimulation::restore(CheckpointReader& in) {
  if (in.get_string() != kMpmCheckpointTag) in.fail("not an MPM state of this version");
  const int64_t n = model_.initial.size();
  MpmState s;
  s.particles = model_.initial;
  s.step = in.get<int64_t>();
  s.time = in.get<double>();
  const double total = in.get<double>();
  s.particles.x = in.get_vector<double>(3 * n);
  s.particles.v = in.get_vector<double>(3 * n);
  s.particles.F = in.get_vector<double>(9 * n);
  s.particles.C = in.get_vector<double>(9 * n);
  s.history.a_bar = in.get_vector<double>(3 * n);
  if (s.step < 0 || !std::isfinite(s.time)) in.fail("inconsistent MPM step and time");
  state_ = std::move(s);
  previous_total_ = total;
}

}  // namespace nexdyn

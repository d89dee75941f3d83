// A scene of particle bodies stepped by implicit (or explicit) MPM (issue 23): the counterpart of
// Simulation for `"particles"` bodies, with the same step contract, so `nexdyn run` and
// `nexdyn resume` drive either (engine/run.cpp).
//
// step() attempts the scene's dt; a failed attempt (Newton, line search, a particle turned inside
// out by an explicit step) leaves the particles as they were and is retried as two steps of half
// the interval, solver.substep_halvings deep at most, by the same loop as Simulation::step()
// (engine/step_retry.hpp). Particles leaving the grid's domain fail the step at once: no smaller
// step brings them back.
//
// stats.csv gets the columns of tet scenes (run.hpp): kinetic energy sum_p 1/2 m_p (|v_p|^2 +
// h^2/4 |C_p|^2) (APIC's affine motion included), elastic energy sum_p V_p^0 Psi(F_p), gravity
// energy -sum_p m_p g . x_p, barrier 0, momentum sum_p m_p v_p; contacts are the grid nodes a
// plane held or pushed in the step, min_distance the smallest distance from a particle to a plane
// (inf without planes, as for tet scenes). A step taken as halves reports the most nodes any of
// its parts held. The transfers and the integrator together change the total energy by
// what the balance columns call integrator_energy (boundary work and friction are not separated
// out for MPM: they are in it too).
#pragma once

#include "engine/mpm/mpm_model.hpp"
#include "engine/mpm/mpm_step.hpp"
#include "engine/scene/scene.hpp"
#include "engine/step_profile.hpp"
#include "engine/step_result.hpp"

#include <algorithm>
#include <cstdint>

namespace nexdyn {

struct MpmState {
  int64_t step = 0;
  double time = 0.0;
  Particles particles;
  MpmParticleHistory history;
};

class MpmSimulation {
 public:
  // Keeps a reference to scene (and its MpmModel); the scene must outlive the simulation.
  explicit MpmSimulation(const Scene& scene);

  StepOutcome step();
  const MpmModel& model() const { return model_; }
  const MpmState& state() const { return state_; }
  const StepStats& last_stats() const { return stats_; }
  const StepProfile& profile() const { return profile_; }
  double peak_factor_bytes() const { return 0.0; }  // no Cholesky factor: the solves are PCG
  const MpmStepper& stepper() const { return stepper_; }
  int64_t pcg_iterations() const { return pcg_iterations_; }

  // Energies, momentum and plane distance of the current state.
  void measure(StepStats& stats) const;

  // Everything the next steps depend on: state() and the total energy the last row's balance
  // was measured from. A simulation of the same scene that adopts them takes the same steps bit
  // for bit (checkpoints: engine/output/step_checkpoint.hpp, which checks them first).
  double previous_total() const { return previous_total_; }
  void adopt(const MpmState& state, double previous_total);
  // A scripted kick between steps: the particles' velocities from `v` (3 x particles).
  void set_velocities(const double* v) { std::copy_n(v, state_.particles.v.size(), state_.particles.v.begin()); }

  // Test seam: attempts at `level` (0: the scene's dt, k: its k-th halving) fail before they
  // start, as a failed solve would (Simulation::fail_attempts_at_level).
  void fail_attempts_at_level(int level) { fail_level_ = level; }

 private:
  // ---- the retry by halving (engine/step_retry.hpp drives these)
  template <typename Stepper>
  friend StepOutcome advance_or_split(Stepper&, double, double, double, int, int, RetryLog&);
  struct Snapshot {
    MpmState state;
    int64_t boundary_nodes = 0;
  };
  Snapshot snapshot() const { return {state_, boundary_nodes_}; }
  void go_back(const Snapshot& before) {
    state_ = before.state;
    boundary_nodes_ = before.boundary_nodes;
  }
  void set_time(double t) { state_.time = t; }
  StepOutcome attempt(double t_start, double t_end, double dt, int level, const Snapshot& before);

  const Scene& scene_;
  const MpmModel& model_;
  MpmStepSettings settings_;
  MpmStepper stepper_;
  MpmState state_;
  StepStats stats_;
  StepProfile profile_;
  double previous_total_ = 0.0;
  int64_t pcg_iterations_ = 0;
  int step_iterations_ = 0;     // Newton iterations of the step under way, failed attempts included
  int64_t boundary_nodes_ = 0;  // the most nodes a plane held in one part of the step under way
  int fail_level_ = -1;         // fail_attempts_at_level
};

}  // namespace nexdyn

// A scene of particle bodies stepped by implicit (or explicit) MPM (issue 23): the counterpart of
// Simulation for `"particles"` bodies, with the same step contract, so `nexdyn run` and
// `nexdyn resume` drive either (engine/run.cpp).
//
// step() attempts the scene's dt; a failed attempt (Newton, line search, a particle turned inside
// out by an explicit step) leaves the particles as they were and is retried as two steps of half
// the interval, solver.substep_halvings deep at most, like Simulation::step(). Particles leaving
// the grid's domain fail the step at once: no smaller step brings them back.
//
// stats.csv gets the columns of tet scenes (run.hpp): kinetic energy sum_p 1/2 m_p (|v_p|^2 +
// h^2/4 |C_p|^2) (APIC's affine motion included), elastic energy sum_p V_p^0 Psi(F_p), gravity
// energy -sum_p m_p g . x_p, barrier 0, momentum sum_p m_p v_p; contacts are the grid nodes a
// plane held or pushed in the step, min_distance the smallest distance from a particle to a plane
// (inf without planes, as for tet scenes). The transfers and the integrator together change the total energy by
// what the balance columns call integrator_energy (boundary work and friction are not separated
// out for MPM: they are in it too).
#pragma once

#include "engine/mpm/mpm_model.hpp"
#include "engine/mpm/mpm_step.hpp"
#include "engine/output/checkpoint_file.hpp"
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"
#include "engine/step_profile.hpp"

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
  const MpmState& state() const { return state_; }
  const StepStats& last_stats() const { return stats_; }
  const StepProfile& profile() const { return profile_; }
  double peak_factor_bytes() const { return 0.0; }  // no Cholesky factor: the solves are PCG
  const MpmStepper& stepper() const { return stepper_; }
  int64_t pcg_iterations() const { return pcg_iterations_; }

  // Energies, momentum and plane distance of the current state.
  void measure(StepStats& stats) const;

  void save(CheckpointWriter& out) const;
  void restore(CheckpointReader& in);

 private:
  MpmStepResult advance_or_split(double dt, int level, int& iterations, int& retries, int64_t& boundary_nodes);

  const Scene& scene_;
  const MpmModel& model_;
  MpmStepSettings settings_;
  MpmStepper stepper_;
  MpmState state_;
  StepStats stats_;
  StepProfile profile_;
  double previous_total_ = 0.0;
  int64_t pcg_iterations_ = 0;
};

}  // namespace nexdyn

// StepHistory: everything a step hands to the next besides the State, in one flat struct.
//
// The State (engine/state.hpp) holds what the integrator advances: positions, velocities,
// accelerations. The history holds what the solver and the potential terms learn along the way
// and carry forward: the barrier stiffness, the multipliers and stiffenings of the augmented
// Lagrangians, the contact pattern of the Newton matrix, the contact force of the last step and
// the energy accounting. The two together are the whole simulation: rolling a failed attempt
// back is a copy of both, and a checkpoint writes exactly both (engine/output/step_checkpoint.hpp).
// Everything else the engine keeps between steps is a cache that can be rebuilt from them.
//
// The objects that use a field bind a reference to it when they are built (JointSet,
// KinematicTargets, IncrementalPotential, ContactPattern), so the struct must not move while they
// live: Simulation owns it beside the State and copies into it, never replaces it.
//
// What is not here: the friction lag (tangent bases, normal forces and start positions of the
// contacts, owned by FrictionPotential). It is taken afresh at x_n at the start of every attempt
// and, with friction_iterations, at the attempt's own solutions, so nothing of it outlives the
// attempt.
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {

struct StepHistory {
  // Barrier stiffness kappa of the IPC barrier (IPC supplemental sec. 3): set at the first solve
  // with contact, then only raised (BarrierTerm, engine/terms/barrier_term.cpp).
  double kappa = 0.0;
  double kappa_max = 0.0;
  bool kappa_from_contact = false;  // kappa was balanced against a contact gradient

  // (3n) the contact and friction force on each free vertex at the end of the last step [N]: the
  // next step's start-of-step contact force (IntegratorParams::contact_memory_scale); empty until
  // a step has measured it.
  std::vector<double> contact_memory;

  // Joints (engine/potential/joints.hpp): lambda_j [N] (num_joints x 3), and the product of the
  // stiffenings so far (a power of two: the stiffness is the same number however it is grouped).
  std::vector<double> joint_multipliers;
  double joint_stiffening = 1.0;

  // Kinematic vertices (engine/potential/kinematic_targets.hpp): lambda_i (num_kinematic x 3), a force
  // times the potential scale s it was accumulated under, that scale, and the product of the
  // stiffenings so far.
  std::vector<double> kinematic_multipliers;
  double kinematic_multiplier_scale = 1.0;
  double kinematic_stiffening = 1.0;

  // The vertex pairs (J, I), I < J, that the Newton matrix's pattern holds beyond the elastic
  // one (engine/sparse/contact_pattern.hpp). They decide the factorisation's ordering and so the
  // last bits of every solve. The stamp names this list; ContactPattern rebuilds its matrix
  // pattern when the stamp is not the one it built from (kContactPatternUnbuilt: never).
  std::vector<std::pair<int32_t, int32_t>> contact_pattern_pairs;
  uint64_t contact_pattern_stamp = 0;
  static constexpr uint64_t kContactPatternUnbuilt = ~uint64_t{0};

  // Sleeping bodies (engine/sleeping.hpp), empty when sleeping is off: per body the steps it has
  // been at rest and its sleeping group (-1: awake; a sleeper is its own group, an older build's
  // checkpoint may hold shared ones), and (3n) where each vertex's rest began [m].
  std::vector<int32_t> rest_steps;
  std::vector<int32_t> sleep_group;
  std::vector<double> rest_anchor;

  // The energy accounting: the total energy where the next step's balance starts [J]
  // (Simulation::step, engine/simulation.cpp), and the energy guard's record
  // (Simulation::guard_energy, engine/simulation_energy.cpp): the energy the integration has
  // created so far (negative: taken out) [J] and the largest energy in motion seen [J].
  double energy_before = 0.0;
  double integrator_created = 0.0;
  double energy_scale = 0.0;

  // The energy Rayleigh damping (engine/terms/damping_term.hpp) has taken out since the start [J].
  double damping_dissipated = 0.0;
};

}  // namespace nexdyn

// Simulation: owns the State, the StepHistory and the potential's terms, and advances them one
// time step at a time. The order of a step is Simulation::attempt in simulation.cpp, one screen:
//
//   choose the scheme   the scene's, or implicit Euler (a first step that starts in contact, or
//                       an attempt the energy guard retakes); the StepContext of the attempt
//   predict             x_tilde from x, v, a and a_bar                      (integrator.cpp)
//   explicit schemes:   x = x_tilde, a = M^-1 f(x)
//   implicit schemes:
//     prepare terms     the attempt's weights into the potential, the contact memory into
//                       x_tilde, the kinematic targets, the joints' stiffness
//     start point       x_n moved as far toward x_n + h v_n as CCD allows
//     solve             Newton on the incremental potential (solver/newton.cpp), inside the
//                       friction lags, the kinematic rounds and the joint multiplier rounds
//     update            a, a_bar, v; contact, friction and joint forces act as one impulse at
//                       the end of the step and stay out of a and a_bar
//   account             the attempt's energy balance: boundary work, friction, kappa
//   finish              x_{n+1} into the State, held vertices onto their paths
//
// A failed attempt (Newton, factorisation, NaN) is rolled back, a copy of State and StepHistory,
// and the interval is attempted as two halves, recursively (engine/step_retry.hpp). After the step:
//   measure             energies, momentum, contact summary for stats.csv; the energy balance's
//                       unexplained rest is the integrator's energy (simulation_energy.cpp)
//
// The Model stays const; the scene must outlive the simulation.
#pragma once

#include "engine/coordinate_map.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/energy_balance.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "engine/solver/linearized_step.hpp"
#include "engine/solver/projective_dynamics.hpp"
#include "engine/terms/damping_term.hpp"
#include "engine/potential/kinematic_targets.hpp"
#include "engine/scene/scene.hpp"
#include "engine/sleeping.hpp"
#include "engine/solver/newton.hpp"
#include "engine/state.hpp"
#include "engine/step_result.hpp"
#include "engine/step_context.hpp"
#include "engine/step_history.hpp"
#include "engine/step_profile.hpp"

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <string>

namespace nexdyn {

// dhat [m] of a scene: contact.dhat, or 1e-3 of the bodies' bounding-box diagonal when absent.
double resolved_dhat(const Scene& scene);

class Simulation {
 public:
  // Keeps references to scene.model; the scene must outlive the simulation.
  explicit Simulation(const Scene& scene);
  Simulation(const Simulation&) = delete;  // the terms hold references into history_
  Simulation& operator=(const Simulation&) = delete;

  // One step of the scene's dt. A failed attempt (Newton, factorisation, NaN) puts the state back
  // and is retried as two steps of half the dt, recursively, solver.substep_halvings deep at
  // most; the next step tries the full dt again. On failure the state is the one before the step.
  StepOutcome step();
  const Model& model() const { return model_; }
  const State& state() const { return state_; }
  const StepHistory& history() const { return history_; }
  const StepStats& last_stats() const { return stats_; }
  // Energies and momentum of the current state (step, time, iterations, wall time untouched).
  // Changes nothing the next step reads.
  void measure(StepStats& stats) const;
  // Moving boundaries and obstacles of a contact scene (empty without).
  const KinematicTargets& kinematic() const { return kinematic_; }
  // Wall time of all steps so far, by phase.
  const StepProfile& profile() const { return profile_; }
  // The largest memory the Newton solver's Cholesky factors held at once [bytes] (0: none).
  double peak_factor_bytes() const { return newton_ ? newton_->peak_factor_bytes() : 0.0; }

  // Everything the next steps depend on is state() and history(): a simulation of the same
  // scene that adopts them takes the same steps bit for bit (checkpoints:
  // engine/output/step_checkpoint.hpp, which checks them against the scene first).
  void adopt(const State& state, const StepHistory& history);
  // A scripted kick between steps: every free vertex's velocity from `v` (3 x num_vertices); held
  // vertices keep their prescribed ones, and an affine body takes the affine motion closest to
  // its surface vertices' velocities (exact for a rigid one; its nodes' rows are not read).
  // A sleeping body that now moves wakes. The kinetic energy it adds is outside the energy balance: the next step's balance
  // starts from the kicked state (total_energy jumps by it between the two rows).
  void set_velocities(const double* v);
  int64_t num_joints() const { return joints_.size(); }
  bool has_contact() const { return contact_ != nullptr; }

  // Test seam: attempts at `level` (0: the scene's dt, k: its k-th halving) fail before they
  // start, as a failed solve would, so a test can compare a rolled-back step with halves.
  void fail_attempts_at_level(int level) { fail_level_ = level; }

 private:
  // ---- the retry by halving (engine/step_retry.hpp drives these; simulation.cpp)
  template <typename Stepper>
  friend StepOutcome advance_or_split(Stepper&, double, double, double, int, int, RetryLog&);
  // What a failed attempt puts back: the State, the StepHistory and the step's balance so far.
  struct Snapshot {
    State state;
    StepHistory history;
    EnergyBalance balance;
    double energy_now = 0.0;
  };
  Snapshot snapshot() const;
  void go_back(const Snapshot& before);
  void set_time(double t) { state_.time = t; }
  // One attempt of [t_start, t_end], retaken with implicit Euler when the energy guard says so.
  StepOutcome attempt(double t_start, double t_end, double dt, int level, const Snapshot& before);
  // ---- the step (simulation.cpp)
  StepOutcome attempt(double dt, double t_next, int level, int& iterations);
  // The scheme of an attempt (see the top of this file) and its context.
  StepContext choose_scheme(double dt, double t_next, int level);
  StepOutcome explicit_update(const StepContext& ctx);
  // ---- the implicit solve (simulation_solve.cpp)
  StepOutcome implicit_solve(const StepContext& ctx, int& iterations);
  // "solver.method": "linearized": one linear solve from x_n (engine/solver/linearized_step.hpp).
  StepOutcome linearized_solve(const StepContext& ctx, int& iterations);
  // "solver.method": "projective_dynamics": local-global iterations from x_tilde
  // (engine/solver/projective_dynamics.hpp); plane obstacles are its own projections.
  StepOutcome projective_dynamics_solve(const StepContext& ctx, int& iterations);
  void prepare_terms(const StepContext& ctx);
  // Newton's starting point for the step (written into x_next_).
  StepOutcome start_point(const StepContext& ctx);
  // The solves of the step, with friction lagged at x_n and, under friction_iterations, at the
  // solutions; then kinematic rounds and joint rounds inside (solve_kinematic, solve_with_joints).
  NewtonResult solve_with_friction(const StepContext& ctx, int& iterations);
  NewtonResult solve_kinematic(const StepContext& ctx, int& iterations);
  NewtonResult solve_with_joints(const StepContext& ctx, int& iterations);
  // Friction bases and normal forces at x (lagged; engine/contact/friction_potential.hpp).
  void lag_friction(const StepContext& ctx, const std::vector<double>& x);
  // ---- after the solve (simulation.cpp)
  // The update of a, a_bar, v after the solve (impulsive forces kept out of a and a_bar).
  void update_after_solve(const StepContext& ctx);
  // The update of a, a_bar, v after a solve with contact (and f_{n+1} kept as the next f_n).
  void update_with_contact(const StepContext& ctx);
  // x_{n+1} into the state; prescribed vertices onto their paths at t_end.
  void finish(const StepContext& ctx, double held_kinetic_before);
  // Throws away what was built from the rolled-back state: Newton's islands and held vertices.
  void drop_caches();
  // Holds the sleeping bodies' vertices in Newton (and lets the woken ones go).
  void hold_sleeping();

  // Held vertices at their prescribed positions (and velocities, accelerations) at time t;
  // kinematic ones too unless `kinematic` is false.
  void prescribe(double t, std::vector<double>& x, std::vector<double>* v, std::vector<double>* a,
                 std::vector<double>* a_bar, bool kinematic = true) const;
  // a = M^-1 f(x) on free vertices; false if f is not finite.
  bool explicit_acceleration(const std::vector<double>& x, std::vector<double>& a);
  // With joints, a_0 solves the KKT system [M J^T; J 0] [a; mu] = [f; 0] instead of M a = f.
  void constrain_initial_acceleration();
  // Affine bodies' axis nodes: v = the rigid rotation with the same angular momentum about the
  // body's centre (at x_next_), dropping the rate of stretch (see there).
  void keep_rigid_axis_velocity();
  // Affine bodies' axis nodes: a = the acceleration of their rigid rotation at positions x, for
  // the angular velocity of (x_motion, v_motion); followers follow (see there).
  void set_rigid_rotation_acceleration(const std::vector<double>& x_motion, const std::vector<double>& v_motion,
                                       const std::vector<double>& x, std::vector<double>& a) const;

  // ---- energy accounting and measurement (simulation_energy.cpp)
  // Adds the boundary work (without the held kinetic energy), friction dissipation and kappa
  // energy of the motion x_old -> x_new to balance_.
  void account_energy(const std::vector<double>& x_old, const std::vector<double>& x_new, double kappa_before,
                      double dt);
  // Kinetic and gravity energy, momentum and angular momentum (about the origin) of state_, summed
  // over the vertices in order.
  struct MotionSums {
    double kinetic = 0.0, gravity = 0.0;
    Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
    Eigen::Vector3d angular_momentum = Eigen::Vector3d::Zero();
  };
  MotionSums motion_sums() const;
  // Total energy of state_ (stats.csv's total_energy), its part in motion (|kinetic + elastic +
  // barrier|) and its gravity part.
  struct Energies {
    double total = 0.0, in_motion = 0.0, gravity = 0.0;
  };
  Energies energies_now() const;
  // The energy guard (time.energy_guard): after an attempt that succeeded, true when its
  // integration would bring the energy it has created since the start above zero (what it took
  // out before may be spent again), and the attempt must be retaken with implicit Euler;
  // otherwise the attempt is booked and false. balance_before: balance_ before the attempt.
  bool guard_energy(const EnergyBalance& balance_before);
  // Rayleigh damping: the force at the start of the run's first step (the end of the step
  // before it, otherwise), once the step's D is known; and the work of the damping force over
  // the attempt's motion x_old -> x_new, booked in balance_ and the history.
  void account_damping(const std::vector<double>& x_old, const std::vector<double>& x_new, double dt);
  // The measure stage: measure(), with the contact summary taken by the barrier itself, which
  // leaves its candidates at a static search of x for the next step's first search.
  void measure_step(StepStats& stats);
  // Energies and momentum without the contact columns.
  void measure_motion(StepStats& stats) const;
  // Projective Dynamics has no barrier: contacts are the vertices its last solve held on plane
  // obstacles, min_distance the smallest vertex-plane distance.
  void measure_planes(StepStats& stats) const;

  const Scene& scene_;
  const Model& model_;
  CoordinateMap map_;  // affine bodies' nodes and followers (identity without them)
  State state_;
  StepHistory history_;  // before the terms, which bind references into it
  StepStats stats_;
  StepProfile profile_;
  JointSet joints_;  // before elastic_, which takes its coupling groups
  ElasticAssembly elastic_;
  std::unique_ptr<BarrierPotential> contact_;  // null without contact
  std::unique_ptr<FrictionPotential> friction_;  // null without friction
  KinematicTargets kinematic_;
  std::unique_ptr<SleepingBodies> sleeping_;  // null without contact or with sleeping off
  std::vector<int32_t> held_asleep_;          // the vertices Newton holds because they sleep
  IncrementalPotential potential_;
  DampingTerm* damping_ = nullptr;  // in potential_; null without damping
  std::unique_ptr<NewtonSolver> newton_;  // built lazily: explicit schemes never need it
  std::unique_ptr<LinearizedStep> linearized_;  // "solver.method": "linearized", built lazily
  std::unique_ptr<ProjectiveDynamics> pd_;      // "solver.method": "projective_dynamics", lazily
  int32_t pd_plane_vertices_ = 0;               // held on planes by PD's last accepted solve
  double joint_tolerance_ = 0.0;          // [m]
  bool kinematic_on_target_ = false;      // this attempt's kinematic vertices are held on target
  std::vector<double> x_next_, a_next_, force_, motion_;  // (3n) step workspaces
  std::vector<double> impulse_;  // (3n) acceleration of the impulsive forces at the step's end
  std::vector<double> elastic_gradient_old_, elastic_gradient_new_;  // (3n) of the boundary work
  EnergyBalance balance_;        // of the step under way, summed over its successful attempts
  // The energy guard: the total energy at the start of the attempt under way [J], whether that
  // attempt is implicit Euler's, and whether the next attempt must be.
  double energy_now_ = 0.0;
  bool last_attempt_euler_ = false, force_euler_ = false;
  int fail_level_ = -1;  // fail_attempts_at_level
  int step_iterations_ = 0;  // Newton iterations of the step under way, failed attempts included
};

}  // namespace nexdyn

// The time step: the stage list every step runs, in order.
//
//   1. prescribe   Dirichlet vertices move to their targets at t + dt (analytic x, v, a)
//   2. predict     x_tilde from x, v, a and a_bar                            (integrator.cpp),
//                  plus the start-of-step contact force's share (contact memory)
//   3. solve       implicit: Newton on the incremental potential          (solver/newton.cpp),
//                  with contact starting from the largest collision-free part of the motion
//                  x_n -> x_n + h v_n
//                  explicit: x = x_tilde, a = M^-1 f(x)
//   4. update      a, a_bar, v from the integrator family; contact, friction and joint forces
//                  act as one impulse at the end of the step and stay out of a and a_bar
//                  (integrator.cpp; update_with_contact)
//   5. account     the step's energy balance: boundary work, friction, kappa (energy_balance.hpp)
//   6. measure     energies and momentum for stats.csv; what the balance's terms leave
//                  unexplained is the integrator's energy
//
// The scheme of a step is the scene's, except for a step that starts in contact before any
// contact memory exists (the first step of a scene whose bodies start touching), which implicit
// Euler takes (step_scheme).
//
// A Simulation owns the State and the solver workspaces; the Model stays const.
#pragma once

#include "engine/elastic_assembly.hpp"
#include "engine/energy_balance.hpp"
#include "engine/incremental_potential.hpp"
#include "engine/kinematic_targets.hpp"
#include "engine/scene/scene.hpp"
#include "engine/solver/newton.hpp"
#include "engine/solver/step_status.hpp"
#include "engine/step_profile.hpp"

#include <Eigen/Core>

#include <memory>
#include <optional>
#include <string>

namespace nexdyn {

// dhat [m] of a scene: contact.dhat, or 1e-3 of the bodies' bounding-box diagonal when absent.
double resolved_dhat(const Scene& scene);

// One row of stats.csv (DESIGN.md section 6).
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
  EnergyBalance balance;  // where the change of total_energy came from (columns after retries)
  int guarded_steps = 0;  // (sub)steps of this step the energy guard retook with implicit Euler
};

struct StepOutcome {
  StepStatus status = StepStatus::ok;
  std::string message;  // empty when ok
};

class Simulation {
 public:
  // Keeps references to scene.model; the scene must outlive the simulation.
  explicit Simulation(const Scene& scene);

  // One step of the scene's dt. A failed attempt (Newton, factorisation, NaN) puts the state back
  // and is retried as two steps of half the dt, recursively, solver.substep_halvings deep at
  // most; the next step tries the full dt again. On failure the state is the one before the step.
  StepOutcome step();
  const State& state() const { return state_; }
  const StepStats& last_stats() const { return stats_; }
  // Energies and momentum of the current state (step, time, iterations, wall time untouched).
  void measure(StepStats& stats) const;
  // Moving boundaries and obstacles of a contact scene (empty without).
  const KinematicTargets& kinematic() const { return kinematic_; }
  // Wall time of all steps so far, by phase.
  const StepProfile& profile() const { return profile_; }
  // The largest memory the Newton solver's Cholesky factors held at once [bytes] (0: none).
  double peak_factor_bytes() const { return newton_ ? newton_->peak_factor_bytes() : 0.0; }

  // Everything the next steps depend on: the State, and what the solver carries from step to
  // step (barrier and joint stiffnesses, multipliers, the contact pattern). A simulation of the
  // same scene restored from it takes the same steps bit for bit.
  void save(CheckpointWriter& out) const;
  // CheckpointError naming the fault when the data does not fit this scene.
  void restore(CheckpointReader& in);

 private:
  // Held vertices at their prescribed positions (and velocities, accelerations) at time t;
  // kinematic ones too unless `kinematic` is false.
  void prescribe(double t, std::vector<double>& x, std::vector<double>* v, std::vector<double>* a,
                 std::vector<double>* a_bar, bool kinematic = true) const;
  // a = M^-1 f(x) on free vertices; false if f is not finite.
  bool explicit_acceleration(const std::vector<double>& x, std::vector<double>& a);

  // One attempt at the step from state_.time to t_next = state_.time + dt (state_.time and
  // state_.step are left to the caller); adds its Newton iterations to `iterations`.
  StepOutcome advance(double dt, double t_next, int& iterations);
  // advance(), and on failure the state put back and the interval taken in two halves.
  StepOutcome advance_or_split(double dt, double t_next, int level, int& iterations, int& retries);
  // Adds the boundary work (without the held kinetic energy), friction dissipation and kappa
  // energy of the motion x_old -> x_new to balance_.
  void account_energy(const std::vector<double>& x_old, const std::vector<double>& x_new, double kappa_before);
  // Kinetic and gravity energy and momentum of state_, summed over the vertices in order.
  struct MotionSums {
    double kinetic = 0.0, gravity = 0.0;
    Eigen::Vector3d momentum = Eigen::Vector3d::Zero();
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
  // The scheme of the step: the scene's, or implicit Euler for a step that starts in contact with
  // no contact force of a previous step to remember (IntegratorParams::contact_memory_scale).
  const IntegratorParams& step_scheme(double dt);
  // x_tilde += (alpha - r) h^2 M^-1 f_n: the start-of-step contact force's part of the step.
  void add_contact_memory(const IntegratorParams& integrator, double dt);
  // The update of a, a_bar, v after a solve with contact (and f_{n+1} kept as the next f_n).
  void update_with_contact(const IntegratorParams& integrator, double dt);
  // Newton's starting point for the step to t_next (written into x_next_).
  StepOutcome start_point(double t_next);
  // The Newton solves of the step: with kinematic vertices, first until they can be moved onto
  // their targets, then with them held there; adds the Newton iterations to `iterations`.
  NewtonResult solve_step(int& iterations);
  // Newton solves repeated with updated joint multipliers until every joint holds to the
  // tolerance.
  NewtonResult solve_with_joints(int& iterations);
  // Friction bases and normal forces at x (lagged; engine/contact/friction_potential.hpp).
  void lag_friction(const std::vector<double>& x);
  // With joints, a_0 solves the KKT system [M J^T; J 0] [a; mu] = [f; 0] instead of M a = f.
  void constrain_initial_acceleration();

  const Scene& scene_;
  const Model& model_;
  State state_;
  StepStats stats_;
  StepProfile profile_;
  JointSet joints_;  // before elastic_, which takes its coupling groups
  ElasticAssembly elastic_;
  std::unique_ptr<BarrierPotential> contact_;  // null without contact
  std::unique_ptr<FrictionPotential> friction_;  // null without friction
  KinematicTargets kinematic_;
  IncrementalPotential potential_;
  std::unique_ptr<NewtonSolver> newton_;  // built lazily: explicit schemes never need it
  double joint_tolerance_ = 0.0;          // [m]
  bool joint_stiffness_set_ = false;
  double joint_stiffening_ = 1.0;          // product of the stiffenings so far
  double kinematic_stiffening_ = 1.0;      // the same for the kinematic vertices
  bool kinematic_on_target_ = false;       // this step's kinematic vertices are held on target
  std::vector<double> x_next_, a_next_, force_, motion_;  // (3n) step workspaces
  std::vector<double> impulse_;  // (3n) acceleration of the impulsive forces at the step's end
  // (3n) the contact and friction force on each free vertex at the end of the last step [N]: the
  // next step's start-of-step contact force (IntegratorParams::contact_memory_scale); 0 elsewhere
  std::vector<double> contact_memory_;
  std::vector<double> elastic_gradient_old_, elastic_gradient_new_;  // (3n) of the boundary work
  EnergyBalance balance_;        // of the step under way, summed over its successful attempts
  double energy_before_ = 0.0;   // [J] total energy of state_, where the next step's balance starts
  // The energy guard: the total energy at the start of the attempt under way [J], the energy
  // the integration has created since the start (negative: taken out), less the allowance for
  // the boundary work's error [J], the largest energy
  // in motion seen (the scale of the guard's margin) [J], whether the attempt under way is implicit Euler's,
  // and whether the next attempt must be.
  double energy_now_ = 0.0, integrator_created_ = 0.0, energy_scale_ = 0.0;
  bool last_attempt_euler_ = false, force_euler_ = false;
  double dt_ = 0.0;  // [s] of the attempt under way (the scene's dt, or a part of it)
};

}  // namespace nexdyn

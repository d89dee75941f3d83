// The implicit solve of a step (Simulation::implicit_solve, see simulation.hpp): the method the
// scene asks for (Newton, the linearised step or Projective Dynamics), and Newton's nesting of
// friction lags, kinematic targets and joint rounds around the solver. The step's driver, the
// updates after the solve and the checkpoints are in simulation.cpp.
#include "engine/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

namespace {
// Joints: the augmented Lagrangian's stiffness relative to the inertia of the joint's vertices
// (JointSet::set_stiffness), the number of multiplier updates per step before the step goes on
// regardless (the violation is in stats.csv), and the stiffening when an update gains less
// than 4x.
constexpr double kJointStiffnessRatio = 1e4;
constexpr int kMaxJointRounds = 30;
constexpr double kJointStiffening = 4.0;
constexpr double kMaxJointStiffening = 1e3;  // over the whole run: k stays conditioned
// Kinematic vertices: stiffness against their inertia (they push whole bodies, so far stiffer
// than a joint), and the most solves of a step that try to bring them onto their targets.
constexpr double kKinematicStiffnessRatio = 1e6;
constexpr int kMaxKinematicAttempts = 8;

// Friction: the most lagging iterations of a step under "friction_iterations": "converged", and
// the relative change of the summed normal force at which the lagging stops.
constexpr int kMaxFrictionLags = 20;
constexpr double kFrictionLagTolerance = 1e-3;
// ... and the increment, in tolerances, below which a solve re-lags at its iterates (at most
// kMaxFrictionLags times). 10: on the 100-body piles, 100 saves more iterations on affine bodies
// but costs the tet pile time in its CCD and line search (docs/performance.md).
constexpr double kRelagBelow = 10.0;
// How far off its chord an affine body's turned trial point may go, in dhat, and still be covered
// by the iteration's one padded CCD sweep (NewtonSettings::turn_reach). On pile_1000_affine's
// landing the bound on a turn (CoordinateMap::turn_pads) passes that in under 3% of the iterations
// (docs/performance.md, "One CCD sweep an iteration").
constexpr double kTurnReach = 10.0;

// Whether lagging still converges: the fixed-point iteration of a lag is linear at best, each
// change of the summed normal force a fraction of the one before. When a change is no smaller
// than the one before, the lags cycle (stiff bodies wedged at several frictional contacts: a
// pile of ten affine bodies spent 2,090 Newton iterations on one step, the normal force
// wandering between 38 and 42 N over 20 re-solves of up to 140 iterations), and further lags
// only cost; the step keeps the friction of its last lag, as with a fixed number of lags.
struct LagContraction {
  double previous = std::numeric_limits<double>::infinity();
  // The change of the summed normal force a lag made; false once it stopped shrinking.
  bool shrinks(double change) {
    const bool ok = change < previous;
    previous = change;
    return ok;
  }
};
}  // namespace

StepOutcome Simulation::implicit_solve(const StepContext& ctx, int& iterations) {
  // Every body asleep and none driven: nothing can move, and the step is x_{n+1} = x_n with
  // every velocity, acceleration and contact force as it was (engine/sleeping.hpp).
  if (sleeping_ && sleeping_->all_asleep()) {
    x_next_ = state_.x;
    return {};
  }
  if (scene_.solver.method == SolverMethod::linearized) return linearized_solve(ctx, iterations);
  if (scene_.solver.method == SolverMethod::projective_dynamics) return projective_dynamics_solve(ctx, iterations);
  prepare_terms(ctx);
  const StepOutcome outcome = start_point(ctx);
  if (outcome.status != StepStatus::ok) return outcome;
  const NewtonResult result = solve_with_friction(ctx, iterations);
  if (result.status != StepStatus::ok) return {result.status, result.message};
  update_after_solve(ctx);
  return outcome;
}

StepOutcome Simulation::linearized_solve(const StepContext& ctx, int& iterations) {
  if (!linearized_) {
    const SolverSettings& solver = scene_.solver;
    linearized_ = std::make_unique<LinearizedStep>(model_, solver.linear, solver.tolerance,
                                                   std::max(solver.max_iterations, 10000));
  }
  prepare_terms(ctx);
  x_next_ = state_.x;
  prescribe(ctx.t_end, x_next_, nullptr, nullptr, nullptr);
  const LinearizedResult result = linearized_->solve(potential_, ctx, damping_, x_next_);
  if (result.status != StepStatus::ok) return {result.status, result.message};
  iterations += 1;
  // Nothing bounded the step: a tet it inverted fails the attempt (retried at half the dt).
  if (!std::isfinite(elastic_.energy(x_next_.data())))
    return {StepStatus::non_finite, "the linearised step inverted a tet"};
  update_after_solve(ctx);
  return {};
}

StepOutcome Simulation::projective_dynamics_solve(const StepContext& ctx, int& iterations) {
  if (!pd_) {
    const SolverSettings& solver = scene_.solver;
    PdSettings settings;
    settings.tolerance = solver.tolerance;
    settings.max_iterations = std::max(solver.max_iterations, 2000);
    settings.chebyshev = solver.chebyshev;
    settings.rho = solver.chebyshev_rho;
    pd_ = std::make_unique<ProjectiveDynamics>(model_, settings);
  }
  // From the predictor, the held vertices at their targets.
  x_next_ = state_.x_tilde;
  prescribe(ctx.t_end, x_next_, nullptr, nullptr, nullptr);
  const PdResult result = pd_->solve(ctx.potential_scale, ctx.dt, state_.x_tilde, x_next_);
  iterations += result.iterations;
  if (result.status != StepStatus::ok) return {result.status, "Projective Dynamics: " + result.message};
  pd_plane_vertices_ = result.plane_vertices;
  // The plane constraints' forces are smooth forces of the step here, not impulses.
  update_implicit(*ctx.scheme, ctx.dt, x_next_, state_.x_tilde, state_.v, state_.a, state_.a_bar);
  return {};
}

void Simulation::prepare_terms(const StepContext& ctx) {
  if (!newton_) {
    newton_ = std::make_unique<NewtonSolver>(model_, potential_);
    newton_->set_profile(&profile_);
  }
  hold_sleeping();
  potential_.begin_step(state_.x_tilde, ctx);
  // The start-of-step contact force's part of the step: x_tilde += (alpha - r) h^2 M^-1 f_n.
  const std::vector<double>& memory = history_.contact_memory;
  if (contact_ && ctx.contact_memory_scale != 0.0 && !memory.empty()) {
    for (int32_t v = 0; v < model_.num_vertices; ++v) {
      if (model_.dirichlet[v] >= 0 || !(model_.mass[v] > 0.0)) continue;
      for (int d = 0; d < 3; ++d)
        state_.x_tilde[3 * v + d] += ctx.contact_memory_scale * memory[3 * v + d] / model_.mass[v];
    }
    map_.follow(state_.x_tilde.data());  // followers' x_tilde = J x_tilde (they have no mass)
  }
  // The augmented Lagrangians' stiffness follows the scene's scheme at this dt (and its
  // multipliers are forces times that scheme's s), whichever scheme takes the attempt.
  const double scene_scale = scene_.time.integrator.potential_scale(ctx.dt);
  if (!kinematic_.empty()) {
    kinematic_.begin_attempt(kKinematicStiffnessRatio, scene_scale);
    std::vector<double>& target = a_next_;
    target = state_.x;
    prescribe(ctx.t_end, target, nullptr, nullptr, nullptr);
    kinematic_.set_targets(target);
    if (kinematic_on_target_) newton_->hold(kinematic_.vertices(), false);
    kinematic_on_target_ = false;
  }
  if (!joints_.empty()) {
    // The joint force is impulsive like the contact force: weight s_c / s = 1 / (gamma c_a).
    joints_.set_stiffness(scene_.time.integrator.joint_weight(), scene_scale, kJointStiffnessRatio,
                          history_.joint_stiffening, elastic_.coupling_slabs());
  }
}

StepOutcome Simulation::start_point(const StepContext& ctx) {
  const bool is_static = scene_.time.integrator.is_static;
  // x_n with the held vertices at their targets: the fallback start. (Kinematic vertices, which
  // exist only with contact, start at x_n: the solve carries them.)
  x_next_ = state_.x;
  prescribe(ctx.t_end, x_next_, nullptr, nullptr, nullptr, false);
  const int64_t n = model_.num_dofs();
  if (!contact_) {
    // Start from the predictor when it is a valid state (fewer iterations), else from x_n.
    if (is_static) return {};
    std::vector<double>& trial = a_next_;
    trial = state_.x_tilde;
    prescribe(ctx.t_end, trial, nullptr, nullptr, nullptr);
    if (std::isfinite(elastic_.energy(trial.data()))) x_next_.swap(trial);
    return {};
  }
  // With contact, every point Newton visits must be intersection-free. The eliminated held
  // vertices do not move here (a moving boundary is kinematic when the scene has contact), so
  // x_n is such a point.
  //
  // With static friction above kinetic, the step's potential is not convex in the slip: a stuck
  // and a sliding minimum can coexist, and the predictor (free flight) would start Newton in the
  // sliding one. From x_n (no slip) a contact that can stick stays stuck, and a body whose
  // momentum beats static friction has no stuck minimum and slides all the same.
  if (is_static || (friction_ && friction_->table().has_static_peak())) return {};
  // Then as far toward x_n + h v_n (kinematic vertices: toward their targets) as CCD allows (it
  // stops short of any contact). That is implicit Euler's predictor; the second-order schemes'
  // x_tilde adds h^2 terms of the acceleration (gravity, and the contact force's memory) that
  // would start a body resting in contact deep in the barrier, where Newton needs ten times
  // the iterations to climb back (measured on scenes/slope_stick.json).
  kinematic_.motion_to_targets(x_next_.data(), motion_.data());
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    if (model_.dirichlet[v] < 0)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * int64_t{v} + d;
        motion_[i] = state_.x[i] + ctx.dt * state_.v[i] - x_next_[i];
      }
  const double alpha = potential_.max_step(x_next_.data(), motion_.data());
  std::vector<double>& trial = a_next_;
  trial.resize(n);
  for (int64_t i = 0; i < n; ++i) trial[i] = x_next_[i] + alpha * motion_[i];
  if (std::isfinite(elastic_.energy(trial.data()))) x_next_.swap(trial);
  return {};
}

NewtonResult Simulation::solve_with_friction(const StepContext& ctx, int& iterations) {
  // Friction is lagged at x_n, then (friction_iterations) at each solution, re-solving.
  if (friction_) lag_friction(ctx, state_.x);
  NewtonResult result = solve_kinematic(ctx, iterations);
  const int lags = scene_.contact.friction_iterations < 0 ? kMaxFrictionLags : scene_.contact.friction_iterations;
  LagContraction contraction;
  for (int lag = 1; friction_ && result.status == StepStatus::ok && lag < lags; ++lag) {
    const double before = friction_->total_normal_force();
    // Only the bodies at contacts whose friction the new lag changed by more than the Newton
    // tolerance resolves see a new potential: the friction term reports them and the next solve
    // thaws them; the rest stay converged.
    lag_friction(ctx, x_next_);
    const double after = friction_->total_normal_force();
    // Converged lagging stops when the forces settle in sum, or when no contact's friction
    // changed by more than a re-solve could resolve at the Newton tolerance.
    if (scene_.contact.friction_iterations < 0 &&
        (std::abs(after - before) <= kFrictionLagTolerance * std::max(after, before) ||
         potential_.friction()->last_lag_changes() == 0 || !contraction.shrinks(std::abs(after - before))))
      break;
    newton_->keep_converged_next_solve();
    result = solve_kinematic(ctx, iterations);
  }
  return result;
}

NewtonResult Simulation::solve_kinematic(const StepContext& ctx, int& iterations) {
  if (kinematic_.empty() || kinematic_on_target_) return solve_with_joints(ctx, iterations);
  // Kinematic vertices: solves with their augmented Lagrangian pull them toward their targets
  // while CCD sweeps their motion; then they are moved onto the targets (as far as CCD allows:
  // a blocked move means another, stiffer solve), held there, and the step is solved again so
  // that the bodies settle against them exactly where they belong.
  for (int attempt = 0;; ++attempt) {
    const NewtonResult result = solve_with_joints(ctx, iterations);
    if (result.status != StepStatus::ok) return result;
    kinematic_.update_multipliers(x_next_.data());  // the holding force, carried to the next step
    kinematic_.motion_to_targets(x_next_.data(), motion_.data());
    const double alpha = potential_.max_step(x_next_.data(), motion_.data());
    const int64_t n = model_.num_dofs();
    for (int64_t i = 0; i < n; ++i) x_next_[i] += alpha * motion_[i];
    if (alpha == 1.0) break;
    if (attempt + 1 == kMaxKinematicAttempts) {
      NewtonResult failed = result;
      failed.status = StepStatus::boundary_collision;
      failed.message = "a moving boundary or obstacle cannot reach its prescribed position: something "
                       "it pushes is held or wedged";
      return failed;
    }
    if (history_.kinematic_stiffening < kMaxJointStiffening) {
      history_.kinematic_stiffening *= kJointStiffening;
      kinematic_.set_stiffness(kKinematicStiffnessRatio);
    }
  }
  kinematic_on_target_ = true;
  newton_->hold(kinematic_.vertices(), true, /*in_islands=*/true);
  return solve_with_joints(ctx, iterations);
}

NewtonResult Simulation::solve_with_joints(const StepContext& ctx, int& iterations) {
  NewtonSettings settings;
  settings.tolerance = scene_.solver.tolerance;
  settings.max_iterations = scene_.solver.max_iterations;
  settings.dt = ctx.dt;
  settings.turn_reach = contact_ ? kTurnReach * contact_->dhat() : 0.0;
  // Lengthened full steps (NewtonSolver::extend_step) go where the model is too stiff, along the
  // nonconvex stretches of the energy, and so can land in another of its minima where static
  // friction is above kinetic (start_point): the thrown block of `slope with static friction`
  // then slid 20 steps held partly by static friction, its momentum gaining 17 to 20 a step
  // instead of 21.9. Not there.
  const bool static_peak = friction_ && friction_->table().has_static_peak();
  settings.extend_steps = !static_peak;
  if (friction_ && scene_.contact.friction_iterations < 0 && !static_peak) {
    // Converged lagging: the friction is re-lagged inside the solve once Newton is near the
    // solution, so that the solve ends close to the lag's fixed point and the re-solves of
    // solve_with_friction are few (measured in docs/performance.md). Not with static friction
    // above kinetic: there the step's potential has a stuck and a sliding minimum (start_point),
    // and a lag taken on the way between them moved the sliding block of `slope with static
    // friction` off g (sin - mu_k cos) by 0.24%.
    settings.relag = [this, &ctx, contraction = LagContraction(), cycling = false](const double* x) mutable {
      if (cycling) return false;
      const double before = friction_->total_normal_force();
      potential_.friction()->lag(x, state_.x.data(), ctx.dt);
      cycling = !contraction.shrinks(std::abs(friction_->total_normal_force() - before));
      return potential_.friction()->last_lag_changes() > 0;
    };
    settings.relag_below = kRelagBelow * settings.tolerance;
    settings.max_relags = kMaxFrictionLags;
  }
  NewtonResult result = newton_->solve(x_next_, settings);
  iterations += result.iterations;
  // A multiplier update moves the minimiser by about the violation; Newton must not call that
  // converged before taking it, so the rounds use a tolerance well below the joint tolerance.
  NewtonSettings round_settings = settings;
  round_settings.tolerance = std::min(settings.tolerance, 0.1 * joint_tolerance_ / ctx.dt);
  double previous = std::numeric_limits<double>::infinity();
  for (int round = 0; !joints_.empty() && result.status == StepStatus::ok && round < kMaxJointRounds; ++round) {
    const double violation = joints_.max_violation(x_next_.data());
    if (violation <= joint_tolerance_) break;
    joints_.update_multipliers(x_next_.data());
    if (violation > previous / kJointStiffening && history_.joint_stiffening < kMaxJointStiffening) {
      history_.joint_stiffening *= kJointStiffening;
      joints_.set_stiffness(joints_.weight(), scene_.time.integrator.potential_scale(ctx.dt),
                            kJointStiffnessRatio, history_.joint_stiffening, elastic_.coupling_slabs());
    }
    previous = violation;
    result = newton_->solve(x_next_, round_settings);
    iterations += result.iterations;
  }
  return result;
}

void Simulation::lag_friction(const StepContext& ctx, const std::vector<double>& x) {
  // Before the first solve with contact the barrier stiffness is still unset: set it from x.
  if (potential_.barrier_stiffness() == 0.0) potential_.begin_solve(x.data());
  potential_.friction()->lag(x.data(), state_.x.data(), ctx.dt);
}

}  // namespace nexdyn

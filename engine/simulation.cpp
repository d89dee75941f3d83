// The stages of a time step, in the order Simulation::attempt runs them (see simulation.hpp).
#include "engine/simulation.hpp"

#include "engine/parallel.hpp"
#include "engine/step_retry.hpp"

#include <Eigen/Geometry>
#include <Eigen/QR>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

namespace nexdyn {

double resolved_dhat(const Scene& scene) {
  if (scene.contact.dhat > 0.0) return scene.contact.dhat;
  const double diagonal = bodies_bbox_diagonal(scene.model);
  return diagonal > 0.0 ? 1e-3 * diagonal : 1e-3;
}

namespace {
// Joints: the default tolerance relative to the bodies' bounding-box diagonal (the solve's own
// constants are in simulation_solve.cpp).
constexpr double kDefaultJointTolerance = 1e-9;

// Sleeping bodies: the default rest speed against the Newton tolerance. A converged step leaves
// every increment below tolerance * dt uncorrected, so bodies at rest keep velocities of a few
// times the tolerance (up to 7x on scenes/stress/pile_100.json).
constexpr double kSleepToleranceRatio = 10.0;

std::unique_ptr<BarrierPotential> make_contact(const Scene& scene) {
  // Projective Dynamics keeps bodies off plane obstacles by its own projections, not by the
  // barrier (the scene refuses every other contact for it).
  if (!scene.contact.enabled || scene.solver.method == SolverMethod::projective_dynamics) return nullptr;
  return std::make_unique<BarrierPotential>(scene.model, resolved_dhat(scene));
}

std::unique_ptr<FrictionPotential> make_friction(const Scene& scene) {
  const ContactSettings& contact = scene.contact;
  if (!contact.has_friction()) return nullptr;
  auto both = [](double mu_k, double mu_s) { return FrictionCoefficients{mu_s < 0.0 ? mu_k : mu_s, mu_k}; };
  FrictionTable table(static_cast<int32_t>(scene.model.materials.size()), both(contact.friction, contact.static_friction));
  for (const ContactSettings::FrictionPair& pair : contact.friction_pairs)
    table.set(pair.a, pair.b, both(pair.friction, pair.static_friction));
  const double diagonal = bodies_bbox_diagonal(scene.model);
  const double epsv = contact.epsv > 0.0 ? contact.epsv : 1e-3 * (diagonal > 0.0 ? diagonal : 1.0);
  return std::make_unique<FrictionPotential>(scene.model, std::move(table), epsv);
}
}  // namespace

Simulation::Simulation(const Scene& scene)
    : scene_(scene), model_(scene.model), map_(scene.model), state_(scene.initial),
      joints_(scene.model, history_.joint_multipliers),
      elastic_(scene.model, joints_.coupling_groups()), contact_(make_contact(scene)),
      friction_(make_friction(scene)), kinematic_(scene.model, history_),
      potential_(scene.model, elastic_, history_, contact_.get(), joints_.empty() ? nullptr : &joints_) {
  // The potential's terms, in order (engine/potential/incremental_potential.hpp): inertia and gravity,
  // elasticity, joints and the barrier (the constructor), then friction and the kinematic targets.
  potential_.set_friction(friction_.get());
  if (friction_) potential_.friction()->set_velocity_tolerance(scene.solver.tolerance);
  if (contact_ && scene.solver.sleep.enabled) {
    const SleepSettings& sleep = scene.solver.sleep;
    const double rest_speed = sleep.velocity > 0.0 ? sleep.velocity : kSleepToleranceRatio * scene.solver.tolerance;
    sleeping_ = std::make_unique<SleepingBodies>(model_, history_, rest_speed, sleep.steps, contact_->dhat());
  }
  if (!kinematic_.empty()) potential_.set_kinematic(&kinematic_);
  if (DampingTerm::wanted(model_)) {
    auto damping = std::make_unique<DampingTerm>(model_, elastic_.pattern(), state_);
    damping_ = damping.get();
    potential_.add_term(std::move(damping));
  }
  potential_.set_profile(&profile_);
  if (contact_) contact_->set_profile(&profile_);
  const int64_t n = model_.num_dofs();
  x_next_.resize(n);
  force_.resize(n);
  motion_.resize(n);
  state_.a.assign(n, 0.0);
  state_.x_tilde = state_.x;
  // Prescribed vertices start with their prescribed velocity and acceleration.
  prescribe(0.0, state_.x, &state_.v, &state_.a, nullptr);
  if (scene.time.consistent_initial_acceleration && !scene.time.integrator.is_static) {
    if (!explicit_acceleration(state_.x, state_.a))
      throw SceneError(scene.file.string() + ": the initial state has non-finite forces (inverted tet?)");
    set_rigid_rotation_acceleration(state_.x, state_.v, state_.x, state_.a);
    if (damping_) {
      damping_->prepare_at_state();
      damping_->add_explicit_acceleration(state_.v.data(), state_.a.data());
    }
    if (!joints_.empty()) constrain_initial_acceleration();
  }
  if (!joints_.empty()) {
    joint_tolerance_ = scene.solver.joint_tolerance > 0.0
                           ? scene.solver.joint_tolerance
                           : kDefaultJointTolerance * std::max(bodies_bbox_diagonal(model_), 1e-3);
  }
  if (scene.time.integrator.is_static) {
    std::fill(state_.v.begin(), state_.v.end(), 0.0);
    std::fill(state_.a.begin(), state_.a.end(), 0.0);
  }
  // Generalized-alpha starts its auxiliary acceleration at the consistent one (Arnold and
  // Bruls' a_0 = q''_0: the positions and velocities stay second order).
  state_.a_bar = state_.a;
  StepStats start;
  measure_step(start);
  history_.energy_before = start.total_energy;
  history_.energy_scale = energies_now().in_motion;
}

// ---- the step -----------------------------------------------------------------------------

StepOutcome Simulation::step() {
  const auto start = std::chrono::steady_clock::now();
  RetryLog retries;
  const double t_next = state_.time + scene_.time.dt;
  step_iterations_ = 0;
  balance_ = {};
  stats_.guarded_steps = 0;
  energy_now_ = history_.energy_before;
  // The groups woken for this step sleep again if the step is stopped: a run resumed from its
  // start must wake them itself, as the run never stopped did.
  std::optional<StepHistory> before_waking;
  if (sleeping_ && sleeping_->num_sleeping() > 0) {
    before_waking = history_;
    sleeping_->wake_near_motion(state_, scene_.time.dt);
  }
  StepOutcome outcome;
  try {
    outcome = advance_or_split(*this, state_.time, t_next, scene_.time.dt, 0, scene_.solver.substep_halvings, retries);
  } catch (const StepStopped& stop) {
    if (before_waking) history_ = std::move(*before_waking);
    return stopped_outcome(stop);
  }
  stats_.retries = retries.retries;
  stats_.retried_because = std::move(retries.first_failure);
  if (outcome.status != StepStatus::ok) return outcome;
  const int iterations = step_iterations_;
  ++state_.step;

  stats_.step = state_.step;
  stats_.time = state_.time;
  stats_.newton_iterations = iterations;
  {
    ProfileScope scope(&profile_, StepPhase::measure);
    measure_step(stats_);
    // Rest counts and sleepers, from the contact candidates the measure left at x.
    if (sleeping_) {
      sleeping_->update(state_, contact_->candidates(), scene_.time.dt);
      stats_.sleeping_bodies = sleeping_->num_sleeping();
    }
    // What the named terms do not explain is the time integration's own doing.
    balance_.integrator_energy = (stats_.total_energy - history_.energy_before) - balance_.boundary_work +
                                 balance_.friction_dissipated + balance_.damping_dissipated -
                                 balance_.kappa_energy;
    stats_.balance = balance_;
    stats_.damping_dissipated = history_.damping_dissipated;
    history_.energy_before = stats_.total_energy;
  }
  stats_.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return outcome;
}

// ---- the retry by halving (engine/step_retry.hpp) --------------------------------------------

Simulation::Snapshot Simulation::snapshot() const { return {state_, history_, balance_, energy_now_}; }

void Simulation::go_back(const Snapshot& before) {
  state_ = before.state;
  history_ = before.history;
  drop_caches();
  balance_ = before.balance;
  energy_now_ = before.energy_now;
}

StepOutcome Simulation::attempt(double /*t_start*/, double t_end, double dt, int level, const Snapshot& before) {
  StepOutcome outcome = attempt(dt, t_end, level, step_iterations_);
  if (outcome.status == StepStatus::ok && guard_energy(before.balance)) {
    // The integration would have created energy: the same interval again with implicit Euler.
    go_back(before);
    force_euler_ = true;
    try {
      outcome = attempt(dt, t_end, level, step_iterations_);
    } catch (const StepStopped&) {
      force_euler_ = false;
      throw;
    }
    force_euler_ = false;
    if (outcome.status == StepStatus::ok) {
      ++stats_.guarded_steps;
      guard_energy(before.balance);
    }
  }
  return outcome;
}

// One attempt at the interval [state_.time, t_next]: the stage list.
StepOutcome Simulation::attempt(double dt, double t_next, int level, int& iterations) {
  if (level == fail_level_) return {StepStatus::max_iterations, "failed on purpose (test seam)"};
  const StepContext ctx = choose_scheme(dt, t_next, level);
  const double kappa_before = history_.kappa;
  const double held_kinetic_before = held_kinetic_energy(model_, state_.v);
  predict_x_tilde(*ctx.scheme, ctx.dt, state_.x, state_.v, state_.a, state_.a_bar, state_.x_tilde);
  const StepOutcome outcome = ctx.scheme->is_explicit() ? explicit_update(ctx) : implicit_solve(ctx, iterations);
  if (outcome.status != StepStatus::ok) return outcome;
  account_energy(state_.x, x_next_, kappa_before, ctx.dt);
  finish(ctx, held_kinetic_before);
  return outcome;
}

StepContext Simulation::choose_scheme(double dt, double t_next, int level) {
  static const IntegratorParams kEuler = *integrator_preset("implicit_euler");
  const IntegratorParams& scene_scheme = scene_.time.integrator;
  const IntegratorParams* scheme = &scene_scheme;
  if (force_euler_) {
    scheme = &kEuler;
  } else if (contact_ && history_.contact_memory.empty() && scene_scheme.contact_memory_scale(dt) != 0.0) {
    // No contact force of a step before this one to remember: the first step, or the first after
    // a checkpoint written without it. Contacts already touching at x_n would then be taken for
    // new ones, and a body resting on a slope would be kicked by the difference; implicit Euler,
    // whose contact weight is its own steady one, takes this step instead and leaves the memory
    // for the next. Without touching contacts the memory is zero.
    if (potential_.barrier()->in_contact(state_.x.data()))
      scheme = &kEuler;
    else
      history_.contact_memory.assign(model_.num_dofs(), 0.0);
  }
  last_attempt_euler_ = scheme->is_implicit_euler();
  return make_step_context(*scheme, state_.time, dt, t_next, level);
}

StepOutcome Simulation::explicit_update(const StepContext& ctx) {
  x_next_ = state_.x_tilde;
  prescribe(ctx.t_end, x_next_, nullptr, nullptr, nullptr);
  a_next_ = state_.a;  // prescribed vertices keep theirs until finish()
  if (!explicit_acceleration(x_next_, a_next_))
    return {StepStatus::non_finite, "non-finite forces after the explicit update (the step is above the "
                                    "stability limit or a tet inverted)"};
  if (damping_) {
    // The damping force at the velocity known before the step's end: v_n + h (1 - gamma) a_n.
    damping_->prepare_at_state();
    const IntegratorParams& p = *ctx.scheme;
    motion_ = state_.v;
    for (size_t i = 0; i < motion_.size(); ++i) motion_[i] += ctx.dt * (1.0 - p.gamma) * state_.a[i];
    damping_->add_explicit_acceleration(motion_.data(), a_next_.data());
  }
  update_explicit(*ctx.scheme, ctx.dt, a_next_, state_.v, state_.a, state_.a_bar);
  return {};
}

void Simulation::update_after_solve(const StepContext& ctx) {
  const IntegratorParams& scheme = *ctx.scheme;
  if (scheme.is_static) {
    if (contact_) potential_.impulsive_forces(x_next_.data(), impulse_);  // the forces, for the balance
    return;
  }
  if (contact_) {
    update_with_contact(ctx);
    return;
  }
  update_implicit(scheme, ctx.dt, x_next_, state_.x_tilde, state_.v, state_.a, state_.a_bar);
  // Joint forces act as one impulse at the end of the step: out of the acceleration carried to
  // the next step (engine/potential/incremental_potential.hpp).
  potential_.impulsive_forces(x_next_.data(), impulse_);
  remove_impulse(scheme, impulse_, state_.a, state_.a_bar);
}

void Simulation::update_with_contact(const StepContext& ctx) {
  // a_{n+1} = M^-1 (elastic + gravity forces) at x_{n+1}, evaluated, not taken from the
  // positions: a stiff barrier turns the small error that Newton's tolerance leaves in x_{n+1}
  // into a large error of the contact force, which a history built from (x - x_tilde) / s
  // minus the contact force would carry into every later step (it made a toppled cube stack's
  // kinetic energy grow to 1e8 J). The positions decide the contact impulse instead: whatever
  // of x_{n+1} - x_tilde the smooth and joint forces do not explain, so the velocity stays as
  // close to the positions as the tolerance, as implicit Euler's does.
  a_next_ = state_.a;  // held vertices keep theirs until finish()
  explicit_acceleration(x_next_, a_next_);
  // Affine bodies' axis nodes: the rigid acceleration at x_{n+1}, for the angular velocity of
  // the step's start; the rest of their motion (the stretch Newton left) is the step's impulse.
  if (!model_.affine_bodies.empty()) set_rigid_rotation_acceleration(state_.x, state_.v, x_next_, a_next_);
  if (damping_) damping_->add_step_acceleration(x_next_.data(), a_next_.data());  // not an impulse
  potential_.impulsive_forces(x_next_.data(), impulse_);  // the forces, for joints and the balance
  const std::vector<double>& joint = potential_.joint_force();
  const IntegratorParams& p = *ctx.scheme;
  const double dt = ctx.dt, s = ctx.potential_scale, s_c = ctx.contact_scale;
  const double s_j = joints_.empty() ? 0.0 : s * joints_.weight();
  const double c_a = p.c_a(), c_f = p.c_f(), c_m = p.c_m(), gamma = p.gamma;
  // Kept when the scene's scheme uses it (also after a first step taken by implicit Euler).
  std::vector<double>& memory = history_.contact_memory;
  const bool remember = scene_.time.integrator.contact_memory_scale(dt) != 0.0;
  if (remember) memory.resize(model_.num_dofs(), 0.0);
  std::vector<double>& x_tilde = state_.x_tilde;
  std::vector<double>&v = state_.v, &a = state_.a, &a_bar = state_.a_bar;
  for (int32_t vertex = 0; vertex < model_.num_vertices; ++vertex) {
    if (model_.dirichlet[vertex] >= 0) {
      if (remember) std::fill_n(memory.begin() + 3 * int64_t{vertex}, 3, 0.0);
      continue;
    }
    // A sleeping body keeps its state (v = 0) and its contact memory for when it wakes.
    if (sleeping_ && sleeping_->vertex_asleep(vertex)) continue;
    const double m = model_.mass[vertex];
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * int64_t{vertex} + d;
      const double a_new = a_next_[i];
      const double j_joint = joint.empty() ? 0.0 : joint[i] / m;
      const double j_contact = (x_next_[i] - x_tilde[i] - s * a_new - s_j * j_joint) / s_c;
      const double a_bar_new = c_a * a_new + (c_f * a[i] - c_m * a_bar[i]);
      v[i] += dt * ((1.0 - gamma) * a_bar[i] + gamma * a_bar_new) + dt * (j_contact + j_joint);
      a[i] = a_new;
      a_bar[i] = a_bar_new;
      if (remember) memory[i] = m * j_contact;
    }
  }
  if (!model_.affine_bodies.empty()) keep_rigid_axis_velocity();
}

void Simulation::finish(const StepContext& ctx, double held_kinetic_before) {
  // Copied, not swapped: x keeps its buffer for the whole run (the Python module's arrays view it).
  std::copy(x_next_.begin(), x_next_.end(), state_.x.begin());
  const bool dynamic = !ctx.scheme->is_static;
  prescribe(ctx.t_end, state_.x, dynamic ? &state_.v : nullptr, dynamic ? &state_.a : nullptr,
            dynamic ? &state_.a_bar : nullptr);
  balance_.boundary_work += held_kinetic_energy(model_, state_.v) - held_kinetic_before;
}

void Simulation::set_velocities(const double* v) {
  const double before = motion_sums().kinetic;
  for (int32_t i = 0; i < model_.num_vertices; ++i)
    if (model_.dirichlet[i] < 0)
      for (int d = 0; d < 3; ++d) state_.v[3 * int64_t{i} + d] = v[3 * int64_t{i} + d];
  map_.fit_nodes(state_.v.data());
  if (sleeping_) sleeping_->wake_moving(state_);  // the next step's hold_sleeping lets them go
  history_.energy_before += motion_sums().kinetic - before;
}

void Simulation::drop_caches() {
  newton_.reset();  // no held vertices, no cached islands: they are rebuilt as needed
  kinematic_on_target_ = false;
  held_asleep_.clear();
  if (contact_) contact_->set_asleep({});
}

void Simulation::hold_sleeping() {
  if (!sleeping_) return;
  std::vector<int32_t> asleep = sleeping_->sleeping_vertices();
  if (asleep == held_asleep_) return;
  newton_->hold(held_asleep_, false);
  newton_->hold(asleep, true);
  if (contact_) contact_->set_asleep(asleep);  // their pairs with each other leave the solve
  held_asleep_.swap(asleep);
}

// ---- helpers of the stages ----------------------------------------------------------------

void Simulation::prescribe(double t, std::vector<double>& x, std::vector<double>* v,
                           std::vector<double>* a, std::vector<double>* a_bar, bool kinematic) const {
  if (!model_.has_dirichlet()) return;
  for (int32_t i = 0; i < model_.num_vertices; ++i) {
    const int32_t id = model_.dirichlet[i];
    if (id < 0) continue;
    const DirichletMotion& m = model_.dirichlet_motions[id];
    if (m.kinematic && !kinematic) continue;
    const DirichletMotion::Point p = m.at(Eigen::Vector3d::Map(&model_.rest_positions[3 * i]), t);
    Eigen::Vector3d::Map(&x[3 * i]) = p.x;
    if (v) Eigen::Vector3d::Map(&(*v)[3 * i]) = p.v;
    if (a) Eigen::Vector3d::Map(&(*a)[3 * i]) = p.a;
    if (a_bar) Eigen::Vector3d::Map(&(*a_bar)[3 * i]) = p.a;
  }
}

bool Simulation::explicit_acceleration(const std::vector<double>& x, std::vector<double>& a) {
  const double energy = elastic_.energy_gradient(x.data(), force_.data());
  if (!std::isfinite(energy)) return false;
  // Affine bodies: the force on their nodes, a = M^-1 f there, and their followers' a = J a.
  map_.fold_gradient(force_.data());
  const Eigen::Vector3d& g = model_.gravity;
  for (int32_t i = 0; i < model_.num_vertices; ++i) {
    if (model_.dirichlet[i] >= 0 || model_.follows_body(i)) continue;
    const bool weightless = model_.axis_node(i);
    for (int d = 0; d < 3; ++d) {
      const double ai = (weightless ? 0.0 : g[d]) - force_[3 * i + d] / model_.mass[i];
      if (!std::isfinite(ai)) return false;
      a[3 * i + d] = ai;
    }
  }
  map_.follow(a.data());
  return true;
}

void Simulation::set_rigid_rotation_acceleration(const std::vector<double>& x_motion,
                                                 const std::vector<double>& v_motion, const std::vector<double>& x,
                                                 std::vector<double>& a) const {
  // An affine body in a rigid motion has angular velocity w (the axial vector of C' C^-1, C its
  // axis nodes c_j as columns) and, free of torques, w' = -I^-1 (w x I w) by Euler's equations,
  // I its inertia tensor; its axis nodes then accelerate as c_j'' = w' x c_j + w x (w x c_j).
  // That is the force the orthogonality potential exists to give. Its own value at a solved
  // point is no use: the potential is stiff and Newton's tolerance leaves an arbitrary stretch
  // in it (at rest at t = 0 it gives nothing, and a body would spend its first step stretching
  // into the centripetal load; after a step in contact a thin body's axis node, L_j = 4e-6 kg m^2,
  // got accelerations of 1e5 m/s^2 from it, and generalized-alpha carried them into the next
  // prediction hundreds of metres away).
  for (const AffineBody& body : model_.affine_bodies) {
    if (sleeping_ && sleeping_->vertex_asleep(body.node)) continue;
    Eigen::Matrix3d C, C_dot, S = Eigen::Matrix3d::Zero();
    for (int j = 0; j < 3; ++j) {
      const int64_t i = 3 * int64_t{body.node + 1 + j};
      C.col(j) = Eigen::Vector3d::Map(&x_motion[i]);
      C_dot.col(j) = Eigen::Vector3d::Map(&v_motion[i]);
      const Eigen::Vector3d c = Eigen::Vector3d::Map(&x[i]);
      S += model_.mass[body.node + 1 + j] * c * c.transpose();  // sum L_j c_j c_j^T [kg m^2]
    }
    const Eigen::Matrix3d W = C_dot * C.inverse();
    const Eigen::Vector3d w(0.5 * (W(2, 1) - W(1, 2)), 0.5 * (W(0, 2) - W(2, 0)), 0.5 * (W(1, 0) - W(0, 1)));
    const Eigen::Matrix3d I = S.trace() * Eigen::Matrix3d::Identity() - S;
    const Eigen::Vector3d w_dot = -I.inverse() * w.cross(I * w);
    for (int j = 0; j < 3; ++j) {
      const int64_t i = 3 * int64_t{body.node + 1 + j};
      const Eigen::Vector3d c = Eigen::Vector3d::Map(&x[i]);
      Eigen::Vector3d::Map(&a[i]) = w_dot.cross(c) + w.cross(w.cross(c));
    }
  }
  map_.follow(a.data());
}

void Simulation::keep_rigid_axis_velocity() {
  // An affine body's axis nodes leave the step with the rigid rotation that carries its angular
  // momentum, C' = [w x c_j] with I w = sum_j L_j c_j x c_j' (I and c_j at x_{n+1}): of all
  // velocities with that angular momentum it has the least kinetic energy, so this only removes
  // energy, and only that of the stretch rate. The stretch is the orthogonality potential's
  // artefact, stiff and of tiny amplitude; its rate, left in the velocity, came back each step
  // as the impulse of the solve that undid it, and after a hard impact it grew into an
  // oscillation at the step's Nyquist frequency (a steel box thrown at 20 m/s: the kinetic
  // energy alternating by 250 J between steps of free flight).
  for (const AffineBody& body : model_.affine_bodies) {
    if (model_.dirichlet[body.node] >= 0) continue;
    if (sleeping_ && sleeping_->vertex_asleep(body.node)) continue;
    Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
    Eigen::Vector3d L = Eigen::Vector3d::Zero();
    for (int j = 0; j < 3; ++j) {
      const int64_t i = 3 * int64_t{body.node + 1 + j};
      const double mass = model_.mass[body.node + 1 + j];
      const Eigen::Vector3d c = Eigen::Vector3d::Map(&x_next_[i]);
      S += mass * c * c.transpose();
      L += mass * c.cross(Eigen::Vector3d::Map(&state_.v[i]));
    }
    const Eigen::Matrix3d I = S.trace() * Eigen::Matrix3d::Identity() - S;
    const Eigen::Vector3d w = I.ldlt().solve(L);
    for (int j = 0; j < 3; ++j) {
      const int64_t i = 3 * int64_t{body.node + 1 + j};
      Eigen::Vector3d::Map(&state_.v[i]) = w.cross(Eigen::Vector3d::Map(&x_next_[i]));
    }
  }
  map_.follow(state_.v.data());
}

void Simulation::constrain_initial_acceleration() {
  // a = M^-1 (f - J^T mu) on free vertices with J a = 0 (J is constant: c is linear), so
  // (J M^-1 J^T) mu = J a_f, a_f = the unconstrained acceleration (held vertices keep theirs).
  const int64_t m = 3 * joints_.size();
  const int64_t n = model_.num_dofs();
  Eigen::VectorXd rhs(m);
  joints_.apply(state_.a.data(), rhs.data());
  Eigen::MatrixXd A(m, m);
  std::vector<double> field(n), unit(m);
  // Followers of affine bodies (massless) are not coordinates: the joint acts on their nodes.
  auto free_inverse_mass = [&](std::vector<double>& f) {
    for (int32_t v = 0; v < model_.num_vertices; ++v)
      for (int d = 0; d < 3; ++d)
        f[3 * v + d] = model_.dirichlet[v] >= 0 || !(model_.mass[v] > 0.0) ? 0.0 : f[3 * v + d] / model_.mass[v];
  };
  for (int64_t i = 0; i < m; ++i) {
    std::fill(field.begin(), field.end(), 0.0);
    std::fill(unit.begin(), unit.end(), 0.0);
    unit[i] = 1.0;
    joints_.apply_transpose(unit.data(), field.data());
    free_inverse_mass(field);
    joints_.apply(field.data(), A.col(i).data());
  }
  // Redundant joints make A singular; the minimum-norm multiplier is then the natural choice.
  const Eigen::VectorXd mu = A.completeOrthogonalDecomposition().solve(rhs);
  std::fill(field.begin(), field.end(), 0.0);
  joints_.apply_transpose(mu.data(), field.data());
  free_inverse_mass(field);
  for (int64_t i = 0; i < n; ++i) state_.a[i] -= field[i];
  map_.follow(state_.a.data());
  // The joint force is J^T lambda with lambda = -mu: the multipliers start there.
  for (int64_t j = 0; j < joints_.size(); ++j) joints_.set_multiplier(j, -mu.segment<3>(3 * j));
}

// ---- checkpoints ----------------------------------------------------------------------------

void Simulation::adopt(const State& state, const StepHistory& history) {
  state_ = state;
  history_ = history;
  if (sleeping_) sleeping_->adopt(state_);
  else history_.rest_steps.clear(), history_.sleep_group.clear(), history_.rest_anchor.clear();
  drop_caches();
}

}  // namespace nexdyn

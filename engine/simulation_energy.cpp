// Energy accounting and measurement of the step (see simulation.hpp): the energy balance of an
// attempt, the energy guard, and the energies, momentum and contact summary of stats.csv.
#include "engine/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

void Simulation::account_energy(const std::vector<double>& x_old, const std::vector<double>& x_new,
                                double kappa_before, double dt) {
  const std::vector<double> none;
  const std::vector<double>& contact_force = contact_ ? potential_.contact_force() : none;
  const std::vector<double>& friction_force = friction_ ? potential_.friction_force() : none;
  if (held_vertices_move(model_, x_old, x_new)) {
    const int64_t n = model_.num_dofs();
    elastic_gradient_old_.resize(n);
    elastic_gradient_new_.resize(n);
    elastic_.energy_gradient(x_old.data(), elastic_gradient_old_.data());
    elastic_.energy_gradient(x_new.data(), elastic_gradient_new_.data());
    balance_.boundary_work += boundary_work(model_, x_old, x_new, elastic_gradient_old_, elastic_gradient_new_,
                                            {&contact_force, &friction_force});
  }
  balance_.friction_dissipated += friction_dissipation(x_old, x_new, friction_force);
  const double kappa = potential_.barrier_stiffness();
  if (contact_ && kappa != kappa_before) balance_.kappa_energy += (kappa - kappa_before) * contact_->energy(x_new.data());
  if (damping_) account_damping(x_old, x_new, dt);
}

// The energy damping took out over the step: dx^T D dx / h with dx = x_{n+1} - x_n and this step's
// D. Never negative (D is PSD). It is the damping force's exact work under implicit Euler
// (dx = h v_{n+1}, force -D v_{n+1}) and under Newmark on a linear problem (dx = h (v_n + v_{n+1}) / 2,
// work -dx . D (v_n + v_{n+1}) / 2); the trapezoid of -D v at the step's two ends, used before,
// went negative when a contact impulse turned the end velocity around.
void Simulation::account_damping(const std::vector<double>& x_old, const std::vector<double>& x_new, double dt) {
  if (scene_.time.integrator.is_static) return;
  std::vector<double> dx(x_new.size()), force(model_.num_dofs());
  for (size_t i = 0; i < dx.size(); ++i) dx[i] = x_new[i] - x_old[i];
  damping_->force(dx.data(), force.data());  // -D dx
  double dissipated = 0.0;
  for (size_t i = 0; i < dx.size(); ++i) dissipated -= dx[i] * force[i];
  dissipated /= dt;
  balance_.damping_dissipated += dissipated;
  history_.damping_dissipated += dissipated;
}

Simulation::MotionSums Simulation::motion_sums() const {
  MotionSums sums;
  for (int32_t i = 0; i < model_.num_vertices; ++i) {
    const double m = model_.mass[i];
    const Eigen::Vector3d vi = Eigen::Vector3d::Map(&state_.v[3 * i]);
    const Eigen::Vector3d xi = Eigen::Vector3d::Map(&state_.x[3 * i]);
    sums.kinetic += 0.5 * m * vi.squaredNorm();
    // An affine body's axis nodes carry its rotation: kinetic energy and angular momentum
    // (1/2 L_j |c_j'|^2, L_j c_j x c_j'), but no weight and no linear momentum (Model::axis_node).
    const double translational = model_.translational_mass(i);
    sums.gravity -= translational * model_.gravity.dot(xi);
    sums.momentum += translational * vi;
    sums.angular_momentum += m * xi.cross(vi);
  }
  return sums;
}

Simulation::Energies Simulation::energies_now() const {
  const auto [kinetic, gravity, momentum, angular_momentum] = motion_sums();
  double barrier = 0.0;
  if (contact_ && potential_.barrier_stiffness() > 0.0)
    barrier = potential_.barrier_stiffness() * contact_->energy(state_.x.data());
  const double in_motion = kinetic + elastic_.energy(state_.x.data()) + barrier;
  return {in_motion + gravity, std::abs(in_motion), gravity};
}

bool Simulation::guard_energy(const EnergyBalance& balance_before) {
  const IntegratorParams& scheme = scene_.time.integrator;
  if (!scene_.time.energy_guard || scheme.is_static || scheme.is_explicit() || scheme.is_implicit_euler()) return false;
  // The energy this attempt's integration created: the change of the total energy that the
  // balance's named terms (boundary work, friction, kappa) do not explain.
  const Energies end = energies_now();
  const double boundary_work = balance_.boundary_work - balance_before.boundary_work;
  const double explained = boundary_work - (balance_.friction_dissipated - balance_before.friction_dissipated) -
                           (balance_.damping_dissipated - balance_before.damping_dissipated) +
                           (balance_.kappa_energy - balance_before.kappa_energy);
  // Less an allowance for the error of the trapezoidal boundary work, 1e-3 of it (its relative
  // error is about (h omega)^2 / 12 for a boundary turning at omega: 4e-5 on bar_twist).
  const double created = end.total - energy_now_ - explained - 1e-3 * std::abs(boundary_work);
  // Allowed: what the integration has taken out so far (numerical damping, impacts), and a
  // margin of 1e-3 of the largest energy in motion seen, this attempt's end included (a body
  // that starts at rest has none before its first step), plus 1e-10 of the gravity energy,
  // whose size depends only on where the origin is. The guard is for energy created steadily
  // (a drift, a blow-up), not for the noise of Newton's tolerance: at 1e-6, Newmark's first
  // step of the cantilever (1.4e-6 of its energy) was retaken, and implicit Euler took 0.32 J.
  const double scale = std::max(history_.energy_scale, end.in_motion);
  const double tolerance = 1e-3 * scale + 1e-10 * std::abs(end.gravity);
  if (!last_attempt_euler_ && history_.integrator_created + created > tolerance) return true;
  history_.integrator_created += created;
  energy_now_ = end.total;
  history_.energy_scale = scale;
  return false;
}

void Simulation::measure_motion(StepStats& stats) const {
  const auto [kinetic, gravity, momentum, angular_momentum] = motion_sums();
  stats.kinetic_energy = kinetic;
  stats.elastic_energy = elastic_.energy(state_.x.data());
  stats.gravity_energy = gravity;
  stats.barrier_energy = 0.0;
  stats.contacts = 0;
  stats.min_distance = std::numeric_limits<double>::infinity();
  stats.total_energy = kinetic + stats.elastic_energy + gravity;
  if (!joints_.empty()) stats.joint_violation = joints_.max_violation(state_.x.data());
  stats.momentum = momentum;
  stats.angular_momentum = angular_momentum;
}

namespace {
void add_contact_summary(StepStats& stats, const BarrierPotential::Summary& summary, double kappa) {
  stats.barrier_energy = kappa * summary.barrier;
  stats.contacts = summary.active;
  stats.min_distance = summary.min_distance;
  stats.total_energy += stats.barrier_energy;
}
}  // namespace

void Simulation::measure_planes(StepStats& stats) const {
  if (contact_ || !scene_.contact.enabled || model_.obstacle_planes.empty()) return;
  stats.contacts = pd_plane_vertices_;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    if (model_.dirichlet[v] >= 0) continue;
    const Eigen::Vector3d x = Eigen::Vector3d::Map(&state_.x[3 * v]);
    for (const ObstaclePlane& plane : model_.obstacle_planes)
      stats.min_distance = std::min(stats.min_distance, (x - plane.point).dot(plane.normal));
  }
}

void Simulation::measure_step(StepStats& stats) {
  measure_motion(stats);
  measure_planes(stats);
  // Leaves the barrier's candidates at a static search of x: the next step's first is free.
  if (contact_) add_contact_summary(stats, contact_->summarize(state_.x.data()), history_.kappa);
}

void Simulation::measure(StepStats& stats) const {
  measure_motion(stats);
  measure_planes(stats);
  // A barrier of its own, so that measuring leaves the step's candidates as they were.
  if (contact_) {
    BarrierPotential barrier(model_, contact_->dhat());
    add_contact_summary(stats, barrier.summarize(state_.x.data()), history_.kappa);
  }
}

}  // namespace nexdyn

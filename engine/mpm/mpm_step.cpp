// One MPM step under the integrator family (see mpm_step.hpp).
#include "engine/mpm/mpm_step.hpp"

#include "engine/mpm/grid_elasticity.hpp"
#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"
#include "kernels/elasticity/elasticity.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace nexdyn {

namespace {

constexpr int kMaxLineSearchHalvings = 40;

double max_abs(const std::vector<double>& a) {
  double m = 0.0;
  for (double x : a) m = std::max(m, std::abs(x));
  return m;
}

}  // namespace

MpmStepper::MpmStepper(const MpmModel& model)
    : model_(model), grid_(make_grid(model.grid_spacing, model.domain_min, model.domain_max)) {}

MpmStepResult MpmStepper::advance(Particles& particles, MpmParticleHistory& history, double t, double dt,
                                  const MpmStepSettings& settings, StepProfile* profile) {
  MpmStepResult result;
  const IntegratorParams& scheme = settings.integrator;
  const bool with_abar = scheme.alpha_m != scheme.alpha_f;
  if (history.a_bar.size() != particles.x.size()) history.a_bar.assign(particles.x.size(), 0.0);
  if (!transfer_to_grid(particles, history, with_abar)) {
    result.ok = false;
    result.status = StepStatus::non_finite;
    result.retry_may_help = false;
    result.message = "particles left the grid: every particle must stay at least 1.5 grid cells inside "
                     "mpm.domain_min and mpm.domain_max";
    return result;
  }
  result.active_nodes = static_cast<int64_t>(active_.size());
  {
    ProfileScope scope(profile, StepPhase::elastic);
    start_of_step_acceleration(particles);
  }
  if (!with_abar) a_bar_ = a_;
  // u_tilde from x_n = 0: the predictor of integrator.hpp in displacements.
  std::vector<double>& zero = trial_;
  zero.assign(u_.size(), 0.0);
  predict_x_tilde(scheme, dt, zero, v_, a_, a_bar_, u_tilde_);
  set_boundary(t, dt);
  const double s = scheme.potential_scale(dt);

  if (scheme.is_explicit()) {
    ProfileScope scope(profile, StepPhase::elastic);
    u_ = u_tilde_;
    project_start(u_);
    scatter_to_dense(u_, dense_u_);
    const double energy = grid_elastic_gradient(grid_, particles, bins_, model_.materials, dense_u_.data(),
                                                dense_work_.data());
    std::vector<double> a_new(u_.size());
    bool finite = std::isfinite(energy);
    for (size_t k = 0; k < active_.size(); ++k)
      for (int d = 0; d < 3; ++d) {
        a_new[3 * k + d] = model_.gravity[d] - dense_work_[3 * int64_t{active_[k]} + d] / m_[k];
        finite = finite && std::isfinite(a_new[3 * k + d]);
      }
    if (!finite) {
      result.ok = false;
      result.status = StepStatus::non_finite;
      result.message = "the explicit step turned a particle inside out (dt too large for the material)";
      return result;
    }
    // A separating node on its plane keeps only an acceleration away from it.
    for (size_t k = 0; k < active_.size(); ++k) {
      if (!separating_[k]) continue;
      const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
      hold_[k] = n.dot(Eigen::Map<const Eigen::Vector3d>(&u_[3 * k])) <= 0.0 ? kNormal : kFree;
      Eigen::Map<Eigen::Vector3d> ak(&a_new[3 * k]);
      if (hold_[k] == kNormal && n.dot(ak) < 0.0) ak -= n * n.dot(ak);
    }
    for (size_t k = 0; k < active_.size(); ++k)
      if (!separating_[k] && hold_[k] != kFree) {
        Eigen::Map<Eigen::Vector3d> ak(&a_new[3 * k]);
        if (hold_[k] == kFull) ak.setZero();
        else ak -= Eigen::Map<const Eigen::Vector3d>(&normal_[3 * k]) * Eigen::Map<const Eigen::Vector3d>(&normal_[3 * k]).dot(ak);
      }
    update_explicit(scheme, dt, a_new, v_, a_, a_bar_);
  } else {
    if (!newton(particles, dt, s, settings, result, profile)) {
      result.ok = false;
      return result;
    }
    update_implicit(scheme, dt, u_, u_tilde_, v_, a_, a_bar_);
  }
  finish_velocities(dt);
  for (size_t k = 0; k < active_.size(); ++k) result.boundary_nodes += hold_[k] != kFree && !in_box_[k];
  transfer_to_particles(particles, history, with_abar);
  return result;
}

bool MpmStepper::transfer_to_grid(const Particles& particles, const MpmParticleHistory& history, bool with_abar) {
  if (bin_particles(grid_, particles, bins_) > 0) return false;
  particles_to_grid(particles, bins_, grid_);
  const int64_t nodes = grid_.num_nodes();
  active_.clear();
  active_index_.assign(static_cast<size_t>(nodes), -1);
  for (int64_t i = 0; i < nodes; ++i)
    if (grid_.mass[i] > 0.0) {
      active_index_[i] = static_cast<int32_t>(active_.size());
      active_.push_back(static_cast<int32_t>(i));
    }
  const size_t na = active_.size();
  m_.resize(na);
  for (auto* buffer : {&v_, &a_, &a_bar_, &u_tilde_, &u_, &normal_, &target_, &box_velocity_}) buffer->assign(3 * na, 0.0);
  hold_.assign(na, kFree);
  separating_.assign(na, 0);
  in_box_.assign(na, 0);
  normal_force_.assign(na, 0.0);
  for (size_t k = 0; k < na; ++k) {
    m_[k] = grid_.mass[active_[k]];
    for (int d = 0; d < 3; ++d) v_[3 * k + d] = grid_.velocity[3 * int64_t{active_[k]} + d];
  }
  dense_u_.assign(static_cast<size_t>(grid_.num_dofs()), 0.0);
  dense_work_.assign(static_cast<size_t>(grid_.num_dofs()), 0.0);
  if (with_abar) {
    // abar_i = sum_p w_ip m_p abar_p / m_i, the same mass-weighted average as the velocity.
    for_each_particle_coloured(bins_, [&](int32_t p) {
      const BSplineStencil s = bspline_stencil(grid_, &particles.x[3 * p]);
      const Eigen::Vector3d ma = particles.mass[p] * Eigen::Map<const Eigen::Vector3d>(&history.a_bar[3 * p]);
      for_each_stencil_node(grid_, s, [&](int64_t node, int, double w, const Eigen::Vector3d&) {
        Eigen::Vector3d::Map(&dense_work_[3 * node]) += w * ma;
      });
    });
    for (size_t k = 0; k < na; ++k)
      for (int d = 0; d < 3; ++d) a_bar_[3 * k + d] = dense_work_[3 * int64_t{active_[k]} + d] / m_[k];
  }
  return true;
}

// a_i^n = f_i^n / m_i: the particles' elastic force at the start of the step, plus gravity.
void MpmStepper::start_of_step_acceleration(const Particles& particles) {
  grid_elastic_gradient(grid_, particles, bins_, model_.materials, dense_u_.data(), dense_work_.data());
  for (size_t k = 0; k < active_.size(); ++k)
    for (int d = 0; d < 3; ++d)
      a_[3 * k + d] = model_.gravity[d] - dense_work_[3 * int64_t{active_[k]} + d] / m_[k];
}

void MpmStepper::set_boundary(double t, double dt) {
  for (size_t k = 0; k < active_.size(); ++k) {
    const Eigen::Vector3d x = grid_.node_position(int64_t{active_[k]});
    for (const MpmBox& box : model_.boxes) {
      const Eigen::Vector3d p0 = box.motion.origin(x, t);
      if ((p0.array() < box.box_min.array()).any() || (p0.array() > box.box_max.array()).any()) continue;
      in_box_[k] = 1;
      hold_[k] = kFull;
      const DirichletMotion::Point end = box.motion.at(p0, t + dt);
      Eigen::Vector3d::Map(&target_[3 * k]) = end.x - x;
      Eigen::Vector3d::Map(&box_velocity_[3 * k]) = end.v;
      break;
    }
    if (in_box_[k]) continue;
    int normals = 0;
    for (const MpmPlane& plane : model_.planes) {
      if (plane.signed_distance(x) > 0.0) continue;
      if (plane.condition == PlaneCondition::sticky || normals > 0) {
        hold_[k] = kFull;  // held; two normal conditions at one node hold it too
        separating_[k] = 0;
        break;
      }
      ++normals;
      hold_[k] = kNormal;
      separating_[k] = plane.condition == PlaneCondition::separating;
      Eigen::Vector3d::Map(&normal_[3 * k]) = plane.normal;
    }
  }
}

// The start of the solve (and the explicit step's position): prescribed nodes on their targets,
// slip nodes on their planes, separating nodes out of theirs. A separating node starts held
// when its predicted position would be inside its plane.
void MpmStepper::project_start(std::vector<double>& u) const {
  for (size_t k = 0; k < active_.size(); ++k) {
    Eigen::Map<Eigen::Vector3d> uk(&u[3 * k]);
    const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
    if (hold_[k] == kFull) uk = Eigen::Map<const Eigen::Vector3d>(&target_[3 * k]);
    else if (hold_[k] == kNormal && (!separating_[k] || n.dot(uk) < 0.0)) uk -= n * n.dot(uk);
  }
}

bool MpmStepper::newton(const Particles& particles, double dt, double s, const MpmStepSettings& settings,
                        MpmStepResult& result, StepProfile* profile) {
  const size_t na = active_.size();
  // A separating node is on its plane within rounding: projecting a displacement onto a plane
  // whose normal is not along an axis leaves n . u at about +-1e-20 m, and a node left free at
  // +1e-20 m that the Newton direction pushes into the plane is cut short by the line search's
  // projection at every step length, so no length decreases the energy and the step is halved
  // (a cube landing on a plane with normal (0, 1, 0.2) took 23 retries in 30 steps).
  const double on_plane = 1e-12 * grid_.h;
  u_ = u_tilde_;
  project_start(u_);
  // Separating nodes start in the working set when they sit on their plane's bound.
  for (size_t k = 0; k < na; ++k)
    if (separating_[k]) {
      const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]), uk(&u_[3 * k]);
      hold_[k] = n.dot(uk) <= on_plane ? kNormal : kFree;
    }
  double E;
  {
    ProfileScope scope(profile, StepPhase::line_search);
    E = energy(particles, u_, s);
  }
  if (!std::isfinite(E)) {
    result.message = "the start of the MPM solve has an inverted particle";
    result.status = StepStatus::non_finite;
    return false;
  }
  const double step_tolerance = settings.tolerance * dt;
  for (int it = 1; it <= settings.max_iterations; ++it) {
    stop_point(SafePoint::newton_iteration);
    result.newton_iterations = it;
    {
      ProfileScope scope(profile, StepPhase::elastic);
      gradient_and_stiffness(particles, u_, s, g_);
    }
    // The working set: a separating node on its bound stays held while the gradient pushes it
    // into the plane (the plane's force is then g . n / s >= 0); otherwise it is let go.
    for (size_t k = 0; k < na; ++k) {
      if (!separating_[k]) continue;
      const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]), uk(&u_[3 * k]), gk(&g_[3 * k]);
      const uint8_t hold = (n.dot(uk) <= on_plane && n.dot(gk) >= 0.0) ? kNormal : kFree;
      hold_[k] = hold;
      normal_force_[k] = hold == kNormal ? n.dot(gk) / s : 0.0;
    }
    // Projected diagonal blocks, inverted: P D P + (I - P), from m I + s D.
    for (size_t k = 0; k < na; ++k) {
      Eigen::Map<Eigen::Matrix3d> D(&diag_[9 * k]);
      D = (m_[k] * Eigen::Matrix3d::Identity() + s * D).eval();
    }
    diag_raw_ = diag_;
    std::vector<double>& rhs = trial_;
    rhs.resize(3 * na);
    for (size_t i = 0; i < 3 * na; ++i) rhs[i] = -g_[i];
    // A separating node on its bound that the gradient lets go but the Newton direction would
    // push into the plane is held after all, and the direction solved again: otherwise the
    // line search's projection onto the plane could leave no descent.
    for (int round = 0; round < 4; ++round) {
      invert_projected_blocks();
      {
        ProfileScope scope(profile, StepPhase::solve);
        result.pcg_iterations += conjugate_gradients(particles, s, rhs, settings.pcg_tolerance, d_);
      }
      bool held_more = false;
      for (size_t k = 0; k < na; ++k) {
        if (!separating_[k] || hold_[k] != kFree) continue;
        const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]), uk(&u_[3 * k]), dk(&d_[3 * k]);
        if (n.dot(uk) <= on_plane && n.dot(dk) < 0.0) {
          hold_[k] = kNormal;
          held_more = true;
        }
      }
      if (!held_more) break;
      diag_ = diag_raw_;
    }
    const double increment = particle_increment(particles, d_);
    if (!std::isfinite(increment) || !std::isfinite(max_abs(d_))) {
      result.message = "the Newton direction is not finite";
      result.status = StepStatus::non_finite;
      return false;
    }
    ProfileScope scope(profile, StepPhase::line_search);
    double alpha = 1.0;
    bool accepted = false;
    for (int halving = 0; halving <= kMaxLineSearchHalvings; ++halving, alpha *= 0.5) {
      trial_.resize(3 * na);
      for (size_t i = 0; i < 3 * na; ++i) trial_[i] = u_[i] + alpha * d_[i];
      // Free separating nodes stop at their plane.
      for (size_t k = 0; k < na; ++k) {
        if (!separating_[k] || hold_[k] != kFree) continue;
        const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
        Eigen::Map<Eigen::Vector3d> uk(&trial_[3 * k]);
        if (n.dot(uk) < 0.0) uk -= n * n.dot(uk);
      }
      const double E_trial = energy(particles, trial_, s);
      if (E_trial <= E) {
        E = E_trial;
        u_.swap(trial_);
        accepted = true;
        break;
      }
      if (alpha * increment < 1e-3 * step_tolerance) break;
    }
    if (!accepted) {
      // Rounding: no decrease is measurable, and the step would not move anything anyway.
      if (increment <= step_tolerance) return true;
      char buf[160];
      std::snprintf(buf, sizeof buf, "the MPM line search found no decrease at Newton iteration %d (increment %.3g m)",
                    it, increment);
      result.message = buf;
      result.status = StepStatus::line_search_failed;
      return false;
    }
    // Converged when no particle moves more than the tolerance allows. The working set may still
    // change at nodes too light to move a particle; every iterate is feasible regardless.
    if (alpha * increment <= step_tolerance) return true;
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "Newton did not converge in %d iterations (solver.max_iterations)",
                settings.max_iterations);
  result.message = buf;
  result.status = StepStatus::max_iterations;
  return false;
}

// The boundary's say on the end velocities: prescribed nodes move with their box, held nodes
// not at all, slip nodes along their plane; under friction a separating node pressed on its
// plane loses up to mu h |f_n| / m_i of its tangential speed.
void MpmStepper::finish_velocities(double dt) {
  for (size_t k = 0; k < active_.size(); ++k) {
    Eigen::Map<Eigen::Vector3d> v(&v_[3 * k]);
    const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
    if (in_box_[k]) {
      v = Eigen::Map<const Eigen::Vector3d>(&box_velocity_[3 * k]);
      continue;
    }
    if (hold_[k] == kFull) {
      v.setZero();
      continue;
    }
    if (!separating_[k]) {
      if (hold_[k] == kNormal) v -= n * n.dot(v);
      continue;
    }
    // A separating node: after an explicit step, the plane takes out the velocity into it.
    double normal_speed_change = normal_force_[k] * dt / m_[k];
    if (n.dot(v) < 0.0 && normal_force_[k] == 0.0) {
      normal_speed_change = -n.dot(v);
      v -= n * n.dot(v);
    }
    if (model_.friction > 0.0 && normal_speed_change > 0.0) {
      Eigen::Vector3d tangential = v - n * n.dot(v);
      const double speed = tangential.norm();
      if (speed > 0.0) v -= tangential * std::min(1.0, model_.friction * normal_speed_change / speed);
    }
  }
}

void MpmStepper::transfer_to_particles(Particles& particles, MpmParticleHistory& history, bool with_abar) {
  dense_v_.assign(static_cast<size_t>(grid_.num_dofs()), 0.0);
  scatter_to_dense(v_, dense_v_);
  scatter_to_dense(u_, dense_u_);
  if (with_abar) {
    std::fill(dense_work_.begin(), dense_work_.end(), 0.0);
    scatter_to_dense(a_bar_, dense_work_);
    parallel_for(particles.size(), [&](int64_t begin, int64_t end) {
      for (int64_t p = begin; p < end; ++p) {
        const BSplineStencil s = bspline_stencil(grid_, &particles.x[3 * p]);
        Eigen::Vector3d a = Eigen::Vector3d::Zero();
        for_each_stencil_node(grid_, s, [&](int64_t node, int, double w, const Eigen::Vector3d&) {
          a += w * Eigen::Map<const Eigen::Vector3d>(&dense_work_[3 * node]);
        });
        Eigen::Vector3d::Map(&history.a_bar[3 * p]) = a;
      }
    });
  }
  grid_to_particles(grid_, dense_v_.data(), dense_u_.data(), particles);
}

}  // namespace nexdyn

// Value, gradient and Hessian of the incremental potential (see incremental_potential.hpp).
#include "engine/incremental_potential.hpp"

#include "engine/parallel.hpp"
#include "kernels/barrier/barrier.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

IncrementalPotential::IncrementalPotential(const Model& model, ElasticAssembly& elastic, StepHistory& history,
                                           BarrierPotential* contact, const JointSet* joints)
    : model_(model), elastic_(elastic), history_(history), contact_(contact), joints_(joints) {
  if (!contact_) return;
  contact_pattern_ = std::make_unique<ContactPattern>(elastic_.pattern(), history.contact_pattern_pairs,
                                                      history.contact_pattern_stamp);
  elastic_values_.resize(elastic_.pattern().nnz());
  bbox_diagonal_ = bodies_bbox_diagonal(model);
  double mass = 0.0;
  int64_t free = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.dirichlet[v] < 0) {
      mass += model.mass[v];
      ++free;
    }
  average_mass_ = free > 0 ? mass / free : 1.0;
}

void IncrementalPotential::begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) {
  x_tilde_ = &x_tilde;
  scale_ = ctx.potential_scale;
  contact_scale_ = ctx.contact_scale;
  inertia_ = ctx.inertia ? 1.0 : 0.0;
  if (contact_pattern_) contact_pattern_->sync();
}

double IncrementalPotential::inertia_gravity_energy(const double* x, int64_t begin, int64_t end) const {
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  double sum = 0.0;
  for (int64_t v = begin; v < end; ++v) {
    double kinetic = 0.0, work = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double dx = x[3 * v + d] - xt[3 * v + d];
      kinetic += dx * dx;
      work += g[d] * dx;
    }
    sum += m[v] * (0.5 * inertia_ * kinetic - scale_ * work);
  }
  return sum;
}

double IncrementalPotential::energy(const double* x) const {
  const double elastic = elastic_.energy(x);
  if (!std::isfinite(elastic)) return std::numeric_limits<double>::infinity();
  double barrier = 0.0;
  if (contact_) {
    barrier = contact_->energy(x);
    if (!std::isfinite(barrier)) return std::numeric_limits<double>::infinity();
  }
  const double joints = joints_ ? joints_->energy(x) : 0.0;
  const double friction = friction_ ? friction_->energy(x) : 0.0;
  const double kinematic = kinematic_ ? kinematic_->energy(x) : 0.0;
  const double inertia = deterministic_sum(model_.num_vertices, [&](int64_t begin, int64_t end) {
    return inertia_gravity_energy(x, begin, end);
  }, 1024);
  return inertia + scale_ * (elastic + joints) +
         contact_scale_ * (history_.kappa * barrier + friction) + kinematic;
}

void IncrementalPotential::group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                                        double* out) {
  // Inertia, gravity and the kinematic targets (unscaled) go straight into out.
  std::fill(out, out + num_groups, 0.0);
  grouped_sum(model_.num_vertices, 1024, [&](int64_t v) { return group_of_vertex[v]; },
              [&](int64_t begin, int64_t end) { return inertia_gravity_energy(x, begin, end); }, out);
  if (kinematic_) kinematic_->group_energy(x, group_of_vertex, out);
  auto zeroed = [&](std::vector<double>& w) -> double* {
    w.assign(num_groups, 0.0);
    return w.data();
  };
  double* elastic = zeroed(group_elastic_);
  double* joints = zeroed(group_joints_);
  double* barrier = zeroed(group_barrier_);
  double* friction = zeroed(group_friction_);
  elastic_.group_energy(x, group_of_vertex, elastic);
  if (joints_) joints_->group_energy(x, group_of_vertex, joints);
  if (contact_) contact_->group_energy(x, group_of_vertex, barrier);
  if (friction_) friction_->group_energy(x, group_of_vertex, friction);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (int32_t k = 0; k < num_groups; ++k) {
    if (!std::isfinite(elastic[k]) || !std::isfinite(barrier[k])) {
      out[k] = kInf;  // an inverted tet or a touching pair (kappa may still be 0: no inf * 0)
      continue;
    }
    out[k] += scale_ * (elastic[k] + joints[k]) + contact_scale_ * (history_.kappa * barrier[k] + friction[k]);
  }
}

void IncrementalPotential::begin_solve(const double* x) {
  if (!contact_) return;
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_->find_candidates(x, nullptr);
  // Initial stiffness (IPC supplemental sec. 3) from the gradients of E / s without the barrier
  // and of the barrier sum, with the held DOFs left out: the kappa that best balances them.
  const int64_t n = model_.num_dofs();
  Eigen::VectorXd grad_energy(n), grad_barrier = Eigen::VectorXd::Zero(n);
  elastic_.energy_gradient(x, grad_energy.data());
  if (joints_) joints_->add_gradient(x, grad_energy.data());
  const double* xt = x_tilde_->data();
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * int64_t{v} + d;
      grad_energy[i] += -model_.mass[v] * model_.gravity[d] + inertia_ * model_.mass[v] * (x[i] - xt[i]) / scale_;
    }
  contact_->assemble(x, 1.0, false);
  contact_->add_gradient(grad_barrier.data());
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    if (model_.dirichlet[v] >= 0) {
      grad_energy.segment<3>(3 * int64_t{v}).setZero();
      grad_barrier.segment<3>(3 * int64_t{v}).setZero();
    }
  const double dhat2 = contact_->dhat() * contact_->dhat();
  // The heuristic works on E / s_c = (E without barrier) / s_c + kappa B: its gradient is
  // (s / s_c) grad(E / s), and its inertia term is M / s_c.
  const double ratio = scale_ / contact_scale_;
  grad_energy *= ratio;
  // The stiffness is a property of the simulation, not of a step: a kappa that changed from
  // step to step would change the barrier's stored energy under resting contact and pump energy
  // into a stack. So it is set at the first solve with contact (kappa_min until then) and after
  // that only raised by the adaptive rule.
  if (!history_.kappa_from_contact) {
    history_.kappa = initial_barrier_stiffness(bbox_diagonal_, dhat2, average_mass_ / contact_scale_,
                                               grad_energy, grad_barrier, history_.kappa_max);
    history_.kappa_from_contact = grad_barrier.squaredNorm() > 0.0;
  }
  prev_min_distance_ = contact_->min_squared_distance(x);
}

void IncrementalPotential::prepare(const double* x, bool first_iteration) {
  if (!contact_) return;
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_->build_active_set(x);  // derivatives in gradient_hessian(), for its subset only
  if (!friction_ || friction_->num_stencils() == 0) {
    contact_pattern_->update(contact_->stencils(), contact_->slab_begin(), first_iteration);
    return;
  }
  // One stencil list for the pattern: the barrier's, then friction's (a copy per iteration; the
  // friction stencils are the barrier's of the lagged state, so the pattern rarely grows).
  contact_stencils_ = contact_->stencils();
  contact_stencils_.insert(contact_stencils_.end(), friction_->stencils().begin(), friction_->stencils().end());
  contact_slab_begin_ = contact_->slab_begin();
  const int64_t offset = contact_slab_begin_.back();
  for (size_t k = 1; k < friction_->slab_begin().size(); ++k)
    contact_slab_begin_.push_back(offset + friction_->slab_begin()[k]);
  contact_pattern_->update(contact_stencils_, contact_slab_begin_, first_iteration);
}

void IncrementalPotential::gradient_hessian(const double* x, double* grad, double* values,
                                            const ActiveSubset* subset) {
  const bool merge = contact_ != nullptr;
  const CscPattern& pattern = this->pattern();
  double* elastic_values = merge ? elastic_values_.data() : values;
  ProfileScope elastic_scope(profile_, StepPhase::elastic);
  // joints' Hessian included (coupling slabs)
  elastic_.gradient_hessian(x, grad, elastic_values, subset);
  if (joints_) joints_->add_gradient(x, grad);
  const IndexRanges all_vertices{{0, model_.num_vertices}};
  const IndexRanges& vertices = subset ? subset->vertices : all_vertices;
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  const double inertia = inertia_, scale = scale_;
  // Scale the elastic part by s, then add the mass diagonal and the inertia/gravity gradient.
  parallel_for_ranges(elastic_.value_ranges(vertices), 8192, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) elastic_values[k] *= scale;
  });
  // Contact derivatives, weighted by s_c kappa (friction: s_c), of the stencils that touch the
  // subset; the pattern's slab array is the barrier's slabs, then friction's.
  const bool with_friction = friction_ && friction_->num_stencils() > 0;
  if (merge) {
    ProfileScope scope(profile_, StepPhase::barrier);
    const uint8_t* mask = subset ? subset->vertex_mask.data() : nullptr;
    contact_->compute_derivatives(x, contact_scale_ * history_.kappa, true, mask);
    if (with_friction) {
      ProfileScope friction_scope(profile_, StepPhase::friction);
      friction_->compute_derivatives(x, contact_scale_, true, mask);
    }
    contact_pattern_->assemble(elastic_values, contact_->local_hessians().data(), values, &vertices,
                               with_friction ? friction_->local_hessians().data() : nullptr,
                               contact_->slab_begin().back());
  }
  parallel_for_ranges(vertices, 1024, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * v + d;
        grad[i] = scale * (grad[i] - m[v] * g[d]) + inertia * m[v] * (x[i] - xt[i]);
        values[pattern.diagonal[i]] += inertia * m[v];
      }
  });
  if (kinematic_) {
    kinematic_->add_gradient(x, grad);
    kinematic_->add_hessian_diagonal(pattern, values);
  }
  if (merge) {
    ProfileScope scope(profile_, StepPhase::barrier);
    contact_->add_gradient(grad);
    if (friction_) {
      ProfileScope friction_scope(profile_, StepPhase::friction);
      friction_->add_gradient(grad);
    }
  }
}

double IncrementalPotential::max_step(const double* x, const double* p) {
  return contact_ ? contact_->max_step(x, p) : 1.0;
}

std::vector<const std::vector<int32_t>*> IncrementalPotential::coupling_stencils() const {
  std::vector<const std::vector<int32_t>*> lists;
  if (contact_) lists.push_back(&contact_->stencils());
  if (friction_ && friction_->num_stencils() > 0) lists.push_back(&friction_->stencils());
  return lists;
}

void IncrementalPotential::impulsive_forces(const double* x, std::vector<double>& delta) {
  const int64_t n = model_.num_dofs();
  delta.assign(n, 0.0);
  if (!contact_ && !joints_) return;
  ProfileScope scope(profile_, StepPhase::barrier);
  // The gradient of s_c kappa B + s_c D + s w Phi_joints (s w = s_c), summed in this order;
  // divided by s (with a minus: a force) it is what update_implicit put into a_{n+1}. The
  // contact and friction parts are kept apart as well, for the energy balance.
  std::vector<double>& impulsive = contact_gradient_;
  impulsive.assign(n, 0.0);
  contact_force_.assign(contact_ ? n : 0, 0.0);
  friction_force_.assign(friction_ ? n : 0, 0.0);
  const double to_force = -1.0 / contact_scale_;
  if (contact_) {
    contact_->assemble(x, contact_scale_ * history_.kappa, false);
    contact_->add_gradient_with_held(impulsive.data());
    for (int64_t i = 0; i < n; ++i) contact_force_[i] = impulsive[i] * to_force;
  }
  if (friction_) {  // friction acts with the contact force that carries it
    friction_->compute_derivatives(x, contact_scale_, false);
    friction_->add_gradient_with_held(impulsive.data());
    std::vector<double>& friction = friction_gradient_;
    friction.assign(n, 0.0);
    friction_->add_gradient_with_held(friction.data());
    for (int64_t i = 0; i < n; ++i) friction_force_[i] = friction[i] * to_force;
  }
  joint_force_.assign(joints_ ? n : 0, 0.0);
  if (joints_) {
    joint_gradient_.assign(n, 0.0);
    joints_->add_gradient(x, joint_gradient_.data());  // of w Phi
    const double to_joint_force = -1.0 / joints_->weight();
    for (int64_t i = 0; i < n; ++i) {
      impulsive[i] += scale_ * joint_gradient_[i];
      joint_force_[i] = joint_gradient_[i] * to_joint_force;
    }
  }
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    if (model_.dirichlet[v] >= 0 || !(model_.mass[v] > 0.0)) continue;
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * int64_t{v} + d;
      delta[i] = -(impulsive[i] / (scale_ * model_.mass[v]));
    }
  }
}

bool IncrementalPotential::end_iteration(const double* x) {
  if (!contact_) return false;
  const double min_distance = contact_->min_squared_distance(x);
  const double kappa = update_barrier_stiffness(prev_min_distance_, min_distance, history_.kappa_max,
                                                history_.kappa, bbox_diagonal_);
  prev_min_distance_ = min_distance;
  const bool changed = kappa != history_.kappa;
  history_.kappa = kappa;
  return changed;
}

}  // namespace nexdyn

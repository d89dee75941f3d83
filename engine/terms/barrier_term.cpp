#include "engine/terms/barrier_term.hpp"

#include "engine/coordinate_map.hpp"
#include "kernels/barrier/barrier.hpp"

#include <Eigen/Core>

#include <cmath>
#include <limits>

namespace nexdyn {

BarrierTerm::BarrierTerm(const Model& model, BarrierPotential& contact, StepHistory& history)
    : model_(model), contact_(contact), history_(history) {
  bbox_diagonal_ = bodies_bbox_diagonal(model);
  double mass = 0.0;
  int64_t free = 0;
  // An affine body counts as its mass spread over its followers, like a tet body's lumped mass
  // over its vertices (its nodes are coordinates, not points).
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.dirichlet[v] < 0) {
      mass += model.translational_mass(v);
      free += model.follows.empty() || model.follows[v] >= 0 || model.follows[v] == Model::kOwnNode;
    }
  average_mass_ = free > 0 ? mass / free : 1.0;
}

void BarrierTerm::begin_step(const std::vector<double>&, const StepContext& ctx) { contact_scale_ = ctx.contact_scale; }

void BarrierTerm::begin_solve(const double* x, const std::function<void(double*)>& preceding_gradient) {
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_.find_candidates(x, nullptr);
  prev_min_distance_ = contact_.min_squared_distance(x);
  // The stiffness is a property of the simulation, not of a step: a kappa that changed from step
  // to step would change the barrier's stored energy under resting contact and pump energy into a
  // stack. So it is set at the first solve with contact (kappa_min until then) and after that
  // only raised by the adaptive rule.
  if (history_.kappa_from_contact) return;
  // Initial stiffness (IPC supplemental sec. 3) from the gradients of E / s_c without the barrier
  // (the terms before this one: inertia M / s_c, gravity, elasticity, joints) and of the barrier
  // sum, with the held DOFs left out: the kappa that best balances them.
  const int64_t n = model_.num_dofs();
  Eigen::VectorXd grad_energy = Eigen::VectorXd::Zero(n), grad_barrier = Eigen::VectorXd::Zero(n);
  preceding_gradient(grad_energy.data());
  grad_energy /= contact_scale_;
  contact_.assemble(x, 1.0, false);
  contact_.add_gradient(grad_barrier.data());
  // With affine bodies both gradients over nodes (the barrier's acts on followers).
  const CoordinateMap map(model_);
  map.fold_gradient(grad_energy.data());
  map.fold_gradient(grad_barrier.data());
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    if (model_.dirichlet[v] >= 0) {
      grad_energy.segment<3>(3 * int64_t{v}).setZero();
      grad_barrier.segment<3>(3 * int64_t{v}).setZero();
    }
  const double dhat2 = contact_.dhat() * contact_.dhat();
  history_.kappa = initial_barrier_stiffness(bbox_diagonal_, dhat2, average_mass_ / contact_scale_, grad_energy,
                                             grad_barrier, history_.kappa_max);
  history_.kappa_from_contact = grad_barrier.squaredNorm() > 0.0;
}

void BarrierTerm::prepare(const double* x) {
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_.build_active_set(x);  // derivatives in add_derivatives(), for its subset only
}

double BarrierTerm::energy(const double* x) const {
  const double barrier = contact_.energy(x);
  // A touching pair is infinite whatever kappa is (it may still be 0: no inf * 0).
  return std::isfinite(barrier) ? history_.kappa * barrier : std::numeric_limits<double>::infinity();
}

void BarrierTerm::add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                                   double* out) {
  group_barrier_.assign(num_groups, 0.0);
  contact_.group_energy(x, group_of_vertex, group_barrier_.data());
  for (int32_t g = 0; g < num_groups; ++g)
    out[g] += std::isfinite(group_barrier_[g]) ? history_.kappa * group_barrier_[g]
                                               : std::numeric_limits<double>::infinity();
}

void BarrierTerm::add_gradient(const double* x, double weight, double* grad) {
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_.assemble(x, weight * history_.kappa, false);
  contact_.add_gradient(grad);
}

void BarrierTerm::add_derivatives(const double* x, double weight, const DerivativeOutput& out) {
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_.compute_derivatives(x, weight * history_.kappa, true, out.subset ? out.subset->vertex_mask.data() : nullptr);
  contact_.add_gradient(out.grad);
}

const std::vector<int32_t>* BarrierTerm::end_iteration(const double* x) {
  const double min_distance = contact_.min_squared_distance(x);
  const double kappa = update_barrier_stiffness(prev_min_distance_, min_distance, history_.kappa_max,
                                                history_.kappa, bbox_diagonal_);
  prev_min_distance_ = min_distance;
  if (kappa == history_.kappa) return nullptr;
  history_.kappa = kappa;
  return &contact_.stencils();  // only the islands with barrier stencils feel kappa
}

bool BarrierTerm::in_contact(const double* x) {
  contact_.find_candidates(x, nullptr);
  return contact_.min_squared_distance(x) < contact_.dhat() * contact_.dhat();
}

void BarrierTerm::build_active_set_at(const double* x) {
  ProfileScope scope(profile_, StepPhase::barrier);
  contact_.find_candidates(x, nullptr);
  contact_.build_active_set(x);
}

}  // namespace nexdyn

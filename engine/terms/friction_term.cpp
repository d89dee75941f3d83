#include "engine/terms/friction_term.hpp"

namespace nexdyn {

void FrictionTerm::lag(const double* x, const double* x_start, double dt) {
  // Only the bodies whose friction forces the new lag changed see a new potential; without a
  // velocity tolerance, every body with friction contacts before or after it.
  if (!changed_pending_) changed_.clear();
  if (!(velocity_tolerance_ > 0.0)) changed_.insert(changed_.end(), friction_.stencils().begin(), friction_.stencils().end());
  barrier_.build_active_set_at(x);
  ProfileScope scope(profile_, StepPhase::friction);
  friction_.lag(barrier_.contact(), x, barrier_.kappa(), x_start, dt);
  if (velocity_tolerance_ > 0.0) {
    last_changed_ = friction_.append_changed_stencils(dt, velocity_tolerance_, changed_);
  } else {
    changed_.insert(changed_.end(), friction_.stencils().begin(), friction_.stencils().end());
    last_changed_ = friction_.num_stencils();
  }
  changed_pending_ = true;
}

const std::vector<int32_t>* FrictionTerm::take_changed_stencils() {
  if (!changed_pending_) return nullptr;
  changed_pending_ = false;
  return &changed_;
}

void FrictionTerm::add_gradient(const double* x, double weight, double* grad) {
  ProfileScope scope(profile_, StepPhase::friction);
  friction_.compute_derivatives(x, weight, false);
  friction_.add_gradient(grad);
}

void FrictionTerm::add_derivatives(const double* x, double weight, const DerivativeOutput& out) {
  if (friction_.num_stencils() == 0) return;
  ProfileScope scope(profile_, StepPhase::friction);
  friction_.compute_derivatives(x, weight, true, out.subset ? out.subset->vertex_mask.data() : nullptr);
  friction_.add_gradient(out.grad);
}

StencilSlabs FrictionTerm::slabs() const {
  if (friction_.num_stencils() == 0) return {};
  return {&friction_.stencils(), &friction_.slab_begin(), friction_.local_hessians().data()};
}

}  // namespace nexdyn

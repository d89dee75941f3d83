// The IPC contact barrier: e(x) = kappa B(x) (engine/contact/barrier_potential.hpp), weight s_c.
// kappa lives in the StepHistory: set at the first solve with contact from the terms listed
// before this one (IPC supplemental sec. 3), then only raised by the adaptive rule at Newton's
// accepted points. The term bounds every step by CCD and keeps the candidate pairs valid for the
// segment it swept. Hessian: one PSD slab per active stencil.
#pragma once

#include "engine/contact/barrier_potential.hpp"
#include "engine/model.hpp"
#include "engine/potential/potential_term.hpp"
#include "engine/step_history.hpp"
#include "engine/step_profile.hpp"

#include <vector>

namespace nexdyn {

class BarrierTerm final : public PotentialTerm {
 public:
  // history: kappa, kappa_max, kappa_from_contact; must outlive the term.
  BarrierTerm(const Model& model, BarrierPotential& contact, StepHistory& history);
  const char* name() const override { return "contact barrier"; }
  TermScale scale() const override { return TermScale::contact; }
  TermHessian hessian() const override { return TermHessian::stencil_slabs; }
  void set_profile(StepProfile* profile) { profile_ = profile; }

  void begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) override;
  void begin_solve(const double* x, const std::function<void(double*)>& preceding_gradient) override;
  void prepare(const double* x) override;
  double energy(const double* x) const override;
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* out) override;
  void add_gradient(const double* x, double weight, double* grad) override;
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override;
  StencilSlabs slabs() const override {
    return {&contact_.stencils(), &contact_.slab_begin(), contact_.local_hessians().data()};
  }
  const std::vector<int32_t>* coupling_stencils() const override { return &contact_.stencils(); }

  void sweep(const double* x, const double* p, const uint8_t* moving, const double* pad) override {
    contact_.sweep(x, p, moving, pad);
  }
  void move_sweep_end(const double* x, const double* p) override { contact_.move_sweep_end(x, p); }
  const ContactCandidates* swept_pairs() const override { return &contact_.candidates(); }
  void group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha) override {
    contact_.group_max_steps(x, group_of_vertex, alpha);
  }
  void linked_max_steps(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                           double* alpha) override {
    contact_.linked_max_steps(x, group_of_vertex, num_groups, alpha);
  }
  double max_step(const double* x, const double* p) override { return contact_.max_step(x, p); }
  const std::vector<int32_t>* end_iteration(const double* x) override;

  // Whether a pair of x is closer than dhat (the candidates are searched at x).
  bool in_contact(const double* x);
  // The active set at x, its candidates searched at x (what friction lags).
  void build_active_set_at(const double* x);
  double kappa() const { return history_.kappa; }
  BarrierPotential& contact() { return contact_; }

 private:
  const Model& model_;
  BarrierPotential& contact_;
  StepHistory& history_;
  StepProfile* profile_ = nullptr;
  double contact_scale_ = 1.0;  // s_c of the attempt
  double bbox_diagonal_ = 1.0, average_mass_ = 0.0;
  double prev_min_distance_ = 0.0;  // squared, at the solve's last accepted point
  std::vector<double> group_barrier_;  // (num_groups) workspace of add_group_energy
};

}  // namespace nexdyn

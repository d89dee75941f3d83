// Lagged friction: e(x) = D(x) (engine/contact/friction_potential.hpp), weight s_c: it rides on
// the contact force. Its bases and normal forces are lagged from the barrier's active set at a
// chosen x (lag()); between lags it is a smooth potential of x. Hessian: one slab per contact.
#pragma once

#include "engine/contact/friction_potential.hpp"
#include "engine/potential/potential_term.hpp"
#include "engine/step_profile.hpp"
#include "engine/terms/barrier_term.hpp"

namespace nexdyn {

class FrictionTerm final : public PotentialTerm {
 public:
  FrictionTerm(FrictionPotential& friction, BarrierTerm& barrier) : friction_(friction), barrier_(barrier) {}
  const char* name() const override { return "friction"; }
  TermScale scale() const override { return TermScale::contact; }
  TermHessian hessian() const override { return TermHessian::stencil_slabs; }
  void set_profile(StepProfile* profile) { profile_ = profile; }

  // Lags the friction at x: the barrier's active set at x (with the current kappa, which must be
  // set), x_start the step's start positions, dt the attempt's time step.
  void lag(const double* x, const double* x_start, double dt);
  // The Newton tolerance [m/s]: a new lag reports (take_changed_stencils) only the contacts whose
  // friction force it changed by more than a re-solve could resolve at this tolerance
  // (FrictionPotential::append_changed_stencils). 0: every contact before and after the lag.
  void set_velocity_tolerance(double tolerance) { velocity_tolerance_ = tolerance; }
  // How many contacts the last lag() changed (as reported).
  int64_t last_lag_changes() const { return last_changed_; }

  double energy(const double* x) const override { return friction_.energy(x); }
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t /*num_groups*/,
                        double* out) override {
    friction_.group_energy(x, group_of_vertex, out);
  }
  void add_gradient(const double* x, double weight, double* grad) override;
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override;
  StencilSlabs slabs() const override;
  const std::vector<int32_t>* coupling_stencils() const override {
    return friction_.num_stencils() > 0 ? &friction_.stencils() : nullptr;
  }
  FrictionPotential& friction() { return friction_; }
  const std::vector<int32_t>* take_changed_stencils() override;

 private:
  FrictionPotential& friction_;
  BarrierTerm& barrier_;
  StepProfile* profile_ = nullptr;
  std::vector<int32_t> changed_;  // the stencils before and after the last lag(s)
  bool changed_pending_ = false;  // changed_ not yet taken
  double velocity_tolerance_ = 0.0;
  int64_t last_changed_ = 0;
};

}  // namespace nexdyn

// Kinematic targets: e(x) = Phi_kinematic(x), the augmented Lagrangian that pulls the vertices of
// moving boundaries and obstacles in contact scenes to their targets (engine/potential/kinematic_targets.hpp),
// weight 1: it is measured against the inertia. Hessian: its stiffness on the diagonal.
#pragma once

#include "engine/potential/kinematic_targets.hpp"
#include "engine/potential/potential_term.hpp"

namespace nexdyn {

class KinematicTerm final : public PotentialTerm {
 public:
  explicit KinematicTerm(const KinematicTargets& targets) : targets_(targets) {}
  const char* name() const override { return "kinematic targets"; }
  TermScale scale() const override { return TermScale::one; }
  TermHessian hessian() const override { return TermHessian::diagonal; }

  double energy(const double* x) const override { return targets_.energy(x); }
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t /*num_groups*/,
                        double* out) override {
    targets_.group_energy(x, group_of_vertex, out);
  }
  void add_gradient(const double* x, double weight, double* grad) override { targets_.add_gradient(x, grad, weight); }
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override {
    targets_.add_gradient(x, out.grad, weight);
  }
  void add_diagonal(const double*, double weight, const CscPattern& pattern, double* values,
                    const ActiveSubset*) override {
    targets_.add_hessian_diagonal(pattern, values, weight);
  }

 private:
  const KinematicTargets& targets_;
};

}  // namespace nexdyn

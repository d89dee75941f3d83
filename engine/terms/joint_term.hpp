// Joints: e(x) = Phi_joints(x), their augmented Lagrangian with its weight 1 / (gamma c_a) inside
// (engine/potential/joints.hpp), weight s. Its Hessian is constant and lives in the elastic pattern's
// coupling slabs (written by JointSet::set_stiffness), so this term adds gradients only.
#pragma once

#include "engine/potential/joints.hpp"
#include "engine/potential/potential_term.hpp"

namespace nexdyn {

class JointTerm final : public PotentialTerm {
 public:
  explicit JointTerm(const JointSet& joints) : joints_(joints) {}
  const char* name() const override { return "joints"; }
  TermScale scale() const override { return TermScale::potential; }
  TermHessian hessian() const override { return TermHessian::pattern_values; }

  double energy(const double* x) const override { return joints_.energy(x); }
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t /*num_groups*/,
                        double* out) override {
    joints_.group_energy(x, group_of_vertex, out);
  }
  void add_gradient(const double* x, double weight, double* grad) override { joints_.add_gradient(x, grad, weight); }
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override {
    joints_.add_gradient(x, out.grad, weight);
  }

 private:
  const JointSet& joints_;
};

}  // namespace nexdyn

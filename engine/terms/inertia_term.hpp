// Inertia and gravity: e(x) = sum_v m_v (i/2 |x_v - x~_v|^2 - s g . (x_v - x~_v)), weight 1,
// with i = 1 for dynamic schemes and 0 for "static", s the potential scale (gravity is a
// potential force) and x~ the predictor. Gravity is measured from x~ rather than from the origin:
// that shifts E by a constant only, but keeps its magnitude near the size of the changes the line
// search compares, so round-off does not swamp the Armijo test. Hessian: the mass diagonal.
#pragma once

#include "engine/model.hpp"
#include "engine/potential/potential_term.hpp"

namespace nexdyn {

class InertiaTerm final : public PotentialTerm {
 public:
  explicit InertiaTerm(const Model& model) : model_(model) {}
  const char* name() const override { return "inertia and gravity"; }
  TermScale scale() const override { return TermScale::one; }
  TermHessian hessian() const override { return TermHessian::diagonal; }

  void begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) override;
  double energy(const double* x) const override;
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* out) override;
  void add_gradient(const double* x, double weight, double* grad) override;
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override;
  void add_diagonal(const double* x, double weight, const CscPattern& pattern, double* values,
                    const ActiveSubset* subset) override;

 private:
  double energy_of(const double* x, int64_t begin, int64_t end) const;  // vertices [begin, end)
  void add_gradient_of(const double* x, double weight, double* grad, int64_t begin, int64_t end) const;

  const Model& model_;
  const std::vector<double>* x_tilde_ = nullptr;
  double inertia_ = 1.0;  // i
  double scale_ = 1.0;    // s
};

}  // namespace nexdyn

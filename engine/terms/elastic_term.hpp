// Elasticity: e(x) = Psi(x), the sum of the tets' strain energies (engine/potential/elastic_assembly.hpp),
// weight s. Its Hessian is the elastic pattern's values, which also carry the joints' constant
// coupling slabs (engine/potential/joints.hpp): the one pattern_values term.
#pragma once

#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/potential_term.hpp"

#include <vector>

namespace nexdyn {

class ElasticTerm final : public PotentialTerm {
 public:
  ElasticTerm(const Model& model, ElasticAssembly& elastic) : model_(model), elastic_(elastic) {}
  const char* name() const override { return "elasticity"; }
  TermScale scale() const override { return TermScale::potential; }
  TermHessian hessian() const override { return TermHessian::pattern_values; }

  double energy(const double* x) const override { return elastic_.energy(x); }
  void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t /*num_groups*/,
                        double* out) override {
    elastic_.group_energy(x, group_of_vertex, out);
  }
  void add_gradient(const double* x, double weight, double* grad) override;
  void add_derivatives(const double* x, double weight, const DerivativeOutput& out) override;

 private:
  const Model& model_;
  ElasticAssembly& elastic_;
  std::vector<double> gradient_;  // (3n) the unweighted gradient
};

}  // namespace nexdyn

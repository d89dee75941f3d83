// The incremental potential of one time step (DESIGN.md section 4):
//   E(x) = w/2 (x - x_tilde)^T M (x - x_tilde) + s (Psi_elastic(x) - sum_i m_i g . (x_i - x_tilde_i))
// with w = 1 for dynamic schemes and 0 for "static". Gravity is measured from x_tilde rather than
// from the origin: that only shifts E by a constant, but keeps its magnitude near the size of the
// changes the line search compares, so round-off does not swamp the Armijo test.
#pragma once

#include "engine/elastic_assembly.hpp"
#include "engine/model.hpp"

#include <vector>

namespace nexdyn {

class IncrementalPotential {
 public:
  IncrementalPotential(const Model& model, ElasticAssembly& elastic)
      : model_(model), elastic_(elastic) {}

  // Fixes x_tilde, the potential scale s and whether inertia is present for the coming solve.
  void begin_step(const std::vector<double>& x_tilde, double scale, bool inertia) {
    x_tilde_ = &x_tilde;
    scale_ = scale;
    inertia_ = inertia ? 1.0 : 0.0;
  }

  // E(x); +inf when x inverts a tet whose material forbids it.
  double energy(const double* x) const;
  // Gradient (3n) and Hessian values (pattern() order, mass on the diagonal) at x.
  void gradient_hessian(const double* x, double* grad, double* hessian_values);

  const HessianPattern& pattern() const { return elastic_.pattern(); }

 private:
  const Model& model_;
  ElasticAssembly& elastic_;
  const std::vector<double>* x_tilde_ = nullptr;
  double scale_ = 1.0;
  double inertia_ = 1.0;
};

}  // namespace nexdyn

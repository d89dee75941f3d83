// Value, gradient and Hessian of the incremental potential (see incremental_potential.hpp).
#include "engine/incremental_potential.hpp"

#include "engine/parallel.hpp"

#include <cmath>
#include <limits>

namespace nexdyn {

double IncrementalPotential::energy(const double* x) const {
  const double elastic = elastic_.energy(x);
  if (!std::isfinite(elastic)) return std::numeric_limits<double>::infinity();
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  const double inertia = inertia_, scale = scale_;
  const double rest = deterministic_sum(model_.num_vertices, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t v = begin; v < end; ++v) {
      double kinetic = 0.0, work = 0.0;
      for (int d = 0; d < 3; ++d) {
        const double dx = x[3 * v + d] - xt[3 * v + d];
        kinetic += dx * dx;
        work += g[d] * dx;
      }
      sum += m[v] * (0.5 * inertia * kinetic - scale * work);
    }
    return sum;
  }, 1024);
  return rest + scale * elastic;
}

void IncrementalPotential::gradient_hessian(const double* x, double* grad, double* values) {
  elastic_.gradient_hessian(x, grad, values);
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const HessianPattern& pattern = elastic_.pattern();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  const double inertia = inertia_, scale = scale_;
  const int64_t num_values = pattern.nnz();
  // Scale the elastic part by s, then add the mass diagonal and the inertia/gravity gradient.
  parallel_for(num_values, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) values[k] *= scale;
  }, 8192);
  parallel_for(model_.num_vertices, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * v + d;
        grad[i] = scale * (grad[i] - m[v] * g[d]) + inertia * m[v] * (x[i] - xt[i]);
        values[pattern.diagonal[i]] += inertia * m[v];
      }
  }, 1024);
}

}  // namespace nexdyn

#include "engine/terms/elastic_term.hpp"

#include "engine/parallel.hpp"

namespace nexdyn {

void ElasticTerm::add_gradient(const double* x, double weight, double* grad) {
  gradient_.resize(model_.num_dofs());
  elastic_.energy_gradient(x, gradient_.data());
  const double* g = gradient_.data();
  parallel_for(model_.num_dofs(), [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) grad[i] += weight * g[i];
  }, 8192);
}

void ElasticTerm::add_derivatives(const double* x, double weight, const DerivativeOutput& out) {
  gradient_.resize(model_.num_dofs());
  elastic_.gradient_hessian(x, gradient_.data(), out.pattern_values, out.subset);
  const IndexRanges all{{0, model_.num_vertices}};
  const IndexRanges& vertices = out.subset ? out.subset->vertices : all;
  double* values = out.pattern_values;
  parallel_for_ranges(elastic_.value_ranges(vertices), 8192, [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) values[k] *= weight;
  });
  const double* g = gradient_.data();
  double* grad = out.grad;
  parallel_for_ranges(vertices, 1024, [&](int64_t b, int64_t e) {
    for (int64_t i = 3 * b; i < 3 * e; ++i) grad[i] += weight * g[i];
  });
}

}  // namespace nexdyn

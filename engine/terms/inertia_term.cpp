#include "engine/terms/inertia_term.hpp"

#include "engine/parallel.hpp"

namespace nexdyn {

void InertiaTerm::begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) {
  x_tilde_ = &x_tilde;
  inertia_ = ctx.inertia ? 1.0 : 0.0;
  scale_ = ctx.potential_scale;
}

double InertiaTerm::energy_of(const double* x, int64_t begin, int64_t end) const {
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  double sum = 0.0;
  for (int64_t v = begin; v < end; ++v) {
    double kinetic = 0.0, work = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double dx = x[3 * v + d] - xt[3 * v + d];
      kinetic += dx * dx;
      work += g[d] * dx;
    }
    // Gravity does not pull an affine body's axis nodes (Model::axis_node).
    const double gravity_scale = model_.axis_node(static_cast<int32_t>(v)) ? 0.0 : scale_;
    sum += m[v] * (0.5 * inertia_ * kinetic - gravity_scale * work);
  }
  return sum;
}

double InertiaTerm::energy(const double* x) const {
  return deterministic_sum(model_.num_vertices, [&](int64_t b, int64_t e) { return energy_of(x, b, e); }, 1024);
}

void InertiaTerm::add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t, double* out) {
  grouped_sum(model_.num_vertices, 1024, [&](int64_t v) { return group_of_vertex[v]; },
              [&](int64_t b, int64_t e) { return energy_of(x, b, e); }, out);
}

void InertiaTerm::add_gradient_of(const double* x, double weight, double* grad, int64_t begin, int64_t end) const {
  const double* xt = x_tilde_->data();
  const double* m = model_.mass.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  for (int64_t v = begin; v < end; ++v) {
    const double gravity_scale = model_.axis_node(static_cast<int32_t>(v)) ? 0.0 : scale_;
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * v + d;
      grad[i] += weight * m[v] * (inertia_ * (x[i] - xt[i]) - gravity_scale * g[d]);
    }
  }
}

void InertiaTerm::add_gradient(const double* x, double weight, double* grad) {
  parallel_for(model_.num_vertices, [&](int64_t b, int64_t e) { add_gradient_of(x, weight, grad, b, e); }, 1024);
}

void InertiaTerm::add_derivatives(const double* x, double weight, const DerivativeOutput& out) {
  const IndexRanges all{{0, model_.num_vertices}};
  parallel_for_ranges(out.subset ? out.subset->vertices : all, 1024,
                      [&](int64_t b, int64_t e) { add_gradient_of(x, weight, out.grad, b, e); });
}

void InertiaTerm::add_diagonal(const double*, double weight, const CscPattern& pattern, double* values,
                               const ActiveSubset* subset) {
  const IndexRanges all{{0, model_.num_vertices}};
  const double* m = model_.mass.data();
  const double w = weight * inertia_;
  parallel_for_ranges(subset ? subset->vertices : all, 1024, [&](int64_t b, int64_t e) {
    for (int64_t v = b; v < e; ++v)
      for (int d = 0; d < 3; ++d) values[pattern.diagonal[3 * v + d]] += w * m[v];
  });
}

}  // namespace nexdyn

#include "engine/terms/damping_term.hpp"

#include "engine/parallel.hpp"

#include <algorithm>

namespace nexdyn {

namespace {
constexpr int64_t kTetGrain = 64;
}  // namespace

bool DampingTerm::wanted(const Model& model) {
  return std::any_of(model.materials.begin(), model.materials.end(),
                     [](const Material& m) { return m.damping.any(); });
}

DampingTerm::DampingTerm(const Model& model, const HessianPattern& pattern, const State& state)
    : model_(model), pattern_(pattern), state_(state) {
  const int32_t n = model.num_vertices;
  tet_a1_.resize(model.num_tets);
  for (int32_t t = 0; t < model.num_tets; ++t) {
    tet_a1_[t] = model.materials[model.tet_material[t]].damping.stiffness;
    stiffness_ = stiffness_ || tet_a1_[t] > 0.0;
  }
  vertex_a2m_.assign(n, 0.0);
  for (int32_t v = 0; v < n; ++v) {
    const int32_t material = model.bodies[model.vertex_body[v]].material;
    if (material >= 0) vertex_a2m_[v] = model.materials[material].damping.mass * model.mass[v];
  }
  if (!stiffness_) return;
  stiffness_slabs_ = std::make_unique<TetSlabOperator>(model);
  values_.assign(pattern.nnz(), 0.0);
}

void DampingTerm::compute_stiffness(const double* x) {
  if (!stiffness_) return;
  stiffness_slabs_->compute(x, tet_a1_);
  stiffness_slabs_->gather(pattern_, values_.data());
}

void DampingTerm::prepare_at_state() { compute_stiffness(state_.x.data()); }

void DampingTerm::begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) {
  const double s = ctx.potential_scale;
  k_ = 0.0;
  if (!ctx.inertia || !(s > 0.0)) return;  // "static": no velocity, no damping
  const IntegratorParams& p = *ctx.scheme;
  const double h = ctx.dt;
  k_ = h * p.gamma * p.c_a() / s;
  x_tilde_ = x_tilde;
  v_pred_.resize(x_tilde.size());
  const double c_f = p.c_f(), c_m = p.c_m();
  for (size_t i = 0; i < v_pred_.size(); ++i)
    v_pred_[i] = state_.v[i] + h * ((1.0 - p.gamma) * state_.a_bar[i] + p.gamma * (c_f * state_.a[i] - c_m * state_.a_bar[i]));
  compute_stiffness(state_.x.data());
}

void DampingTerm::velocity(const double* x, double* v) const {
  const int64_t n = model_.num_dofs();
  parallel_for(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) v[i] = v_pred_[i] + k_ * (x[i] - x_tilde_[i]);
  }, 3 * kDampingVertexGrain);
}

void DampingTerm::damped(const double* v, double* out) const {
  if (stiffness_) stiffness_slabs_->apply(v, out);
  parallel_for(model_.num_vertices, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i)
      for (int d = 0; d < 3; ++d)
        out[3 * i + d] = (stiffness_ ? out[3 * i + d] : 0.0) + vertex_a2m_[i] * v[3 * i + d];
  }, kDampingVertexGrain);
}

double DampingTerm::mass_quadratic(const double* v, int64_t begin, int64_t end) const {
  double s = 0.0;
  for (int64_t i = begin; i < end; ++i)
    s += vertex_a2m_[i] * (v[3 * i] * v[3 * i] + v[3 * i + 1] * v[3 * i + 1] + v[3 * i + 2] * v[3 * i + 2]);
  return s;
}

double DampingTerm::quadratic(const double* v) const {
  const double sum = deterministic_sum(model_.num_vertices, [&](int64_t b, int64_t e) {
    return mass_quadratic(v, b, e);
  }, kDampingVertexGrain);
  return stiffness_ ? sum + stiffness_slabs_->quadratic(v) : sum;
}

double DampingTerm::energy(const double* x) const {
  if (k_ == 0.0) return 0.0;
  v_.resize(model_.num_dofs());
  velocity(x, v_.data());
  return quadratic(v_.data()) / (2.0 * k_);
}

void DampingTerm::add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t, double* out) {
  if (k_ == 0.0) return;
  v_.resize(model_.num_dofs());
  velocity(x, v_.data());
  const double* v = v_.data();
  const double half_over_k = 0.5 / k_;
  grouped_sum(model_.num_vertices, kDampingVertexGrain, [&](int64_t i) { return group_of_vertex[i]; },
              [&](int64_t b, int64_t e) { return half_over_k * mass_quadratic(v, b, e); }, out);
  if (!stiffness_) return;
  const int32_t* tets = model_.tets.data();
  auto group_of = [&](int64_t t) {
    for (int c = 0; c < 4; ++c)
      if (group_of_vertex[tets[4 * t + c]] >= 0) return group_of_vertex[tets[4 * t + c]];
    return int32_t{-1};
  };
  grouped_sum(model_.num_tets, kTetGrain, group_of, [&](int64_t b, int64_t e) {
    double s = 0.0;
    for (int64_t t = b; t < e; ++t) s += stiffness_slabs_->tet_quadratic(t, v);
    return half_over_k * s;
  }, out);
}

void DampingTerm::add_gradient(const double* x, double weight, double* grad) {
  if (k_ == 0.0) return;
  const int64_t n = model_.num_dofs();
  v_.resize(n);
  dv_.resize(n);
  velocity(x, v_.data());
  damped(v_.data(), dv_.data());
  parallel_for(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) grad[i] += weight * dv_[i];
  }, 3 * kDampingVertexGrain);
}

void DampingTerm::add_derivatives(const double* x, double weight, const DerivativeOutput& out) {
  if (k_ == 0.0) return;
  add_gradient(x, weight, out.grad);
  // Hessian k D, added to the columns the elastic term has just written (only those of the
  // subset: the others keep the values of an earlier iteration).
  const double w = weight * k_;
  const IndexRanges all{{0, model_.num_vertices}};
  parallel_for_ranges(out.subset ? out.subset->vertices : all, kDampingVertexGrain, [&](int64_t b, int64_t e) {
    for (int64_t v = b; v < e; ++v) {
      if (stiffness_)
        for (int64_t i = pattern_.col_ptr[3 * v]; i < pattern_.col_ptr[3 * v + 3]; ++i)
          out.pattern_values[i] += w * values_[i];
      for (int d = 0; d < 3; ++d) out.pattern_values[pattern_.diagonal[3 * v + d]] += w * vertex_a2m_[v];
    }
  });
}

void DampingTerm::force(const double* v, double* force) const {
  damped(v, force);
  for (int64_t i = 0; i < model_.num_dofs(); ++i) force[i] = -force[i];
}

void DampingTerm::add_explicit_acceleration(const double* v, double* a) const {
  dv_.resize(model_.num_dofs());
  damped(v, dv_.data());
  for (int32_t i = 0; i < model_.num_vertices; ++i) {
    if (model_.dirichlet[i] >= 0 || !(model_.mass[i] > 0.0)) continue;
    for (int d = 0; d < 3; ++d) a[3 * i + d] -= dv_[3 * i + d] / model_.mass[i];
  }
}

void DampingTerm::add_step_acceleration(const double* x, double* a) const {
  if (k_ == 0.0) return;
  v_.resize(model_.num_dofs());
  velocity(x, v_.data());
  add_explicit_acceleration(v_.data(), a);
}

}  // namespace nexdyn

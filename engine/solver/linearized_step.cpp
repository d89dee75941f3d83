#include "engine/solver/linearized_step.hpp"

#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

namespace {

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  return deterministic_sum(static_cast<int64_t>(a.size()), [&](int64_t begin, int64_t end) {
    double s = 0.0;
    for (int64_t i = begin; i < end; ++i) s += a[i] * b[i];
    return s;
  }, kLinearizedGrain);
}

double max_abs(const std::vector<double>& a) {
  double m = 0.0;
  for (double v : a) m = std::max(m, std::abs(v));
  return m;
}
}  // namespace

LinearizedStep::LinearizedStep(const Model& model, LinearSolverKind kind, double tolerance, int max_cg_iterations)
    : model_(model), kind_(kind), tolerance_(tolerance), max_cg_iterations_(max_cg_iterations) {
  const int64_t n = model.num_dofs();
  held_.assign(n, 0);
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.eliminated(v) || !(model.mass[v] > 0.0)) std::fill_n(held_.begin() + 3 * int64_t{v}, 3, uint8_t{1});
  grad_.assign(n, 0.0);
  d_.assign(n, 0.0);
}

LinearizedResult LinearizedStep::solve(IncrementalPotential& potential, const StepContext& ctx,
                                       const DampingTerm* damping, std::vector<double>& x) {
  potential.begin_solve(x.data());
  potential.prepare(x.data(), true);
  LinearizedResult result;
  if (kind_ == LinearSolverKind::cholmod) {
    result = solve_cholmod(potential, x);
  } else {
    potential.gradient(x.data(), grad_.data());
    if (!std::all_of(grad_.begin(), grad_.end(), [](double g) { return std::isfinite(g); }))
      return {StepStatus::non_finite, "non-finite gradient at the start of the linearised step (an inverted tet?)"};
    result = solve_pcg(ctx, damping, x);
  }
  if (result.status != StepStatus::ok) return result;
  for (size_t i = 0; i < x.size(); ++i) x[i] += d_[i];
  return result;
}

// ---- CHOLMOD --------------------------------------------------------------------------------

LinearizedResult LinearizedStep::solve_cholmod(IncrementalPotential& potential, std::vector<double>& x) {
  const CscPattern& pattern = potential.pattern();
  values_.resize(pattern.nnz());
  potential.gradient_hessian(x.data(), grad_.data(), values_.data());
  if (!std::all_of(grad_.begin(), grad_.end(), [](double g) { return std::isfinite(g); }))
    return {StepStatus::non_finite, "non-finite gradient at the start of the linearised step (an inverted tet?)"};
  // Held DOFs keep d = 0: their rows and columns become the identity's.
  for (int64_t col = 0; col < pattern.num_dofs; ++col)
    for (int64_t k = pattern.col_ptr[col]; k < pattern.col_ptr[col + 1]; ++k) {
      const int64_t row = pattern.row_idx[k];
      if (held_[col] || held_[row]) values_[k] = row == col ? 1.0 : 0.0;
    }
  std::vector<double>& rhs = r_;
  rhs.resize(grad_.size());
  for (size_t i = 0; i < rhs.size(); ++i) rhs[i] = held_[i] ? 0.0 : -grad_[i];
  if (!cholmod_) {
    cholmod_ = std::make_unique<CholmodSolver>();
    if (cholmod_->analyze(pattern.num_dofs, pattern.col_ptr.data(), pattern.row_idx.data()) != StepStatus::ok) {
      const std::string why = cholmod_->error();
      cholmod_.reset();
      return {StepStatus::linear_solver_failed, "linearised step: " + why};
    }
  }
  if (StepStatus s = cholmod_->factorize(values_.data()); s != StepStatus::ok)
    return {s, "linearised step: " + cholmod_->error()};
  if (StepStatus s = cholmod_->solve(rhs.data(), d_.data()); s != StepStatus::ok)
    return {s, "linearised step: " + cholmod_->error()};
  return {};
}

// ---- matrix-free conjugate gradients --------------------------------------------------------

void LinearizedStep::apply(const double* w, double* out) const {
  stiffness_->apply(w, out);
  const int64_t n = model_.num_dofs();
  parallel_for(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) out[i] = held_[i] ? 0.0 : out[i] + diag_[i] * w[i];
  }, kLinearizedGrain);
}

LinearizedResult LinearizedStep::solve_pcg(const StepContext& ctx, const DampingTerm* damping, std::vector<double>& x) {
  const int64_t n = model_.num_dofs();
  // The gradient of E at x0 comes from the potential's terms; H's parts are rebuilt here.
  if (!stiffness_) stiffness_ = std::make_unique<TetSlabOperator>(model_);
  const double s = ctx.potential_scale;
  const double k = damping ? damping->velocity_slope() : 0.0;
  tet_scale_.resize(model_.num_tets);
  for (int32_t t = 0; t < model_.num_tets; ++t) tet_scale_[t] = s * (1.0 + (damping ? k * damping->tet_stiffness()[t] : 0.0));
  if (!stiffness_->compute(x.data(), tet_scale_))
    return {StepStatus::non_finite, "non-finite stiffness at the start of the linearised step (an inverted tet?)"};
  diag_.assign(n, 0.0);
  const double inertia = ctx.inertia ? 1.0 : 0.0;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const double a2m = damping ? damping->vertex_mass_damping()[v] : 0.0;
    for (int d = 0; d < 3; ++d) diag_[3 * v + d] = inertia * model_.mass[v] + s * k * a2m;
  }
  // Jacobi preconditioner: the inverse of H's diagonal on the free DOFs.
  inverse_diag_.resize(n);
  stiffness_->diagonal(inverse_diag_.data());
  for (int64_t i = 0; i < n; ++i) {
    const double h = inverse_diag_[i] + diag_[i];
    inverse_diag_[i] = held_[i] || !(h > 0.0) ? 0.0 : 1.0 / h;
  }

  r_.resize(n);
  z_.resize(n);
  p_.resize(n);
  hp_.resize(n);
  // r = b - H d with d = 0, b = -grad E(x0) (grad_, from solve()).
  std::fill(d_.begin(), d_.end(), 0.0);
  for (int64_t i = 0; i < n; ++i) r_[i] = held_[i] ? 0.0 : -grad_[i];
  for (int64_t i = 0; i < n; ++i) z_[i] = inverse_diag_[i] * r_[i];
  p_ = z_;
  double rz = dot(r_, z_);
  const double target = kCgToleranceRatio * tolerance_ * ctx.dt;
  LinearizedResult result;
  for (int it = 0;; ++it) {
    if (it % 64 == 0) stop_point();
    result.residual = max_abs(z_) / ctx.dt;
    if (max_abs(z_) <= target) {
      result.cg_iterations = it;
      return result;
    }
    if (it == max_cg_iterations_)
      return {StepStatus::max_iterations,
              "conjugate gradients did not reach the tolerance in " + std::to_string(it) + " iterations", it,
              result.residual};
    apply(p_.data(), hp_.data());
    const double php = dot(p_, hp_);
    if (!(php > 0.0) || !std::isfinite(php))
      return {StepStatus::factorization_failed, "conjugate gradients met a direction of non-positive curvature", it,
              result.residual};
    const double alpha = rz / php;
    for (int64_t i = 0; i < n; ++i) {
      d_[i] += alpha * p_[i];
      r_[i] -= alpha * hp_[i];
      z_[i] = inverse_diag_[i] * r_[i];
    }
    const double rz_new = dot(r_, z_);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (int64_t i = 0; i < n; ++i) p_[i] = z_[i] + beta * p_[i];
  }
}

}  // namespace nexdyn

// Newton driver (see newton.hpp).
#include "engine/solver/newton.hpp"

#include "engine/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace nexdyn {

namespace {
// Armijo sufficient-decrease constant and the smallest step length tried before giving up.
constexpr double kArmijo = 1e-4;
constexpr double kMinStepLength = 1e-10;

std::string format(const char* fmt, double a, double b = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), fmt, a, b);
  return buf;
}
}  // namespace

NewtonSolver::NewtonSolver(const Model& model, IncrementalPotential& potential)
    : model_(model), potential_(potential) {
  const int64_t n = model.num_dofs();
  constrained_dof_.assign(n, 0);
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.eliminated(v))
      for (int d = 0; d < 3; ++d) constrained_dof_[3 * v + d] = 1;
  grad_.resize(n);
  direction_.resize(n);
  trial_.resize(n);
  analyze_pattern();
}

void NewtonSolver::hold(const std::vector<int32_t>& vertices, bool held) {
  for (int32_t v : vertices)
    for (int d = 0; d < 3; ++d) constrained_dof_[3 * int64_t{v} + d] = held;
  collect_constrained_values();
}

void NewtonSolver::collect_constrained_values() {
  const CscPattern& pattern = potential_.pattern();
  constrained_values_.clear();
  for (int64_t c = 0; c < pattern.num_dofs; ++c)
    for (int64_t k = pattern.col_ptr[c]; k < pattern.col_ptr[c + 1]; ++k)
      if (constrained_dof_[c] || constrained_dof_[pattern.row_idx[k]])
        constrained_values_.push_back(k);
}

void NewtonSolver::analyze_pattern() {
  const CscPattern& pattern = potential_.pattern();
  collect_constrained_values();
  values_.resize(pattern.nnz());
  cholmod_.analyze(pattern.num_dofs, pattern.col_ptr.data(), pattern.row_idx.data());
  analyzed_version_ = potential_.pattern_version();
}

void NewtonSolver::eliminate_dirichlet(double* grad, double* values) const {
  const CscPattern& pattern = potential_.pattern();
  for (int64_t k : constrained_values_) values[k] = 0.0;
  for (int64_t i = 0; i < pattern.num_dofs; ++i)
    if (constrained_dof_[i]) {
      grad[i] = 0.0;
      values[pattern.diagonal[i]] = 1.0;
    }
}

NewtonResult NewtonSolver::solve(std::vector<double>& x, const NewtonSettings& settings) {
  NewtonResult result;
  const int64_t n = static_cast<int64_t>(x.size());
  potential_.begin_solve(x.data());
  double energy = potential_.energy(x.data());
  if (!std::isfinite(energy)) {
    result.status = StepStatus::non_finite;
    result.message = "the starting point of the step has infinite energy (an inverted tet or "
                     "touching contact)";
    return result;
  }
  for (int it = 0; it < settings.max_iterations; ++it) {
    potential_.prepare(x.data(), it == 0);
    if (potential_.pattern_version() != analyzed_version_) {
      ProfileScope scope(profile_, StepPhase::analysis);
      analyze_pattern();
      ++result.analyses;
    }
    potential_.gradient_hessian(x.data(), grad_.data(), values_.data());
    eliminate_dirichlet(grad_.data(), values_.data());
    if (!std::all_of(grad_.begin(), grad_.end(), [](double g) { return std::isfinite(g); })) {
      result.status = StepStatus::non_finite;
      result.message = "NaN or infinity in the gradient at Newton iteration " + std::to_string(it);
      return result;
    }
    {
      ProfileScope scope(profile_, StepPhase::factorization);
      if (!cholmod_.factorize(values_.data())) {
        result.status = StepStatus::factorization_failed;
        result.message = "factorisation failed at Newton iteration " + std::to_string(it) + ": " +
                         cholmod_.error();
        return result;
      }
    }
    {
      ProfileScope scope(profile_, StepPhase::solve);
      cholmod_.solve(grad_.data(), direction_.data());
    }
    double max_step = 0.0, slope = 0.0;
    for (int64_t i = 0; i < n; ++i) {
      direction_[i] = -direction_[i];
      max_step = std::max(max_step, std::abs(direction_[i]));
      slope += grad_[i] * direction_[i];
    }
    result.iterations = it + 1;
    result.increment = max_step / settings.dt;
    if (result.increment < settings.tolerance) {
      result.energy = energy;
      return result;
    }

    // Backtracking line search. Energies are compared with a round-off allowance: near the
    // minimum the decrease s*alpha*g.p can be smaller than the error of summing E itself.
    const double noise = 1e-13 * std::max(1.0, std::abs(energy));
    double alpha = potential_.max_step(x.data(), direction_.data()), trial_energy = 0.0;
    if (!(alpha > 0.0)) {
      result.status = StepStatus::line_search_failed;
      result.message = "continuous collision detection allows no motion along the Newton direction";
      return result;
    }
    {
      ProfileScope scope(profile_, StepPhase::line_search);
      for (;;) {
        for (int64_t i = 0; i < n; ++i) trial_[i] = x[i] + alpha * direction_[i];
        trial_energy = potential_.energy(trial_.data());
        if (trial_energy <= energy + kArmijo * alpha * slope + noise) break;
        alpha *= 0.5;
        if (alpha < kMinStepLength) {
          result.status = StepStatus::line_search_failed;
          result.message = format("line search found no decrease along the Newton direction "
                                  "(increment %.3g m/s, energy %.6g)", result.increment, energy);
          return result;
        }
      }
    }
    x.swap(trial_);
    energy = trial_energy;
    if (potential_.end_iteration(x.data())) energy = potential_.energy(x.data());
  }
  result.status = StepStatus::max_iterations;
  result.message = format("Newton did not converge in the iteration limit (last increment "
                          "%.3g m/s, tolerance %.3g m/s)", result.increment, settings.tolerance);
  result.energy = energy;
  return result;
}

}  // namespace nexdyn

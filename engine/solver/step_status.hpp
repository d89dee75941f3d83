// How a step ended. The solver never throws: every failure on its path, the linear solver's
// included, comes back as one of these with a sentence saying why, and the driver decides (a
// failed attempt is put back and retried as two halves, Simulation::advance_or_split).
#pragma once

#include <string_view>

namespace nexdyn {

enum class StepStatus {
  ok,
  max_iterations,         // Newton increment still above the tolerance
  line_search_failed,     // no step length decreased the energy
  factorization_failed,   // the Newton matrix is not positive definite (Cholesky refused it)
  non_finite,             // NaN/inf in the energy or gradient, or an inverted start
  boundary_collision,     // a moving boundary or obstacle cannot reach its prescribed position
  linear_solver_failed,   // CHOLMOD could not analyse, factorise or solve whatever the values:
                          // out of memory, a matrix too large for its indices, invalid input
};

inline std::string_view step_status_name(StepStatus s) {
  switch (s) {
    case StepStatus::ok: return "ok";
    case StepStatus::max_iterations: return "max_iterations";
    case StepStatus::line_search_failed: return "line_search_failed";
    case StepStatus::factorization_failed: return "factorization_failed";
    case StepStatus::non_finite: return "non_finite";
    case StepStatus::boundary_collision: return "boundary_collision";
    case StepStatus::linear_solver_failed: return "linear_solver_failed";
  }
  return "?";
}

}  // namespace nexdyn

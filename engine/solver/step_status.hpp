// How a step ended. The solver never throws: it returns one of these and the driver decides.
#pragma once

#include <string_view>

namespace nexdyn {

enum class StepStatus {
  ok,
  max_iterations,         // Newton increment still above the tolerance
  line_search_failed,     // no step length decreased the energy
  factorization_failed,   // CHOLMOD refused the matrix (not positive definite)
  non_finite,             // NaN/inf in the energy or gradient, or an inverted start
  boundary_collision,     // a moving boundary or obstacle cannot reach its prescribed position
};

inline std::string_view step_status_name(StepStatus s) {
  switch (s) {
    case StepStatus::ok: return "ok";
    case StepStatus::max_iterations: return "max_iterations";
    case StepStatus::line_search_failed: return "line_search_failed";
    case StepStatus::factorization_failed: return "factorization_failed";
    case StepStatus::non_finite: return "non_finite";
    case StepStatus::boundary_collision: return "boundary_collision";
  }
  return "?";
}

}  // namespace nexdyn

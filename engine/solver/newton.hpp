// Projected Newton on the incremental potential with a CCD-capped backtracking (Armijo) line
// search (DESIGN.md section 5).
//
// Per iteration: gradient and PSD-projected Hessian (parallel, deterministic), Dirichlet DOFs
// eliminated (their rows and columns become identity, their gradient zero), CHOLMOD numeric
// factorisation (the symbolic analysis is redone only when contact changed the pattern),
// direction p = -H^-1 g. Converged when the increment in velocity units, max|p| / dt, is below
// the tolerance. Otherwise the step length starts at the largest collision-free fraction of p
// (continuous collision detection) and halves until the energy decreases enough; with contact
// every trial point is intersection-free and its barrier is evaluated over the pairs close to the
// whole segment. A failure is returned as a StepStatus with a sentence saying why; the solver
// never accepts a step it could not finish.
#pragma once

#include "engine/incremental_potential.hpp"
#include "engine/model.hpp"
#include "engine/solver/cholmod_solver.hpp"
#include "engine/solver/step_status.hpp"
#include "engine/step_profile.hpp"

#include <string>
#include <vector>

namespace nexdyn {

struct NewtonSettings {
  double tolerance = 1e-5;  // [m/s] on max|p| / dt
  int max_iterations = 100;
  double dt = 0.01;         // [s] turns the increment into a velocity
};

struct NewtonResult {
  StepStatus status = StepStatus::ok;
  int iterations = 0;        // linear solves
  int analyses = 0;          // symbolic factorisations (pattern changes)
  double increment = 0.0;    // last max|p| / dt [m/s]
  double energy = 0.0;       // E at the returned x
  std::string message;       // why it failed; empty when ok
};

class NewtonSolver {
 public:
  NewtonSolver(const Model& model, IncrementalPotential& potential);

  // Minimises the potential starting from x (Dirichlet DOFs already at their targets).
  // On success x is the minimiser; on failure x is the last accepted iterate.
  NewtonResult solve(std::vector<double>& x, const NewtonSettings& settings);

  // Times the linear solves and line searches into `profile` (may be null: no timing).
  void set_profile(StepProfile* profile) { profile_ = profile; }

  // Holds these vertices where they are in the coming solves (held = true), or releases them
  // again; for kinematic vertices once they are on their targets (engine/kinematic_targets.hpp).
  void hold(const std::vector<int32_t>& vertices, bool held);

 private:
  void eliminate_dirichlet(double* grad, double* values) const;
  // (Re)does the symbolic analysis and the Dirichlet bookkeeping for the potential's pattern.
  void analyze_pattern();
  // The value indices of constrained rows and columns, from constrained_dof_.
  void collect_constrained_values();

  const Model& model_;
  IncrementalPotential& potential_;
  CholmodSolver cholmod_;
  StepProfile* profile_ = nullptr;
  int64_t analyzed_version_ = -1;
  std::vector<uint8_t> constrained_dof_;      // (3n) 1 where a Dirichlet condition holds
  std::vector<int64_t> constrained_values_;   // value indices in a constrained row or column
  std::vector<double> grad_, direction_, values_, trial_;
};

}  // namespace nexdyn

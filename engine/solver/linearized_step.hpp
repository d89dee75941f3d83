// The linearised implicit step ("solver.method": "linearized"; seed 004, after Baraff and
// Witkin 1998 and VegaFEM): one linear solve per step instead of Newton's iterations.
//
// The step minimises the quadratic model of the incremental potential E at the start point x0
// (x_n, the held vertices at their targets):
//   H d = -grad E(x0),   x_{n+1} = x0 + d,   H = M + s K(x0) + s k D,
// with K the PSD-projected elastic stiffness and k D the Rayleigh damping's Hessian
// (engine/terms/damping_term.hpp). Under implicit Euler (s = h^2, s k = h) and with the velocity
// as unknown, this is seed 004's [M + h D + h^2 K] dv = h [f - (h K + D) v]; the other schemes
// of the family take their own s and k. Nothing bounds the step: no line search, no CCD, so
// contact and joints are refused (engine/scene/scene.cpp), and a step that inverts a tet fails
// and is retried at half the interval like any failed step.
//
// H is solved by CHOLMOD (the Newton pattern, analysed once) or, with "solver.linear": "pcg", by
// conjugate gradients with a Jacobi preconditioner on products H w computed tet by tet
// (engine/sparse/tet_slab_operator.hpp), without assembling K. CG stops when the preconditioned
// residual, an estimate of the error left in d, is below kCgToleranceRatio of the Newton
// tolerance (velocity-scaled, m/s), so both paths agree to well within that tolerance.
#pragma once

#include "engine/potential/incremental_potential.hpp"
#include "engine/model.hpp"
#include "engine/solver/linear_solver_kind.hpp"
#include "engine/sparse/cholmod_solver.hpp"
#include "engine/step_result.hpp"
#include "engine/sparse/tet_slab_operator.hpp"
#include "engine/step_context.hpp"
#include "engine/terms/damping_term.hpp"

#include <memory>
#include <string>
#include <vector>

namespace nexdyn {

// Entries per chunk of the step's vector sums and updates (a system needs more DOFs than this for
// them to run on several threads).
inline constexpr int64_t kLinearizedGrain = 4096;

struct LinearizedResult {
  StepStatus status = StepStatus::ok;
  std::string message;     // why, when not ok
  int cg_iterations = 0;   // conjugate-gradient iterations (0 with CHOLMOD)
  double residual = 0.0;   // CG: the last max |P^-1 r| / dt [m/s]
};

class LinearizedStep {
 public:
  static constexpr double kCgToleranceRatio = 1e-3;

  // tolerance: solver.tolerance [m/s]; max_cg_iterations: CG's cap.
  LinearizedStep(const Model& model, LinearSolverKind kind, double tolerance, int max_cg_iterations);

  // x: in, the start point x0 (held vertices at their targets); out, x0 + d. The potential must
  // have begun the step (begin_step); damping is its damping term or null.
  LinearizedResult solve(IncrementalPotential& potential, const StepContext& ctx, const DampingTerm* damping,
                         std::vector<double>& x);

 private:
  LinearizedResult solve_cholmod(IncrementalPotential& potential, std::vector<double>& x);
  LinearizedResult solve_pcg(const StepContext& ctx, const DampingTerm* damping, std::vector<double>& x);
  void apply(const double* w, double* out) const;  // out = H w on the free DOFs (0 on held ones)

  const Model& model_;
  LinearSolverKind kind_;
  double tolerance_;
  int max_cg_iterations_;
  std::vector<uint8_t> held_;         // (3n) 1 on the DOFs of eliminated vertices
  std::vector<double> grad_, values_;  // gradient (3n), Hessian values (pattern order)
  std::vector<double> d_;              // (3n) the step
  std::unique_ptr<CholmodSolver> cholmod_;
  // Matrix-free H = diag + sum_t S_t.
  std::unique_ptr<TetSlabOperator> stiffness_;
  std::vector<double> tet_scale_, diag_, inverse_diag_;
  std::vector<double> r_, z_, p_, hp_;  // CG vectors (3n)
};

}  // namespace nexdyn

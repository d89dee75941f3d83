// Sparse Cholesky of the Newton system with CHOLMOD (supernodal or simplicial, int64 indices).
//
// The symbolic analysis (fill-reducing ordering, elimination tree, supernodes) depends only on the
// pattern, so it runs once per pattern and every Newton iteration after that pays only for the
// numeric factorisation. The matrix is the upper triangle in CSC form (stype = +1) whose arrays
// stay owned by the caller; this class only points CHOLMOD at them.
//
// Nothing here throws. CHOLMOD reports trouble in its status code (its memory comes from malloc,
// which returns null rather than throwing), and every call that can fail returns a StepStatus:
// factorization_failed when the matrix is not positive definite, linear_solver_failed when CHOLMOD
// could not do the work at all (out of memory, a problem too large for its integers or the
// BLAS's, invalid input); error() then says which call failed and why, in CHOLMOD's words.
#pragma once

#include "engine/step_result.hpp"

#include <cstdint>
#include <string>
#include <vector>

struct cholmod_common_struct;
struct cholmod_factor_struct;
struct cholmod_dense_struct;

namespace nexdyn {

class CholmodSolver {
 public:
  // Supernodal factors run dense kernels on supernodes (cholmod_runtime.hpp): the fastest choice
  // for large matrices. Simplicial ones (no dense kernels) win on the smallest (island_system.hpp).
  explicit CholmodSolver(bool supernodal = true);
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  // Symbolic analysis of the upper-triangular CSC pattern. Keeps pointers to the arrays.
  // ok, or linear_solver_failed (no analysis is kept then).
  StepStatus analyze(int64_t n, const int64_t* col_ptr, const int64_t* row_idx);
  bool has_analysis() const { return factor_ != nullptr; }

  // Numeric factorisation with the given values (same pattern as analyze): ok,
  // factorization_failed (not positive definite) or linear_solver_failed (no analysis to factorise
  // with, or CHOLMOD failed). Throws StepStopped (engine/stop_request.hpp) when a stop request
  // came during it: it may then have ended early, leaving no usable factor.
  StepStatus factorize(const double* values);

  // Solves A x = b with the last factorisation: ok, or linear_solver_failed (x is then left
  // alone). No allocation after the first successful call.
  StepStatus solve(const double* b, double* x);
  // Frees a supernodal factor's values, keeping the analysis: the next factorize() allocates
  // them again. For systems that sit idle (their values are recomputed on every use anyway).
  void release_numeric();

  // Why the last failed call failed; kept until the next failure.
  const std::string& error() const { return error_; }

  // Whether CHOLMOD's dense kernels may run on several threads at once: true when they are the
  // engine's own (cholmod_runtime.hpp), which take no lock and share no buffer; false if some
  // other BLAS got CHOLMOD's calls (the serial OpenBLAS, for one, must not be called concurrently).
  static bool blas_is_thread_safe();
  // Non-zeros of the Cholesky factor and flops of one factorisation, from the last analysis.
  double factor_nonzeros() const;
  double factor_flops() const;
  // Memory of the numeric factor [bytes]: its values and, when supernodal, its row indices.
  double factor_bytes() const;
  // Name of the fill-reducing ordering chosen by the last analysis.
  std::string ordering_name() const;

 private:
  // Records "<what> failed: <CHOLMOD's status in words>" in error_; returns linear_solver_failed.
  StepStatus cholmod_failure(const std::string& what);

  cholmod_common_struct* common_ = nullptr;
  cholmod_factor_struct* factor_ = nullptr;
  cholmod_dense_struct* x_ = nullptr;   // solve2 workspaces, reused across solves
  cholmod_dense_struct* y_ = nullptr;
  cholmod_dense_struct* e_ = nullptr;
  int64_t n_ = 0;
  const int64_t* col_ptr_ = nullptr;
  const int64_t* row_idx_ = nullptr;
  std::string error_;
};

}  // namespace nexdyn

// CHOLMOD wrapper (see cholmod_solver.hpp).
#include "engine/sparse/cholmod_solver.hpp"

#include "engine/sparse/cholmod_runtime.hpp"
#include "engine/stop_request.hpp"

#include <cholmod.h>

#include <cstring>
#include <string>

namespace nexdyn {

namespace {
// A cholmod_sparse header over the caller's arrays (CHOLMOD never frees them: we never call
// cholmod_free_sparse on it).
cholmod_sparse wrap(int64_t n, const int64_t* col_ptr, const int64_t* row_idx, const double* values) {
  cholmod_sparse a;
  std::memset(&a, 0, sizeof(a));
  a.nrow = static_cast<size_t>(n);
  a.ncol = static_cast<size_t>(n);
  a.nzmax = static_cast<size_t>(col_ptr[n]);
  a.p = const_cast<int64_t*>(col_ptr);
  a.i = const_cast<int64_t*>(row_idx);
  a.x = const_cast<double*>(values);
  a.stype = 1;  // symmetric, upper triangle stored
  a.itype = CHOLMOD_LONG;
  a.xtype = values ? CHOLMOD_REAL : CHOLMOD_PATTERN;
  a.dtype = CHOLMOD_DOUBLE;
  a.sorted = 1;
  a.packed = 1;
  return a;
}

// CHOLMOD's failure codes in words, the code's name last so that it can be looked up.
std::string status_text(int status) {
  switch (status) {
    case CHOLMOD_OUT_OF_MEMORY: return "out of memory (CHOLMOD_OUT_OF_MEMORY)";
    case CHOLMOD_TOO_LARGE:
      return "the problem is too large for CHOLMOD's integers or the BLAS's (CHOLMOD_TOO_LARGE)";
    case CHOLMOD_INVALID: return "invalid input (CHOLMOD_INVALID)";
    case CHOLMOD_NOT_INSTALLED: return "a method this build of CHOLMOD lacks (CHOLMOD_NOT_INSTALLED)";
    case CHOLMOD_GPU_PROBLEM: return "a GPU error (CHOLMOD_GPU_PROBLEM)";
    default: return "CHOLMOD status " + std::to_string(status);
  }
}
}  // namespace

bool CholmodSolver::blas_is_thread_safe() { return set_up_cholmod_runtime(); }


CholmodSolver::CholmodSolver(bool supernodal) {
  set_up_cholmod_runtime();  // before CHOLMOD allocates anything
  common_ = new cholmod_common;
  cholmod_l_start(common_);
  common_->supernodal = supernodal ? CHOLMOD_SUPERNODAL : CHOLMOD_SIMPLICIAL;
  // A simplicial LDL^T would accept an indefinite matrix; LL^T stops at the first bad pivot.
  common_->final_ll = 1;
  common_->print = 0;
  common_->error_handler = nullptr;
  // Keep going after a not-positive-definite pivot is found so that we can report it ourselves.
  common_->quick_return_if_not_posdef = 1;
}

CholmodSolver::~CholmodSolver() {
  if (factor_) cholmod_l_free_factor(&factor_, common_);
  if (x_) cholmod_l_free_dense(&x_, common_);
  if (y_) cholmod_l_free_dense(&y_, common_);
  if (e_) cholmod_l_free_dense(&e_, common_);
  cholmod_l_finish(common_);
  delete common_;
}

StepStatus CholmodSolver::cholmod_failure(const std::string& what) {
  error_ = what + " failed: " + status_text(common_->status);
  return StepStatus::linear_solver_failed;
}

StepStatus CholmodSolver::analyze(int64_t n, const int64_t* col_ptr, const int64_t* row_idx) {
  if (factor_) cholmod_l_free_factor(&factor_, common_);
  n_ = n;
  col_ptr_ = col_ptr;
  row_idx_ = row_idx;
  cholmod_sparse a = wrap(n, col_ptr, row_idx, nullptr);
  factor_ = cholmod_l_analyze(&a, common_);
  if (!factor_)
    return cholmod_failure("CHOLMOD symbolic analysis of a " + std::to_string(n) + " x " + std::to_string(n) +
                           " matrix with " + std::to_string(col_ptr[n]) + " stored entries");
  return StepStatus::ok;
}

double CholmodSolver::factor_nonzeros() const { return common_->lnz; }
double CholmodSolver::factor_flops() const { return common_->fl; }

void CholmodSolver::release_numeric() {
  if (!factor_ || !factor_->is_super || factor_->xtype == CHOLMOD_PATTERN) return;
  // Supernodal numeric to supernodal symbolic: CHOLMOD frees the values and keeps the rest.
  cholmod_l_change_factor(CHOLMOD_PATTERN, /*to_ll=*/1, /*to_super=*/1, /*to_packed=*/1,
                          /*to_monotonic=*/1, factor_, common_);
}

double CholmodSolver::factor_bytes() const {
  if (!factor_) return 0.0;
  if (factor_->is_super && factor_->xtype == CHOLMOD_PATTERN) return 8.0 * double(factor_->ssize);
  if (factor_->is_super) return 8.0 * (double(factor_->xsize) + double(factor_->ssize));
  return 16.0 * double(factor_->nzmax);  // simplicial: a value and a row index per entry
}

std::string CholmodSolver::ordering_name() const {
  if (!factor_) return "none";
  switch (factor_->ordering) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_AMD: return "AMD";
    case CHOLMOD_METIS: return "METIS";
    case CHOLMOD_NESDIS: return "NESDIS";
    case CHOLMOD_COLAMD: return "COLAMD";
    default: return "other";
  }
}

StepStatus CholmodSolver::factorize(const double* values) {
  if (!factor_) {
    error_ = "CHOLMOD numeric factorisation asked for without a symbolic analysis (the last one failed)";
    return StepStatus::linear_solver_failed;
  }
  cholmod_sparse a = wrap(n_, col_ptr_, row_idx_, values);
  const int ok = cholmod_l_factorize(&a, factor_, common_);
  stop_point();  // a stop request cut the factorisation short (cholmod_runtime.cpp's dpotrf_)
  if (common_->status == CHOLMOD_NOT_POSDEF) {
    error_ = "matrix not positive definite at column " + std::to_string(factor_->minor);
    return StepStatus::factorization_failed;
  }
  if (!ok) return cholmod_failure("CHOLMOD numeric factorisation of a " + std::to_string(n_) + " x " +
                                  std::to_string(n_) + " matrix");
  return StepStatus::ok;
}

StepStatus CholmodSolver::solve(const double* b, double* x) {
  cholmod_dense rhs;
  std::memset(&rhs, 0, sizeof(rhs));
  rhs.nrow = static_cast<size_t>(n_);
  rhs.ncol = 1;
  rhs.nzmax = static_cast<size_t>(n_);
  rhs.d = static_cast<size_t>(n_);
  rhs.x = const_cast<double*>(b);
  rhs.xtype = CHOLMOD_REAL;
  rhs.dtype = CHOLMOD_DOUBLE;
  // Fails when the first call cannot allocate the workspaces, or without a numeric factor.
  if (!cholmod_l_solve2(CHOLMOD_A, factor_, &rhs, nullptr, &x_, nullptr, &y_, &e_, common_))
    return cholmod_failure("CHOLMOD solve with the factor of a " + std::to_string(n_) + " x " +
                           std::to_string(n_) + " matrix");
  std::memcpy(x, x_->x, sizeof(double) * static_cast<size_t>(n_));
  return StepStatus::ok;
}

}  // namespace nexdyn

// One island's linear system: its rows and columns of the Newton matrix, factorised on their own.
//
// The global matrix is assembled as before (one pattern, one gather); an island copies its values
// out through a table built once per global pattern, so islands cost nothing to assemble and
// keep their symbolic analysis for as long as their own block of the pattern is unchanged (a
// body falling alone keeps its analysis for the whole run).
//
// Small islands are factorised dense (a 27-vertex box is an 81 x 81 matrix: a dense Cholesky is
// faster than any sparse bookkeeping). Larger ones go to CHOLMOD: simplicial up to a size where
// supernodes pay off, supernodal beyond (a torus of 600 DOFs already factorises 1.7x faster).
// Supernodal CHOLMOD runs dense kernels per supernode; they are the engine's own
// (cholmod_runtime.hpp), which take no lock, so all islands run in parallel. Were they some
// other BLAS's, which may keep unlocked global buffers (the serial OpenBLAS does), supernodal
// islands must never be factorised or solved at the same time as each other (must_run_alone();
// newton.cpp runs them one after the other). Each island's numbers are the same either way.
//
// Nothing here throws: a block that is not positive definite, a CHOLMOD failure, a pattern over
// the 32-bit value tables or memory running out while building them all come back as a
// StepStatus from factorize() or solve(), with error() saying why (step_status.hpp).
#pragma once

#include "engine/sparse/cholmod_solver.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace nexdyn {

class IslandSystem {
 public:
  // Islands up to this many DOFs are dense; up to kSimplicialDofs simplicial CHOLMOD. From
  // bench/bench_islands (one thread): an 81-DOF box takes 22 us dense, 23 simplicial, 25
  // supernodal; a 375-DOF box 744 dense, 526 simplicial, 226 supernodal; a 2,187-DOF box 37 ms
  // simplicial against 4.8 supernodal. Simplicial islands run in parallel and supernodal ones
  // one at a time, so simplicial keeps the sizes where it is close.
  static constexpr int64_t kDenseDofs = 96;
  static constexpr int64_t kSimplicialDofs = 240;

  // vertices: the island's, increasing.
  explicit IslandSystem(std::vector<int32_t> vertices);

  const std::vector<int32_t>& vertices() const { return vertices_; }
  int64_t num_dofs() const { return 3 * static_cast<int64_t>(vertices_.size()); }
  // Supernodal CHOLMOD over a BLAS that must not be called from two threads at once.
  bool must_run_alone() const {
    return cholmod_ && num_dofs() > kSimplicialDofs && !CholmodSolver::blas_is_thread_safe();
  }

  // Builds the value table for the global pattern of this version; local_index[v] is v's place
  // in the island's vertex list and island_of[v] its island (this one is `island`). Redoes the
  // symbolic analysis only when the island's block of the pattern changed; returns true then.
  // When that fails, the failure is kept and the next factorize() returns it; the next call,
  // of any version, tries again.
  bool update_pattern(const CscPattern& global, int64_t version, const int32_t* island_of,
                      const int32_t* local_index, int32_t island);

  // Factorises the island's block of the global values: ok, factorization_failed (not positive
  // definite) or linear_solver_failed (the pattern or CHOLMOD failed); error() says why.
  StepStatus factorize(const double* global_values);
  // out = H^-1 rhs on the island's DOFs (other entries of out are left alone): ok, or
  // linear_solver_failed (out untouched).
  StepStatus solve(const double* global_rhs, double* global_out);
  const std::string& error() const { return error_; }
  // Frees the factor of a supernodal island, keeping its analysis (CholmodSolver::release_numeric).
  void release_numeric() {
    if (cholmod_) cholmod_->release_numeric();
  }
  // Memory of the factor [bytes] (a dense island keeps an n x n matrix).
  double factor_bytes() const {
    return cholmod_ ? cholmod_->factor_bytes() : 8.0 * static_cast<double>(dense_.size());
  }

  int64_t last_used = 0;        // solve counter of the last use (newton.cpp evicts stale islands)
  int64_t last_iteration = 0;   // Newton iteration counter (over all solves) of the last use

 private:
  // The body of update_pattern; may throw std::bad_alloc, which update_pattern turns into a status.
  bool build_tables(const CscPattern& global, const int32_t* island_of, const int32_t* local_index,
                    int32_t island);

  std::vector<int32_t> vertices_;
  int64_t pattern_version_ = -1;
  StepStatus pattern_status_ = StepStatus::ok;  // of the last update_pattern; error_ says why
  // The island's upper triangle in local DOFs: each entry's index into the global values and
  // (sparse islands) CSC arrays and values for CHOLMOD, or (dense islands) its place in dense_,
  // row + n col: a dense island needs no CSC copy at all.
  std::vector<uint32_t> value_source_;      // (local nnz)
  std::vector<int64_t> col_ptr_, row_idx_;  // sparse
  std::vector<double> values_;              // sparse
  std::vector<uint16_t> dense_slot_;        // dense
  std::vector<double> rhs_, out_;
  Eigen::MatrixXd dense_;  // dense islands: the matrix, then its factor U (A = U^T U) in place
  std::unique_ptr<CholmodSolver> cholmod_;
  std::string error_;
};

}  // namespace nexdyn

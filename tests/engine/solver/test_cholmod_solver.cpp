// The CHOLMOD wrapper (engine/sparse/cholmod_solver.hpp) on a small tridiagonal system, simplicial
// and supernodal: a singular and an indefinite matrix are refused with factorization_failed and
// a sentence, CHOLMOD running out of memory in each of its three calls comes back as
// linear_solver_failed naming the call and CHOLMOD's status, nothing throws, and the same solver
// works again once the matrix or the memory is back.
#include "engine/sparse/cholmod_solver.hpp"
#include "engine/stop_request.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "tests/engine/solver/suitesparse_out_of_memory.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Dense>

#include <cmath>
#include <csignal>
#include <limits>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

// The upper triangle of an n x n tridiagonal matrix, with its values: 4 on the diagonal, -1 next
// to it (positive definite: diagonally dominant).
struct Tridiagonal {
  static constexpr int64_t n = 6;
  CscPattern pattern;
  std::vector<double> values;
  std::vector<double> rhs;

  Tridiagonal() {
    pattern.num_dofs = n;
    pattern.col_ptr.push_back(0);
    for (int64_t c = 0; c < n; ++c) {
      if (c > 0) {
        pattern.row_idx.push_back(c - 1);
        values.push_back(-1.0);
      }
      pattern.diagonal.push_back(static_cast<int64_t>(pattern.row_idx.size()));
      pattern.row_idx.push_back(c);
      values.push_back(4.0);
      pattern.col_ptr.push_back(static_cast<int64_t>(pattern.row_idx.size()));
      rhs.push_back(1.0 + 0.5 * static_cast<double>(c));
    }
  }
  // The value index of entry (row, col), row <= col.
  int64_t at(int64_t row, int64_t col) const {
    for (int64_t k = pattern.col_ptr[col]; k < pattern.col_ptr[col + 1]; ++k)
      if (pattern.row_idx[k] == row) return k;
    FAIL("no stored entry (" << row << ", " << col << ")");
    return -1;
  }
  StepStatus analyze(CholmodSolver& solver) const {
    return solver.analyze(n, pattern.col_ptr.data(), pattern.row_idx.data());
  }
  // |A x - b| / |b| for these values.
  double residual(const std::vector<double>& x) const {
    const Eigen::MatrixXd a = test::dense_from(pattern, values);
    const Eigen::Map<const Eigen::VectorXd> xv(x.data(), n), b(rhs.data(), n);
    return (a * xv - b).norm() / b.norm();
  }
};

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// Factorises the good values and solves: the answer to round-off.
void check_solves(CholmodSolver& solver, const Tridiagonal& t) {
  REQUIRE(solver.factorize(t.values.data()) == StepStatus::ok);
  std::vector<double> x(Tridiagonal::n, std::numeric_limits<double>::quiet_NaN());
  REQUIRE(solver.solve(t.rhs.data(), x.data()) == StepStatus::ok);
  CHECK(t.residual(x) <= 1e-14);
}

}  // namespace

TEST_CASE("cholmod solver: a singular or an indefinite matrix is factorization_failed with its column, and good values factorise again") {
  for (const bool supernodal : {false, true}) {
    CAPTURE(supernodal);
    const Tridiagonal t;
    CholmodSolver solver(supernodal);
    REQUIRE(t.analyze(solver) == StepStatus::ok);
    check_solves(solver, t);

    // Singular: rows 0 and 1 equal ([1 1; 1 1], uncoupled from the rest), whatever the ordering a
    // pivot of exactly 1 - 1 = 0.
    std::vector<double> singular = t.values;
    singular[t.at(0, 0)] = singular[t.at(1, 1)] = singular[t.at(0, 1)] = 1.0;
    singular[t.at(1, 2)] = 0.0;
    CHECK(test::dense_from(t.pattern, singular).fullPivLu().rank() == Tridiagonal::n - 1);  // the premise
    CHECK(solver.factorize(singular.data()) == StepStatus::factorization_failed);
    CHECK(contains(solver.error(), "matrix not positive definite at column "));
    check_solves(solver, t);

    // Indefinite: one negative diagonal entry (an LDL^T would take it; LL^T must not).
    std::vector<double> indefinite = t.values;
    indefinite[t.at(3, 3)] = -4.0;
    solver.release_numeric();  // also from a supernodal factor without values
    CHECK(solver.factorize(indefinite.data()) == StepStatus::factorization_failed);
    CHECK(contains(solver.error(), "matrix not positive definite at column "));
    check_solves(solver, t);
  }
}

TEST_CASE("cholmod solver: out of memory in the analysis, the factorisation or the first solve is linear_solver_failed with CHOLMOD's status") {
  for (const bool supernodal : {false, true}) {
    CAPTURE(supernodal);
    const Tridiagonal t;

    // Never analysed: refused, not a crash.
    CholmodSolver fresh(supernodal);
    CHECK(fresh.factorize(t.values.data()) == StepStatus::linear_solver_failed);
    CHECK(contains(fresh.error(), "without a symbolic analysis"));

    // The analysis.
    CholmodSolver solver(supernodal);
    {
      test::SuiteSparseOutOfMemory no_memory;
      CHECK(t.analyze(solver) == StepStatus::linear_solver_failed);
    }
    CHECK(solver.error() == "CHOLMOD symbolic analysis of a 6 x 6 matrix with 11 stored entries failed: "
                            "out of memory (CHOLMOD_OUT_OF_MEMORY)");
    CHECK_FALSE(solver.has_analysis());
    CHECK(solver.factorize(t.values.data()) == StepStatus::linear_solver_failed);
    CHECK(contains(solver.error(), "without a symbolic analysis"));
    REQUIRE(t.analyze(solver) == StepStatus::ok);
    check_solves(solver, t);

    // The numeric factorisation, from a factor without values.
    CholmodSolver second(supernodal);
    REQUIRE(t.analyze(second) == StepStatus::ok);
    {
      test::SuiteSparseOutOfMemory no_memory;
      CHECK(second.factorize(t.values.data()) == StepStatus::linear_solver_failed);
    }
    CHECK(second.error() == "CHOLMOD numeric factorisation of a 6 x 6 matrix failed: out of memory (CHOLMOD_OUT_OF_MEMORY)");
    CHECK(second.has_analysis());
    check_solves(second, t);

    // The first solve (it allocates the workspaces the later ones reuse); x is left alone.
    CholmodSolver third(supernodal);
    REQUIRE(t.analyze(third) == StepStatus::ok);
    REQUIRE(third.factorize(t.values.data()) == StepStatus::ok);
    std::vector<double> x(Tridiagonal::n, -7.0);
    {
      test::SuiteSparseOutOfMemory no_memory;
      CHECK(third.solve(t.rhs.data(), x.data()) == StepStatus::linear_solver_failed);
    }
    CHECK(third.error() == "CHOLMOD solve with the factor of a 6 x 6 matrix failed: out of memory (CHOLMOD_OUT_OF_MEMORY)");
    CHECK(x == std::vector<double>(Tridiagonal::n, -7.0));
    REQUIRE(third.solve(t.rhs.data(), x.data()) == StepStatus::ok);
    CHECK(t.residual(x) <= 1e-14);
  }
}

TEST_CASE("cholmod solver: a stop request during a factorisation throws the stop, and the next one factorises") {
  for (const bool supernodal : {false, true}) {
    CAPTURE(supernodal);
    const Tridiagonal t;
    CholmodSolver solver(supernodal);
    REQUIRE(t.analyze(solver) == StepStatus::ok);
    request_stop(SIGTERM);
    CHECK_THROWS_AS(solver.factorize(t.values.data()), StepStopped);
    clear_stop_request();
    check_solves(solver, t);
  }
}

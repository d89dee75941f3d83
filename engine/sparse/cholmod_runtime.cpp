// The engine's OpenMP, BLAS and LAPACK entry points for CHOLMOD (see cholmod_runtime.hpp).
//
// The BLAS routines follow the reference BLAS's contracts for every argument CHOLMOD or any other
// caller may pass (both triangles, both sides, transposes, unit diagonals, any vector stride),
// including the ones callers rely on without thinking: beta = 0 sets C without reading it (C may
// hold NaN), alpha = 0 reads neither A nor B. Matrices are column-major with leading dimensions,
// as in Fortran; integers are 32-bit, as in Debian's BLAS and CHOLMOD. Arguments are trusted (the
// reference BLAS would report a bad one through xerbla; CHOLMOD passes none).
#include "engine/sparse/cholmod_runtime.hpp"

#include "engine/stop_request.hpp"

#include <SuiteSparse_config.h>
#include <dlfcn.h>
#include <malloc.h>
#include <sys/mman.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <vector>

namespace {

using Matrix = Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
using ConstMatrix = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;

bool is(const char* flag, char upper_case) { return *flag == upper_case || *flag == upper_case + ('a' - 'A'); }
bool transposed(const char* trans) { return is(trans, 'T') || is(trans, 'C'); }  // real: C is T

// C := beta C over the whole matrix or one triangle, without reading C when beta is 0.
template <typename View>
void scale(View c, double beta) {
  if (beta == 0.0) c.setZero();
  else if (beta != 1.0) c *= beta;
}

// A vector of n elements spaced inc apart; a negative inc runs from the far end (BLAS's rule).
// Unit strides are used in place, others through a contiguous copy written back by store().
class StridedVector {
 public:
  StridedVector(double* x, int n, int inc) : x_(x), n_(n), inc_(inc) {
    if (inc_ == 1) return;
    copy_.resize(static_cast<size_t>(n_));
    for (int i = 0; i < n_; ++i) copy_[i] = x_[offset(i)];
  }
  Eigen::Map<Eigen::VectorXd> map() { return {inc_ == 1 ? x_ : copy_.data(), n_}; }
  void store() {
    if (inc_ != 1)
      for (int i = 0; i < n_; ++i) x_[offset(i)] = copy_[i];
  }

 private:
  std::ptrdiff_t offset(int i) const {
    return inc_ > 0 ? std::ptrdiff_t{i} * inc_ : std::ptrdiff_t{n_ - 1 - i} * -std::ptrdiff_t{inc_};
  }
  double* x_;
  int n_, inc_;
  std::vector<double> copy_;
};

// Solves op(A) X = B (on the left) or X op(A) = B (on the right) in place, A triangular.
template <int Side, typename Rhs>
void triangular_solve(const ConstMatrix& a, bool lower, bool trans, bool unit_diagonal, Rhs&& b) {
  // op(A) is lower triangular when A is lower and not transposed, or upper and transposed.
  const bool op_lower = lower != trans;
  auto solve = [&](const auto& op_a) {
    if (op_lower && unit_diagonal) op_a.template triangularView<Eigen::UnitLower>().template solveInPlace<Side>(b);
    else if (op_lower) op_a.template triangularView<Eigen::Lower>().template solveInPlace<Side>(b);
    else if (unit_diagonal) op_a.template triangularView<Eigen::UnitUpper>().template solveInPlace<Side>(b);
    else op_a.template triangularView<Eigen::Upper>().template solveInPlace<Side>(b);
  };
  if (trans) solve(a.transpose());
  else solve(a);
}

// CHOLMOD's memory, every block starting on a 64-byte boundary. Eigen's vector kernels take the
// first elements of a column one at a time until an aligned address, so where a sum starts its
// packets depends on the address modulo 64. glibc's malloc aligns to 16 bytes only, and which
// block it hands out depends on its thread's arena: two runs on different thread counts gave
// different factors. With every CHOLMOD array aligned, the addresses CHOLMOD passes to the BLAS
// are fixed offsets into them, which depend on the matrix's structure alone.
constexpr size_t kAlignment = 64;

// Big blocks (a supernodal factor's values: the folding 100x100 mat's are 90 to 150 MB, and each
// new symbolic analysis allocates them afresh) start on a 2 MB boundary and are marked for
// transparent huge pages. The kernel then faults them in 2 MB at a time instead of 4 KB: on the
// mat, 1.5 M page faults became 0.1 M and the folding steps' factorisation took half the time
// (docs/performance.md, issue 19's fourth round). Where huge pages are off (or madvise fails),
// the block is an ordinary aligned one; its contents do not depend on it either way.
constexpr size_t kHugePage = size_t{2} << 20;
constexpr size_t kHugeMinBytes = size_t{8} << 20;

void* aligned_malloc(size_t size) {
  void* p = nullptr;
  if (size >= kHugeMinBytes) {
    if (posix_memalign(&p, kHugePage, size) != 0) return nullptr;
    madvise(p, size & ~(kHugePage - 1), MADV_HUGEPAGE);  // whole huge pages only; a hint
    return p;
  }
  return posix_memalign(&p, kAlignment, std::max<size_t>(size, 1)) == 0 ? p : nullptr;
}

void* aligned_calloc(size_t count, size_t size) {
  if (size != 0 && count > SIZE_MAX / size) return nullptr;
  void* p = aligned_malloc(count * size);
  if (p) std::memset(p, 0, count * size);
  return p;
}

// realloc's contract: the first min(old, new) bytes kept; on failure null, and p left as it was.
void* aligned_realloc(void* p, size_t size) {
  if (!p) return aligned_malloc(size);
  void* q = aligned_malloc(size);
  if (!q) return nullptr;
  std::memcpy(q, p, std::min(size, malloc_usable_size(p)));
  std::free(p);
  return q;
}

}  // namespace

extern "C" {

// OpenMP: the region's body once, on the calling thread. That is what a region of one thread
// does: outside any region omp_get_num_threads() is 1 and omp_get_thread_num() 0, so the body's
// loop covers its whole range. CHOLMOD (SuiteSparse 5) opens such a region around small loops of
// every supernode; libgomp's would end in a barrier released by a futex_wake system call (a fifth
// of pile_100's CPU samples), and never starts threads that would spin against TBB's.
void GOMP_parallel(void (*body)(void*), void* data, unsigned /*num_threads*/, unsigned /*flags*/) { body(data); }

// C := alpha op(A) op(B) + beta C, C m x n.
void dgemm_(const char* trans_a, const char* trans_b, const int* m, const int* n, const int* k, const double* alpha,
            const double* a, const int* lda, const double* b, const int* ldb, const double* beta, double* c,
            const int* ldc) {
  if (*m <= 0 || *n <= 0) return;
  Matrix c_(c, *m, *n, Eigen::OuterStride<>(*ldc));
  scale(c_, *beta);
  if (*k <= 0 || *alpha == 0.0) return;
  const bool ta = transposed(trans_a), tb = transposed(trans_b);
  const ConstMatrix a_(a, ta ? *k : *m, ta ? *m : *k, Eigen::OuterStride<>(*lda));
  const ConstMatrix b_(b, tb ? *n : *k, tb ? *k : *n, Eigen::OuterStride<>(*ldb));
  if (!ta && !tb) c_.noalias() += *alpha * a_ * b_;
  else if (!ta) c_.noalias() += *alpha * a_ * b_.transpose();
  else if (!tb) c_.noalias() += *alpha * a_.transpose() * b_;
  else c_.noalias() += *alpha * a_.transpose() * b_.transpose();
}

// One triangle of C := alpha A A^T + beta C (A n x k), or of alpha A^T A + beta C (A k x n).
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha, const double* a,
            const int* lda, const double* beta, double* c, const int* ldc) {
  if (*n <= 0) return;
  Matrix c_(c, *n, *n, Eigen::OuterStride<>(*ldc));
  const bool lower = is(uplo, 'L');
  if (lower) scale(c_.triangularView<Eigen::Lower>(), *beta);
  else scale(c_.triangularView<Eigen::Upper>(), *beta);
  if (*k <= 0 || *alpha == 0.0) return;
  const bool t = transposed(trans);
  const ConstMatrix a_(a, t ? *k : *n, t ? *n : *k, Eigen::OuterStride<>(*lda));
  auto update = [&](auto&& factor) {
    if (lower) c_.selfadjointView<Eigen::Lower>().rankUpdate(factor, *alpha);
    else c_.selfadjointView<Eigen::Upper>().rankUpdate(factor, *alpha);
  };
  if (t) update(a_.transpose());
  else update(a_);
}

// B := alpha op(A)^-1 B (side L) or alpha B op(A)^-1 (side R), A triangular, B m x n.
void dtrsm_(const char* side, const char* uplo, const char* trans, const char* diag, const int* m, const int* n,
            const double* alpha, const double* a, const int* lda, double* b, const int* ldb) {
  if (*m <= 0 || *n <= 0) return;
  Matrix b_(b, *m, *n, Eigen::OuterStride<>(*ldb));
  scale(b_, *alpha);
  if (*alpha == 0.0) return;
  const bool left = is(side, 'L');
  const ConstMatrix a_(a, left ? *m : *n, left ? *m : *n, Eigen::OuterStride<>(*lda));
  if (left) triangular_solve<Eigen::OnTheLeft>(a_, is(uplo, 'L'), transposed(trans), is(diag, 'U'), b_);
  else triangular_solve<Eigen::OnTheRight>(a_, is(uplo, 'L'), transposed(trans), is(diag, 'U'), b_);
}

// Cholesky factor of A in place: A = L L^T in the lower triangle (uplo L) or U^T U in the upper.
// info: 0, or j when the leading minor of order j is not positive definite (the factor is then
// complete up to column j - 1, as LAPACK's).
//
// A stop request (engine/stop_request.hpp) fails it at column 1: CHOLMOD then ends the
// factorisation of a big island at the supernode under way instead of finishing it (seconds on
// the folding 100x100 mat), and CholmodSolver::factorize throws the stop.
void dpotrf_(const char* uplo, const int* n, double* a, const int* lda, int* info) {
  *info = 0;
  if (*n <= 0) return;
  if (nexdyn::stop_requested() != 0) {
    *info = 1;
    return;
  }
  Matrix a_(a, *n, *n, Eigen::OuterStride<>(*lda));
  // Eigen's in-place blocked Cholesky (what Eigen::LLT runs) returns the failing column, which
  // LLT's public interface does not.
  const Eigen::Index failed = is(uplo, 'L') ? Eigen::internal::llt_inplace<double, Eigen::Lower>::blocked(a_)
                                            : Eigen::internal::llt_inplace<double, Eigen::Upper>::blocked(a_);
  if (failed >= 0) *info = static_cast<int>(failed) + 1;
}

// x := op(A)^-1 x, A n x n triangular.
void dtrsv_(const char* uplo, const char* trans, const char* diag, const int* n, const double* a, const int* lda,
            double* x, const int* incx) {
  if (*n <= 0) return;
  const ConstMatrix a_(a, *n, *n, Eigen::OuterStride<>(*lda));
  StridedVector x_(x, *n, *incx);
  triangular_solve<Eigen::OnTheLeft>(a_, is(uplo, 'L'), transposed(trans), is(diag, 'U'), x_.map());
  x_.store();
}

// y := alpha op(A) x + beta y, A m x n.
void dgemv_(const char* trans, const int* m, const int* n, const double* alpha, const double* a, const int* lda,
            const double* x, const int* incx, const double* beta, double* y, const int* incy) {
  if (*m <= 0 || *n <= 0) return;
  const bool t = transposed(trans);
  StridedVector y_(y, t ? *n : *m, *incy);
  scale(y_.map(), *beta);
  if (*alpha != 0.0) {
    const ConstMatrix a_(a, *m, *n, Eigen::OuterStride<>(*lda));
    StridedVector x_(const_cast<double*>(x), t ? *m : *n, *incx);  // read only
    if (t) y_.map().noalias() += *alpha * a_.transpose() * x_.map();
    else y_.map().noalias() += *alpha * a_ * x_.map();
  }
  y_.store();
}

}  // extern "C"

namespace nexdyn {

bool set_up_cholmod_runtime() {
  static const bool bound = [] {
    // Before CHOLMOD allocates anything (free() takes both malloc's blocks and these).
    SuiteSparse_config.malloc_func = aligned_malloc;
    SuiteSparse_config.calloc_func = aligned_calloc;
    SuiteSparse_config.realloc_func = aligned_realloc;
    SuiteSparse_config.free_func = std::free;
    const std::pair<const char*, void*> ours[] = {
        {"GOMP_parallel", reinterpret_cast<void*>(&GOMP_parallel)},
        {"dgemm_", reinterpret_cast<void*>(&dgemm_)},
        {"dsyrk_", reinterpret_cast<void*>(&dsyrk_)},
        {"dtrsm_", reinterpret_cast<void*>(&dtrsm_)},
        {"dpotrf_", reinterpret_cast<void*>(&dpotrf_)},
        {"dtrsv_", reinterpret_cast<void*>(&dtrsv_)},
        {"dgemv_", reinterpret_cast<void*>(&dgemv_)}};
    // dlsym over the global scope finds what the dynamic linker binds CHOLMOD's references to.
    for (const auto& [name, address] : ours)
      if (dlsym(RTLD_DEFAULT, name) != address) return false;
    return true;
  }();
  return bound;
}

}  // namespace nexdyn

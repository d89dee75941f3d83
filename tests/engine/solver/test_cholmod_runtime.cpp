// The engine's OpenMP, BLAS and LAPACK entry points for CHOLMOD (engine/sparse/cholmod_runtime.hpp):
// CHOLMOD's calls reach them, and each routine keeps its reference-BLAS contract, checked against
// plain loops over every flag combination, with leading dimensions larger than the rows, vector
// strides other than 1 (negative ones run from the far end), beta = 0 over a C full of NaN (BLAS
// does not read it) and a matrix whose third leading minor is not positive definite; and CHOLMOD's
// memory: aligned, big blocks on huge-page boundaries, realloc's contract kept.
#include "engine/sparse/cholmod_runtime.hpp"
#include "engine/stop_request.hpp"

#include <SuiteSparse_config.h>
#include <dlfcn.h>
#include <doctest/doctest.h>

#include <cmath>
#include <csignal>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

extern "C" {
void GOMP_parallel(void (*body)(void*), void* data, unsigned num_threads, unsigned flags);
void dgemm_(const char*, const char*, const int*, const int*, const int*, const double*, const double*, const int*,
            const double*, const int*, const double*, double*, const int*);
void dsyrk_(const char*, const char*, const int*, const int*, const double*, const double*, const int*,
            const double*, double*, const int*);
void dtrsm_(const char*, const char*, const char*, const char*, const int*, const int*, const double*,
            const double*, const int*, double*, const int*);
void dpotrf_(const char*, const int*, double*, const int*, int*);
void dtrsv_(const char*, const char*, const char*, const int*, const double*, const int*, double*, const int*);
void dgemv_(const char*, const int*, const int*, const double*, const double*, const int*, const double*,
            const int*, const double*, double*, const int*);
}

namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// A column-major rows x cols matrix stored with leading dimension ld = rows + 2; the two spare
// rows of every column hold a marker that no routine may change.
struct Dense {
  int rows, cols, ld;
  std::vector<double> data;
  static constexpr double kMarker = 12345.0;
  Dense(int r, int c, std::mt19937& rng, double diagonal_boost = 0.0) : rows(r), cols(c), ld(r + 2) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    data.assign(static_cast<size_t>(ld) * cols, kMarker);
    for (int j = 0; j < cols; ++j)
      for (int i = 0; i < rows; ++i) (*this)(i, j) = u(rng) + (i == j ? diagonal_boost : 0.0);
  }
  double& operator()(int i, int j) { return data[static_cast<size_t>(i) + static_cast<size_t>(j) * ld]; }
  double operator()(int i, int j) const { return data[static_cast<size_t>(i) + static_cast<size_t>(j) * ld]; }
  bool markers_intact() const {
    for (int j = 0; j < cols; ++j)
      for (int i = rows; i < ld; ++i)
        if ((*this)(i, j) != kMarker) return false;
    return true;
  }
};

// op(M)(i, j) for M stored as `m`.
double op(const Dense& m, bool trans, int i, int j) { return trans ? m(j, i) : m(i, j); }

}  // namespace

TEST_CASE("cholmod runtime: CHOLMOD's OpenMP, BLAS and LAPACK calls reach the engine's definitions") {
  CHECK(nexdyn::set_up_cholmod_runtime());
  // libgomp is loaded (CHOLMOD needs its omp_get_thread_num and the like), and its own entry point
  // is not the one found: were it, every supernode would end in a futex_wake system call.
  void* const gomp = dlopen("libgomp.so.1", RTLD_LAZY | RTLD_NOLOAD);
  REQUIRE(gomp != nullptr);
  CHECK(dlsym(gomp, "GOMP_parallel") != reinterpret_cast<void*>(&GOMP_parallel));
  dlclose(gomp);
}

TEST_CASE("cholmod runtime: dgemm and dsyrk against plain loops, every transpose and triangle") {
  std::mt19937 rng(7);
  const int m = 13, n = 9, k = 17;
  for (const char* ta : {"N", "T", "C"})
    for (const char* tb : {"N", "t"})
      for (const double beta : {0.0, 1.0, -0.5}) {
        CAPTURE(ta);
        CAPTURE(tb);
        CAPTURE(beta);
        const bool ta_t = *ta != 'N', tb_t = *tb != 'N';
        const Dense a(ta_t ? k : m, ta_t ? m : k, rng), b(tb_t ? n : k, tb_t ? k : n, rng);
        Dense c(m, n, rng);
        if (beta == 0.0)
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < m; ++i) c(i, j) = kNaN;
        const Dense c0 = c;
        const double alpha = -1.25;
        dgemm_(ta, tb, &m, &n, &k, &alpha, a.data.data(), &a.ld, b.data.data(), &b.ld, &beta, c.data.data(), &c.ld);
        double worst = 0.0;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < m; ++i) {
            double sum = 0.0;
            for (int l = 0; l < k; ++l) sum += op(a, ta_t, i, l) * op(b, tb_t, l, j);
            const double expected = alpha * sum + (beta == 0.0 ? 0.0 : beta * c0(i, j));
            worst = std::max(worst, std::abs(c(i, j) - expected));
          }
        CHECK(worst <= 1e-13);
        CHECK(c.markers_intact());
      }

  for (const char* uplo : {"L", "u"})
    for (const char* trans : {"N", "T"})
      for (const double beta : {0.0, 0.75}) {
        CAPTURE(uplo);
        CAPTURE(trans);
        CAPTURE(beta);
        const bool lower = *uplo == 'L', t = *trans == 'T';
        const Dense a(t ? k : n, t ? n : k, rng);
        Dense c(n, n, rng);
        if (beta == 0.0)  // the triangle written is not read; the other one must stay as it is
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i)
              if (lower ? i >= j : i <= j) c(i, j) = kNaN;
        const Dense c0 = c;
        const double alpha = 0.5;
        dsyrk_(uplo, trans, &n, &k, &alpha, a.data.data(), &a.ld, &beta, c.data.data(), &c.ld);
        double worst = 0.0;
        bool other_triangle_kept = true;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            if (lower ? i < j : i > j) {
              other_triangle_kept = other_triangle_kept && c(i, j) == c0(i, j);
              continue;
            }
            double sum = 0.0;
            for (int l = 0; l < k; ++l) sum += op(a, t, i, l) * op(a, t, j, l);
            const double expected = alpha * sum + (beta == 0.0 ? 0.0 : beta * c0(i, j));
            worst = std::max(worst, std::abs(c(i, j) - expected));
          }
        CHECK(worst <= 1e-13);
        CHECK(other_triangle_kept);
        CHECK(c.markers_intact());
      }
}

TEST_CASE("cholmod runtime: dtrsm and dtrsv solve what they multiply back to, every side and flag") {
  std::mt19937 rng(11);
  const int m = 11, n = 6;
  for (const char* side : {"L", "R"})
    for (const char* uplo : {"L", "U"})
      for (const char* trans : {"N", "T"})
        for (const char* diag : {"N", "U"}) {
          CAPTURE(side);
          CAPTURE(uplo);
          CAPTURE(trans);
          CAPTURE(diag);
          const bool left = *side == 'L', lower = *uplo == 'L', t = *trans == 'T', unit = *diag == 'U';
          const int na = left ? m : n;
          // Well conditioned: a dominant diagonal. The unused triangle and, with a unit diagonal,
          // the diagonal itself hold NaN: the routine must not read them.
          Dense a(na, na, rng, 4.0);
          for (int j = 0; j < na; ++j)
            for (int i = 0; i < na; ++i)
              if ((lower ? i < j : i > j) || (unit && i == j)) a(i, j) = kNaN;
          auto tri = [&](int i, int j) {  // op(A)(i, j) as the routine must see it
            const int r = t ? j : i, c = t ? i : j;
            if (r == c) return unit ? 1.0 : a(r, c);
            return (lower ? r > c : r < c) ? a(r, c) : 0.0;
          };
          Dense b(m, n, rng);
          const Dense b0 = b;
          const double alpha = 2.0;
          dtrsm_(side, uplo, trans, diag, &m, &n, &alpha, a.data.data(), &a.ld, b.data.data(), &b.ld);
          double worst = 0.0;  // op(A) X - alpha B, or X op(A) - alpha B
          for (int j = 0; j < n; ++j)
            for (int i = 0; i < m; ++i) {
              double sum = 0.0;
              for (int l = 0; l < na; ++l) sum += left ? tri(i, l) * b(l, j) : b(i, l) * tri(l, j);
              worst = std::max(worst, std::abs(sum - alpha * b0(i, j)));
            }
          CHECK(worst <= 1e-12);
          CHECK(b.markers_intact());

          if (!left) continue;
          // dtrsv on column 0 of b0, with strides 1, 3 and -2.
          for (const int inc : {1, 3, -2}) {
            CAPTURE(inc);
            const int stride = std::abs(inc);
            std::vector<double> x(static_cast<size_t>(m) * stride, kNaN);
            auto at = [&](int i) -> double& { return x[static_cast<size_t>(inc > 0 ? i : m - 1 - i) * stride]; };
            for (int i = 0; i < m; ++i) at(i) = b0(i, 0);
            dtrsv_(uplo, trans, diag, &m, a.data.data(), &a.ld, x.data(), &inc);
            double worst_v = 0.0;
            for (int i = 0; i < m; ++i) {
              double sum = 0.0;
              for (int l = 0; l < m; ++l) sum += tri(i, l) * at(l);
              worst_v = std::max(worst_v, std::abs(sum - b0(i, 0)));
            }
            CHECK(worst_v <= 1e-12);
            size_t untouched_nan = 0;  // the gaps between the elements stay as they were
            for (double v : x) untouched_nan += std::isnan(v);
            CHECK(untouched_nan == x.size() - static_cast<size_t>(m));
          }
        }
}

TEST_CASE("cholmod runtime: dgemv against plain loops with strides, dpotrf's factor and its failing column") {
  std::mt19937 rng(13);
  const int m = 10, n = 7;
  const Dense a(m, n, rng);
  for (const char* trans : {"N", "T"})
    for (const int inc : {1, 2, -3})
      for (const double beta : {0.0, -2.0}) {
        CAPTURE(trans);
        CAPTURE(inc);
        CAPTURE(beta);
        const bool t = *trans == 'T';
        const int nx = t ? m : n, ny = t ? n : m, stride = std::abs(inc);
        auto index = [&](int i, int len) { return static_cast<size_t>(inc > 0 ? i : len - 1 - i) * stride; };
        std::vector<double> x(static_cast<size_t>(nx) * stride), y(static_cast<size_t>(ny) * stride, 0.5);
        for (int i = 0; i < nx; ++i) x[index(i, nx)] = 0.1 * i - 0.3;
        if (beta == 0.0)
          for (int i = 0; i < ny; ++i) y[index(i, ny)] = kNaN;
        const std::vector<double> y0 = y;
        const double alpha = 1.5;
        dgemv_(trans, &m, &n, &alpha, a.data.data(), &a.ld, x.data(), &inc, &beta, y.data(), &inc);
        double worst = 0.0;
        for (int i = 0; i < ny; ++i) {
          double sum = 0.0;
          for (int l = 0; l < nx; ++l) sum += op(a, t, i, l) * x[index(l, nx)];
          const double expected = alpha * sum + (beta == 0.0 ? 0.0 : beta * y0[index(i, ny)]);
          worst = std::max(worst, std::abs(y[index(i, ny)] - expected));
        }
        CHECK(worst <= 1e-13);
        size_t gaps_kept = 0;
        for (size_t s = 0; s < y.size(); ++s) gaps_kept += (s % stride != 0) && y[s] == 0.5;
        CHECK(gaps_kept == y.size() - static_cast<size_t>(ny));
      }

  // A = G G^T + n I is positive definite: the factor multiplies back to it.
  const int size = 40;  // past Eigen's unblocked size, so the blocked path runs too
  const Dense g(size, size, rng);
  for (const char* uplo : {"L", "U"}) {
    CAPTURE(uplo);
    const bool lower = *uplo == 'L';
    Dense spd(size, size, rng);
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < size; ++i) {
        double sum = i == j ? size : 0.0;
        for (int l = 0; l < size; ++l) sum += g(i, l) * g(j, l);
        spd(i, j) = sum;
      }
    Dense f = spd;
    int info = -1;
    dpotrf_(uplo, &size, f.data.data(), &f.ld, &info);
    CHECK(info == 0);
    auto factor = [&](int i, int j) {  // L(i, j), with L = U^T for the upper triangle
      if (i < j) return 0.0;
      return lower ? f(i, j) : f(j, i);
    };
    double worst = 0.0;
    for (int j = 0; j < size; ++j)
      for (int i = 0; i < size; ++i) {
        double sum = 0.0;
        for (int l = 0; l < size; ++l) sum += factor(i, l) * factor(j, l);
        worst = std::max(worst, std::abs(sum - spd(i, j)) / size);
      }
    CHECK(worst <= 1e-12);
    CHECK(f.markers_intact());

    // Its third leading minor made indefinite: info names column 3 (1-based), as LAPACK's does.
    Dense bad = spd;
    bad(2, 2) = -1.0;
    dpotrf_(uplo, &size, bad.data.data(), &bad.ld, &info);
    CHECK(info == 3);

    // A stop request (engine/stop_request.hpp) fails it at once at column 1, untouched, so that
    // CHOLMOD ends a big factorisation at the supernode under way.
    Dense stopped = spd;
    nexdyn::request_stop(SIGTERM);
    dpotrf_(uplo, &size, stopped.data.data(), &stopped.ld, &info);
    nexdyn::clear_stop_request();
    CHECK(info == 1);
    CHECK(stopped.data == spd.data);
  }
}

TEST_CASE("cholmod runtime: CHOLMOD's blocks are 64-byte aligned, big ones on 2 MB, and keep realloc's contract") {
  REQUIRE(nexdyn::set_up_cholmod_runtime());
  const SuiteSparse_config_struct& c = SuiteSparse_config;
  auto offset = [](const void* p, uintptr_t alignment) { return reinterpret_cast<uintptr_t>(p) % alignment; };
  const size_t big = size_t{9} << 20;  // over the 8 MB from which blocks ask for huge pages
  for (size_t bytes : {size_t{1}, size_t{24}, size_t{1000}, size_t{3} << 20, big}) {
    auto* p = static_cast<unsigned char*>(c.malloc_func(bytes));
    REQUIRE(p != nullptr);
    CHECK(offset(p, 64) == 0);
    if (bytes >= big) CHECK(offset(p, uintptr_t{2} << 20) == 0);
    p[0] = p[bytes - 1] = 7;  // the whole block is ours
    c.free_func(p);
  }
  // calloc zeroes a big block too (its pages may come back from an earlier, written one).
  auto* zeroed = static_cast<unsigned char*>(c.calloc_func(big / 8, 8));
  REQUIRE(zeroed != nullptr);
  size_t nonzero = 0;
  for (size_t k = 0; k < big; k += 4093) nonzero += zeroed[k] != 0;
  CHECK(nonzero == 0);
  c.free_func(zeroed);
  // realloc keeps the first min(old, new) bytes across the 8 MB line, in both directions.
  auto* p = static_cast<unsigned char*>(c.malloc_func(1000));
  REQUIRE(p != nullptr);
  for (int k = 0; k < 1000; ++k) p[k] = static_cast<unsigned char>(k * 31);
  auto* grown = static_cast<unsigned char*>(c.realloc_func(p, big));
  REQUIRE(grown != nullptr);
  CHECK(offset(grown, uintptr_t{2} << 20) == 0);
  bool kept = true;
  for (int k = 0; k < 1000; ++k) kept &= grown[k] == static_cast<unsigned char>(k * 31);
  CHECK(kept);
  grown[big - 1] = 5;
  auto* shrunk = static_cast<unsigned char*>(c.realloc_func(grown, 500));
  REQUIRE(shrunk != nullptr);
  CHECK(offset(shrunk, 64) == 0);
  kept = true;
  for (int k = 0; k < 500; ++k) kept &= shrunk[k] == static_cast<unsigned char>(k * 31);
  CHECK(kept);
  c.free_func(shrunk);
}

// BlockedBoxes::scan with AVX2 (see box_scan.hpp): a block of 8 boxes is two compares of 4, and
// AVX2 has no compress-store, so the hits' ids are gathered to the front of a vector by a
// permutation looked up from the 8-bit hit mask (256 permutations, 8 KB) and stored whole.
#include "bvh/box_scan.hpp"

#if defined(__AVX2__)
#include <immintrin.h>

namespace nexdyn::box_scan {

namespace {

// kCompress.lanes[m] lists the set bits of m in increasing order, then zeros.
struct CompressTable {
  alignas(32) int32_t lanes[256][8];
  constexpr CompressTable() : lanes{} {
    for (int m = 0; m < 256; ++m) {
      int n = 0;
      for (int k = 0; k < 8; ++k)
        if (m & (1 << k)) lanes[m][n++] = k;
    }
  }
};
constexpr CompressTable kCompress;

// Bit k set iff box at + k (k < 4) overlaps the query.
unsigned overlapping4(const double* const* lo, const double* const* hi, int64_t at, const __m256d* qlo,
                      const __m256d* qhi) {
  __m256d hit = _mm256_and_pd(_mm256_cmp_pd(_mm256_loadu_pd(lo[0] + at), qhi[0], _CMP_LE_OQ),
                              _mm256_cmp_pd(qlo[0], _mm256_loadu_pd(hi[0] + at), _CMP_LE_OQ));
  for (int d = 1; d < 3; ++d) {
    hit = _mm256_and_pd(hit, _mm256_cmp_pd(_mm256_loadu_pd(lo[d] + at), qhi[d], _CMP_LE_OQ));
    hit = _mm256_and_pd(hit, _mm256_cmp_pd(qlo[d], _mm256_loadu_pd(hi[d] + at), _CMP_LE_OQ));
  }
  return static_cast<unsigned>(_mm256_movemask_pd(hit));
}

unsigned overlapping8(const double* const* lo, const double* const* hi, int64_t at, const __m256d* qlo,
                      const __m256d* qhi) {
  return overlapping4(lo, hi, at, qlo, qhi) | overlapping4(lo, hi, at + 4, qlo, qhi) << 4;
}

}  // namespace

int32_t scan_avx2(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                  const double* upper, int32_t* out) {
  const __m256d qlo[3] = {_mm256_set1_pd(lower[0]), _mm256_set1_pd(lower[1]), _mm256_set1_pd(lower[2])};
  const __m256d qhi[3] = {_mm256_set1_pd(upper[0]), _mm256_set1_pd(upper[1]), _mm256_set1_pd(upper[2])};
  const unsigned first_lanes = 0xffu << first_lane;
  int32_t count = 0;
  for (int64_t group = first; group < last; group += 8) {
    const unsigned in_range = last - group >= 8 ? 0xffu : (1u << (last - group)) - 1;
    for (unsigned blocks = overlapping8(a.block_lo, a.block_hi, group, qlo, qhi) & in_range; blocks != 0;
         blocks &= blocks - 1) {
      const int64_t b = group + __builtin_ctz(blocks);
      const unsigned hits = overlapping8(a.lo, a.hi, 8 * b, qlo, qhi) & (b == first ? first_lanes : 0xffu);
      const __m256i ids = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.id + 8 * b));
      const __m256i order = _mm256_load_si256(reinterpret_cast<const __m256i*>(kCompress.lanes[hits]));
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(out + count), _mm256_permutevar8x32_epi32(ids, order));
      count += __builtin_popcount(hits);
    }
  }
  return count;
}

}  // namespace nexdyn::box_scan

#else  // a compiler or machine without these instructions: never chosen (kernels/isa.hpp)

namespace nexdyn::box_scan {
int32_t scan_avx2(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                  const double* upper, int32_t* out) {
  return scan_scalar(a, first, last, first_lane, lower, upper, out);
}
}  // namespace nexdyn::box_scan

#endif

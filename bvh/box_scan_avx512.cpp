// BlockedBoxes::scan with AVX-512 F + VL (see box_scan.hpp): one block of 8 boxes per compare,
// and the hits' ids written with one masked compress-store.
#include "bvh/box_scan.hpp"

#if defined(__AVX512F__) && defined(__AVX512VL__)
#include <immintrin.h>

namespace nexdyn::box_scan {

namespace {

// Lanes of `lanes` whose boxes (8 consecutive entries from `at`) overlap the query.
__mmask8 overlapping(const double* const* lo, const double* const* hi, int64_t at, const __m512d* qlo,
                     const __m512d* qhi, __mmask8 lanes) {
  for (int d = 0; d < 3; ++d) {
    lanes = _mm512_mask_cmp_pd_mask(lanes, _mm512_loadu_pd(lo[d] + at), qhi[d], _CMP_LE_OQ);
    lanes = _mm512_mask_cmp_pd_mask(lanes, qlo[d], _mm512_loadu_pd(hi[d] + at), _CMP_LE_OQ);
  }
  return lanes;
}

}  // namespace

int32_t scan_avx512(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                    const double* upper, int32_t* out) {
  const __m512d qlo[3] = {_mm512_set1_pd(lower[0]), _mm512_set1_pd(lower[1]), _mm512_set1_pd(lower[2])};
  const __m512d qhi[3] = {_mm512_set1_pd(upper[0]), _mm512_set1_pd(upper[1]), _mm512_set1_pd(upper[2])};
  const auto first_lanes = static_cast<__mmask8>(0xffu << first_lane);
  int32_t count = 0;
  // The block boxes of 8 blocks per compare; then each overlapping block's own boxes.
  for (int64_t group = first; group < last; group += 8) {
    const auto in_range = static_cast<__mmask8>(last - group >= 8 ? 0xffu : (1u << (last - group)) - 1);
    for (unsigned blocks = overlapping(a.block_lo, a.block_hi, group, qlo, qhi, in_range); blocks != 0;
         blocks &= blocks - 1) {
      const int64_t b = group + __builtin_ctz(blocks);
      const __mmask8 hits = overlapping(a.lo, a.hi, 8 * b, qlo, qhi, b == first ? first_lanes : 0xff);
      _mm256_mask_compressstoreu_epi32(out + count, hits,
                                       _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.id + 8 * b)));
      count += __builtin_popcount(hits);
    }
  }
  return count;
}

}  // namespace nexdyn::box_scan

#else  // a compiler or machine without these instructions: never chosen (kernels/isa.hpp)

namespace nexdyn::box_scan {
int32_t scan_avx512(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                    const double* upper, int32_t* out) {
  return scan_scalar(a, first, last, first_lane, lower, upper, out);
}
}  // namespace nexdyn::box_scan

#endif

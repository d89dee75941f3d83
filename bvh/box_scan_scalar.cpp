// BlockedBoxes::scan in plain C++ (see box_scan.hpp): the path of CPUs without AVX2.
#include "bvh/box_scan.hpp"

namespace nexdyn::box_scan {

namespace {

bool overlaps(const double* const* lo, const double* const* hi, int64_t at, const double* lower,
              const double* upper) {
  bool hit = true;
  for (int d = 0; d < 3; ++d) hit &= (lo[d][at] <= upper[d]) & (lower[d] <= hi[d][at]);
  return hit;
}

}  // namespace

int32_t scan_scalar(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                    const double* upper, int32_t* out) {
  int32_t count = 0;
  for (int64_t b = first; b < last; ++b) {
    if (!overlaps(a.block_lo, a.block_hi, b, lower, upper)) continue;
    // Branch-free: every id is written, and kept by counting it only on a hit.
    for (int k = (b == first ? first_lane : 0); k < 8; ++k) {
      out[count] = a.id[8 * b + k];
      count += overlaps(a.lo, a.hi, 8 * b + k, lower, upper);
    }
  }
  return count;
}

}  // namespace nexdyn::box_scan

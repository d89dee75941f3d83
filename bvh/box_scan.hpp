// The inner loop of BlockedBoxes::scan (bvh/blocked_boxes.hpp), once per instruction-set path.
//
// Each path lives in a file of its own, compiled for that instruction set only
// (bvh/CMakeLists.txt), and BlockedBoxes::scan calls the one active_isa() names
// (kernels/isa.hpp). Those files include nothing but this header and the intrinsics, and use no
// template or inline function of a library: an inline function compiled there with AVX-512 could
// be the copy the linker keeps for the whole program, and then crash a CPU without it.
//
// All paths return the same ids in the same order: a box is reported iff its closed intervals
// overlap the query's on all three axes, compared in doubles.
#pragma once

#include <cstdint>

namespace nexdyn::box_scan {

// One BlockedBoxes' arrays (see there for the layout).
struct Arrays {
  const double* lo[3];        // per slot, 8 slots per block
  const double* hi[3];
  const double* block_lo[3];  // per block; readable (empty boxes) 8 blocks past the last one
  const double* block_hi[3];
  const int32_t* id;          // per slot
};

// Ids of the boxes in blocks [first, last) that overlap [lower, upper], in slot order; in block
// `first` only slots from lane `first_lane` on. Writes out[0, count) and may write up to 8 ids
// past that (the caller's room); returns count.
int32_t scan_scalar(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                    const double* upper, int32_t* out);
int32_t scan_avx2(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                  const double* upper, int32_t* out);
int32_t scan_avx512(const Arrays& a, int64_t first, int64_t last, int first_lane, const double* lower,
                    const double* upper, int32_t* out);

}  // namespace nexdyn::box_scan

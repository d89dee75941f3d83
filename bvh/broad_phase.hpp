// Broad phase: all pairs of overlapping axis-aligned boxes, from flat (n x 3) double arrays.
//
// Embree builds a BVH over user geometries (one primitive per box) and rtcCollide walks two of
// them. Embree works in float, so every double box is widened to the nearest floats outside it
// (lower rounded down, upper rounded up): the float BVH can only report more candidates, never
// fewer. Each candidate is then checked against the exact double boxes, so the output equals the
// O(n^2) brute force bit for bit (see DESIGN.md section 1, note on rtcCollide).
//
// Overlap is on closed intervals: boxes that only touch at a face, edge or corner overlap.
//
// Output is a sorted, duplicate-free list of (i, j) pairs. It does not depend on the number of
// TBB threads: the callback collects per thread, the lists are concatenated and sorted.
//
// Exceptions only at the edge: an Embree error (device creation, out of memory, bad arguments)
// becomes a std::runtime_error naming the Embree call. Box arrays must be finite with
// lower <= upper; Embree silently drops invalid boxes, which would lose pairs.
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

typedef struct RTCDeviceTy* RTCDevice;

namespace nexdyn {

// Boxes per TBB chunk when the double boxes are rounded out to floats; the conversion is per box,
// so the grain changes only the scheduling, never a result.
inline constexpr size_t kBoxConvertGrain = 4096;

using IndexPair = std::pair<int32_t, int32_t>;

// The process-wide Embree device: created on first use (function-static, thread-safe), released
// at exit. Its error callback records the last Embree error; `check` throws it as a
// std::runtime_error naming `where`.
class EmbreeDevice {
 public:
  static EmbreeDevice& instance();
  RTCDevice get() const { return device_; }
  // Throws std::runtime_error if Embree reported an error since the last check.
  void check(const char* where) const;

  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;
  ~EmbreeDevice();

 private:
  EmbreeDevice();
  RTCDevice device_ = nullptr;
};

// All (i, j), i in A, j in B, whose closed boxes overlap; sorted by (i, j).
//   a_lower, a_upper: (na x 3) packed xyz, b_lower, b_upper: (nb x 3).
std::vector<IndexPair> overlapping_pairs(const double* a_lower, const double* a_upper, int32_t na,
                                         const double* b_lower, const double* b_upper, int32_t nb);

// All (i, j), i < j, whose closed boxes overlap; sorted by (i, j).
//   lower, upper: (n x 3) packed xyz.
std::vector<IndexPair> self_overlapping_pairs(const double* lower, const double* upper, int32_t n);

// O(n^2) references with the same contract, for tests and benchmarks.
std::vector<IndexPair> overlapping_pairs_brute_force(const double* a_lower, const double* a_upper,
                                                     int32_t na, const double* b_lower,
                                                     const double* b_upper, int32_t nb);
std::vector<IndexPair> self_overlapping_pairs_brute_force(const double* lower, const double* upper,
                                                          int32_t n);

// Closed-interval overlap of box i of (lo0, up0) and box j of (lo1, up1), arrays (n x 3).
inline bool boxes_overlap(const double* lo0, const double* up0, int64_t i, const double* lo1,
                          const double* up1, int64_t j) {
  for (int d = 0; d < 3; ++d) {
    if (lo0[3 * i + d] > up1[3 * j + d] || lo1[3 * j + d] > up0[3 * i + d]) return false;
  }
  return true;
}

}  // namespace nexdyn

// Lists of boxes kept in a given order, for box queries whose hits must come out in that order.
//
// Why not a tree: up to a few thousand boxes a linear scan with vector compares beats a tree
// query (measured on one cube of 5^3 cells, its 450 edge boxes queried with each of them:
// 0.44 us per BoxTree query, 0.045 us per scan), and a scan reports its hits in list order, so
// a caller that lists boxes by id gets sorted hits with no sort.
//
// Layout: one array per coordinate and side. Each list is padded with empty boxes (lower +inf,
// upper -inf, overlapping nothing) to whole blocks of kBlock boxes, so a block is one vector
// compare per bound (AVX-512: 8 doubles; AVX2: two compares of 4). Each block also has the union
// of its boxes, and a scan tests those first (8 blocks at a time) and skips the blocks they rule
// out: consecutive ids of a mesh are usually near each other, so block boxes are compact. Overlap
// is on closed intervals in doubles (boxes_overlap in bvh/broad_phase.hpp), exactly like a loop
// over the boxes. The scan itself is in bvh/box_scan_*.cpp, one file per instruction set, chosen
// at run time (kernels/isa.hpp); every path gives the same ids in the same order.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "bvh/box_scan.hpp"
#include "kernels/isa.hpp"

namespace nexdyn {

class BlockedBoxes {
 public:
  static constexpr int kBlock = 8;

  // Lays out lists of the given sizes; then set() must fill every box of each list and
  // finish() complete it (lists are independent: in parallel if wanted). The arrays stay
  // uninitialised until then, so that no serial pass writes them all first.
  void layout(const std::vector<int32_t>& sizes) {
    first_block_.assign(sizes.size() + 1, 0);
    size_.assign(sizes.begin(), sizes.end());
    for (size_t l = 0; l < sizes.size(); ++l)
      first_block_[l + 1] = first_block_[l] + (sizes[l] + kBlock - 1) / kBlock;
    const int64_t blocks = first_block_.back();
    // Block boxes are read 8 blocks at a time: pad them past the last block.
    for (int d = 0; d < 3; ++d) {
      lo_[d] = std::make_unique_for_overwrite<double[]>(blocks * kBlock);
      hi_[d] = std::make_unique_for_overwrite<double[]>(blocks * kBlock);
      block_lo_[d] = std::make_unique_for_overwrite<double[]>(blocks + kBlock);
      block_hi_[d] = std::make_unique_for_overwrite<double[]>(blocks + kBlock);
      std::fill_n(&block_lo_[d][blocks], kBlock, kEmptyLower);
      std::fill_n(&block_hi_[d][blocks], kBlock, kEmptyUpper);
    }
    id_ = std::make_unique_for_overwrite<int32_t[]>(blocks * kBlock);
  }

  // Box `index` of `list`.
  void set(int32_t list, int32_t index, const double* lower, const double* upper, int32_t id) {
    const int64_t slot = first_block_[list] * kBlock + index;
    for (int d = 0; d < 3; ++d) {
      lo_[d][slot] = lower[d];
      hi_[d][slot] = upper[d];
    }
    id_[slot] = id;
  }

  // Pads the last block of `list` with empty boxes and computes its block boxes.
  void finish(int32_t list) {
    const int64_t first = first_block_[list], last = first_block_[list + 1];
    for (int64_t slot = first * kBlock + size_[list]; slot < last * kBlock; ++slot) {
      for (int d = 0; d < 3; ++d) {
        lo_[d][slot] = kEmptyLower;
        hi_[d][slot] = kEmptyUpper;
      }
      id_[slot] = 0;
    }
    for (int64_t b = first; b < last; ++b)
      for (int d = 0; d < 3; ++d) {
        block_lo_[d][b] = *std::min_element(&lo_[d][b * kBlock], &lo_[d][b * kBlock] + kBlock);
        block_hi_[d][b] = *std::max_element(&hi_[d][b * kBlock], &hi_[d][b * kBlock] + kBlock);
      }
  }

  int32_t size(int32_t list) const { return size_[list]; }

  // Writes the ids of the boxes of `list` from index `from` on that overlap [lower, upper],
  // in list order, to out (room for size(list) - from + kBlock ids); returns their number.
  int32_t scan(int32_t list, int32_t from, const double* lower, const double* upper,
               int32_t* out) const;

 private:
  static constexpr double kEmptyLower = std::numeric_limits<double>::infinity();
  static constexpr double kEmptyUpper = -std::numeric_limits<double>::infinity();

  std::vector<int64_t> first_block_;  // list l: blocks [first_block_[l], first_block_[l + 1])
  std::vector<int32_t> size_;
  std::unique_ptr<double[]> lo_[3], hi_[3];  // per slot (block b: slots [8 b, 8 b + 8))
  std::unique_ptr<int32_t[]> id_;
  std::unique_ptr<double[]> block_lo_[3], block_hi_[3];  // per block
};

inline int32_t BlockedBoxes::scan(int32_t list, int32_t from, const double* lower,
                                  const double* upper, int32_t* out) const {
  const box_scan::Arrays arrays{{lo_[0].get(), lo_[1].get(), lo_[2].get()},
                                {hi_[0].get(), hi_[1].get(), hi_[2].get()},
                                {block_lo_[0].get(), block_lo_[1].get(), block_lo_[2].get()},
                                {block_hi_[0].get(), block_hi_[1].get(), block_hi_[2].get()},
                                id_.get()};
  const int64_t first = first_block_[list] + from / kBlock;
  const int64_t last = first_block_[list + 1];
  const int first_lane = from % kBlock;
  switch (active_isa()) {
    case Isa::avx512: return box_scan::scan_avx512(arrays, first, last, first_lane, lower, upper, out);
    case Isa::avx2: return box_scan::scan_avx2(arrays, first, last, first_lane, lower, upper, out);
    case Isa::scalar: break;
  }
  return box_scan::scan_scalar(arrays, first, last, first_lane, lower, upper, out);
}

}  // namespace nexdyn

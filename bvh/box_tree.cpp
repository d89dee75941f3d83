// BoxTree construction (see box_tree.hpp).
#include "bvh/box_tree.hpp"

#include <algorithm>
#include <limits>

namespace nexdyn {

namespace {

// Spreads the low 21 bits of x to every third bit of a 64-bit word.
uint64_t spread_bits(uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffff;
  x = (x | x << 16) & 0x1f0000ff0000ff;
  x = (x | x << 8) & 0x100f00f00f00f00f;
  x = (x | x << 4) & 0x10c30c30c30c30c3;
  x = (x | x << 2) & 0x1249249249249249;
  return x;
}

}  // namespace

void BoxTree::build(const double* lower, const double* upper, int32_t begin, int32_t end) {
  nodes_.clear();
  if (end <= begin) return;
  lower_ = lower;
  upper_ = upper;
  // The box of all centres (as lower + upper, twice the centre).
  double lo[3], hi[3];
  for (int d = 0; d < 3; ++d) {
    lo[d] = std::numeric_limits<double>::infinity();
    hi[d] = -std::numeric_limits<double>::infinity();
  }
  for (int64_t id = begin; id < end; ++id)
    for (int d = 0; d < 3; ++d) {
      const double c = lower[3 * id + d] + upper[3 * id + d];
      lo[d] = std::min(lo[d], c);
      hi[d] = std::max(hi[d], c);
    }
  // Morton order of the centres on a 2^21 grid over that box, ties by id: the tree depends on the
  // input only, and consecutive runs of the order are compact in space.
  constexpr double kCells = double((1 << 21) - 1);
  double scale[3];
  for (int d = 0; d < 3; ++d) scale[d] = hi[d] > lo[d] ? kCells / (hi[d] - lo[d]) : 0.0;
  order_.resize(static_cast<size_t>(end - begin));
  for (int32_t id = begin; id < end; ++id) {
    uint64_t code = 0;
    for (int d = 0; d < 3; ++d) {
      const double c = lower[3 * int64_t{id} + d] + upper[3 * int64_t{id} + d];
      code |= spread_bits(static_cast<uint64_t>((c - lo[d]) * scale[d])) << d;
    }
    order_[id - begin] = {code, id};
  }
  std::sort(order_.begin(), order_.end());
  ids_.resize(order_.size());
  for (size_t s = 0; s < order_.size(); ++s) ids_[s] = order_[s].second;
  nodes_.reserve(static_cast<size_t>(end - begin) / 2 + 1);
  int32_t max_id;
  build_node(0, end - begin, lo, hi, max_id);
}

// Appends the node over slots [first, first + count) of the Morton order and its subtrees;
// returns its index and writes the union of its boxes to lo, hi and its largest id to max_id.
// Up to 4 primitives become the children; more are cut into 4 runs of (nearly) equal length,
// which keeps the tree balanced.
int32_t BoxTree::build_node(int32_t first, int32_t count, double* lo, double* hi, int32_t& max_id) {
  const auto index = static_cast<int32_t>(nodes_.size());
  nodes_.emplace_back();
  for (int k = 0; k < kWidth; ++k) {
    for (int d = 0; d < 3; ++d) {
      nodes_[index].lower[d][k] = std::numeric_limits<double>::infinity();
      nodes_[index].upper[d][k] = -std::numeric_limits<double>::infinity();
    }
    nodes_[index].child[k] = 0;  // absent children never overlap anything
    nodes_[index].max_id[k] = -1;
  }
  nodes_[index].primitive_mask = 0;

  int32_t group_first[kWidth], group_count[kWidth];
  int groups = 0;
  if (count <= kWidth) {
    for (int32_t s = 0; s < count; ++s) {
      group_first[groups] = first + s;
      group_count[groups++] = 1;
    }
  } else {
    for (int g = 0; g < kWidth; ++g) {
      group_first[g] = first + static_cast<int32_t>(int64_t{count} * g / kWidth);
      group_count[g] = first + static_cast<int32_t>(int64_t{count} * (g + 1) / kWidth) - group_first[g];
    }
    groups = kWidth;
  }

  for (int d = 0; d < 3; ++d) {
    lo[d] = std::numeric_limits<double>::infinity();
    hi[d] = -std::numeric_limits<double>::infinity();
  }
  max_id = -1;
  for (int k = 0; k < groups; ++k) {
    double child_lo[3], child_hi[3];
    int32_t child, child_max_id;
    if (group_count[k] == 1) {
      const int64_t id = ids_[group_first[k]];
      for (int d = 0; d < 3; ++d) {
        child_lo[d] = lower_[3 * id + d];
        child_hi[d] = upper_[3 * id + d];
      }
      child = ~ids_[group_first[k]];
      child_max_id = ids_[group_first[k]];
    } else {
      child = build_node(group_first[k], group_count[k], child_lo, child_hi, child_max_id);
    }
    max_id = std::max(max_id, child_max_id);
    Node& node = nodes_[index];  // build_node may have moved the vector
    node.child[k] = child;
    node.max_id[k] = child_max_id;
    if (group_count[k] == 1) node.primitive_mask |= 1u << k;
    for (int d = 0; d < 3; ++d) {
      node.lower[d][k] = child_lo[d];
      node.upper[d][k] = child_hi[d];
      lo[d] = std::min(lo[d], child_lo[d]);
      hi[d] = std::max(hi[d], child_hi[d]);
    }
  }
  return index;
}

}  // namespace nexdyn

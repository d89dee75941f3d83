// BoxTree construction (see box_tree.hpp).
#include "bvh/box_tree.hpp"

#include <algorithm>
#include <limits>

namespace nexdyn {

void BoxTree::build(const double* lower, const double* upper, int32_t begin, int32_t end) {
  nodes_.clear();
  if (end <= begin) return;
  lower_ = lower;
  upper_ = upper;
  ids_.resize(static_cast<size_t>(end - begin));
  for (int32_t s = 0; s < end - begin; ++s) ids_[s] = begin + s;
  nodes_.reserve(static_cast<size_t>(end - begin) / 2 + 1);
  // The root's box, exactly; below it the split axes follow estimated extents.
  double lo[3], hi[3];
  for (int d = 0; d < 3; ++d) {
    lo[d] = std::numeric_limits<double>::infinity();
    hi[d] = -std::numeric_limits<double>::infinity();
  }
  for (int64_t id = begin; id < end; ++id)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], lower[3 * id + d]);
      hi[d] = std::max(hi[d], upper[3 * id + d]);
    }
  const double extent[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
  build_node(0, end - begin, extent, lo, hi);
}

// Reorders slots [first, first + count) so that the first count / 2 have the smaller centres
// along `axis` (ties by id: the tree depends on the input only). Splitting at the median keeps
// the tree balanced.
void BoxTree::split_in_half(int32_t first, int32_t count, int axis) {
  auto centre = [&](int64_t id) { return lower_[3 * id + axis] + upper_[3 * id + axis]; };
  const auto slots = ids_.begin() + first;
  std::nth_element(slots, slots + count / 2, slots + count, [&](int32_t a, int32_t b) {
    const double ca = centre(a), cb = centre(b);
    return ca < cb || (ca == cb && a < b);
  });
}

// Appends the node over slots [first, first + count) and its subtrees; returns its index and
// writes the union of its boxes to lo, hi. `extent` estimates the size of the range's box: each
// split goes along its longest axis (which keeps siblings apart on surfaces) and halves it there,
// so no pass over the boxes is needed to pick the axis.
int32_t BoxTree::build_node(int32_t first, int32_t count, const double* extent, double* lo,
                            double* hi) {
  const auto index = static_cast<int32_t>(nodes_.size());
  nodes_.emplace_back();
  for (int k = 0; k < kWidth; ++k) {
    for (int d = 0; d < 3; ++d) {
      nodes_[index].lower[d][k] = std::numeric_limits<double>::infinity();
      nodes_[index].upper[d][k] = -std::numeric_limits<double>::infinity();
    }
    nodes_[index].child[k] = 0;  // absent children never overlap anything
  }
  nodes_[index].primitive_mask = 0;

  // Up to 4 primitives become the children; more are split in half twice, into 4 groups.
  int32_t group_first[kWidth], group_count[kWidth];
  double group_extent[kWidth][3];
  int groups = 0;
  if (count <= kWidth) {
    for (int32_t s = 0; s < count; ++s) {
      group_first[groups] = first + s;
      group_count[groups++] = 1;
    }
  } else {
    auto longest = [](const double* e) { return e[1] > e[0] ? (e[2] > e[1] ? 2 : 1) : (e[2] > e[0] ? 2 : 0); };
    double half_extent[3] = {extent[0], extent[1], extent[2]};
    const int axis = longest(extent);
    half_extent[axis] *= 0.5;
    split_in_half(first, count, axis);
    const int sub_axis = longest(half_extent);
    split_in_half(first, count / 2, sub_axis);
    split_in_half(first + count / 2, count - count / 2, sub_axis);
    const int32_t half[2] = {count / 2, count - count / 2};
    for (int h = 0; h < 2; ++h) {
      const int32_t base = first + (h == 0 ? 0 : half[0]);
      group_first[2 * h] = base;
      group_count[2 * h] = half[h] / 2;
      group_first[2 * h + 1] = base + half[h] / 2;
      group_count[2 * h + 1] = half[h] - half[h] / 2;
    }
    for (int g = 0; g < kWidth; ++g) {
      for (int d = 0; d < 3; ++d) group_extent[g][d] = half_extent[d];
      group_extent[g][sub_axis] *= 0.5;
    }
    groups = kWidth;
  }

  for (int d = 0; d < 3; ++d) {
    lo[d] = std::numeric_limits<double>::infinity();
    hi[d] = -std::numeric_limits<double>::infinity();
  }
  for (int k = 0; k < groups; ++k) {
    double child_lo[3], child_hi[3];
    int32_t child;
    if (group_count[k] == 1) {
      const int64_t id = ids_[group_first[k]];
      for (int d = 0; d < 3; ++d) {
        child_lo[d] = lower_[3 * id + d];
        child_hi[d] = upper_[3 * id + d];
      }
      child = ~ids_[group_first[k]];
    } else {
      child = build_node(group_first[k], group_count[k], group_extent[k], child_lo, child_hi);
    }
    Node& node = nodes_[index];  // build_node may have moved the vector
    node.child[k] = child;
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

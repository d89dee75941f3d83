// Islands of the Newton system (see islands.hpp).
#include "engine/sparse/islands.hpp"

#include <cstddef>
#include <numeric>

namespace nexdyn {

void DisjointSets::reset(int32_t n) {
  parent_.resize(n);
  std::iota(parent_.begin(), parent_.end(), 0);
}

int32_t DisjointSets::find(int32_t a) {
  while (parent_[a] != a) {
    parent_[a] = parent_[parent_[a]];  // path halving
    a = parent_[a];
  }
  return a;
}

void DisjointSets::join(int32_t a, int32_t b) {
  a = find(a);
  b = find(b);
  if (a < b) parent_[b] = a;
  else if (b < a) parent_[a] = b;
}

Islands::Islands(const CscPattern& elastic, int32_t num_vertices)
    : elastic_(elastic), moving_(num_vertices, 1) {
  set_moving(moving_);
}

void Islands::set_moving(const std::vector<uint8_t>& moving) {
  moving_ = moving;
  const int32_t n = static_cast<int32_t>(moving_.size());
  sets_.reset(n);
  // Every vertex block of the pattern couples vertex I (row) and J (column); one DOF column per
  // vertex sees all of its blocks above the diagonal.
  for (int32_t j = 0; j < n; ++j) {
    if (!moving_[j]) continue;
    const int64_t c = 3 * int64_t{j};
    for (int64_t k = elastic_.col_ptr[c]; k < elastic_.col_ptr[c + 1]; k += 3) {
      const int32_t i = static_cast<int32_t>(elastic_.row_idx[k] / 3);
      if (i != j && moving_[i]) sets_.join(i, j);
    }
  }
  for (int32_t v = 0; v < n; ++v) sets_.find(v);
  static_parent_ = sets_.parents();
}

void Islands::build(const std::vector<const std::vector<int32_t>*>& stencil_lists) {
  const int32_t n = static_cast<int32_t>(moving_.size());
  sets_.parents() = static_parent_;
  for (const std::vector<int32_t>* list : stencil_lists) {
    const std::vector<int32_t>& s = *list;
    for (std::size_t k = 0; k + 4 <= s.size(); k += 4) {
      int32_t first = -1;
      for (int a = 0; a < 4; ++a) {
        const int32_t v = s[k + a];
        if (v < 0 || !moving_[v]) continue;
        if (first < 0) first = v;
        else sets_.join(first, v);
      }
    }
  }
  // Label islands by their smallest vertex, which is their root: a root is labelled before any
  // other member because the scan runs in increasing vertex order.
  island_of_.assign(n, -1);
  int32_t count = 0;
  for (int32_t v = 0; v < n; ++v) {
    if (!moving_[v]) continue;
    const int32_t root = sets_.find(v);
    island_of_[v] = root == v ? count++ : island_of_[root];
  }
  vertex_ptr_.assign(count + 1, 0);
  for (int32_t v = 0; v < n; ++v)
    if (island_of_[v] >= 0) ++vertex_ptr_[island_of_[v] + 1];
  for (int32_t i = 0; i < count; ++i) vertex_ptr_[i + 1] += vertex_ptr_[i];
  vertices_.resize(vertex_ptr_[count]);
  local_index_.assign(n, -1);
  std::vector<int32_t>& fill = fill_;  // next free slot of each island
  fill.assign(vertex_ptr_.begin(), vertex_ptr_.end() - 1);
  for (int32_t v = 0; v < n; ++v) {
    const int32_t i = island_of_[v];
    if (i < 0) continue;
    local_index_[v] = fill[i] - vertex_ptr_[i];
    vertices_[fill[i]++] = v;
  }
}

}  // namespace nexdyn

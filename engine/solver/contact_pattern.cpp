// Elastic + contact Newton pattern (see contact_pattern.hpp).
#include "engine/solver/contact_pattern.hpp"

#include "engine/parallel.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace nexdyn {

ContactPattern::ContactPattern(const HessianPattern& elastic) : elastic_(elastic) {
  // Vertex column J of the elastic pattern: DOF column 3J lists rows 3I, 3I+1, 3I+2 per
  // neighbour I < J, then 3J.
  const int64_t nv = elastic.num_dofs / 3;
  elastic_neighbor_ptr_.assign(nv + 1, 0);
  for (int64_t j = 0; j < nv; ++j) {
    for (int64_t k = elastic.col_ptr[3 * j]; k < elastic.col_ptr[3 * j + 1] - 1; k += 3)
      elastic_neighbors_.push_back(static_cast<int32_t>(elastic.row_idx[k] / 3));
    elastic_neighbor_ptr_[j + 1] = static_cast<int32_t>(elastic_neighbors_.size());
  }
  merged_ = elastic;  // the CscPattern part
}

int64_t ContactPattern::block_value(int32_t i, int64_t column) const {
  const auto first = merged_.row_idx.begin() + merged_.col_ptr[column];
  const auto last = merged_.row_idx.begin() + merged_.col_ptr[column + 1];
  const auto it = std::lower_bound(first, last, 3 * int64_t{i});
  if (it == last || *it != 3 * int64_t{i}) return -1;
  return it - merged_.row_idx.begin();
}

void ContactPattern::rebuild(std::vector<std::pair<int32_t, int32_t>> pairs) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  contact_pairs_ = std::move(pairs);

  const int64_t nv = elastic_.num_dofs / 3;
  // Merged neighbours of each vertex column: sorted union of elastic and contact neighbours.
  std::vector<int32_t> ptr(nv + 1, 0), neighbors;
  neighbors.reserve(elastic_neighbors_.size() + contact_pairs_.size());
  auto contact = contact_pairs_.begin();
  for (int64_t j = 0; j < nv; ++j) {
    const size_t start = neighbors.size();
    for (int32_t k = elastic_neighbor_ptr_[j]; k < elastic_neighbor_ptr_[j + 1]; ++k)
      neighbors.push_back(elastic_neighbors_[k]);
    const size_t elastic_end = neighbors.size();
    for (; contact != contact_pairs_.end() && contact->first == j; ++contact)
      neighbors.push_back(contact->second);
    std::inplace_merge(neighbors.begin() + start, neighbors.begin() + elastic_end, neighbors.end());
    ptr[j + 1] = static_cast<int32_t>(neighbors.size());
  }

  CscPattern& p = merged_;
  p.num_dofs = elastic_.num_dofs;
  p.col_ptr.assign(p.num_dofs + 1, 0);
  for (int64_t j = 0; j < nv; ++j)
    for (int d = 0; d < 3; ++d) p.col_ptr[3 * j + d + 1] = 3 * int64_t{ptr[j + 1] - ptr[j]} + d + 1;
  for (int64_t c = 0; c < p.num_dofs; ++c) p.col_ptr[c + 1] += p.col_ptr[c];
  p.row_idx.resize(p.col_ptr.back());
  p.diagonal.resize(p.num_dofs);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t j = begin; j < end; ++j)
      for (int d = 0; d < 3; ++d) {
        int64_t k = p.col_ptr[3 * j + d];
        for (int32_t q = ptr[j]; q < ptr[j + 1]; ++q)
          for (int r = 0; r < 3; ++r) p.row_idx[k++] = 3 * int64_t{neighbors[q]} + r;
        for (int r = 0; r <= d; ++r) p.row_idx[k++] = 3 * j + r;
        p.diagonal[3 * j + d] = k - 1;
      }
  }, 1024);
  ++version_;
}

bool ContactPattern::update(const std::vector<int32_t>& stencils, bool allow_shrink) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  if (num * 144 > int64_t{UINT32_MAX})
    throw std::length_error("more than 29.8 M contact pairs in one Newton system: not supported");

  // Vertex pairs the stencils couple that the tets do not.
  auto elastic_has = [&](int32_t j, int32_t i) {
    const auto first = elastic_neighbors_.begin() + elastic_neighbor_ptr_[j];
    const auto last = elastic_neighbors_.begin() + elastic_neighbor_ptr_[j + 1];
    return std::binary_search(first, last, i);
  };
  std::vector<std::pair<int32_t, int32_t>> needed;
  for (int64_t s = 0; s < num; ++s)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) {
        const int32_t i = stencils[4 * s + a], j = stencils[4 * s + b];
        if (i >= 0 && j >= 0 && i < j && !elastic_has(j, i)) needed.emplace_back(j, i);
      }
  std::sort(needed.begin(), needed.end());
  needed.erase(std::unique(needed.begin(), needed.end()), needed.end());

  bool changed = false;
  const bool covered = std::includes(contact_pairs_.begin(), contact_pairs_.end(), needed.begin(),
                                     needed.end());
  if (!covered) {
    std::vector<std::pair<int32_t, int32_t>> all = contact_pairs_;
    all.insert(all.end(), needed.begin(), needed.end());
    rebuild(std::move(all));
    changed = true;
  } else if (allow_shrink && contact_pairs_.size() > 4 * needed.size() + 64) {
    rebuild(std::move(needed));
    changed = true;
  }

  // Gather table: count per column, prefix-sum, fill in stencil order.
  entry_ptr_.assign(merged_.num_dofs + 1, 0);
  auto for_each_block = [&](auto&& f) {
    for (int64_t s = 0; s < num; ++s)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const int32_t i = stencils[4 * s + a], j = stencils[4 * s + b];
          if (i < 0 || j < 0 || i > j) continue;
          for (int c = 0; c < 3; ++c) f(s, a, b, i, j, c);
        }
  };
  for_each_block([&](int64_t, int, int, int32_t, int32_t j, int c) { ++entry_ptr_[3 * int64_t{j} + c + 1]; });
  for (int64_t c = 0; c < merged_.num_dofs; ++c) entry_ptr_[c + 1] += entry_ptr_[c];
  entries_.resize(entry_ptr_.back());
  std::vector<int64_t> fill(entry_ptr_.begin(), entry_ptr_.end() - 1);
  for_each_block([&](int64_t s, int a, int b, int32_t i, int32_t j, int c) {
    const int64_t column = 3 * int64_t{j} + c;
    const int64_t value = block_value(i, column);
    const uint32_t length = (i == j) ? static_cast<uint32_t>(c + 1) : 3u;
    entries_[fill[column]++] = {value, static_cast<uint32_t>(s * 144 + (3 * b + c) * 12 + 3 * a), length};
  });
  return changed;
}

void ContactPattern::assemble(const double* elastic_values, const double* slabs, double* values) const {
  const CscPattern& e = elastic_;
  parallel_for(merged_.num_dofs, [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c) {
      // Elastic rows are a sorted subset of the merged rows: merge by walking both.
      int64_t k = merged_.col_ptr[c];
      const int64_t k_end = merged_.col_ptr[c + 1];
      for (int64_t q = e.col_ptr[c]; q < e.col_ptr[c + 1]; ++q) {
        while (merged_.row_idx[k] != e.row_idx[q]) values[k++] = 0.0;
        values[k++] = elastic_values[q];
      }
      for (; k < k_end; ++k) values[k] = 0.0;
      for (int64_t q = entry_ptr_[c]; q < entry_ptr_[c + 1]; ++q) {
        const Entry& en = entries_[q];
        for (uint32_t r = 0; r < en.length; ++r) values[en.value + r] += slabs[en.source + r];
      }
    }
  }, 512);
}

}  // namespace nexdyn

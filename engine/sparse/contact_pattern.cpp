// Elastic + contact Newton pattern (see contact_pattern.hpp).
#include "engine/sparse/contact_pattern.hpp"

#include "engine/parallel.hpp"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace nexdyn {

ContactPattern::ContactPattern(const HessianPattern& elastic, std::vector<std::pair<int32_t, int32_t>>& pairs,
                               uint64_t& stamp)
    : elastic_(elastic), contact_pairs_(pairs), stamp_(stamp), built_stamp_(stamp) {
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
  if (!contact_pairs_.empty()) rebuild(contact_pairs_);
}

int64_t ContactPattern::block_value(int32_t i, int64_t column) const {
  const auto first = merged_.row_idx.begin() + merged_.col_ptr[column];
  const auto last = merged_.row_idx.begin() + merged_.col_ptr[column + 1];
  const auto it = std::lower_bound(first, last, 3 * int64_t{i});
  if (it == last || *it != 3 * int64_t{i}) return -1;
  return it - merged_.row_idx.begin();
}

bool ContactPattern::sync() {
  if (stamp_ == built_stamp_) return false;
  rebuild(contact_pairs_);
  return true;
}

void ContactPattern::rebuild(std::vector<std::pair<int32_t, int32_t>> pairs) {
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  contact_pairs_ = std::move(pairs);
  // Every list of pairs built gets a name of its own, so a history copied back over a newer one
  // (whose name the pattern holds) is always seen as different.
  static std::atomic<uint64_t> last_stamp{0};
  stamp_ = built_stamp_ = ++last_stamp;

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

void ContactPattern::locate_blocks(const std::vector<int32_t>& stencils) {
  const int64_t num = static_cast<int64_t>(stencil_size_.size());
  parallel_for(num, [&](int64_t begin, int64_t end) {
    for (int64_t s = begin; s < end; ++s) {
      const int32_t* v = &stencils[4 * s];
      int64_t k = block_begin_[s];
      for (int a = 0; a < stencil_size_[s]; ++a)
        for (int b = a; b < stencil_size_[s]; ++b, ++k) {
          const int32_t i = std::min(v[a], v[b]), j = std::max(v[a], v[b]);
          block_value_[k] = i < 0 ? kHeld : block_value(i, 3 * int64_t{j});
        }
    }
  }, 1024);
}

bool ContactPattern::update(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin,
                            bool allow_shrink) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  if (slab_begin[num] > int64_t{UINT32_MAX})
    throw std::length_error("over 4.29 G contact Hessian values in one Newton system: not supported");
  layout_blocks(stencils, slab_begin);
  const bool changed = fit_pairs(stencils, allow_shrink);
  if (changed) locate_blocks(stencils);
  build_gather_table(stencils, slab_begin);
  return changed;
}

void ContactPattern::layout_blocks(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  stencil_size_.resize(num);
  block_begin_.resize(num + 1);
  block_begin_[0] = 0;
  for (int64_t s = 0; s < num; ++s) {
    const int64_t slab = slab_begin[s + 1] - slab_begin[s];
    const int n = slab == 9 ? 1 : slab == 36 ? 2 : slab == 81 ? 3 : 4;
    stencil_size_[s] = static_cast<int8_t>(n);
    block_begin_[s + 1] = block_begin_[s] + n * (n + 1) / 2;
  }
  block_value_.resize(block_begin_[num]);
  locate_blocks(stencils);
}

bool ContactPattern::fit_pairs(const std::vector<int32_t>& stencils, bool allow_shrink) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  // Calls f(i, j, k) for every upper-triangle 3x3 block of every stencil: its vertices i <= j
  // (i = -1 when one is absent or held) and its index k into block_value_.
  auto for_each_block = [&](auto&& f) {
    for (int64_t s = 0; s < num; ++s) {
      const int32_t* v = &stencils[4 * s];
      int64_t k = block_begin_[s];
      for (int a = 0; a < stencil_size_[s]; ++a)
        for (int b = a; b < stencil_size_[s]; ++b, ++k) f(std::min(v[a], v[b]), std::max(v[a], v[b]), k);
    }
  };
  // The vertex pairs (J, I), I < J, of some stencil's blocks for which `keep` is true.
  auto pairs_where = [&](auto&& keep) {
    std::vector<std::pair<int32_t, int32_t>> pairs;
    for_each_block([&](int32_t i, int32_t j, int64_t k) {
      if (i >= 0 && i != j && keep(i, j, block_value_[k])) pairs.emplace_back(j, i);
    });
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    return pairs;
  };
  auto elastic_has = [&](int32_t i, int32_t j) {
    const auto first = elastic_neighbors_.begin() + elastic_neighbor_ptr_[j];
    const auto last = elastic_neighbors_.begin() + elastic_neighbor_ptr_[j + 1];
    return std::binary_search(first, last, i);
  };

  bool changed = false;
  if (std::find(block_value_.begin(), block_value_.end(), kAbsent) != block_value_.end()) {
    std::vector<std::pair<int32_t, int32_t>> all =
        pairs_where([](int32_t, int32_t, int64_t value) { return value == kAbsent; });
    all.insert(all.end(), contact_pairs_.begin(), contact_pairs_.end());
    rebuild(std::move(all));
    changed = true;
  } else if (allow_shrink) {
    // Distinct contact (non-elastic) blocks in use, each counted once by its value index.
    seen_.assign(merged_.nnz() / 64 + 1, 0);
    int64_t used = 0;
    for_each_block([&](int32_t i, int32_t j, int64_t k) {
      if (i < 0 || i == j || elastic_has(i, j)) return;
      uint64_t& word = seen_[block_value_[k] / 64];
      const uint64_t bit = uint64_t{1} << (block_value_[k] % 64);
      used += (word & bit) == 0;
      word |= bit;
    });
    if (static_cast<double>(contact_pairs_.size()) > kShrinkRatio * static_cast<double>(used) + kShrinkSlack) {
      rebuild(pairs_where([&](int32_t i, int32_t j, int64_t) { return !elastic_has(i, j); }));
      changed = true;
    }
  }
  return changed;
}

void ContactPattern::build_gather_table(const std::vector<int32_t>& stencils,
                                        const std::vector<int64_t>& slab_begin) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  // Gather table: a stable counting sort of the blocks by vertex column. Counting at J + 2 and
  // filling through J + 1 leaves entry_ptr_[J] at column J's first entry.
  const int64_t nv = merged_.num_dofs / 3;
  entry_ptr_.assign(nv + 2, 0);
  for (int64_t s = 0; s < num; ++s) {
    const int32_t* v = &stencils[4 * s];
    for (int a = 0; a < stencil_size_[s]; ++a)
      for (int b = a; b < stencil_size_[s]; ++b)
        if (v[a] >= 0 && v[b] >= 0) ++entry_ptr_[std::max(v[a], v[b]) + 2];
  }
  for (int64_t j = 0; j < nv; ++j) entry_ptr_[j + 2] += entry_ptr_[j + 1];
  entries_.resize(entry_ptr_[nv + 1]);
  for (int64_t s = 0; s < num; ++s) {
    const int32_t* v = &stencils[4 * s];
    const int n = stencil_size_[s];
    int64_t k = block_begin_[s];
    for (int a = 0; a < n; ++a)
      for (int b = a; b < n; ++b, ++k) {
        if (block_value_[k] == kHeld) continue;
        // The block's rows belong to the smaller vertex id, its columns to the larger.
        const int row = v[a] <= v[b] ? a : b, col = v[a] <= v[b] ? b : a;
        const Entry entry{block_value_[k], static_cast<uint32_t>(slab_begin[s] + 3 * col * 3 * n + 3 * row),
                          static_cast<uint16_t>(3 * n), static_cast<uint16_t>(a == b)};
        entries_[entry_ptr_[v[col] + 1]++] = entry;
      }
  }
}

void ContactPattern::assemble(const double* elastic_values, const std::vector<const double*>& pieces,
                              const std::vector<int64_t>& piece_begin, double* values,
                              const IndexRanges* vertices) const {
  const int last_piece = static_cast<int>(pieces.size()) - 1;
  const CscPattern& e = elastic_;
  const IndexRanges all{{0, merged_.num_dofs / 3}};
  parallel_for_ranges(vertices ? *vertices : all, 256, [&](int64_t begin, int64_t end) {
    for (int64_t j = begin; j < end; ++j)
      for (int c = 0; c < 3; ++c) {
        const int64_t column = 3 * j + c;
        // Elastic rows are a sorted subset of the merged rows: merge by walking both.
        int64_t k = merged_.col_ptr[column];
        const int64_t k_end = merged_.col_ptr[column + 1];
        for (int64_t q = e.col_ptr[column]; q < e.col_ptr[column + 1]; ++q) {
          while (merged_.row_idx[k] != e.row_idx[q]) values[k++] = 0.0;
          values[k++] = elastic_values[q];
        }
        for (; k < k_end; ++k) values[k] = 0.0;
        // DOF column 3J + c lists the same rows as 3J, shifted (and its diagonal block has c + 1).
        const int64_t shift = merged_.col_ptr[column] - merged_.col_ptr[3 * j];
        for (int64_t q = entry_ptr_[j]; q < entry_ptr_[j + 1]; ++q) {
          const Entry& en = entries_[q];
          const int rows = en.diagonal ? c + 1 : 3;
          double* out = values + en.value + shift;
          const int64_t source = en.source;
          int p = last_piece;
          while (source < piece_begin[p]) --p;
          const double* in = pieces[p] + (source - piece_begin[p]) + c * en.stride;
          for (int r = 0; r < rows; ++r) out[r] += in[r];
        }
      }
  });
}

}  // namespace nexdyn

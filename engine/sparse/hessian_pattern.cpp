// Symbolic and numeric gather of the tet Hessian (see hessian_pattern.hpp).
#include "engine/sparse/hessian_pattern.hpp"

#include "engine/parallel.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <utility>

namespace nexdyn {

HessianPattern build_tet_hessian_pattern(int32_t num_vertices, const std::vector<int32_t>& tets) {
  const int64_t num_tets = static_cast<int64_t>(tets.size()) / 4;
  if (num_tets > HessianPattern::kMaxTets)
    throw std::length_error("more than " + std::to_string(HessianPattern::kMaxTets) +
                            " tets in one Hessian: not supported");
  HessianPattern pattern;
  pattern.num_dofs = 3 * int64_t{num_vertices};

  // Vertex-level upper pattern: for every vertex J, the sorted neighbours I <= J.
  std::vector<std::pair<int32_t, int32_t>> pairs;  // (J, I) so sorting groups by column
  pairs.reserve(static_cast<size_t>(num_tets) * 10 + num_vertices);
  for (int32_t v = 0; v < num_vertices; ++v) pairs.emplace_back(v, v);  // mass diagonal
  for (int64_t t = 0; t < num_tets; ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a; b < 4; ++b) {
        const int32_t va = tets[4 * t + a], vb = tets[4 * t + b];
        pairs.emplace_back(std::max(va, vb), std::min(va, vb));
      }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());

  std::vector<int64_t> vertex_col_begin(num_vertices + 1, 0);
  for (const auto& [j, i] : pairs) ++vertex_col_begin[j + 1];
  for (int32_t v = 0; v < num_vertices; ++v) vertex_col_begin[v + 1] += vertex_col_begin[v];

  // DOF-level CSC. Column 3J+d holds, for each neighbour I < J, rows 3I..3I+2, then rows 3J..3J+d.
  pattern.col_ptr.assign(pattern.num_dofs + 1, 0);
  for (int32_t j = 0; j < num_vertices; ++j) {
    const int64_t off_diagonal = vertex_col_begin[j + 1] - vertex_col_begin[j] - 1;
    for (int d = 0; d < 3; ++d) pattern.col_ptr[3 * j + d + 1] = 3 * off_diagonal + d + 1;
  }
  for (int64_t c = 0; c < pattern.num_dofs; ++c) pattern.col_ptr[c + 1] += pattern.col_ptr[c];
  pattern.row_idx.resize(pattern.col_ptr.back());
  pattern.diagonal.resize(pattern.num_dofs);
  for (int32_t j = 0; j < num_vertices; ++j)
    for (int d = 0; d < 3; ++d) {
      int64_t k = pattern.col_ptr[3 * j + d];
      for (int64_t p = vertex_col_begin[j]; p < vertex_col_begin[j + 1]; ++p) {
        const int32_t i = pairs[p].second;
        const int rows = (i == j) ? d + 1 : 3;
        pattern.segment_value.push_back(k);
        pattern.segment_length.push_back(static_cast<uint8_t>(rows));
        for (int r = 0; r < rows; ++r) pattern.row_idx[k++] = 3 * int64_t{i} + r;
      }
      pattern.diagonal[3 * j + d] = k - 1;
    }
  // Segments were created in value order, so the segment of a first value is a binary search.
  auto segment_of = [&](int64_t first_value) {
    return std::lower_bound(pattern.segment_value.begin(), pattern.segment_value.end(), first_value) -
           pattern.segment_value.begin();
  };

  // Value index of the entry (row 3I + r, column 3J + c) with I <= J: neighbours are sorted, so a
  // binary search in vertex column J finds I, and rows of I are contiguous in every column of J.
  auto value_index = [&](int32_t i, int r, int32_t j, int c) {
    const auto first = pairs.begin() + vertex_col_begin[j];
    const auto last = pairs.begin() + vertex_col_begin[j + 1];
    const int64_t slot = std::lower_bound(first, last, std::make_pair(j, i)) - first;
    return pattern.col_ptr[3 * j + c] + 3 * slot + r;
  };

  // Gather table: count, prefix-sum, fill (tets in increasing order, so sources stay sorted).
  struct Entry { int64_t segment; uint32_t source; };
  std::vector<Entry> entries;
  entries.reserve(static_cast<size_t>(num_tets) * 26);
  for (int64_t t = 0; t < num_tets; ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) {
        const int32_t va = tets[4 * t + a], vb = tets[4 * t + b];
        if (va > vb) continue;  // the (b, a) block lands in the upper triangle
        for (int c = 0; c < 3; ++c) {
          const int64_t local_col = 3 * b + c;
          entries.push_back({segment_of(value_index(va, 0, vb, c)),
                             static_cast<uint32_t>(t * 144 + local_col * 12 + 3 * a)});
        }
      }
  const int64_t num_segments = pattern.num_segments();
  pattern.segment_source_ptr.assign(num_segments + 1, 0);
  for (const Entry& e : entries) ++pattern.segment_source_ptr[e.segment + 1];
  for (int64_t g = 0; g < num_segments; ++g)
    pattern.segment_source_ptr[g + 1] += pattern.segment_source_ptr[g];
  pattern.segment_sources.resize(entries.size());
  std::vector<int64_t> fill(pattern.segment_source_ptr.begin(), pattern.segment_source_ptr.end() - 1);
  for (const Entry& e : entries) pattern.segment_sources[fill[e.segment]++] = e.source;
  return pattern;
}

void gather_hessian_segments(const HessianPattern& pattern, const SlabSource& slab, double* values,
                             int64_t begin, int64_t end) {
  const int64_t tets_end = 144 * slab.extra_from;
  const int64_t tets_first = 144 * slab.first_tet;
  {
    for (int64_t g = begin; g < end; ++g) {
      // Rows past the segment's length read the (unused) lower triangle of a diagonal block:
      // still inside the tet's slab, and simpler than three loop variants.
      double s0 = 0.0, s1 = 0.0, s2 = 0.0;
      for (int64_t s = pattern.segment_source_ptr[g]; s < pattern.segment_source_ptr[g + 1]; ++s) {
        const int64_t source = pattern.segment_sources[s];
        const double* block =
            source < tets_end ? slab.tets + (source - tets_first) : slab.extra + (source - tets_end);
        s0 += block[0];
        s1 += block[1];
        s2 += block[2];
      }
      double* out = values + pattern.segment_value[g];
      out[0] = s0;
      if (pattern.segment_length[g] > 1) out[1] = s1;
      if (pattern.segment_length[g] > 2) out[2] = s2;
    }
  }
}

}  // namespace nexdyn

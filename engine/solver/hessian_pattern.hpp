// Symbolic phase of Hessian assembly: the sparsity pattern of the upper triangle (CSC, as CHOLMOD
// reads a symmetric matrix with stype > 0) and, for every value, the list of per-element slab
// entries that are summed into it.
//
// Numeric phase (every Newton iteration): each tet writes its projected 12x12 block into its own
// slab of 144 doubles (in parallel, no sharing), then `gather` sums slab entries into the CSC
// values column by column, always in tet order. No atomics, so the matrix is bitwise the same
// whatever the number of threads.
#pragma once

#include <cstdint>
#include <vector>

namespace nexdyn {

struct HessianPattern {
  static constexpr int64_t kMaxTets = (int64_t{1} << 32) / 144;  // 29.8 M tets

  int64_t num_dofs = 0;
  std::vector<int64_t> col_ptr;  // (num_dofs + 1) CSC column starts
  std::vector<int64_t> row_idx;  // (nnz) row of each value, sorted within a column, row <= col
  std::vector<int64_t> diagonal; // (num_dofs) value index of each diagonal entry
  // Gather table, CSR over values: value k receives slab[sources[source_ptr[k] .. source_ptr[k+1])].
  // A slab index is tet * 144 + local_col * 12 + local_row (column-major 12x12 per tet); 32 bits
  // halve the gather's index traffic and cover meshes up to kMaxTets.
  std::vector<int64_t> source_ptr;   // (nnz + 1)
  std::vector<uint32_t> sources;     // (num_tets x 78), ordered by tet within each value

  int64_t nnz() const { return static_cast<int64_t>(row_idx.size()); }
};

// Builds the pattern of a tet mesh with `num_vertices` vertices, 3 DOFs each. Throws
// std::length_error beyond HessianPattern::kMaxTets tets.
HessianPattern build_tet_hessian_pattern(int32_t num_vertices, const std::vector<int32_t>& tets);

// values[k] = sum of slab entries listed for k (parallel over values, deterministic).
void gather_hessian(const HessianPattern& pattern, const double* slab, double* values);

}  // namespace nexdyn

// Symbolic phase of Hessian assembly: the sparsity pattern of the upper triangle (CSC, as CHOLMOD
// reads a symmetric matrix with stype > 0) and, for every value, the list of per-element slab
// entries that are summed into it.
//
// Numeric phase (every Newton iteration): each tet writes its projected 12x12 block into its own
// slab of 144 doubles (in parallel, no sharing), then gather_hessian_segments sums slab entries
// into the CSC values column by column, always in tet order. No atomics, so the matrix is bitwise
// the same whatever the number of threads.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace nexdyn {

// The upper triangle of a symmetric matrix in CSC form, 3 DOFs per vertex. Every vertex column J
// holds whole 3x3 blocks: for each neighbour vertex I < J rows 3I..3I+2, then rows 3J..3J+d of
// its diagonal block (d = 0, 1, 2 for the DOF columns 3J+d).
struct CscPattern {
  int64_t num_dofs = 0;
  std::vector<int64_t> col_ptr;  // (num_dofs + 1) CSC column starts
  std::vector<int64_t> row_idx;  // (nnz) row of each value, sorted within a column, row <= col
  std::vector<int64_t> diagonal; // (num_dofs) value index of each diagonal entry

  int64_t nnz() const { return static_cast<int64_t>(row_idx.size()); }
};

struct HessianPattern : CscPattern {
  static constexpr int64_t kMaxTets = (int64_t{1} << 32) / 144;  // 29.8 M tets

  // Gather table over segments. A segment is a run of 1-3 consecutive values of one column that
  // come from one 3x3 vertex block (rows 3I..3I+2, or 3J..3J+d on the diagonal), so every tet
  // that touches it contributes 1-3 consecutive entries of its slab: one index serves them all.
  // A slab index is tet * 144 + local_col * 12 + local_row (column-major 12x12 per tet); 32 bits
  // cover meshes up to kMaxTets.
  std::vector<int64_t> segment_value;       // (num_segments) index of the segment's first value
  std::vector<uint8_t> segment_length;      // (num_segments) 1, 2 or 3 values
  std::vector<int64_t> segment_source_ptr;  // (num_segments + 1) CSR into segment_sources
  std::vector<uint32_t> segment_sources;    // (num_tets x 26) slab index of the first row,
                                            // ordered by tet within each segment

  int64_t num_segments() const { return static_cast<int64_t>(segment_value.size()); }
};

// Builds the pattern of a tet mesh with `num_vertices` vertices, 3 DOFs each. Throws
// std::length_error beyond HessianPattern::kMaxTets tets.
HessianPattern build_tet_hessian_pattern(int32_t num_vertices, const std::vector<int32_t>& tets);

// Where a gather finds the slab entries: slab index s (tet * 144 + ...) is read at
// tets[s - 144 * first_tet] below element extra_from, and at extra[s - 144 * extra_from] from it
// on. A caller can so keep the slabs of a block of tets only, and other elements' slabs (coupling
// groups, numbered after the tets) apart.
struct SlabSource {
  const double* tets = nullptr;
  int64_t first_tet = 0;
  const double* extra = nullptr;
  int64_t extra_from = std::numeric_limits<int64_t>::max() / 144;
};
// values = the sum of the slab entries of each segment of [begin, end) (each value summed in tet
// order; callers run disjoint segment ranges in parallel, so the result is the same whatever the
// thread count).
void gather_hessian_segments(const HessianPattern& pattern, const SlabSource& slab, double* values,
                             int64_t begin, int64_t end);

}  // namespace nexdyn

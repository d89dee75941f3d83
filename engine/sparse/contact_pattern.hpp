// The Newton matrix's pattern when contact couples vertices that no tet couples.
//
// Pattern = the elastic pattern plus a 3x3 block for every vertex pair of some contact stencil.
// Contact pairs come and go every iteration, but CHOLMOD's symbolic analysis is only valid for
// one pattern, and redoing it costs about as much as a factorisation. So the pattern keeps every
// pair it has been given (a superset is still a valid pattern: absent pairs are stored zeros) and
// is rebuilt only when a stencil needs a pair it lacks, or, at the start of a step, when it has
// grown well past what the current contacts need (kShrinkRatio).
//
// Values: the elastic values (in the elastic pattern's order) are merged column by column, then
// the contact slabs are added through a gather table built per active set: one entry per 3x3
// block of a stencil in the upper triangle, bucketed by vertex column and kept in stencil order
// within a column, so every value is summed in the same order whatever the number of threads.
#pragma once

#include "engine/active_subset.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {

class ContactPattern {
 public:
  // The pairs the pattern holds live in `pairs` (StepHistory::contact_pattern_pairs: sorted (J, I),
  // I < J, in range), named by `stamp`; both must outlive the pattern.
  ContactPattern(const HessianPattern& elastic, std::vector<std::pair<int32_t, int32_t>>& pairs,
                 uint64_t& stamp);

  // Rebuilds the matrix pattern from the pairs when they are not the ones it was built from (a
  // step rolled back, a checkpoint read). Returns true when it did.
  bool sync();

  // Makes the pattern hold every vertex pair of the stencils and builds their gather table.
  // stencils: (num x 4) vertex ids, -1 = no DOFs (held, or past the stencil's n vertices);
  // slab_begin: (num + 1) start of each stencil's column-major 3n x 3n slab in the slab array,
  // so n = sqrt(slab size) / 3. With allow_shrink, a pattern holding more than
  // kShrinkRatio x (the pairs the stencils need) + kShrinkSlack pairs is rebuilt to fit them.
  // Returns true when the pattern changed. Over 2^32 contact values (more than the gather
  // table's indices reach) it throws std::length_error before changing anything; NewtonSolver
  // turns that into a failed step (newton.hpp).
  bool update(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin,
              bool allow_shrink);
  // A pair the contacts no longer use is a stored zero, but CHOLMOD factorises it all the same:
  // on the folded 100x100 mat the stale pairs of a pattern kept until 4x made the factorisation
  // 1.5x dearer (docs/performance.md, issue 19 fifth round). Each rebuild costs a new symbolic
  // analysis of the islands it touches, hence a margin rather than an exact fit.
  static constexpr double kShrinkRatio = 1.5;
  static constexpr int64_t kShrinkSlack = 64;

  const CscPattern& pattern() const { return merged_; }
  // Incremented by every rebuild of the pattern.
  int64_t version() const { return version_; }
  int64_t num_contact_pairs() const { return static_cast<int64_t>(contact_pairs_.size()); }

  // values (merged nnz) = elastic values placed into the merged pattern + the sum over stencils
  // of their slabs (laid out as given to update()).
  // With vertex ranges, only those vertices' columns are written.
  // The slab array may come in pieces, one per term (the barrier's slabs, then friction's,
  // without a copy): slab index k is read from pieces[p][k - piece_begin[p]] for the last p with
  // piece_begin[p] <= k (piece_begin[0] = 0, increasing).
  void assemble(const double* elastic_values, const std::vector<const double*>& pieces,
                const std::vector<int64_t>& piece_begin, double* values, const IndexRanges* vertices = nullptr) const;
  void assemble(const double* elastic_values, const double* contact_slabs, double* values,
                const IndexRanges* vertices = nullptr) const {
    assemble(elastic_values, {contact_slabs}, {0}, values, vertices);
  }

 private:
  void rebuild(std::vector<std::pair<int32_t, int32_t>> pairs);
  // The steps of update(): each stencil's size and blocks; the pattern grown to every block (or
  // shrunk to fit, with allow_shrink), true when rebuilt; the gather table of the blocks.
  void layout_blocks(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin);
  bool fit_pairs(const std::vector<int32_t>& stencils, bool allow_shrink);
  void build_gather_table(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin);
  // Value index of the first row of block (vertex row I, DOF column c) in the merged pattern,
  // or -1 when the block is absent.
  int64_t block_value(int32_t i, int64_t column) const;

  const HessianPattern& elastic_;
  CscPattern merged_;
  int64_t version_ = 0;
  std::vector<int32_t> elastic_neighbor_ptr_;            // (num_vertices + 1) CSR
  std::vector<int32_t> elastic_neighbors_;               // vertices I < J coupled by a tet
  // Sorted (J, I), I < J, not elastic: the pairs depend on the run's history, and the pattern
  // decides the factorisation's ordering and so the last bits of every solve, so they live in the
  // StepHistory (rolled back and checkpointed with it).
  std::vector<std::pair<int32_t, int32_t>>& contact_pairs_;
  uint64_t& stamp_;          // the history's name for contact_pairs_
  uint64_t built_stamp_ = 0;  // the name of the pairs merged_ was built from

  // Value index of every block (a <= b) of every stencil: kAbsent when the pattern lacks it,
  // kHeld when a vertex has no DOFs.
  void locate_blocks(const std::vector<int32_t>& stencils);
  static constexpr int64_t kAbsent = -1, kHeld = -2;

  struct Entry {
    int64_t value;      // value index of the block's first row in its vertex's first DOF column
    uint32_t source;    // slab index of the block's first row in its first column
    uint16_t stride;    // 3n: the slab's column length
    uint16_t diagonal;  // 1 when the block is on the diagonal: DOF column c holds rows 0..c
  };
  std::vector<int8_t> stencil_size_;    // (num stencils) n
  std::vector<int64_t> block_begin_;    // (num stencils + 1) first block; n (n + 1) / 2 each
  std::vector<int64_t> block_value_;    // (blocks) value index, kAbsent or kHeld
  std::vector<uint64_t> seen_;          // (nnz / 64 + 1) bitmap of the shrink check
  std::vector<int64_t> entry_ptr_;      // (num_vertices + 2) entries of each vertex column
  std::vector<Entry> entries_;
};

}  // namespace nexdyn

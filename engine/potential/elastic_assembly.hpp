// Elastic energy, gradient and PSD-projected Hessian of all tets, and of the affine bodies'
// orthogonality potential kappa V ||A A^T - I||^2 (their elastic energy: Model::AffineBody),
// assembled in parallel.
//
// Element kernels (kernels/elasticity) write per-tet slabs indexed by tet id; the slabs are then
// gathered into global arrays in a fixed order (vertex -> its tet corners, CSC value -> its slab
// entries), so every result is bitwise independent of the thread count.
#pragma once

#include "engine/active_subset.hpp"
#include "engine/model.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

class ElasticAssembly {
 public:
  // coupling_groups: (num_groups x 4) vertex ids of extra constant Hessian terms that are not
  // tets (joints, engine/potential/joints.hpp). Their vertex pairs are in pattern(), and their 12x12 slabs
  // (coupling_slabs(), zero until written) are added to every gradient_hessian().
  // Each affine body adds a coupling group of its own after these, its four nodes, whose slab is
  // its orthogonality Hessian at the x of the last gradient_hessian().
  // block_tets: the size Hessian blocks are merged up to (see the members; tests use small ones).
  static constexpr int64_t kBlockTets = 8192;
  explicit ElasticAssembly(const Model& model, const std::vector<int32_t>& coupling_groups = {},
                           int64_t block_tets = kBlockTets);

  // Total elastic energy at positions x (3n); +inf when a neo-Hookean tet is inverted.
  double energy(const double* x) const;
  // total[g] += the energy of the tets whose moving vertices are in group g (group_of_vertex[v],
  // -1 = does not move; tets with no moving vertex are left out). Deterministic.
  void group_energy(const double* x, const int32_t* group_of_vertex, double* total) const;
  // Energy, and the gradient written (not added) into grad (3n).
  double energy_gradient(const double* x, double* grad);
  // Gradient (3n) and the projected Hessian's values in pattern() order (no mass term). With a
  // subset, only its tets are evaluated and only its vertices' gradient entries and Hessian
  // columns are written (the rest keep what they held).
  void gradient_hessian(const double* x, double* grad, double* hessian_values,
                        const ActiveSubset* subset = nullptr);
  // The Hessian values of the columns of these vertices (pattern() order).
  IndexRanges value_ranges(const IndexRanges& vertices) const {
    return mapped_ranges(vertices, [&](int64_t v) { return pattern_.col_ptr[3 * v]; });
  }

  const HessianPattern& pattern() const { return pattern_; }
  // (num_groups x 144) column-major 12x12 slabs of the coupling groups.
  double* coupling_slabs() { return coupling_hessian_.data(); }

 private:
  void gather_gradient(double* grad, int64_t vertex_begin, int64_t vertex_end) const;
  double sum_tet_energies() const;
  // The affine bodies' orthogonality energy at x, and grad += its gradient (only the bodies in
  // the subset, when given).
  double affine_energy(const double* x) const;
  void add_affine_gradient(const double* x, double* grad, const ActiveSubset* subset) const;

  const Model& model_;
  HessianPattern pattern_;
  int64_t num_groups_ = 0;               // coupling groups, the affine bodies' included
  int64_t affine_group_begin_ = 0;       // the first affine body's coupling group
  std::vector<int64_t> corner_ptr_;      // (num_vertices + 1) CSR: vertex -> its tet corners
  std::vector<int64_t> corners_;         // (4 num_tets) tet * 4 + corner, increasing per vertex
  std::vector<int64_t> vertex_segment_;  // (num_vertices + 1) first gather segment of each vertex
  std::vector<double> tet_energy_;       // (num_tets) slab
  std::vector<double> tet_gradient_;     // (num_tets x 12) slab
  // Hessian slabs are computed and gathered block by block: a block is a run of consecutive tets
  // that shares no vertex with the other tets (whole bodies, in practice), merged up to
  // kBlockTets tets (9.4 MB of slabs, work enough for every thread), so only one block's slabs
  // (1.2 KB per tet) exist at a time.
  std::vector<int64_t> block_begin_;         // (num_blocks + 1) first tet of each block
  std::vector<IndexRanges> block_vertices_;  // (num_blocks) the vertices of its tets
  IndexRanges loose_vertices_;               // vertices of no tet (coupling groups only)
  std::vector<double> block_hessian_;        // (largest block x 144) column-major 12x12 slabs
  std::vector<double> coupling_hessian_;     // (num_groups x 144) slabs of the coupling groups
};

}  // namespace nexdyn

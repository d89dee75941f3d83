// Elastic energy, gradient and PSD-projected Hessian of all tets, assembled in parallel.
//
// Element kernels (kernels/elasticity) write per-tet slabs indexed by tet id; the slabs are then
// gathered into global arrays in a fixed order (vertex -> its tet corners, CSC value -> its slab
// entries), so every result is bitwise independent of the thread count.
#pragma once

#include "engine/active_subset.hpp"
#include "engine/model.hpp"
#include "engine/solver/hessian_pattern.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

class ElasticAssembly {
 public:
  // coupling_groups: (num_groups x 4) vertex ids of extra constant Hessian terms that are not
  // tets (joints, engine/joints.hpp). Their vertex pairs are in pattern(), and their 12x12 slabs
  // (coupling_slabs(), zero until written) are added to every gradient_hessian().
  explicit ElasticAssembly(const Model& model, const std::vector<int32_t>& coupling_groups = {});

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
  double* coupling_slabs() {
    allocate_hessian_slabs();
    return tet_hessian_.data() + 144 * int64_t{model_.num_tets};
  }

 private:
  void gather_gradient(double* grad, int64_t vertex_begin, int64_t vertex_end) const;
  // The Hessian slabs exist once a Hessian or a coupling slab is asked for (1.2 KB per tet that
  // energy-only users, such as explicit schemes, never pay).
  void allocate_hessian_slabs() {
    if (tet_hessian_.empty()) tet_hessian_.assign(144 * (int64_t{model_.num_tets} + num_groups_), 0.0);
  }
  double sum_tet_energies() const;

  const Model& model_;
  HessianPattern pattern_;
  int64_t num_groups_ = 0;               // coupling groups
  std::vector<int64_t> corner_ptr_;      // (num_vertices + 1) CSR: vertex -> its tet corners
  std::vector<int64_t> corners_;         // (4 num_tets) tet * 4 + corner, increasing per vertex
  std::vector<int64_t> vertex_segment_;  // (num_vertices + 1) first gather segment of each vertex
  std::vector<double> tet_energy_;       // (num_tets) slab
  std::vector<double> tet_gradient_;     // (num_tets x 12) slab
  std::vector<double> tet_hessian_;      // ((num_tets + num_groups) x 144) slab, column-major
                                         // 12x12: the tets', then the coupling groups'
};

}  // namespace nexdyn

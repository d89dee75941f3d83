// A sum of per-tet 12x12 matrices applied without assembling it: y = sum_t S_t v_t, with S_t a
// scale times the tet's PSD-projected elastic Hessian (kernels/elasticity/elasticity_range.hpp)
// at some positions. Rayleigh damping's stiffness part (engine/terms/damping_term.hpp) and the
// matrix-free conjugate gradients of the linearised step (engine/solver/linearized_step.hpp)
// use it: seed 004's "K w without assembling K".
//
// Products run per tet in parallel into per-tet outputs, then every vertex sums its tets' outputs
// in tet order, so y is the same double on any number of threads.
#pragma once

#include "engine/model.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

class TetSlabOperator {
 public:
  explicit TetSlabOperator(const Model& model);

  // S_t = tet_scale[t] K_t(x) (zero where the scale is 0; no Hessian is computed there).
  // Returns false if a tet's Hessian is not finite (an inverted neo-Hookean tet).
  bool compute(const double* x, const std::vector<double>& tet_scale);
  // out = sum_t S_t v_t (3n, written).
  void apply(const double* v, double* out) const;
  // v_t^T S_t v_t of tet t.
  double tet_quadratic(int64_t t, const double* v) const;
  // out (3n) = the diagonal of sum_t S_t (written).
  void diagonal(double* out) const;
  // sum_t v_t^T S_t v_t, summed in a fixed order.
  double quadratic(const double* v) const;
  // The matrix's values in `pattern` (the elastic pattern of the same tets; its coupling groups
  // read zeros), written.
  void gather(const HessianPattern& pattern, double* values) const;

 private:
  // out[3v + d] = sum over v's tet corners (tet t, corner a) of value(t, 3a + d), in tet order.
  template <typename Value>
  void gather_corners(Value&& value, double* out) const;

  const Model& model_;
  std::vector<int64_t> corner_ptr_;     // (num_vertices + 1) CSR: vertex -> its tet corners
  std::vector<int64_t> corners_;        // tet * 4 + corner, in tet order per vertex
  std::vector<double> slabs_;           // (num_tets x 144) column-major 12x12
  std::vector<double> tet_gradient_;    // (num_tets x 12) scratch of the Hessian kernels
  mutable std::vector<double> tet_out_; // (num_tets x 12) scratch: S_t v_t
  mutable std::vector<double> zero_extra_;
};

}  // namespace nexdyn

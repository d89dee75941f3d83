// What the two files of ProjectiveDynamics share (projective_dynamics.cpp, the solve;
// pd_spectral_radius.cpp, the estimate of its spectral radius): the tets' gradient rows, the
// clock of the solver's statistics, and the gather of per-tet slabs onto the free vertices.
#pragma once

#include "engine/model.hpp"
#include "engine/parallel.hpp"
#include "engine/solver/projective_dynamics.hpp"

#include <Eigen/Core>

#include <chrono>
#include <cstdint>

namespace nexdyn::pd {

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// The 4x3 D of tet t (rows d_a): F = sum_a x_a d_a^T. Rows 1..3 are the rows of Dm^-1
// (column-major in the model), row 0 minus their sum.
inline void tet_rows(const Model& model, int64_t t, Eigen::Vector3d d[4]) {
  const double* m = model.Dm_inv.data() + 9 * t;
  for (int i = 0; i < 3; ++i) d[i + 1] = Eigen::Vector3d(m[i], m[3 + i], m[6 + i]);
  d[0] = -(d[1] + d[2] + d[3]);
}

}  // namespace nexdyn::pd

namespace nexdyn {

template <typename TetFn>
void ProjectiveDynamics::tet_to_vertices(TetFn&& fn, std::vector<double>& out) {
  double* slab = slab_.data();
  parallel_for(model_.num_tets, [&](int64_t begin, int64_t end) {
    for (int64_t t = begin; t < end; ++t) fn(t, slab + 12 * t);
  }, kPdTetGrain);
  const int64_t nf = num_free_;
  out.resize(3 * nf);
  parallel_for(nf, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      double sum[3] = {0.0, 0.0, 0.0};
      for (int64_t k = corner_ptr_[i]; k < corner_ptr_[i + 1]; ++k) {
        const double* c = slab + 3 * corners_[k];  // tet * 12 + corner * 3
        for (int d = 0; d < 3; ++d) sum[d] += c[d];
      }
      for (int d = 0; d < 3; ++d) out[d * nf + i] = sum[d];
    }
  }, kPdVertexGrain);
}

}  // namespace nexdyn

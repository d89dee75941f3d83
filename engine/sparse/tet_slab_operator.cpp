#include "engine/sparse/tet_slab_operator.hpp"

#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity_range.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

namespace {
constexpr int64_t kTetGrain = 64;
constexpr int64_t kVertexGrain = 1024;

// v_t: the 12 entries of tet t's corners.
inline void tet_values(const int32_t* tet, const double* v, double* vt) {
  for (int c = 0; c < 4; ++c)
    for (int d = 0; d < 3; ++d) vt[3 * c + d] = v[3 * int64_t{tet[c]} + d];
}
}  // namespace

template <typename Value>
void TetSlabOperator::gather_corners(Value&& value, double* out) const {
  parallel_for(model_.num_vertices, [&](int64_t b, int64_t e) {
    for (int64_t v = b; v < e; ++v)
      for (int d = 0; d < 3; ++d) {
        double sum = 0.0;
        for (int64_t k = corner_ptr_[v]; k < corner_ptr_[v + 1]; ++k) {
          const int64_t c = corners_[k];
          sum += value(c / 4, 3 * (c % 4) + d);
        }
        out[3 * v + d] = sum;
      }
  }, kVertexGrain);
}

TetSlabOperator::TetSlabOperator(const Model& model) : model_(model) {
  const int32_t n = model.num_vertices;
  corner_ptr_.assign(n + 1, 0);
  for (int32_t v : model.tets) ++corner_ptr_[v + 1];
  for (int32_t v = 0; v < n; ++v) corner_ptr_[v + 1] += corner_ptr_[v];
  corners_.resize(model.tets.size());
  std::vector<int64_t> next(corner_ptr_.begin(), corner_ptr_.end() - 1);
  for (int64_t c = 0; c < static_cast<int64_t>(model.tets.size()); ++c) corners_[next[model.tets[c]]++] = c;
  slabs_.assign(144 * static_cast<size_t>(model.num_tets), 0.0);
  tet_gradient_.assign(12 * static_cast<size_t>(model.num_tets), 0.0);
  tet_out_.assign(12 * static_cast<size_t>(model.num_tets), 0.0);
}

bool TetSlabOperator::compute(const double* x, const std::vector<double>& tet_scale) {
  const TetRange range{x, model_.tets.data(), model_.Dm_inv.data(), model_.rest_volume.data()};
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    parallel_for(batch.tet_end - batch.tet_begin, [&](int64_t b, int64_t e) {
      const int64_t begin = batch.tet_begin + b, end = batch.tet_begin + e;
      hessian_range(mat.model, range, begin, end, mat.lame, tet_gradient_.data(), slabs_.data());
      for (int64_t t = begin; t < end; ++t) {
        const double scale = tet_scale[t];
        for (int64_t i = 144 * t; i < 144 * (t + 1); ++i) slabs_[i] = scale == 0.0 ? 0.0 : scale * slabs_[i];
      }
    }, kTetGrain);
  }
  return deterministic_sum(model_.num_tets, [&](int64_t b, int64_t e) {
    double bad = 0.0;
    for (int64_t i = 144 * b; i < 144 * e; ++i) bad += std::isfinite(slabs_[i]) ? 0.0 : 1.0;
    return bad;
  }, kTetGrain) == 0.0;
}

double TetSlabOperator::tet_quadratic(int64_t t, const double* v) const {
  double vt[12];
  tet_values(&model_.tets[4 * t], v, vt);
  const double* S = &slabs_[144 * t];
  double sum = 0.0;
  for (int col = 0; col < 12; ++col) {
    double row = 0.0;
    for (int r = 0; r < 12; ++r) row += S[12 * col + r] * vt[r];
    sum += vt[col] * row;
  }
  return sum;
}

double TetSlabOperator::quadratic(const double* v) const {
  return deterministic_sum(model_.num_tets, [&](int64_t b, int64_t e) {
    double sum = 0.0;
    for (int64_t t = b; t < e; ++t) sum += tet_quadratic(t, v);
    return sum;
  }, kTetGrain);
}

void TetSlabOperator::apply(const double* v, double* out) const {
  parallel_for(model_.num_tets, [&](int64_t b, int64_t e) {
    for (int64_t t = b; t < e; ++t) {
      double vt[12];
      tet_values(&model_.tets[4 * t], v, vt);
      const double* S = &slabs_[144 * t];
      double* o = &tet_out_[12 * t];
      for (int r = 0; r < 12; ++r) o[r] = 0.0;
      for (int col = 0; col < 12; ++col)
        for (int r = 0; r < 12; ++r) o[r] += S[12 * col + r] * vt[col];
    }
  }, kTetGrain);
  gather_corners([&](int64_t t, int64_t local) { return tet_out_[12 * t + local]; }, out);
}

void TetSlabOperator::diagonal(double* out) const {
  gather_corners([&](int64_t t, int64_t local) { return slabs_[144 * t + 13 * local]; }, out);
}

void TetSlabOperator::gather(const HessianPattern& pattern, double* values) const {
  // The gather table also reads the slabs of the pattern's coupling groups (joints), numbered
  // after the tets: zeros here.
  int64_t extra = 1;
  for (uint32_t s : pattern.segment_sources)
    extra = std::max<int64_t>(extra, static_cast<int64_t>(s) / 144 + 1 - model_.num_tets);
  zero_extra_.assign(144 * static_cast<size_t>(extra), 0.0);
  const SlabSource source{slabs_.data(), 0, zero_extra_.data(), model_.num_tets};
  parallel_for(pattern.num_segments(), [&](int64_t b, int64_t e) {
    gather_hessian_segments(pattern, source, values, b, e);
  }, 2048);
}

}  // namespace nexdyn

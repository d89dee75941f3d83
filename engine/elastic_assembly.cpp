// Parallel elastic assembly over material batches (see elastic_assembly.hpp).
#include "engine/elastic_assembly.hpp"

#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity_range.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

namespace {
// Tets per parallel chunk: a Hessian chunk is 64 x 1.2 KB of output, a comfortable L2 working set.
constexpr int64_t kTetGrain = 64;

TetRange tet_range(const Model& m, const double* x) {
  return TetRange{x, m.tets.data(), m.Dm_inv.data(), m.rest_volume.data()};
}
}  // namespace

namespace {
std::vector<int32_t> concatenated(const std::vector<int32_t>& a, const std::vector<int32_t>& b) {
  std::vector<int32_t> out(a);
  out.insert(out.end(), b.begin(), b.end());
  return out;
}
}  // namespace

ElasticAssembly::ElasticAssembly(const Model& model, const std::vector<int32_t>& coupling_groups)
    : model_(model),
      pattern_(build_tet_hessian_pattern(model.num_vertices, coupling_groups.empty()
                                                                 ? model.tets
                                                                 : concatenated(model.tets, coupling_groups))) {
  const int64_t nv = model.num_vertices, nt = model.num_tets;
  corner_ptr_.assign(nv + 1, 0);
  for (int64_t c = 0; c < 4 * nt; ++c) ++corner_ptr_[model.tets[c] + 1];
  for (int64_t v = 0; v < nv; ++v) corner_ptr_[v + 1] += corner_ptr_[v];
  corners_.resize(4 * nt);
  std::vector<int64_t> fill(corner_ptr_.begin(), corner_ptr_.end() - 1);
  for (int64_t c = 0; c < 4 * nt; ++c) corners_[fill[model.tets[c]]++] = c;
  tet_energy_.resize(nt);
  tet_gradient_.resize(12 * nt);
  num_groups_ = static_cast<int64_t>(coupling_groups.size() / 4);
  // Segments are in value order, and a vertex's columns are contiguous values.
  vertex_segment_.resize(nv + 1);
  for (int64_t v = 0; v <= nv; ++v)
    vertex_segment_[v] = std::lower_bound(pattern_.segment_value.begin(), pattern_.segment_value.end(),
                                          pattern_.col_ptr[3 * v]) - pattern_.segment_value.begin();
}

double ElasticAssembly::energy(const double* x) const {
  const TetRange range = tet_range(model_, x);
  double total = 0.0;
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    total += deterministic_sum(batch.tet_end - batch.tet_begin, [&](int64_t b, int64_t e) {
      return energy_range(mat.model, range, batch.tet_begin + b, batch.tet_begin + e, mat.lame);
    }, kTetGrain);
  }
  return total;
}

void ElasticAssembly::group_energy(const double* x, const int32_t* group_of_vertex, double* total) const {
  const TetRange range = tet_range(model_, x);
  const int32_t* tets = model_.tets.data();
  auto group_of = [&](int64_t t) {
    for (int c = 0; c < 4; ++c)
      if (group_of_vertex[tets[4 * t + c]] >= 0) return group_of_vertex[tets[4 * t + c]];
    return -1;
  };
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    const int64_t first = batch.tet_begin;
    grouped_sum(batch.tet_end - batch.tet_begin, kTetGrain,
                [&](int64_t i) { return group_of(first + i); },
                [&](int64_t b, int64_t e) { return energy_range(mat.model, range, first + b, first + e, mat.lame); },
                total);
  }
}

double ElasticAssembly::sum_tet_energies() const {
  double total = 0.0;
  for (double e : tet_energy_) total += e;
  return total;
}

void ElasticAssembly::gather_gradient(double* grad, int64_t vertex_begin, int64_t vertex_end) const {
  {
    for (int64_t v = vertex_begin; v < vertex_end; ++v) {
      double g[3] = {0.0, 0.0, 0.0};
      for (int64_t k = corner_ptr_[v]; k < corner_ptr_[v + 1]; ++k) {
        const double* slab = tet_gradient_.data() + 3 * corners_[k];  // 12 t + 3 corner
        g[0] += slab[0];
        g[1] += slab[1];
        g[2] += slab[2];
      }
      grad[3 * v + 0] = g[0];
      grad[3 * v + 1] = g[1];
      grad[3 * v + 2] = g[2];
    }
  }
}

double ElasticAssembly::energy_gradient(const double* x, double* grad) {
  const TetRange range = tet_range(model_, x);
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    parallel_for(batch.tet_end - batch.tet_begin, [&](int64_t b, int64_t e) {
      gradient_range(mat.model, range, batch.tet_begin + b, batch.tet_begin + e, mat.lame,
                     tet_energy_.data(), tet_gradient_.data());
    }, kTetGrain);
  }
  parallel_for(model_.num_vertices, [&](int64_t b, int64_t e) { gather_gradient(grad, b, e); }, 1024);
  return sum_tet_energies();
}

void ElasticAssembly::gradient_hessian(const double* x, double* grad, double* hessian_values,
                                       const ActiveSubset* subset) {
  allocate_hessian_slabs();
  const TetRange range = tet_range(model_, x);
  const IndexRanges all_tets{{0, model_.num_tets}};
  const IndexRanges& tets = subset ? subset->tets : all_tets;
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    IndexRanges in_batch;
    for (const auto& [b, e] : tets) {
      const int64_t lo = std::max<int64_t>(b, batch.tet_begin), hi = std::min<int64_t>(e, batch.tet_end);
      if (lo < hi) in_batch.emplace_back(lo, hi);
    }
    parallel_for_ranges(in_batch, kTetGrain, [&](int64_t b, int64_t e) {
      hessian_range(mat.model, range, b, e, mat.lame, tet_gradient_.data(), tet_hessian_.data());
    });
  }
  if (!subset) {
    parallel_for(model_.num_vertices, [&](int64_t b, int64_t e) { gather_gradient(grad, b, e); }, 1024);
    gather_hessian(pattern_, tet_hessian_.data(), hessian_values);
    return;
  }
  parallel_for_ranges(subset->vertices, 1024, [&](int64_t b, int64_t e) { gather_gradient(grad, b, e); });
  const IndexRanges segments = mapped_ranges(subset->vertices, [&](int64_t v) { return vertex_segment_[v]; });
  parallel_for_ranges(segments, 2048, [&](int64_t b, int64_t e) {
    gather_hessian_segments(pattern_, tet_hessian_.data(), hessian_values, b, e);
  });
}

}  // namespace nexdyn

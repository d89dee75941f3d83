// Parallel elastic assembly over material batches (see elastic_assembly.hpp).
#include "engine/elastic_assembly.hpp"

#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity_range.hpp"

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

double ElasticAssembly::sum_tet_energies() const {
  double total = 0.0;
  for (double e : tet_energy_) total += e;
  return total;
}

void ElasticAssembly::gather_gradient(double* grad) const {
  parallel_for(model_.num_vertices, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
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
  }, 1024);
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
  gather_gradient(grad);
  return sum_tet_energies();
}

void ElasticAssembly::gradient_hessian(const double* x, double* grad, double* hessian_values) {
  allocate_hessian_slabs();
  const TetRange range = tet_range(model_, x);
  for (const MaterialBatch& batch : model_.material_batches) {
    const Material& mat = model_.materials[batch.material];
    parallel_for(batch.tet_end - batch.tet_begin, [&](int64_t b, int64_t e) {
      hessian_range(mat.model, range, batch.tet_begin + b, batch.tet_begin + e, mat.lame,
                    tet_gradient_.data(), tet_hessian_.data());
    }, kTetGrain);
  }
  gather_gradient(grad);
  gather_hessian(pattern_, tet_hessian_.data(), hessian_values);
}

}  // namespace nexdyn

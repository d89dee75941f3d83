// Parallel elastic assembly over material batches (see elastic_assembly.hpp).
#include "engine/potential/elastic_assembly.hpp"

#include "engine/parallel.hpp"
#include "kernels/affine/affine_body.hpp"
#include "kernels/elasticity/elasticity_range.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

namespace {
// Tets per parallel chunk: a Hessian chunk is 64 x 1.2 KB of output, a comfortable L2 working set.
constexpr int64_t kTetGrain = 64;
// Affine bodies per parallel chunk (one 9x9 projected Hessian each).
constexpr int64_t kAffineGrain = 64;

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

// The coupling groups after the given ones: each affine body's four nodes [p, c_0, c_1, c_2],
// whose 12x12 slab holds its orthogonality Hessian. p's rows and columns are zero (p meets the
// c_j only through contact), but it is in the group so that a body's four nodes are always in
// one island and one line-search group, as the coordinate map needs: a follower moves with all
// four (engine/coordinate_map.hpp).
std::vector<int32_t> with_affine_groups(const Model& model, const std::vector<int32_t>& groups) {
  std::vector<int32_t> out(groups);
  for (const AffineBody& body : model.affine_bodies)
    for (int k = 0; k < 4; ++k) out.push_back(body.node + k);
  return out;
}

// The kernel's A for an affine body: rows c_0, c_1, c_2, so A = (A_body R)^T, whose singular
// values, hence ||A A^T - I||, are the body's; its gradient and Hessian come in node order.
Eigen::Matrix3d axis_rows(const AffineBody& body, const double* x) {
  Eigen::Matrix3d A;
  for (int j = 0; j < 3; ++j) A.row(j) = Eigen::Vector3d::Map(x + 3 * int64_t{body.node + 1 + j});
  return A;
}

// kappa V: the orthogonality potential's weight.
double orthogonality_weight(const AffineBody& body) { return body.stiffness * body.volume; }
}  // namespace

ElasticAssembly::ElasticAssembly(const Model& model, const std::vector<int32_t>& coupling_groups,
                                 int64_t block_tets)
    : model_(model),
      pattern_(build_tet_hessian_pattern(
          model.num_vertices, coupling_groups.empty() && model.affine_bodies.empty()
                                  ? model.tets
                                  : concatenated(model.tets, with_affine_groups(model, coupling_groups)))) {
  const int64_t nv = model.num_vertices, nt = model.num_tets;
  corner_ptr_.assign(nv + 1, 0);
  for (int64_t c = 0; c < 4 * nt; ++c) ++corner_ptr_[model.tets[c] + 1];
  for (int64_t v = 0; v < nv; ++v) corner_ptr_[v + 1] += corner_ptr_[v];
  corners_.resize(4 * nt);
  std::vector<int64_t> fill(corner_ptr_.begin(), corner_ptr_.end() - 1);
  for (int64_t c = 0; c < 4 * nt; ++c) corners_[fill[model.tets[c]]++] = c;
  tet_energy_.resize(nt);
  tet_gradient_.resize(12 * nt);
  affine_group_begin_ = static_cast<int64_t>(coupling_groups.size() / 4);
  num_groups_ = affine_group_begin_ + static_cast<int64_t>(model.affine_bodies.size());
  // Segments are in value order, and a vertex's columns are contiguous values.
  vertex_segment_.resize(nv + 1);
  for (int64_t v = 0; v <= nv; ++v)
    vertex_segment_[v] = std::lower_bound(pattern_.segment_value.begin(), pattern_.segment_value.end(),
                                          pattern_.col_ptr[3 * v]) - pattern_.segment_value.begin();
  coupling_hessian_.assign(144 * num_groups_, 0.0);

  // Blocks: tet t ends a closed run when no vertex of a tet <= t appears in a later tet; runs are
  // merged up to block_tets (a longer run is a block of its own).
  std::vector<int64_t> last_tet(nv, -1);
  for (int64_t c = 0; c < 4 * nt; ++c) last_tet[model.tets[c]] = c / 4;
  block_begin_.assign(1, 0);
  int64_t reach = -1;
  for (int64_t t = 0; t < nt; ++t) {
    for (int c = 0; c < 4; ++c) reach = std::max(reach, last_tet[model.tets[4 * t + c]]);
    if (reach != t) continue;
    if (block_begin_.size() >= 2 && t + 1 - block_begin_[block_begin_.size() - 2] <= block_tets)
      block_begin_.back() = t + 1;  // the run joins the last block
    else
      block_begin_.push_back(t + 1);
  }
  const int64_t num_blocks = static_cast<int64_t>(block_begin_.size()) - 1;
  block_vertices_.assign(num_blocks, {});
  for (int64_t v = 0; v < nv; ++v) {
    if (last_tet[v] < 0) {
      append_index(loose_vertices_, v);
      continue;
    }
    const int64_t k = std::upper_bound(block_begin_.begin(), block_begin_.end(), last_tet[v]) -
                      block_begin_.begin() - 1;
    append_index(block_vertices_[k], v);
  }
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
  return total + affine_energy(x);
}

double ElasticAssembly::affine_energy(const double* x) const {
  const std::vector<AffineBody>& bodies = model_.affine_bodies;
  if (bodies.empty()) return 0.0;
  return deterministic_sum(static_cast<int64_t>(bodies.size()), [&](int64_t b, int64_t e) {
    double sum = 0.0;
    for (int64_t k = b; k < e; ++k)
      sum += orthogonality_weight(bodies[k]) * orthogonality_energy(axis_rows(bodies[k], x));
    return sum;
  }, kAffineGrain);
}

void ElasticAssembly::add_affine_gradient(const double* x, double* grad, const ActiveSubset* subset) const {
  const std::vector<AffineBody>& bodies = model_.affine_bodies;
  parallel_for(static_cast<int64_t>(bodies.size()), [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) {
      const AffineBody& body = bodies[k];
      if (subset && !subset->vertex_mask[body.node]) continue;
      const AffineVector9 g = orthogonality_weight(body) * orthogonality_gradient(axis_rows(body, x));
      for (int i = 0; i < 9; ++i) grad[3 * int64_t{body.node + 1} + i] += g[i];
    }
  }, kAffineGrain);
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
  const std::vector<AffineBody>& bodies = model_.affine_bodies;
  if (bodies.empty()) return;
  grouped_sum(static_cast<int64_t>(bodies.size()), kAffineGrain,
              [&](int64_t k) { return group_of_vertex[bodies[k].node]; },
              [&](int64_t b, int64_t e) {
                double sum = 0.0;
                for (int64_t k = b; k < e; ++k)
                  sum += orthogonality_weight(bodies[k]) * orthogonality_energy(axis_rows(bodies[k], x));
                return sum;
              },
              total);
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
  add_affine_gradient(x, grad, nullptr);
  return sum_tet_energies() + affine_energy(x);
}

void ElasticAssembly::gradient_hessian(const double* x, double* grad, double* hessian_values,
                                       const ActiveSubset* subset) {
  const TetRange range = tet_range(model_, x);
  const IndexRanges all_tets{{0, model_.num_tets}};
  const IndexRanges all_vertices{{0, model_.num_vertices}};
  const IndexRanges& tets = subset ? subset->tets : all_tets;
  const IndexRanges& vertices = subset ? subset->vertices : all_vertices;
  auto gather_columns = [&](const IndexRanges& columns, const SlabSource& source) {
    const IndexRanges segments = mapped_ranges(columns, [&](int64_t v) { return vertex_segment_[v]; });
    parallel_for_ranges(segments, 2048, [&](int64_t b, int64_t e) {
      gather_hessian_segments(pattern_, source, hessian_values, b, e);
    });
  };

  // Block by block: the slabs of its tets (those in the subset), then its vertices' columns.
  SlabSource source{nullptr, 0, coupling_hessian_.data(), model_.num_tets};
  for (size_t k = 0; k + 1 < block_begin_.size(); ++k) {
    const IndexRanges in_block = intersect_ranges(tets, {{block_begin_[k], block_begin_[k + 1]}});
    if (in_block.empty()) continue;
    const int64_t first = block_begin_[k];
    block_hessian_.resize(std::max<size_t>(block_hessian_.size(), 144 * (block_begin_[k + 1] - first)));
    // The kernels index their output by tet: shift the tet arrays so block tet `first` is tet 0.
    const TetRange shifted{x, range.tets + 4 * first, range.Dm_inv + 9 * first, range.volume + first};
    for (const MaterialBatch& batch : model_.material_batches) {
      const Material& mat = model_.materials[batch.material];
      IndexRanges in_batch;
      for (const auto& [b, e] : intersect_ranges(in_block, {{batch.tet_begin, batch.tet_end}}))
        in_batch.emplace_back(b - first, e - first);
      parallel_for_ranges(in_batch, kTetGrain, [&](int64_t b, int64_t e) {
        hessian_range(mat.model, shifted, b, e, mat.lame, tet_gradient_.data() + 12 * first,
                      block_hessian_.data());
      });
    }
    source.tets = block_hessian_.data();
    source.first_tet = first;
    gather_columns(intersect_ranges(vertices, block_vertices_[k]), source);
  }
  // Affine bodies' orthogonality Hessians into their coupling slabs (p's rows and columns zero).
  const std::vector<AffineBody>& bodies = model_.affine_bodies;
  parallel_for(static_cast<int64_t>(bodies.size()), [&](int64_t b, int64_t e) {
    for (int64_t k = b; k < e; ++k) {
      const AffineBody& body = bodies[k];
      if (subset && !subset->vertex_mask[body.node]) continue;
      const AffineMatrix9 H = orthogonality_weight(body) * orthogonality_hessian_for_turns(axis_rows(body, x));
      Eigen::Map<Eigen::Matrix<double, 12, 12>> slab(coupling_hessian_.data() + 144 * (affine_group_begin_ + k));
      slab.setZero();
      slab.bottomRightCorner<9, 9>() = H;
    }
  }, kAffineGrain);
  gather_columns(intersect_ranges(vertices, loose_vertices_), source);  // coupling slabs only
  parallel_for_ranges(vertices, 1024, [&](int64_t b, int64_t e) { gather_gradient(grad, b, e); });
  add_affine_gradient(x, grad, subset);
}

}  // namespace nexdyn

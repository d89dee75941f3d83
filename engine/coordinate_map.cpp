// The map between nodes and vertex positions (see coordinate_map.hpp).
#include "engine/coordinate_map.hpp"

#include "engine/active_subset.hpp"
#include "engine/parallel.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

namespace nexdyn {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Slab size (entries) -> the stencil's width n, as the contact pattern reads it.
int width_of_slab(int64_t entries) {
  return entries == 9 ? 1 : entries == 36 ? 2 : entries == 81 ? 3 : 4;
}

// The sub-stencils of a stencil over K nodes (coordinate_map.hpp): one when 0 < K <= 4; else the
// nodes in chunks of two, chunk i = positions [2i, 2i + 2), and one sub-stencil per pair of
// chunks i < j in lexicographic order, holding chunk i's nodes then chunk j's.
int num_chunks(int K) { return (K + 1) / 2; }
int num_sub_stencils(int K) {
  if (K <= 4) return K > 0 ? 1 : 0;  // none for a stencil of held vertices only
  const int m = num_chunks(K);
  return m * (m - 1) / 2;
}

// The positions (into the K nodes) of sub-stencil `sub`'s nodes; returns how many.
int sub_stencil_positions(int K, int sub, int* positions) {
  if (K <= 4) {
    for (int a = 0; a < K; ++a) positions[a] = a;
    return K;
  }
  const int m = num_chunks(K);
  int i = 0, j = 1;
  for (int s = 0; s < sub; ++s)
    if (++j == m) j = ++i + 1;
  int n = 0;
  for (int chunk : {i, j})
    for (int a = 2 * chunk; a < std::min(2 * chunk + 2, K); ++a) positions[n++] = a;
  return n;
}

// Which sub-stencil carries the 3x3 block of nodes at positions a and b: the pair of their
// chunks, or for two nodes of one chunk i the first pair holding i, (0, 1) or (0, i).
int owner_of_block(int K, int a, int b) {
  if (K <= 4) return 0;
  const int m = num_chunks(K);
  int i = std::min(a / 2, b / 2), j = std::max(a / 2, b / 2);
  if (i == j) {
    if (i == 0) j = 1;
    else j = i, i = 0;
  }
  // Index of pair (i, j) in lexicographic order.
  return i * (2 * m - i - 1) / 2 + (j - i - 1);
}

}  // namespace

CoordinateMap::CoordinateMap(const Model& model) : model_(model) {}

int CoordinateMap::turn(const double* x, const double* direction, const int32_t* group_of_vertex,
                        const double* group_alpha, double* trial) const {
  int turned = 0;
  for (const AffineBody& body : model_.affine_bodies) {
    const int32_t g = group_of_vertex[body.node];
    if (g < 0) continue;
    Eigen::Matrix3d C, D;
    for (int j = 0; j < 3; ++j) {
      C.col(j) = Eigen::Vector3d::Map(x + 3 * int64_t{body.node + 1 + j});
      D.col(j) = Eigen::Vector3d::Map(direction + 3 * int64_t{body.node + 1 + j});
    }
    if (D.squaredNorm() == 0.0 || !(C.determinant() > 0.0)) continue;
    const double alpha = group_alpha[g];
    const Eigen::Matrix3d M = alpha * D * C.inverse();
    const Eigen::Matrix3d W = 0.5 * (M - M.transpose());
    const Eigen::Matrix3d E = 0.5 * (M + M.transpose());
    const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));  // W's axial vector: a turn by |w|
    const double theta = w.norm();
    if (!(theta > 1e-9)) continue;
    const Eigen::Matrix3d turned_c =
        Eigen::AngleAxisd(theta, w / theta).toRotationMatrix() * (Eigen::Matrix3d::Identity() + E) * C;
    double* q = trial + 3 * int64_t{body.node};
    for (int j = 0; j < 3; ++j) Eigen::Vector3d::Map(q + 3 * (j + 1)) = turned_c.col(j);
    for (int64_t v = body.follower_begin; v < body.follower_begin + body.follower_count; ++v) {
      const double* y = &model_.follower_rest[3 * v];
      for (int d = 0; d < 3; ++d) trial[3 * v + d] = q[d] + y[0] * q[3 + d] + y[1] * q[6 + d] + y[2] * q[9 + d];
    }
    ++turned;
  }
  return turned;
}

void CoordinateMap::turn_pads(const double* x, const double* direction, const uint8_t* moves, double* pad) const {
  std::fill_n(pad, model_.num_vertices, 0.0);
  parallel_for(static_cast<int64_t>(model_.affine_bodies.size()), [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      const AffineBody& body = model_.affine_bodies[b];
      if (!moves[body.node]) continue;
      Eigen::Matrix3d C, D;
      for (int j = 0; j < 3; ++j) {
        C.col(j) = Eigen::Vector3d::Map(x + 3 * int64_t{body.node + 1 + j});
        D.col(j) = Eigen::Vector3d::Map(direction + 3 * int64_t{body.node + 1 + j});
      }
      if (D.squaredNorm() == 0.0 || !(C.determinant() > 0.0)) continue;  // turn() leaves it straight
      // M = D C^-1 = W + E. The turned axes R (I + E) C against the chord's (I + W + E) C differ
      // by ((R - I - W) + (R - I) E) C, with R = exp(W) a turn by theta = |w|:
      // |R - I - W| <= (theta - sin theta) + (1 - cos theta), |R - I| <= 2 sin(theta / 2), both
      // growing with theta up to pi (and at most 2 beyond), |E| <= |E|_F. A smaller alpha scales
      // theta and E down, so the bound at alpha = 1 holds for every trial.
      const Eigen::Matrix3d M = D * C.inverse();
      const Eigen::Matrix3d W = 0.5 * (M - M.transpose());
      const double e_norm = (0.5 * (M + M.transpose())).norm();
      const double theta = Eigen::Vector3d(W(2, 1), W(0, 2), W(1, 0)).norm();
      const double bend = theta < kPi ? 1.0 - std::cos(theta) : 2.0;
      const double chord = theta < kPi ? 2.0 * std::sin(0.5 * theta) : 2.0;
      const double factor = (theta - std::sin(theta)) + bend + chord * e_norm;
      const Eigen::Vector3d p = Eigen::Vector3d::Map(x + 3 * int64_t{body.node});
      for (int64_t v = body.follower_begin; v < body.follower_begin + body.follower_count; ++v)
        pad[v] = factor * (Eigen::Vector3d::Map(x + 3 * v) - p).norm();
    }
  }, 64);
}

VertexNodes CoordinateMap::nodes_of(int32_t v) const {
  VertexNodes out;
  if (v < 0) return out;
  if (!follows(v)) {
    out.node[0] = v;
    out.weight[0] = 1.0;
    out.count = 1;
    return out;
  }
  const AffineBody& body = model_.affine_bodies[model_.follows[v]];
  out.count = 4;
  out.node[0] = body.node;
  out.weight[0] = 1.0;
  for (int j = 0; j < 3; ++j) {
    out.node[1 + j] = body.node + 1 + j;
    out.weight[1 + j] = model_.follower_rest[3 * int64_t{v} + j];
  }
  return out;
}

void CoordinateMap::follow(double* x) const {
  if (identity()) return;
  parallel_for(model_.num_vertices, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const int32_t b = model_.follows[v];
      if (b < 0) continue;
      const int64_t node = model_.affine_bodies[b].node;
      const double* y = &model_.follower_rest[3 * v];
      for (int d = 0; d < 3; ++d)
        x[3 * v + d] = x[3 * node + d] + y[0] * x[3 * (node + 1) + d] + y[1] * x[3 * (node + 2) + d] +
                       y[2] * x[3 * (node + 3) + d];
    }
  }, 1024);
}

void CoordinateMap::fit_nodes(double* x) const {
  if (identity()) return;
  for (const AffineBody& body : model_.affine_bodies) {
    if (model_.dirichlet[body.node] >= 0) continue;  // a held body keeps its nodes
    Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
    Eigen::Matrix<double, 4, 3> right = Eigen::Matrix<double, 4, 3>::Zero();
    for (int64_t v = body.follower_begin; v < body.follower_begin + body.follower_count; ++v) {
      const Eigen::Vector4d w(1.0, model_.follower_rest[3 * v], model_.follower_rest[3 * v + 1],
                              model_.follower_rest[3 * v + 2]);
      normal += w * w.transpose();
      right += w * Eigen::RowVector3d::Map(x + 3 * v);
    }
    const Eigen::Matrix<double, 4, 3> nodes = normal.ldlt().solve(right);
    for (int k = 0; k < 4; ++k) Eigen::RowVector3d::Map(x + 3 * (int64_t{body.node} + k)) = nodes.row(k);
  }
  follow(x);
}

void CoordinateMap::fold_gradient(double* g) const {
  if (identity()) return;
  const int64_t num_bodies = static_cast<int64_t>(model_.affine_bodies.size());
  parallel_for(num_bodies, [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      const AffineBody& body = model_.affine_bodies[b];
      double* gp = g + 3 * int64_t{body.node};
      for (int64_t v = body.follower_begin; v < body.follower_begin + body.follower_count; ++v) {
        const double* y = &model_.follower_rest[3 * v];
        for (int d = 0; d < 3; ++d) {
          const double gv = g[3 * v + d];
          gp[d] += gv;
          gp[3 + d] += y[0] * gv;
          gp[6 + d] += y[1] * gv;
          gp[9 + d] += y[2] * gv;
          g[3 * v + d] = 0.0;
        }
      }
    }
  }, 16);
}

int CoordinateMap::stencil_nodes_of(const int32_t* ids, int64_t slab, VertexNodes* vertices, int32_t* nodes) const {
  const int k = width_of_slab(slab);
  for (int i = 0; i < k; ++i) vertices[i] = nodes_of(ids[i]);
  const int K = stencil_nodes(vertices, k, nodes);
  if (K < 0) throw std::logic_error("a stencil touches more than two affine bodies");
  std::sort(nodes, nodes + K);  // one order for every stencil over these nodes
  return K;
}

void CoordinateMap::map_stencils(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin,
                                 MappedStencils& out) const {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  // Groups by node set, numbered in order of first appearance.
  using NodeSet = std::array<int32_t, kMaxStencilNodes>;
  struct NodeSetHash {
    size_t operator()(const NodeSet& key) const {
      uint64_t h = 1469598103934665603ull;  // FNV-1a
      for (int32_t node : key) h = (h ^ static_cast<uint32_t>(node)) * 1099511628211ull;
      return static_cast<size_t>(h);
    }
  };
  std::unordered_map<NodeSet, int64_t, NodeSetHash> group_of_set;
  group_of_set.reserve(static_cast<size_t>(num));
  std::vector<int64_t> group_of_source(num, -1);
  out.nodes.clear();
  VertexNodes vertices[4];
  for (int64_t s = 0; s < num; ++s) {
    NodeSet key;
    key.fill(-1);
    const int K = stencil_nodes_of(&stencils[4 * s], slab_begin[s + 1] - slab_begin[s], vertices, key.data());
    if (K == 0) continue;  // held vertices only: nothing to map
    const auto [it, fresh] = group_of_set.try_emplace(key, static_cast<int64_t>(group_of_set.size()));
    if (fresh) out.nodes.insert(out.nodes.end(), key.begin(), key.end());
    group_of_source[s] = it->second;
  }
  const int64_t groups = static_cast<int64_t>(group_of_set.size());
  // Each group's sources, ascending (a counting sort over the sources in order).
  out.source_begin.assign(groups + 1, 0);
  for (int64_t g : group_of_source)
    if (g >= 0) ++out.source_begin[g + 1];
  for (int64_t g = 0; g < groups; ++g) out.source_begin[g + 1] += out.source_begin[g];
  out.sources.resize(out.source_begin[groups]);
  std::vector<int64_t> fill(out.source_begin.begin(), out.source_begin.end() - 1);
  for (int64_t s = 0; s < num; ++s)
    if (group_of_source[s] >= 0) out.sources[fill[group_of_source[s]]++] = s;
  // Each group's sub-stencils.
  out.first.assign(groups + 1, 0);
  out.stencils.clear();
  out.slab_begin.assign(1, 0);
  int positions[4];
  for (int64_t g = 0; g < groups; ++g) {
    const int32_t* nodes = &out.nodes[kMaxStencilNodes * g];
    const int K = static_cast<int>(std::count_if(nodes, nodes + kMaxStencilNodes, [](int32_t v) { return v >= 0; }));
    const int subs = num_sub_stencils(K);
    for (int sub = 0; sub < subs; ++sub) {
      const int n = sub_stencil_positions(K, sub, positions);
      for (int a = 0; a < 4; ++a) out.stencils.push_back(a < n ? nodes[positions[a]] : -1);
      out.slab_begin.push_back(out.slab_begin.back() + 9 * n * n);
    }
    out.first[g + 1] = out.first[g] + subs;
  }
}

void CoordinateMap::map_coupling(const std::vector<int32_t>& stencils, std::vector<int32_t>& out) const {
  // Every id counts (coupling lists have no slabs): width 4.
  std::vector<int64_t> slab_begin(stencils.size() / 4 + 1);
  for (size_t s = 0; s < slab_begin.size(); ++s) slab_begin[s] = 144 * static_cast<int64_t>(s);
  MappedStencils mapped;
  map_stencils(stencils, slab_begin, mapped);
  out = std::move(mapped.stencils);
}

void CoordinateMap::map_slabs(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin,
                              const double* slabs, const MappedStencils& mapped, double* out,
                              const uint8_t* active) const {
  parallel_for(mapped.num_groups(), [&](int64_t begin, int64_t end) {
    VertexNodes vertices[4];
    int32_t nodes[kMaxStencilNodes];
    double one[9 * kMaxStencilNodes * kMaxStencilNodes];
    double sum[9 * kMaxStencilNodes * kMaxStencilNodes];
    int positions[4];
    for (int64_t g = begin; g < end; ++g) {
      const int64_t* source = &mapped.sources[mapped.source_begin[g]];
      const int64_t count = mapped.source_begin[g + 1] - mapped.source_begin[g];
      if (!touches(&stencils[4 * source[0]], active)) continue;
      int K = 0;
      for (int64_t i = 0; i < count; ++i) {
        const int64_t s = source[i];
        const int64_t size = slab_begin[s + 1] - slab_begin[s];
        K = stencil_nodes_of(&stencils[4 * s], size, vertices, nodes);
        map_stencil_hessian_upper(vertices, width_of_slab(size), slabs + slab_begin[s], nodes, K, i == 0 ? sum : one);
        if (i > 0)
          for (int c = 0, N = 3 * K; c < N; ++c)
            for (int r = 0; r <= c; ++r) sum[c * N + r] += one[c * N + r];
      }
      mirror_upper(sum, K);
      const int N = 3 * K;
      for (int64_t sub = mapped.first[g]; sub < mapped.first[g + 1]; ++sub) {
        const int local = static_cast<int>(sub - mapped.first[g]);
        const int n = sub_stencil_positions(K, local, positions);
        double* slab = out + mapped.slab_begin[sub];
        for (int b = 0; b < n; ++b)
          for (int a = 0; a < n; ++a) {
            const bool mine = owner_of_block(K, positions[a], positions[b]) == local;
            for (int c = 0; c < 3; ++c)
              for (int r = 0; r < 3; ++r)
                slab[(3 * b + c) * 3 * n + 3 * a + r] =
                    mine ? sum[(3 * positions[b] + c) * N + 3 * positions[a] + r] : 0.0;
          }
      }
    }
  }, 64);
}

void CoordinateMap::follow_groups(int32_t* group) const {
  if (identity()) return;
  for (const AffineBody& body : model_.affine_bodies)
    std::fill_n(group + body.follower_begin, body.follower_count, group[body.node]);
}

}  // namespace nexdyn

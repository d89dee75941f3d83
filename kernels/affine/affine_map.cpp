// The coordinate map of one stencil (see affine_map.hpp).
#include "kernels/affine/affine_map.hpp"

#include <algorithm>

namespace nexdyn {

namespace {

// The place of `node` among the stencil's nodes.
int local_node(const int32_t* nodes, int K, int32_t node) {
  return static_cast<int>(std::find(nodes, nodes + K, node) - nodes);
}

}  // namespace

int stencil_nodes(const VertexNodes* vertices, int k, int32_t* nodes) {
  int K = 0;
  for (int i = 0; i < k; ++i)
    for (int t = 0; t < vertices[i].count; ++t) {
      const int32_t node = vertices[i].node[t];
      if (local_node(nodes, K, node) < K) continue;
      if (K == kMaxStencilNodes) return -1;
      nodes[K++] = node;
    }
  return K;
}

void map_stencil_hessian_upper(const VertexNodes* vertices, int k, const double* slab, const int32_t* nodes, int K,
                               double* mapped) {
  const int n = 3 * k, N = 3 * K;
  int local[4][4];
  for (int i = 0; i < k; ++i)
    for (int t = 0; t < vertices[i].count; ++t) local[i][t] = local_node(nodes, K, vertices[i].node[t]);
  for (int c = 0; c < N; ++c) std::fill(mapped + c * N, mapped + c * N + c + 1, 0.0);
  // The upper triangle, block (a, b) with a <= b: H_ij's share in it is w_ia w_jb H_ij (the
  // blocks a > b get theirs from H_ji by the mirror below).
  for (int j = 0; j < k; ++j)
    for (int tj = 0; tj < vertices[j].count; ++tj) {
      const int b = local[j][tj];
      for (int i = 0; i < k; ++i)
        for (int ti = 0; ti < vertices[i].count; ++ti) {
          const int a = local[i][ti];
          if (a > b) continue;
          const double w = vertices[i].weight[ti] * vertices[j].weight[tj];
          for (int s = 0; s < 3; ++s)
            for (int r = 0; r < (a == b ? s + 1 : 3); ++r)
              mapped[(3 * b + s) * N + 3 * a + r] += w * slab[(3 * j + s) * n + 3 * i + r];
        }
    }
}

void mirror_upper(double* mapped, int K) {
  const int N = 3 * K;
  for (int c = 0; c < N; ++c)
    for (int r = c + 1; r < N; ++r) mapped[c * N + r] = mapped[r * N + c];
}

void map_stencil_hessian(const VertexNodes* vertices, int k, const double* slab, const int32_t* nodes, int K,
                         double* mapped) {
  map_stencil_hessian_upper(vertices, k, slab, nodes, K, mapped);
  mirror_upper(mapped, K);
}

void map_stencil_gradient(const VertexNodes* vertices, int k, const double* gradient, const int32_t* nodes, int K,
                          double* mapped) {
  std::fill(mapped, mapped + 3 * K, 0.0);
  for (int i = 0; i < k; ++i)
    for (int t = 0; t < vertices[i].count; ++t) {
      const int a = local_node(nodes, K, vertices[i].node[t]);
      for (int d = 0; d < 3; ++d) mapped[3 * a + d] += vertices[i].weight[t] * gradient[3 * i + d];
    }
}

}  // namespace nexdyn

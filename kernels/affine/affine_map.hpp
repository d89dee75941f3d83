// The map from coordinates to vertex positions, one stencil at a time.
//
// A vertex of a tet body is its own coordinate node. A vertex of an affine body with rest
// coordinates y (in the body's principal frame, about its centre of mass) moves as
//   x = p + y_0 c_0 + y_1 c_1 + y_2 c_2,
// p and the columns c_j of the body's matrix being its four nodes: its Jacobian is
// [I, y_0 I, y_1 I, y_2 I], scalar weights on 3x3 identity blocks. So every vertex is a weighted
// sum of at most four nodes, x_i = sum_t w_it q_{n_it}, and a term written over vertex positions
// (contact, friction, joints) becomes one over nodes by the chain rule:
//   gradient  g_a = sum_i w_ia g_i                        (J^T g)
//   Hessian   H_ab = sum_i sum_j w_ia w_jb H_ij           (J^T H J, per 3x3 block)
// A projected (PSD) vertex Hessian stays PSD. Every vertex path is linear in q, so a straight
// step in q moves every vertex on a straight line and the CCD needs no change.
#pragma once

#include <cstdint>

namespace nexdyn {

// How one vertex moves: x = sum_t weight[t] q_{node[t]}, t < count (1 for a tet vertex, 4 for an
// affine one: p, c_0, c_1, c_2 with weights 1, y_0, y_1, y_2).
struct VertexNodes {
  int32_t node[4] = {-1, -1, -1, -1};
  double weight[4] = {0.0, 0.0, 0.0, 0.0};
  int count = 0;
};

// The most nodes a mapped stencil can touch: a contact stencil pairs primitives of two bodies,
// 4 nodes each when both are affine.
inline constexpr int kMaxStencilNodes = 8;

// The nodes of the stencil whose k vertices move as `vertices` (k <= 4), each node once, in the
// order the vertices first name them. Returns their number K (<= kMaxStencilNodes), or -1 when
// there would be more.
int stencil_nodes(const VertexNodes* vertices, int k, int32_t* nodes);

// J^T H J: `slab` is the column-major 3k x 3k Hessian over the k vertices, `mapped` (3K x 3K,
// column-major) receives it over the K nodes from stencil_nodes. Exactly symmetric when `slab`
// is: each mapped entry sums the same products in the same order as its mirror.
void map_stencil_hessian(const VertexNodes* vertices, int k, const double* slab, const int32_t* nodes, int K,
                         double* mapped);
// The same in two parts, for sums of several stencils over one node set: the upper triangle
// (row <= column; the rest of `mapped` is left as it was), then its mirror into the lower one.
// Upper triangles summed, then mirrored once, equal the sum of the mirrored ones bit for bit.
void map_stencil_hessian_upper(const VertexNodes* vertices, int k, const double* slab, const int32_t* nodes, int K,
                               double* mapped);
void mirror_upper(double* mapped, int K);

// J^T g: `gradient` (3k) over the k vertices, `mapped` (3K) over the K nodes.
void map_stencil_gradient(const VertexNodes* vertices, int k, const double* gradient, const int32_t* nodes, int K,
                          double* mapped);

}  // namespace nexdyn

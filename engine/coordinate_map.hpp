// The one layer between the coordinates Newton solves for and the vertex positions every term is
// written in (issue 40, affine bodies).
//
// The unknowns are "nodes", 3 DOFs each, stored in the vertex arrays: a vertex of a tet body is
// its own node; an affine body (Model::affine_bodies) adds four node vertices p, c_0, c_1, c_2
// (kernels/affine/affine_map.hpp), and its surface vertices *follow* them:
//   x_v = p + y_0 c_0 + y_1 c_1 + y_2 c_2,   y = Model::follower_rest of v.
// A follower is no unknown: Newton holds it like an eliminated vertex. Every term still sees
// vertex positions (contact, friction, CCD and output need no change), and this map carries what
// the terms produce over to the nodes by the chain rule (J the vertex Jacobian):
//   positions   x_followers = J q                        follow()
//   gradient    g_nodes += J^T g_followers                fold_gradient()
//   Hessian     the slabs of stencil terms, J^T H J        map_stencils(), map_slabs()
//   direction   p_followers = J p_nodes (the map is linear, so a straight step in q moves every
//               follower on a straight line and the CCD sweeps it unchanged)   follow()
// A mapped stencil touches up to 8 nodes (two affine bodies). Stencils over the same nodes (the
// contacts of one pair of bodies: tens of them in a pile) are summed into one node stencil,
// J^T (sum of their H) J, so that the contact pattern, its assembly and the islands see one
// stencil per pair of bodies, not one per contact. The contact pattern, the islands and the slab
// terms work in stencils of 4 vertices, so a node stencil of more than 4 nodes is cut into
// sub-stencils of at most 4: its nodes in chunks of two, one sub-stencil per pair of chunks, each
// 3x3 block copied into exactly one of them (so their sum is the node stencil's matrix).
//
// A model without affine bodies has the identity map (identity() true): callers skip it and the
// engine's results stay bit for bit those of a tet-only engine.
#pragma once

#include "engine/model.hpp"
#include "kernels/affine/affine_map.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

// Stencils over nodes (num x 4, -1 = none) made from stencils over vertices, with the slab
// layout of their J^T H J pieces. The source stencils over one set of nodes form a group; each
// group is one node stencil, cut into sub-stencils.
struct MappedStencils {
  std::vector<int32_t> stencils;       // (num x 4) node ids of the sub-stencils
  std::vector<int64_t> slab_begin;     // (num + 1) start of each sub-stencil's 3n x 3n slab
  std::vector<int64_t> first;          // (groups + 1) each group's first sub-stencil
  std::vector<int32_t> nodes;          // (groups x kMaxStencilNodes) its nodes, ascending, -1 past K
  std::vector<int64_t> source_begin;   // (groups + 1) into sources
  std::vector<int64_t> sources;        // each group's source stencils, ascending
  int64_t num_groups() const { return static_cast<int64_t>(first.size()) - 1; }
};

class CoordinateMap {
 public:
  explicit CoordinateMap(const Model& model);

  bool identity() const { return model_.affine_bodies.empty(); }
  bool follows(int32_t v) const { return model_.follows_body(v); }
  // How vertex v moves (a node: itself with weight 1; -1: count 0).
  VertexNodes nodes_of(int32_t v) const;

  // x (3 per vertex) at every follower from the nodes: positions, or a direction.
  void follow(double* x) const;
  // The other way: each affine body's nodes (p, c_0, c_1, c_2 rows of x) set to the affine field
  // closest to its followers' values in least squares, then the followers to that field: exact
  // for a field the body can carry (a rigid or affine motion). Scripted velocities use it.
  void fit_nodes(double* x) const;
  // g at the nodes += J^T g at the followers, whose entries are then zeroed (they are no
  // unknowns). Per body, in vertex order: the same bits on any number of threads.
  void fold_gradient(double* g) const;
  // The node stencils of `stencils` (num x 4 vertex ids, -1 = none), with slab sizes; `slab_begin`
  // gives each source slab's size (3n x 3n, n its used width). Groups are numbered in the order
  // of their first source: the same on any number of threads.
  void map_stencils(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin,
                    MappedStencils& out) const;
  // The node stencils of `stencils` for coupling alone (islands, thawing): no slab sizes.
  void map_coupling(const std::vector<int32_t>& stencils, std::vector<int32_t>& out) const;
  // out (mapped.slab_begin.back() values) = the sub-stencils' slabs of J^T (sum of H) J over
  // each group, H the source slabs (`slabs`, laid out by `slab_begin`) of the stencils `mapped`
  // was made from, summed in source order. With `active` (a vertex mask, as ActiveSubset's), only
  // the groups touching an active vertex (the sources of a group touch the same bodies): the
  // others' sub-stencils touch no active node, and an assembly over the active columns reads none.
  void map_slabs(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin, const double* slabs,
                 const MappedStencils& mapped, double* out, const uint8_t* active = nullptr) const;
  // The line search's trial point, turned: each affine body whose first node is in a moving group
  // (group_of_vertex[node] >= 0) takes the step alpha = group_alpha[group] of `direction` from x
  // as a turn by exp(alpha W) after the stretch alpha E, W and E the skew and symmetric parts of
  // D C^-1 (C the axis nodes at x, D their direction), instead of along the chord C + alpha D,
  // which stretches the body by (alpha theta)^2 / 2. Writes the axis nodes and the followers of
  // those bodies into trial (whose p nodes must already be x + alpha d); returns how many turned.
  int turn(const double* x, const double* direction, const int32_t* group_of_vertex, const double* group_alpha,
           double* trial) const;
  // How far turn() can take each follower from the chord point x + alpha d, for any alpha in
  // [0, 1] and any scaling of `direction` by at most 1: pad[v] (num_vertices, written; 0 but for
  // the followers of bodies whose first node moves[]). A sweep padded by it covers the turned
  // trial points (BarrierPotential::sweep), so they need no search of their own.
  void turn_pads(const double* x, const double* direction, const uint8_t* moves, double* pad) const;
  // group[v] of every follower = the group of its body's first node (-1 = does not move).
  void follow_groups(int32_t* group) const;

 private:
  // The nodes of source stencil s (width 4, slab size from `slab`), ascending, and its vertices'
  // nodes.
  int stencil_nodes_of(const int32_t* ids, int64_t slab, VertexNodes* vertices, int32_t* nodes) const;

  const Model& model_;
};

}  // namespace nexdyn

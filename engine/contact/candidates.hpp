// Contact candidates: the primitive pairs whose distance may be below a threshold somewhere on a
// linear motion x0 -> x1 (DESIGN.md section 5; issue 3, "broad phase").
//
// The collision mesh is the Model's surface (all bodies and obstacle meshes) plus its analytic
// obstacle planes. Pairs are vertex-triangle, edge-edge and vertex-plane. Pairs that can never be
// a contact are dropped here, once, so every later stage loops over useful pairs only:
//   * a vertex against a triangle it is a corner of, and two edges sharing a vertex (adjacent);
//   * pairs with no free vertex (all four Dirichlet-held, e.g. two triangles of one obstacle):
//     nothing in the solve can move them, so they carry no force and no CCD limit.
//
// Broad phase (candidates.cpp): Embree finds the pairs of bodies whose boxes overlap; then each
// primitive scans, in id order, the primitives of its own body and those of each neighbouring
// body that lie within its body's box (a tree query for lists too long to scan).
// A primitive's box covers it at x0 and at x1, so by convexity it covers the primitive at every
// point of the motion; inflated by r on every side, two boxes overlap whenever the primitives
// come within 2 r of each other at some time in [0, 1]. Pairs within one body are boxed in the
// body's co-moving frame (its mean displacement taken out of x1): distances within the body are
// the same in that frame, and a body falling a long way no longer pairs every primitive with
// every other one on its path. Output lists are sorted and equal to the brute-force reference
// (same boxes, same frames) whatever the number of threads.
#pragma once

#include "bvh/broad_phase.hpp"
#include "engine/model.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace nexdyn {

struct ContactCandidates {
  std::vector<IndexPair> vertex_triangle;  // (vertex id, surface triangle index), sorted
  std::vector<IndexPair> edge_edge;        // (surface edge a, surface edge b), a < b, sorted
  std::vector<IndexPair> vertex_plane;     // (vertex id, obstacle plane index), sorted

  int64_t size() const {
    return static_cast<int64_t>(vertex_triangle.size() + edge_edge.size() + vertex_plane.size());
  }
  void clear() {
    vertex_triangle.clear();
    edge_edge.clear();
    vertex_plane.clear();
  }
};

// The vertex ids of a pair, in the order of its barrier stencil (kernels/barrier/barrier_stencils.hpp):
// vertex-triangle p, t0, t1, t2; edge-edge ea0, ea1, eb0, eb1; vertex-plane v, then -1s.
using PairVertices = std::array<int32_t, 4>;

inline PairVertices vertex_triangle_vertices(const Model& m, const IndexPair& pair) {
  const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
  return {pair.first, t[0], t[1], t[2]};
}
inline PairVertices edge_edge_vertices(const Model& m, const IndexPair& pair) {
  const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
  const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
  return {ea[0], ea[1], eb[0], eb[1]};
}
inline PairVertices vertex_plane_vertices(const IndexPair& pair) { return {pair.first, -1, -1, -1}; }

// Calls f(list, vertices_of) for the three lists in order: `list` a pointer to the member of
// ContactCandidates (so that one call can walk the same list of several sets of candidates),
// vertices_of(pair) the pair's PairVertices.
template <typename F>
void for_each_pair_list(const Model& m, F&& f) {
  f(&ContactCandidates::vertex_triangle, [&m](const IndexPair& pair) { return vertex_triangle_vertices(m, pair); });
  f(&ContactCandidates::edge_edge, [&m](const IndexPair& pair) { return edge_edge_vertices(m, pair); });
  f(&ContactCandidates::vertex_plane, [](const IndexPair& pair) { return vertex_plane_vertices(pair); });
}

// Every non-adjacent pair with a free vertex, not both of one affine body (they keep their
// distance), that may come closer than 2 * inflation along
// x0 -> x1 (positions (num_vertices x 3)); x1 == nullptr means the static configuration x0.
// Vertex-plane pairs: the vertex's signed distance to the plane is below 2 * inflation at x0 or
// x1 (it is linear in time, so that covers the whole motion).
// With `moving` (num_vertices flags), "free" means moving[v] instead of not Dirichlet-held: only
// pairs with a vertex that moves are found, and the work is that of the moving bodies only
// (for re-searching after a motion of a few bodies, barrier_potential.cpp).
// With `pad` (num_vertices), each vertex's box is widened by pad[v] more: the pairs cover any
// path that stays within pad[v] of the segment x0 -> x1 (an affine body's turned trial points,
// CoordinateMap::turn_pads).
void find_contact_candidates(const Model& model, const double* x0, const double* x1,
                             double inflation, ContactCandidates& out, const uint8_t* moving = nullptr,
                             const double* pad = nullptr);

// The O(n^2) reference with the same contract, for tests.
void find_contact_candidates_brute_force(const Model& model, const double* x0, const double* x1,
                                         double inflation, ContactCandidates& out,
                                         const uint8_t* moving = nullptr, const double* pad = nullptr);

}  // namespace nexdyn

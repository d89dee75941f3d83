// The contact active set: which candidate pairs (candidates.hpp) are closer than dhat at x, and
// the contact stencils they form. The barrier and friction potentials evaluate their derivatives
// over these stencils (barrier_potential.hpp, friction_potential.hpp).
//
// Two parts:
//   * a per-candidate cache: each pair's squared distance and closest feature at the positions it
//     was last computed at. A Newton iteration moves only the islands not yet converged, so most
//     pairs keep their numbers from one iteration to the next; refresh() recomputes only the pairs
//     that are new or have a vertex whose position changed (compared exactly). A pair whose
//     primitives' bounding boxes are farther apart than dhat is inactive without its distance
//     kernel: its cached distance is then that box gap, a lower bound (at least dhat^2); so is
//     an inactive pair whose cached distance, less how far each side moved since, is still
//     beyond dhat: its distance becomes that difference;
//   * the stencils, one per closest feature rather than one per active pair: a vertex facing a
//     vertex of another surface is the closest point of several vertex-triangle and edge-edge
//     pairs, all with the same point-point distance, so their barriers are the same number. Pairs
//     whose closest feature is point-point or point-edge are merged into one stencil per feature
//     (its sorted vertex ids) with an integer multiplicity, and a stencil's energy and derivatives
//     are multiplicity x one evaluation (as ipc-toolkit does). Point-triangle interiors, edge-edge
//     interiors and mollified (nearly parallel) edge-edge pairs are unique per pair and stay one
//     stencil each; a mollified pair keeps all 4 vertices because its mollifier depends on all.
//
// Stencil order: unique stencils in candidate order, then merged ones by first vertex; fixed
// chunks and a stable counting sort keep it independent of the number of threads. stencils()
// lists each stencil's vertex ids padded to 4 (vertex-triangle: p, t0, t1, t2; edge-edge: ea0,
// ea1, eb0, eb1; point-edge: p, e0 < e1; point-point: a < b; vertex-plane: v); absent and
// eliminated held vertices are -1, the latter because their rows and columns are eliminated from
// the Newton system anyway. A stencil of n vertices (1 vertex-plane, 2 point-point, 3 point-edge,
// 4 otherwise) has a 3n x 3n Hessian slab.
#pragma once

#include "engine/contact/candidates.hpp"
#include "engine/model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace nexdyn {

// Closest feature of a stencil; decides its size and derivative kernel
// (kernels/barrier/barrier_stencils.hpp).
enum class ContactStencilKind : uint8_t {
  vertex_plane, point_point, point_edge, point_triangle, edge_edge, edge_edge_mollified
};
int contact_stencil_size(ContactStencilKind kind);  // vertices n: the slab is 3n x 3n

class ContactActiveSet {
 public:
  // dhat2: squared activation distance [m^2].
  ContactActiveSet(const Model& model, double dhat2);

  // ---- per-candidate cache
  // The candidate list was replaced: nothing cached is known any more.
  void forget_pairs(const ContactCandidates& candidates) { known_.assign(static_cast<size_t>(candidates.size()), 0); }
  // The candidate list was rebuilt from kept pairs and new ones: new pair i was old pair
  // origin[i] (-1: new, unknown) of the old_size of before. Kept pairs keep their entries.
  void carry_pairs(int64_t old_size, const std::vector<int64_t>& origin);
  // Brings every candidate's squared distance and closest feature up to date at x.
  void refresh(const ContactCandidates& candidates, const double* x);
  // Smallest squared distance over the candidates at x (refreshes; +inf without candidates):
  // exact when below dhat^2, else a lower bound that is at least dhat^2 (see the top).
  double min_squared_distance(const ContactCandidates& candidates, const double* x);
  // A lower bound on candidate i's distance at any x: its cached distance less how far each of
  // its two sides (vertices s[0, split) and s[split, 4)) is from where it was cached at most
  // (at the x of the last refresh: the cached distance, exact below dhat), from `motion`, each
  // vertex's distance from there (motion_since_cache at that x). -1 when the cache does not know
  // the pair or the bound is not positive. [m]
  void motion_since_cache(const double* x, std::vector<double>& motion) const;
  // The bodies of candidate i's two sides (a vertex-plane pair: its vertex's body, then -1),
  // where known_ is set.
  struct SideBodies {
    int32_t first = -1, second = -1;
  };
  // Per body, the largest motion_since_cache of the vertices pairs are made of (an affine body's
  // nodes left out: they are no points of its surface), from `motion` (NaN: +inf).
  void body_motion_since_cache(const std::vector<double>& motion, std::vector<double>& body_motion) const;
  // distance_bound from each side's body's largest motion instead of the pair's own vertices':
  // never above it, bit for bit (the sums and differences of larger numbers), and read without
  // the pair's vertices. -1 for an unknown pair, a vertex-plane pair or a bound not positive.
  double body_distance_bound(int64_t i, const double* body_motion) const {
    if (!knows_side_bodies(i)) return -1.0;
    const SideBodies& b = side_bodies_[i];
    const double bound = std::sqrt(distance_[i]) - (body_motion[b.first] + body_motion[b.second]);
    return bound > 0.0 ? bound : -1.0;  // (NaN: -1)
  }
  // Whether side_bodies(i) is known (a vertex-triangle or edge-edge pair the cache knows).
  bool knows_side_bodies(int64_t i) const {
    return i < static_cast<int64_t>(known_.size()) && known_[i] && side_bodies_[i].second >= 0;
  }
  const SideBodies& side_bodies(int64_t i) const { return side_bodies_[i]; }
  double distance_bound(int64_t i, const PairVertices& s, int split, const double* motion) const {
    if (i >= static_cast<int64_t>(known_.size()) || !known_[i]) return -1.0;
    double side[2] = {0.0, 0.0};
    for (int k = 0; k < 4; ++k) side[k >= split] = std::max(side[k >= split], motion[s[k]]);
    const double bound = std::sqrt(distance_[i]) - (side[0] + side[1]);
    return bound > 0.0 ? bound : -1.0;  // (NaN: -1)
  }

  // ---- stencils
  // The active set at x: candidates closer than dhat, merged into stencils (see the top).
  void build(const ContactCandidates& candidates, const double* x);
  // Candidate pairs closer than dhat (the sum of the multiplicities).
  int64_t num_active_pairs() const { return num_active_pairs_; }
  int64_t num_stencils() const { return static_cast<int64_t>(kind_.size()); }
  const std::vector<ContactStencilKind>& kinds() const { return kind_; }  // (num_stencils)
  // (num_stencils x 4) real vertex ids, held ones included; vertex-plane: v, plane index.
  const std::vector<int32_t>& vertices() const { return vertices_; }
  const std::vector<int32_t>& multiplicities() const { return multiplicity_; }  // (num_stencils)
  // (num_stencils) The closest-feature case (EdgeEdgeCase) of each edge-edge stencil at the x of
  // the build, which the mollified kernel would otherwise classify again; 0 for other kinds.
  const std::vector<uint8_t>& edge_edge_cases() const { return edge_edge_case_; }
  const std::vector<int32_t>& stencils() const { return stencils_; }            // (num_stencils x 4)
  const std::vector<int64_t>& slab_begin() const { return slab_begin_; }        // (num_stencils + 1)

 private:
  // A point-point (c = -1) or point-edge feature before merging: its vertices in key order.
  struct FeatureKey {
    int32_t a, b, c;  // point-point: a < b; point-edge: point a, edge b < c
  };
  // The passes of build().
  void count_active(const ContactCandidates& candidates);
  void list_unique_and_features(const ContactCandidates& candidates);
  void merge_features();
  void finish_stencils();

  const Model& model_;
  double dhat2_ = 0.0;

  // Cache, per candidate (vertex-triangle, then edge-edge, then vertex-plane): its squared
  // distance and code (0 inactive, else closest feature + 1, see active_set.cpp) at positions_,
  // valid where known_ is set.
  std::vector<double> positions_;         // (3 num_vertices) where the cached numbers were computed
  std::vector<double> vertex_motion_;     // (num_vertices) workspace of refresh() [m]
  std::vector<uint8_t> known_;            // (candidates)
  std::vector<double> distance_;          // (candidates) [m^2]
  std::vector<uint8_t> code_;             // (candidates)
  std::vector<SideBodies> side_bodies_;   // (candidates)
  std::vector<uint8_t> carried_known_, carried_code_;  // workspaces of carry_pairs()
  std::vector<double> carried_distance_;
  std::vector<SideBodies> carried_side_bodies_;

  // Workspace of build(), kept to avoid allocation per iteration.
  std::vector<int64_t> chunk_unique_begin_;     // (chunks + 1) unique stencils before each chunk
  std::vector<int64_t> chunk_feature_begin_;    // (chunks + 1) mergeable pairs before each chunk
  std::vector<FeatureKey> features_;            // (mergeable pairs) in candidate order
  std::vector<FeatureKey> features_by_vertex_;  // the same, bucketed by a
  std::vector<int64_t> vertex_feature_begin_;   // (num_vertices + 2) bucket of each vertex
  std::vector<int64_t> vertex_stencil_begin_;   // (num_vertices + 1) first merged stencil of each

  // The active set of the last build().
  int64_t num_active_pairs_ = 0;
  std::vector<ContactStencilKind> kind_;  // (num_stencils)
  std::vector<int32_t> vertices_;         // (num_stencils x 4) real vertex ids; vertex-plane: v, plane
  std::vector<int32_t> multiplicity_;     // (num_stencils) active pairs merged into the stencil
  std::vector<uint8_t> edge_edge_case_;   // (num_stencils) EdgeEdgeCase of edge-edge stencils
  std::vector<int32_t> stencils_;         // (num_stencils x 4) vertex ids, -1 = absent or held
  std::vector<int64_t> slab_begin_;       // (num_stencils + 1) prefix of (3n)^2
};

}  // namespace nexdyn

// Islands: the independent pieces of one Newton system.
//
// The moving vertices of a scene are coupled by tets and joints (the elastic pattern) and, at a
// given x, by contact stencils (barrier and lagged friction). Where nothing couples two groups of
// vertices, the incremental potential is a sum of independent parts and the Newton matrix is
// block diagonal, so each group (an island) has its own Newton direction, its own factorisation
// and its own convergence. A pile of 1,000 bodies has up to 1,000 islands: solving them as one
// system made every body pay for the iterations of the slowest impact (newton.cpp uses this).
//
// Vertices that do not move (eliminated or held: all their DOFs constrained) belong to no island
// and couple nothing: two bodies resting on a fixed mesh are two islands.
//
// Islands are numbered in the order of their smallest vertex and list their vertices in
// increasing order, so the numbering depends on the couplings only, never on a thread count.
#pragma once

#include "engine/sparse/hessian_pattern.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

// Union-find over [0, n) whose root is always the smallest member (so labels are reproducible).
class DisjointSets {
 public:
  void reset(int32_t n);
  int32_t find(int32_t a);
  void join(int32_t a, int32_t b);
  int32_t size() const { return static_cast<int32_t>(parent_.size()); }
  std::vector<int32_t>& parents() { return parent_; }

 private:
  std::vector<int32_t> parent_;
};

class Islands {
 public:
  // elastic: the tet and joint pattern (vertex blocks of 3 DOFs).
  Islands(const CscPattern& elastic, int32_t num_vertices);

  // Which vertices move (moving[v] != 0); redoes the couplings through the elastic pattern.
  void set_moving(const std::vector<uint8_t>& moving);

  // Islands at the current contacts: the elastic couplings plus every pair of moving vertices that
  // share a stencil of any list (num x 4 vertex ids, -1 = none).
  void build(const std::vector<const std::vector<int32_t>*>& stencil_lists);

  int32_t num_islands() const { return static_cast<int32_t>(vertex_ptr_.size()) - 1; }
  // Island of vertex v, -1 when v does not move.
  int32_t island_of(int32_t v) const { return island_of_[v]; }
  const std::vector<int32_t>& island_of_vertex() const { return island_of_; }
  // Vertices of island i, increasing: vertices()[vertex_ptr()[i] .. vertex_ptr()[i + 1]).
  const std::vector<int32_t>& vertex_ptr() const { return vertex_ptr_; }
  const std::vector<int32_t>& vertices() const { return vertices_; }
  int32_t island_size(int32_t i) const { return vertex_ptr_[i + 1] - vertex_ptr_[i]; }
  // Position of v in its island's vertex list.
  int32_t local_index(int32_t v) const { return local_index_[v]; }
  const std::vector<int32_t>& local_indices() const { return local_index_; }

 private:
  const CscPattern& elastic_;
  std::vector<uint8_t> moving_;          // (num_vertices)
  std::vector<int32_t> static_parent_;   // (num_vertices) union-find of the elastic couplings
  DisjointSets sets_;                    // per build: static couplings + stencils
  std::vector<int32_t> island_of_;       // (num_vertices) -1 = does not move
  std::vector<int32_t> local_index_;     // (num_vertices)
  std::vector<int32_t> vertex_ptr_;      // (num_islands + 1)
  std::vector<int32_t> vertices_;        // (moving vertices) grouped by island
  std::vector<int32_t> fill_;  // (num_islands) workspace of build()
};

}  // namespace nexdyn

// A small bounding-box tree for many box queries against one body's primitives.
//
// The contact broad phase scans short box lists (bvh/blocked_boxes.hpp: faster than this tree
// below a few thousand boxes, and hits come out in id order); this tree is its fallback for
// longer ones, where a query costs a log instead of a scan.
//
// Why not Embree here: Embree answers "which boxes of scene A overlap which boxes of scene B"
// (rtcCollide) but has no box query, and building a scene costs about half a millisecond even
// for a thousand boxes (measured: 125 scenes of 902 boxes took 55 ms on this machine).
//
// Layout: a 4-wide tree. Each node holds the boxes of its (up to) 4 children side by side, one
// array per coordinate, so a query tests all four with the same few instructions (the compiler
// turns the loop into vector compares) and branches once per node instead of once per box. A
// child is another node or a single primitive, whose box is then its exact input box. The build
// sorts the primitives once by the Morton code of their box centres and cuts that order into 4
// equal runs per node (cheaper than median splits, which cost one nth_element per level). Boxes
// are doubles and child boxes are exact unions, so a query reports exactly the boxes that overlap
// it on closed intervals (boxes_overlap in bvh/broad_phase.hpp), like the O(n^2) loop.
#pragma once

#include <bit>
#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {
class BoxTree {
 public:
  // Builds over boxes [begin, end) of the (n x 3) lower/upper arrays; ids reported by query()
  // are indices into those arrays. An empty range gives an empty tree.
  void build(const double* lower, const double* upper, int32_t begin, int32_t end);

  bool empty() const { return nodes_.empty(); }

  // Calls visit(id) for every box of the tree that overlaps [lower, upper] (closed), in no
  // particular order.
  template <typename Visit>
  void query(const double* lower, const double* upper, Visit&& visit) const {
    query_above(lower, upper, -1, visit);
  }
  // The same for the boxes with id > min_id only. Subtrees whose ids are all <= min_id are not
  // entered: a search of a body's own pairs that keeps each pair from its lower id (a < b) skips
  // about half of the tree's overlaps this way.
  template <typename Visit>
  void query_above(const double* lower, const double* upper, int32_t min_id, Visit&& visit) const;

 private:
  static constexpr int kWidth = 4;
  struct Node {
    double lower[3][kWidth];  // child boxes; an absent child has lower +inf, upper -inf
    double upper[3][kWidth];
    int32_t child[kWidth];    // node index, or ~id of a primitive
    int32_t max_id[kWidth];   // the largest primitive id under each child (-1: absent child)
    unsigned primitive_mask;  // bit k set: child k is a primitive
  };

  int32_t build_node(int32_t first, int32_t count, double* lo, double* hi, int32_t& max_id);

  std::vector<Node> nodes_;
  // Build inputs and workspace.
  const double* lower_ = nullptr;
  const double* upper_ = nullptr;
  std::vector<std::pair<uint64_t, int32_t>> order_;  // (Morton code, id), sorted
  std::vector<int32_t> ids_;                         // primitive ids in Morton order
};

template <typename Visit>
void BoxTree::query_above(const double* lower, const double* upper, int32_t min_id, Visit&& visit) const {
  if (nodes_.empty()) return;
  int32_t stack[128];  // 3 pushes per level at most, depth < 32 for < 2^31 boxes
  int top = 0;
  stack[top++] = 0;
  const double qlo[3] = {lower[0], lower[1], lower[2]};
  const double qhi[3] = {upper[0], upper[1], upper[2]};
  while (top > 0) {
    const Node& node = nodes_[stack[--top]];
    // Closed-interval overlap of the four child boxes with the query, as a bit mask: no branch
    // per box (overlap tests are coin flips for the branch predictor, and a miss costs more than
    // the test).
    unsigned hits = 0;
    for (int k = 0; k < kWidth; ++k) {
      const bool hit = (node.lower[0][k] <= qhi[0]) & (qlo[0] <= node.upper[0][k]) &
                       (node.lower[1][k] <= qhi[1]) & (qlo[1] <= node.upper[1][k]) &
                       (node.lower[2][k] <= qhi[2]) & (qlo[2] <= node.upper[2][k]) &
                       (node.max_id[k] > min_id);
      hits |= unsigned{hit} << k;
    }
    for (unsigned m = hits & node.primitive_mask; m != 0; m &= m - 1)
      visit(~node.child[std::countr_zero(m)]);
    for (unsigned m = hits & ~node.primitive_mask; m != 0; m &= m - 1)
      stack[top++] = node.child[std::countr_zero(m)];
  }
}

}  // namespace nexdyn

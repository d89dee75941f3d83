// Broad phase of contact (see candidates.hpp).
//
// Two levels. Bodies first: the boxes of whole bodies go through Embree (bvh/broad_phase.hpp),
// which gives the pairs of bodies that can touch. Then primitives, by linear scans of box lists
// kept in id order (bvh/blocked_boxes.hpp), which report their hits already sorted:
//   * each body's neighbours: a primitive finds the neighbour bodies its box overlaps;
//   * for each (body A, neighbour B): the subset of B's primitives that overlap A's box, found
//     once. Only those can meet a primitive of A, and for bodies side by side they are few (a
//     face's worth), so each primitive of A scans them;
//   * each body's own primitives, in its frame, for same-body pairs.
// Taking the neighbours below A, then A itself, then the neighbours above (ids are contiguous
// per body, in body order) gives each primitive's partners in increasing order, and chunks of
// primitives concatenated in order give the sorted list: no sort at all. Lists longer than 2048
// boxes (big bodies) are queried through a BoxTree instead, and those hits are sorted per
// primitive. On 125 cubes of 5^3 cells this took the broad phase from 100 ms to 17 ms on
// one thread.
//
// Same-body pairs are tested in the body's co-moving frame: the body's mean displacement
// x1 - x0 is taken out of the end positions first. Translating both primitives of a pair by the
// same t * shift changes no distance between them, so this is exact, and it keeps a falling body
// from pairing every primitive with every other one along its path.
#include "engine/contact/candidates.hpp"

#include "engine/contact/candidate_search.hpp"

#include <algorithm>
#include <limits>
#include <memory>

namespace nexdyn {

using namespace candidate_search;

namespace {

// One search: the boxes, neighbour subsets and trees that the pair loops share, built in the
// constructor; then the vertex-triangle and edge-edge loops.
class CandidateSearch {
 public:
  CandidateSearch(const Model& m, const uint8_t* free, const double* x0, const double* x1, double inflation,
                  const double* pad)
      : m_(m),
        free_(free),
        prims_(body_primitives(m, free)),
        neighbors_(neighbor_bodies(m, prims_, x0, x1, inflation, pad)),
        own_searched_(own_searched(m, prims_)),
        searched_(searched(own_searched_, neighbors_)),
        boxes_(m, prims_, searched_.data(), own_searched_.data(), x0, x1, inflation, pad),
        world_(boxes_.world),
        own_(boxes_.body_frame()),
        tri_free_(free_flags<3>(free, m.surface_triangles.data(), static_cast<int64_t>(m.surface_triangles.size() / 3))),
        edge_free_(free_flags<2>(free, m.surface_edges.data(), static_cast<int64_t>(m.surface_edges.size() / 2))),
        world_lists_(prims_, world_, searched_.data()),
        // Vertex-triangle pairs need every neighbour's triangles; edge-edge pairs are found from
        // their lower edge, so only the higher-numbered neighbours' edges.
        tri_near_(neighbor_subsets(neighbors_, world_lists_.triangles, world_.t_lo, world_.t_hi,
                                   [](int64_t) { return true; })),
        edge_near_(neighbor_subsets(neighbors_, world_lists_.edges, world_.e_lo, world_.e_hi,
                                    [&](int64_t k) { return neighbors_.body[k] > neighbors_.owner[k]; })),
        // Same-body pairs scan the body's own lists (in its frame), or its tree when too long.
        moving_lists_(boxes_.moving ? std::make_unique<BodyLists>(prims_, own_, own_searched_.data()) : nullptr),
        own_lists_(moving_lists_ ? *moving_lists_ : world_lists_),
        same_body_(prims_, own_) {
    build_neighbor_trees();
  }

  void vertex_triangle_pairs(std::vector<IndexPair>& out) const;
  void edge_edge_pairs(std::vector<IndexPair>& out) const;

 private:
  // A pair lies within one body with a free vertex, or between neighbours (one of them with a
  // free vertex): only those bodies' primitives are boxed and searched (a re-search after a few
  // bodies moved costs what those bodies cost).
  // An affine body has no own pairs (same_affine_body): its own primitives are not searched, and
  // one without neighbours (falling alone) is not searched at all.
  static std::vector<uint8_t> own_searched(const Model& m, const std::vector<BodyPrimitives>& prims) {
    std::vector<uint8_t> out(prims.size());
    for (size_t b = 0; b < prims.size(); ++b) out[b] = prims[b].any_free;
    for (const AffineBody& body : m.affine_bodies) out[body.body] = 0;
    return out;
  }
  static std::vector<uint8_t> searched(const std::vector<uint8_t>& own_searched, const NeighborBodies& neighbors) {
    std::vector<uint8_t> out(own_searched.size());
    for (size_t b = 0; b < out.size(); ++b) out[b] = own_searched[b] || neighbors.ptr[b + 1] > neighbors.ptr[b];
    return out;
  }
  // Trees over the world boxes of the neighbours too many to scan.
  void build_neighbor_trees();
  // A tree query's partners, sorted (trees report in no particular order).
  // min_id: only partners above it (-1: all).
  template <typename Keep>
  static void put_tree_hits(const BoxTree& tree, const double* lo, const double* hi, int32_t first, Keep&& keep,
                            PairBuffer& buffer, int32_t min_id = -1) {
    const size_t start = buffer.size();
    tree.query_above(lo, hi, min_id, [&](int32_t p) {
      buffer.room(1);
      buffer.put(first, p, keep(p));
    });
    buffer.sort_from(start);
  }
  // A primitive's pairs with neighbour entry k (whose body's box it overlaps): a scan of the
  // subset or, for big subsets, a query of the neighbour's tree.
  void neighbor_pairs(const NeighborSubsets& subsets, const std::vector<BoxTree>& trees,
                      const std::vector<uint8_t>& partner_free, int32_t k, const double* lo, const double* hi,
                      int32_t first, bool first_free, PairBuffer& buffer) const {
    auto keep = [&](int32_t p) { return first_free | (partner_free[p] != 0); };
    if (subsets.use_tree[k]) return put_tree_hits(trees[neighbors_.body[k]], lo, hi, first, keep, buffer);
    int32_t* ids = buffer.scratch(subsets.boxes.size(k));
    const int32_t n = subsets.boxes.scan(k, 0, lo, hi, ids);
    if (first_free)
      buffer.put_all(first, ids, n);
    else
      buffer.put_kept(first, ids, n, keep);
  }

  const Model& m_;
  const uint8_t* free_;
  const std::vector<BodyPrimitives> prims_;
  const NeighborBodies neighbors_;
  const std::vector<uint8_t> own_searched_, searched_;
  const SurfaceBoxes boxes_;
  const FrameBoxes& world_;
  const FrameBoxes& own_;
  const std::vector<uint8_t> tri_free_, edge_free_;
  const BodyLists world_lists_;
  const NeighborSubsets tri_near_, edge_near_;
  const std::unique_ptr<BodyLists> moving_lists_;
  const BodyLists& own_lists_;
  const SameBodyTrees same_body_;
  std::vector<BoxTree> tri_world_, edge_world_;
};

void CandidateSearch::build_neighbor_trees() {
  const auto nb = static_cast<int64_t>(m_.bodies.size());
  std::vector<uint8_t> tri_tree_needed(nb, 0), edge_tree_needed(nb, 0);
  for (size_t k = 0; k < neighbors_.body.size(); ++k) {
    tri_tree_needed[neighbors_.body[k]] |= tri_near_.use_tree[k];
    edge_tree_needed[neighbors_.body[k]] |= edge_near_.use_tree[k];
  }
  tri_world_.resize(nb);
  edge_world_.resize(nb);
  parallel_for(nb, [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      if (tri_tree_needed[b])
        tri_world_[b].build(world_.t_lo.data(), world_.t_hi.data(), prims_[b].t_begin, prims_[b].t_end);
      if (edge_tree_needed[b])
        edge_world_[b].build(world_.e_lo.data(), world_.e_hi.data(), prims_[b].e_begin, prims_[b].e_end);
    }
  }, 1);
}

// Each surface vertex against the neighbours below its body, its own body and the neighbours
// above, so that its partners come out in increasing triangle order.
void CandidateSearch::vertex_triangle_pairs(std::vector<IndexPair>& out) const {
  collect_pairs(
      static_cast<int64_t>(m_.surface_vertices.size()),
      [&](int32_t i, PairBuffer& buffer) {
        const int32_t v = m_.surface_vertices[i];
        const int32_t body = m_.vertex_body[v];
        if (!searched_[body]) return;
        const bool v_free = is_free(free_, v);
        const double* lo = &world_.v_lo[3 * int64_t{i}];
        const double* hi = &world_.v_hi[3 * int64_t{i}];
        int32_t* near = buffer.scratch(neighbors_.ptr[body + 1] - neighbors_.ptr[body], 1);
        const int32_t near_count = neighbors_.near(body, 0, lo, hi, near);
        int32_t j = 0;
        for (; j < near_count && near[j] < neighbors_.above[body]; ++j)
          neighbor_pairs(tri_near_, tri_world_, tri_free_, near[j], lo, hi, v, v_free, buffer);
        if (own_searched_[body]) {
          const double* own_lo = &own_.v_lo[3 * int64_t{i}];
          const double* own_hi = &own_.v_hi[3 * int64_t{i}];
          auto keep = [&](int32_t t) { return keep_vertex_triangle(m_, free_, v, t); };
          if (same_body_.triangle_tree[body]) {
            put_tree_hits(same_body_.triangles[body], own_lo, own_hi, v, keep, buffer);
          } else {
            int32_t* ids = buffer.scratch(own_lists_.triangles.size(body));
            buffer.put_kept(v, ids, own_lists_.triangles.scan(body, 0, own_lo, own_hi, ids), keep);
          }
        }
        for (; j < near_count; ++j)
          neighbor_pairs(tri_near_, tri_world_, tri_free_, near[j], lo, hi, v, v_free, buffer);
      },
      out);
}

// Each edge against the higher-numbered edges of its body, then of the neighbours above its body.
void CandidateSearch::edge_edge_pairs(std::vector<IndexPair>& out) const {
  collect_pairs(
      static_cast<int64_t>(m_.surface_edges.size() / 2),
      [&](int32_t a, PairBuffer& buffer) {
        const int32_t body = m_.vertex_body[m_.surface_edges[2 * int64_t{a}]];
        if (!searched_[body]) return;
        if (own_searched_[body]) {
          const double* own_lo = &own_.e_lo[3 * int64_t{a}];
          const double* own_hi = &own_.e_hi[3 * int64_t{a}];
          if (same_body_.edge_tree[body]) {
            auto keep = [&](int32_t b) { return keep_edge_edge(m_, free_, a, b); };
            put_tree_hits(same_body_.edges[body], own_lo, own_hi, a, keep, buffer, /*min_id=*/a);
          } else {
            auto keep = [&](int32_t b) { return keep_edge_edge(m_, free_, a, b); };
            int32_t* ids = buffer.scratch(own_lists_.edges.size(body));
            const int32_t above_a = a + 1 - prims_[body].e_begin;
            buffer.put_kept(a, ids, own_lists_.edges.scan(body, above_a, own_lo, own_hi, ids), keep);
          }
        }
        const double* lo = &world_.e_lo[3 * int64_t{a}];
        const double* hi = &world_.e_hi[3 * int64_t{a}];
        int32_t* near = buffer.scratch(neighbors_.ptr[body + 1] - neighbors_.ptr[body], 1);
        const int32_t above = neighbors_.above[body] - neighbors_.ptr[body];
        const int32_t near_count = neighbors_.near(body, above, lo, hi, near);
        for (int32_t j = 0; j < near_count; ++j)
          neighbor_pairs(edge_near_, edge_world_, edge_free_, near[j], lo, hi, a, edge_free_[a] != 0, buffer);
      },
      out);
}

}  // namespace

void find_contact_candidates(const Model& m, const double* x0, const double* x1, double inflation,
                             ContactCandidates& out, const uint8_t* moving, const double* pad) {
  const std::vector<uint8_t> free_storage = free_vertices(m, moving);
  const uint8_t* free = free_storage.data();
  const CandidateSearch search(m, free, x0, x1, inflation, pad);
  search.vertex_triangle_pairs(out.vertex_triangle);
  search.edge_edge_pairs(out.edge_edge);
  find_vertex_plane(m, free, x0, x1, inflation, pad, out.vertex_plane);
}

void find_contact_candidates_brute_force(const Model& m, const double* x0, const double* x1,
                                         double inflation, ContactCandidates& out, const uint8_t* moving,
                                         const double* pad) {
  const std::vector<uint8_t> free_storage = free_vertices(m, moving);
  const uint8_t* free = free_storage.data();
  const SurfaceBoxes boxes(m, body_primitives(m, free), nullptr, nullptr, x0, x1, inflation, pad);
  // Same-body pairs compare body-frame boxes, others world boxes.
  auto frame = [&](int32_t body_a, int32_t body_b) -> const FrameBoxes& {
    return body_a == body_b ? boxes.body_frame() : boxes.world;
  };
  out.clear();
  const auto nv = static_cast<int64_t>(m.surface_vertices.size());
  const auto ne = static_cast<int64_t>(m.surface_edges.size() / 2);
  const auto nt = static_cast<int64_t>(m.surface_triangles.size() / 3);
  for (int64_t i = 0; i < nv; ++i) {
    const int32_t v = m.surface_vertices[i];
    for (int64_t t = 0; t < nt; ++t) {
      const FrameBoxes& f = frame(m.vertex_body[v], m.vertex_body[m.surface_triangles[3 * t]]);
      if (boxes_overlap(f.v_lo.data(), f.v_hi.data(), i, f.t_lo.data(), f.t_hi.data(), t) &&
          keep_vertex_triangle(m, free, v, static_cast<int32_t>(t)))
        out.vertex_triangle.emplace_back(v, static_cast<int32_t>(t));
    }
  }
  for (int64_t e = 0; e < ne; ++e)
    for (int64_t g = e + 1; g < ne; ++g) {
      const FrameBoxes& f =
          frame(m.vertex_body[m.surface_edges[2 * e]], m.vertex_body[m.surface_edges[2 * g]]);
      if (boxes_overlap(f.e_lo.data(), f.e_hi.data(), e, f.e_lo.data(), f.e_hi.data(), g) &&
          keep_edge_edge(m, free, static_cast<int32_t>(e), static_cast<int32_t>(g)))
        out.edge_edge.emplace_back(static_cast<int32_t>(e), static_cast<int32_t>(g));
    }
  find_vertex_plane(m, free, x0, x1, inflation, pad, out.vertex_plane);
}

}  // namespace nexdyn

// The parts of the broad phase (candidates.cpp): primitive boxes per frame, the neighbour bodies
// and their primitive subsets, the sorted pair buffers. Internal to candidates.cpp and its brute
// force; the algorithm is described at the top of candidates.cpp.
#pragma once

#include "bvh/blocked_boxes.hpp"
#include "bvh/box_tree.hpp"
#include "engine/active_subset.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/parallel.hpp"

#include <algorithm>
#include <limits>
#include <memory>
#include <vector>

namespace nexdyn::candidate_search {

// Primitives per parallel chunk of the query loops.
inline constexpr int64_t kQueryGrain = 512;
// Longest lists scanned rather than queried through a tree: a neighbour's subset, and a body's
// own triangles or edges. A scan tests 64 boxes per vector compare of block boxes, so it stays
// cheaper than a tree query up to a few thousand boxes.
inline constexpr int32_t kMaxScan = 2048;
inline constexpr int32_t kMaxBodyScan = 2048;

// free[v]: v can move in the search's motion. By default every vertex not held by a Dirichlet
// condition; a caller re-searching after only some vertices moved passes those instead.
inline bool is_free(const uint8_t* free, int32_t v) { return free[v] != 0; }

inline std::vector<uint8_t> free_vertices(const Model& m, const uint8_t* moving) {
  std::vector<uint8_t> free(static_cast<size_t>(m.num_vertices));
  for (int32_t v = 0; v < m.num_vertices; ++v) free[v] = moving ? moving[v] : m.dirichlet[v] < 0;
  return free;
}

// Whether vertices a and b are points of one affine body: their distance never changes (up to
// the body's tiny stretch), so a pair of its own primitives is never a contact.
inline bool same_affine_body(const Model& m, int32_t a, int32_t b) {
  if (m.follows.empty()) return false;
  const int32_t body = m.follows[a];
  return (body >= 0) & (body == m.follows[b]);
}

// The filters of candidates.hpp, shared by the fast and the brute-force paths. Written with
// bitwise operators: they run on every box overlap, and whether a pair passes is unpredictable.
inline bool keep_vertex_triangle(const Model& m, const uint8_t* free, int32_t v, int32_t t) {
  const int32_t* tri = &m.surface_triangles[3 * int64_t{t}];
  const bool not_corner = (v != tri[0]) & (v != tri[1]) & (v != tri[2]);
  const bool any_free =
      is_free(free, v) | is_free(free, tri[0]) | is_free(free, tri[1]) | is_free(free, tri[2]);
  return not_corner & any_free & !same_affine_body(m, v, tri[0]);
}

inline bool keep_edge_edge(const Model& m, const uint8_t* free, int32_t a, int32_t b) {
  const int32_t* ea = &m.surface_edges[2 * int64_t{a}];
  const int32_t* eb = &m.surface_edges[2 * int64_t{b}];
  const bool disjoint = (ea[0] != eb[0]) & (ea[0] != eb[1]) & (ea[1] != eb[0]) & (ea[1] != eb[1]);
  const bool any_free =
      is_free(free, ea[0]) | is_free(free, ea[1]) | is_free(free, eb[0]) | is_free(free, eb[1]);
  return disjoint & any_free & !same_affine_body(m, ea[0], eb[0]);
}

// Per body: the mean of x1 - x0 over its vertices (zero without x1), affine axis nodes left out.
inline std::vector<Eigen::Vector3d> body_shifts(const Model& m, const double* x0, const double* x1) {
  std::vector<Eigen::Vector3d> shift(m.bodies.size(), Eigen::Vector3d::Zero());
  if (!x1) return shift;
  parallel_for(static_cast<int64_t>(m.bodies.size()), [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      const BodyRange& body = m.bodies[b];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int32_t count = 0;
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
        if (m.axis_node(v)) continue;  // a column of an affine body's A R: no point that moves
        sum += Eigen::Vector3d::Map(x1 + 3 * int64_t{v}) - Eigen::Vector3d::Map(x0 + 3 * int64_t{v});
        ++count;
      }
      if (count > 0) shift[b] = sum / count;
    }
  }, 1);
  return shift;
}

// Boxes (lower, upper: 3 per primitive, by primitive index) of the primitives with K vertices
// each in `ranges`, covering them at x0 and at x1 - shift of their body (no shift: shift ==
// nullptr), inflated by r and by each vertex's pad[v] (null: none).
template <int K>
void primitive_boxes(const Model& m, const int32_t* ids, const IndexRanges& ranges, const double* x0,
                     const double* x1, const Eigen::Vector3d* shift, double r, const double* pad,
                     double* lower, double* upper) {
  parallel_for_ranges(ranges, 1024, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const int64_t first = ids[K * i];
      const double* s = shift ? shift[m.vertex_body[first]].data() : nullptr;
      for (int d = 0; d < 3; ++d) {
        double lo = x0[3 * first + d], hi = lo;
        for (int k = 0; k < K; ++k) {
          const int64_t v = ids[K * i + k];
          double v_lo = x0[3 * v + d], v_hi = v_lo;
          if (x1) {
            const double end_position = s ? x1[3 * v + d] - s[d] : x1[3 * v + d];
            v_lo = std::min(v_lo, end_position);
            v_hi = std::max(v_hi, end_position);
          }
          if (pad) v_lo -= pad[v], v_hi += pad[v];
          lo = std::min(lo, v_lo);
          hi = std::max(hi, v_hi);
        }
        lower[3 * i + d] = lo - r;
        upper[3 * i + d] = hi + r;
      }
    }
  });
}

// n doubles, left uninitialised: boxes are written only for the bodies a search needs, and
// zero-filling a vector for every primitive would cost more than searching a few bodies.
class Doubles {
 public:
  void resize(size_t n) { data_.reset(new double[n]); }
  double* data() { return data_.get(); }
  const double* data() const { return data_.get(); }
  double& operator[](size_t i) { return data_[i]; }
  const double& operator[](size_t i) const { return data_[i]; }

 private:
  std::unique_ptr<double[]> data_;
};

// Index ranges of one body's primitives: surface vertices [sv_begin, sv_end) of
// Model::surface_vertices, its triangles and its edges.
struct BodyPrimitives {
  int32_t sv_begin = 0, sv_end = 0;
  int32_t t_begin = 0, t_end = 0;
  int32_t e_begin = 0, e_end = 0;
  bool any_free = false;  // some vertex of the body is free: its own pairs can matter
};

inline std::vector<BodyPrimitives> body_primitives(const Model& m, const uint8_t* free) {
  std::vector<BodyPrimitives> out(m.bodies.size());
  for (size_t b = 0; b < m.bodies.size(); ++b) {
    const BodyRange& body = m.bodies[b];
    BodyPrimitives& p = out[b];
    const auto sv = m.surface_vertices.begin();
    p.sv_begin = static_cast<int32_t>(
        std::lower_bound(sv, m.surface_vertices.end(), body.vertex_begin) - sv);
    p.sv_end = static_cast<int32_t>(
        std::lower_bound(sv, m.surface_vertices.end(), body.vertex_begin + body.vertex_count) - sv);
    p.t_begin = body.triangle_begin;
    p.t_end = body.triangle_begin + body.triangle_count;
    p.e_begin = body.edge_begin;
    p.e_end = body.edge_begin + body.edge_count;
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count && !p.any_free; ++v)
      p.any_free = is_free(free, v);
  }
  return out;
}

// Boxes of the surface vertices, edges and triangles of the bodies with wanted[b] (null: all) in
// one frame, by primitive index; the other bodies' entries are left unset.
struct FrameBoxes {
  Doubles v_lo, v_hi, e_lo, e_hi, t_lo, t_hi;
  FrameBoxes(const Model& m, const std::vector<BodyPrimitives>& prims, const uint8_t* wanted,
             const double* x0, const double* x1, const Eigen::Vector3d* shift, double r, const double* pad) {
    IndexRanges sv, edges, triangles;
    for (size_t b = 0; b < prims.size(); ++b) {
      if (wanted && !wanted[b]) continue;
      append_range(sv, prims[b].sv_begin, prims[b].sv_end);
      append_range(edges, prims[b].e_begin, prims[b].e_end);
      append_range(triangles, prims[b].t_begin, prims[b].t_end);
    }
    v_lo.resize(3 * m.surface_vertices.size());
    v_hi.resize(3 * m.surface_vertices.size());
    e_lo.resize(m.surface_edges.size() / 2 * 3);
    e_hi.resize(m.surface_edges.size() / 2 * 3);
    t_lo.resize(m.surface_triangles.size());
    t_hi.resize(m.surface_triangles.size());
    primitive_boxes<1>(m, m.surface_vertices.data(), sv, x0, x1, shift, r, pad, v_lo.data(), v_hi.data());
    primitive_boxes<2>(m, m.surface_edges.data(), edges, x0, x1, shift, r, pad, e_lo.data(), e_hi.data());
    primitive_boxes<3>(m, m.surface_triangles.data(), triangles, x0, x1, shift, r, pad, t_lo.data(),
                       t_hi.data());
  }
};

// Primitive boxes for pairs of different bodies (world frame, the bodies with world_wanted) and
// for pairs within one body (its co-moving frame, the bodies with own_wanted). Without motion the
// two frames are the same boxes.
struct SurfaceBoxes {
  FrameBoxes world;
  std::unique_ptr<FrameBoxes> moving;  // null without x1
  SurfaceBoxes(const Model& m, const std::vector<BodyPrimitives>& prims, const uint8_t* world_wanted,
               const uint8_t* own_wanted, const double* x0, const double* x1, double r, const double* pad)
      : world(m, prims, world_wanted, x0, x1, nullptr, r, pad) {
    if (!x1) return;
    const std::vector<Eigen::Vector3d> shift = body_shifts(m, x0, x1);
    moving = std::make_unique<FrameBoxes>(m, prims, own_wanted, x0, x1, shift.data(), r, pad);
  }
  const FrameBoxes& body_frame() const { return moving ? *moving : world; }
};

// The pairs of bodies whose world boxes overlap, as a CSR over bodies (found by Embree over the
// body boxes). A body's box is the union of its surface vertices' boxes, which contain its edges'
// and triangles'. Pairs of two bodies without a free vertex are left out.
struct NeighborBodies {
  std::vector<int32_t> ptr;     // body A's entries: [ptr[A], ptr[A + 1])
  std::vector<int32_t> above;   // body A's first entry with a neighbour numbered above A
  std::vector<int32_t> owner;   // entry k: A
  std::vector<int32_t> body;    // entry k: the neighbour B, increasing within A's entries
  BlockedBoxes boxes;           // list A: the boxes of A's neighbours, ids: their entries k
  std::vector<double> body_lo, body_hi;  // (num_bodies x 3) every body's box

  // Writes the entries of A, from its `from`-th on, whose neighbour's box overlaps [lo, hi],
  // in order, to out; returns their number.
  int32_t near(int32_t a, int32_t from, const double* lo, const double* hi, int32_t* out) const {
    return boxes.scan(a, from, lo, hi, out);
  }
};

inline NeighborBodies neighbor_bodies(const Model& m, const std::vector<BodyPrimitives>& prims,
                               const double* x0, const double* x1, double r, const double* pad) {
  const auto nb = static_cast<int32_t>(m.bodies.size());
  NeighborBodies out;
  std::vector<double>& lo = out.body_lo;
  std::vector<double>& hi = out.body_hi;
  lo.resize(3 * size_t(nb));
  hi.resize(3 * size_t(nb));
  parallel_for(nb, [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      for (int d = 0; d < 3; ++d) {
        lo[3 * b + d] = std::numeric_limits<double>::infinity();
        hi[3 * b + d] = -std::numeric_limits<double>::infinity();
      }
      // The union of the vertex boxes (primitive_boxes<1>): the same numbers, since rounding
      // the inflation is monotone.
      for (int64_t i = prims[b].sv_begin; i < prims[b].sv_end; ++i) {
        const int64_t v = m.surface_vertices[i];
        for (int d = 0; d < 3; ++d) {
          double vlo = x0[3 * v + d], vhi = vlo;
          if (x1) {
            vlo = std::min(vlo, x1[3 * v + d]);
            vhi = std::max(vhi, x1[3 * v + d]);
          }
          if (pad) vlo -= pad[v], vhi += pad[v];
          lo[3 * b + d] = std::min(lo[3 * b + d], vlo - r);
          hi[3 * b + d] = std::max(hi[3 * b + d], vhi + r);
        }
      }
    }
  }, 1);
  // Embree drops boxes with lower > upper; a body without surface primitives has no pairs.
  std::vector<int32_t> with_surface;
  for (int32_t b = 0; b < nb; ++b)
    if (prims[b].sv_end > prims[b].sv_begin) with_surface.push_back(b);
  std::vector<double> slo, shi;
  for (int32_t b : with_surface) {
    slo.insert(slo.end(), &lo[3 * size_t(b)], &lo[3 * size_t(b)] + 3);
    shi.insert(shi.end(), &hi[3 * size_t(b)], &hi[3 * size_t(b)] + 3);
  }
  std::vector<IndexPair> pairs =
      self_overlapping_pairs(slo.data(), shi.data(), static_cast<int32_t>(with_surface.size()));

  std::vector<IndexPair> both;
  both.reserve(2 * pairs.size());
  for (const IndexPair& p : pairs) {
    const int32_t a = with_surface[p.first], b = with_surface[p.second];
    if (!prims[a].any_free && !prims[b].any_free) continue;
    both.emplace_back(a, b);
    both.emplace_back(b, a);
  }
  std::sort(both.begin(), both.end());
  out.ptr.assign(size_t(nb) + 1, 0);
  out.above.assign(size_t(nb), 0);
  out.owner.resize(both.size());
  out.body.resize(both.size());
  for (size_t k = 0; k < both.size(); ++k) {
    const auto [a, b] = both[k];
    ++out.ptr[a + 1];
    out.above[a] += b < a;
    out.owner[k] = a;
    out.body[k] = b;
  }
  std::vector<int32_t> count(static_cast<size_t>(nb));
  for (int32_t b = 0; b < nb; ++b) {
    count[b] = out.ptr[b + 1];
    out.ptr[b + 1] += out.ptr[b];
    out.above[b] += out.ptr[b];
  }
  out.boxes.layout(count);
  for (int32_t a = 0; a < nb; ++a) {
    for (int32_t k = out.ptr[a]; k < out.ptr[a + 1]; ++k)
      out.boxes.set(a, k - out.ptr[a], &lo[3 * size_t(out.body[k])], &hi[3 * size_t(out.body[k])], k);
    out.boxes.finish(a);
  }
  return out;
}

// One chunk's output pairs. put() writes every pair and only advances past the kept ones, so the
// filters cost no branch; room(n) must come first for the n puts that follow.
class PairBuffer {
 public:
  void room(size_t n) {
    if (size_ + n > pairs_.size()) pairs_.resize(std::max(2 * pairs_.size(), size_ + n + 1024));
  }
  void put(int32_t first, int32_t second, bool keep) {
    pairs_[size_] = {first, second};
    size_ += keep;
  }
  // Puts (first, ids[j]) for j < n: all of them, or those with keep(ids[j]).
  void put_all(int32_t first, const int32_t* ids, int32_t n) {
    room(static_cast<size_t>(n));
    for (int32_t j = 0; j < n; ++j) pairs_[size_ + j] = {first, ids[j]};
    size_ += static_cast<size_t>(n);
  }
  template <typename Keep>
  void put_kept(int32_t first, const int32_t* ids, int32_t n, Keep&& keep) {
    room(static_cast<size_t>(n));
    for (int32_t j = 0; j < n; ++j) put(first, ids[j], keep(ids[j]));
  }
  // Room for the ids of a scan of n boxes (BlockedBoxes::scan); two independent areas.
  int32_t* scratch(int32_t n, int area = 0) {
    std::vector<int32_t>& s = scratch_[area];
    if (static_cast<size_t>(n + BlockedBoxes::kBlock) > s.size()) s.resize(2 * static_cast<size_t>(n) + 64);
    return s.data();
  }
  size_t size() const { return size_; }
  const IndexPair* data() const { return pairs_.data(); }
  // Sorts the pairs put since size() was `start` (one primitive's partners from a tree query).
  void sort_from(size_t start) {
    std::sort(pairs_.begin() + static_cast<int64_t>(start), pairs_.begin() + static_cast<int64_t>(size_));
  }

 private:
  std::vector<IndexPair> pairs_;
  size_t size_ = 0;
  std::vector<int32_t> scratch_[2];
};

// Runs emit(i, buffer) for every primitive i of [0, n) in parallel chunks, each putting its pairs
// in sorted order, and concatenates the chunks in order.
template <typename Emit>
void collect_pairs(int64_t n, Emit&& emit, std::vector<IndexPair>& out) {
  std::vector<PairBuffer> chunks(static_cast<size_t>((n + kQueryGrain - 1) / kQueryGrain));
  for_each_chunk(n, kQueryGrain, [&](int64_t c, int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) emit(static_cast<int32_t>(i), chunks[c]);
  });
  std::vector<size_t> offset(chunks.size() + 1, 0);
  for (size_t c = 0; c < chunks.size(); ++c) offset[c + 1] = offset[c] + chunks[c].size();
  out.resize(offset.back());
  parallel_for(static_cast<int64_t>(chunks.size()), [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c)
      std::copy(chunks[c].data(), chunks[c].data() + chunks[c].size(), out.begin() + static_cast<int64_t>(offset[c]));
  }, 1);
}

// One frame's boxes of the triangles and edges of the bodies with wanted[b], listed by id (list
// b: body b; empty for the others).
struct BodyLists {
  BlockedBoxes triangles, edges;

  BodyLists(const std::vector<BodyPrimitives>& prims, const FrameBoxes& f, const uint8_t* wanted) {
    const auto nb = static_cast<int64_t>(prims.size());
    std::vector<int32_t> triangle_count(nb, 0), edge_count(nb, 0);
    for (int64_t b = 0; b < nb; ++b) {
      if (!wanted[b]) continue;
      triangle_count[b] = prims[b].t_end - prims[b].t_begin;
      edge_count[b] = prims[b].e_end - prims[b].e_begin;
    }
    triangles.layout(triangle_count);
    edges.layout(edge_count);
    parallel_for(nb, [&](int64_t begin, int64_t end) {
      for (int64_t b = begin; b < end; ++b) {
        if (!wanted[b]) continue;
        const BodyPrimitives& p = prims[b];
        for (int32_t t = p.t_begin; t < p.t_end; ++t)
          triangles.set(b, t - p.t_begin, &f.t_lo[3 * int64_t{t}], &f.t_hi[3 * int64_t{t}], t);
        triangles.finish(b);
        for (int32_t e = p.e_begin; e < p.e_end; ++e)
          edges.set(b, e - p.e_begin, &f.e_lo[3 * int64_t{e}], &f.e_hi[3 * int64_t{e}], e);
        edges.finish(b);
      }
    }, 1);
  }
};

// Per primitive of K vertices: whether one of them is free. Primitives of different bodies share
// no vertex, so for them this is the whole filter of candidates.hpp.
template <int K>
std::vector<uint8_t> free_flags(const uint8_t* free, const int32_t* ids, int64_t n) {
  std::vector<uint8_t> out(static_cast<size_t>(n));
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      bool any = false;
      for (int k = 0; k < K; ++k) any |= is_free(free, ids[K * i + k]);
      out[i] = any;
    }
  }, 4096);
  return out;
}

// For each entry k = (body A, neighbour B) of the neighbour CSR: the primitives of B whose world
// boxes overlap A's body box, listed by id (list k). A primitive of A only ever meets these, so
// it scans them and gets its partners in B already sorted. A subset larger than kMaxScan is not
// listed: that entry queries B's tree instead (use_tree), so a big body next to a small one
// costs a log per query, not a long scan.
struct NeighborSubsets {
  BlockedBoxes boxes;
  std::vector<uint8_t> use_tree;
};

// body_lists: every body's primitives (world frame) of the kind wanted, boxes lower/upper;
// only entries with wanted(k) get a subset.
template <typename Wanted>
NeighborSubsets neighbor_subsets(const NeighborBodies& neighbors, const BlockedBoxes& body_lists,
                                 const Doubles& lower, const Doubles& upper, Wanted&& wanted) {
  const auto entries = static_cast<int64_t>(neighbors.body.size());
  NeighborSubsets s;
  std::vector<std::vector<int32_t>> found(static_cast<size_t>(entries));  // B's ids, in order
  std::vector<int32_t> size(static_cast<size_t>(entries), 0);
  s.use_tree.assign(static_cast<size_t>(entries), 0);
  parallel_for(entries, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      if (!wanted(k)) continue;
      const int32_t b = neighbors.body[k];
      const int64_t owner = neighbors.owner[k];
      std::vector<int32_t>& ids = found[k];
      ids.resize(static_cast<size_t>(body_lists.size(b) + BlockedBoxes::kBlock));
      ids.resize(static_cast<size_t>(body_lists.scan(b, 0, &neighbors.body_lo[3 * owner],
                                                     &neighbors.body_hi[3 * owner], ids.data())));
      s.use_tree[k] = ids.size() > size_t{kMaxScan};
      size[k] = s.use_tree[k] ? 0 : static_cast<int32_t>(ids.size());
    }
  }, 16);
  s.boxes.layout(size);
  parallel_for(entries, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      for (int32_t j = 0; j < size[k]; ++j) {
        const int64_t p = found[k][j];
        s.boxes.set(k, j, &lower[3 * p], &upper[3 * p], found[k][j]);
      }
      s.boxes.finish(k);
    }
  }, 16);
  return s;
}

inline void find_vertex_plane(const Model& m, const uint8_t* free, const double* x0, const double* x1, double inflation,
                              const double* pad, std::vector<IndexPair>& out) {
  out.clear();
  for (int32_t v : m.surface_vertices) {
    if (!is_free(free, v)) continue;
    for (size_t p = 0; p < m.obstacle_planes.size(); ++p) {
      const ObstaclePlane& plane = m.obstacle_planes[p];
      auto signed_distance = [&](const double* x) {
        return (Eigen::Vector3d::Map(x + 3 * int64_t{v}) - plane.point).dot(plane.normal);
      };
      double s = signed_distance(x0);
      if (x1) s = std::min(s, signed_distance(x1));
      if (pad) s -= pad[v];
      if (s < 2.0 * inflation) out.emplace_back(v, static_cast<int32_t>(p));
    }
  }
}

// Trees over the bodies whose own triangles (edges) are too many to scan for their own pairs,
// in the body frame.
struct SameBodyTrees {
  std::vector<uint8_t> triangle_tree, edge_tree;  // per body: use the tree
  std::vector<BoxTree> triangles, edges;

  SameBodyTrees(const std::vector<BodyPrimitives>& prims, const FrameBoxes& own) {
    const auto nb = static_cast<int64_t>(prims.size());
    triangle_tree.assign(nb, 0);
    edge_tree.assign(nb, 0);
    triangles.resize(nb);
    edges.resize(nb);
    parallel_for(nb, [&](int64_t begin, int64_t end) {
      for (int64_t b = begin; b < end; ++b) {
        const BodyPrimitives& p = prims[b];
        triangle_tree[b] = p.any_free && p.t_end - p.t_begin > kMaxBodyScan;
        edge_tree[b] = p.any_free && p.e_end - p.e_begin > kMaxBodyScan;
        if (triangle_tree[b]) triangles[b].build(own.t_lo.data(), own.t_hi.data(), p.t_begin, p.t_end);
        if (edge_tree[b]) edges[b].build(own.e_lo.data(), own.e_hi.data(), p.e_begin, p.e_end);
      }
    }, 1);
  }
};

}  // namespace nexdyn::candidate_search

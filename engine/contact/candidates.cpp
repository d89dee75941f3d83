// Broad phase of contact (see candidates.hpp).
//
// Two levels. Bodies first: the boxes of whole bodies go through Embree (bvh/broad_phase.hpp),
// which gives the pairs of bodies that can touch. Then primitives: every body gets a BoxTree over
// its triangles and one over its edges, and every surface vertex (edge) queries the trees of its
// own body and of the bodies next to it. A primitive's partners come out together, so sorting
// them locally and concatenating in primitive order gives the sorted list directly.
//
// Same-body pairs are tested in the body's co-moving frame: the body's mean displacement
// x1 - x0 is taken out of the end positions first. Translating both primitives of a pair by the
// same t * shift changes no distance between them, so this is exact, and it keeps a falling body
// from pairing every primitive with every other one along its path.
#include "engine/contact/candidates.hpp"

#include "bvh/box_tree.hpp"
#include "engine/parallel.hpp"

#include <algorithm>
#if defined(__AVX512F__)
#include <immintrin.h>
#endif
#include <bit>
#include <limits>
#include <memory>

namespace nexdyn {

namespace {

// Primitives per parallel chunk of the query loops.
constexpr int64_t kQueryGrain = 512;
// Boxes per block of the linear scans: one vector compare of doubles (AVX-512).
constexpr int kLanes = 8;
// A neighbour's subset larger than this is queried through the neighbour's tree, not scanned.
constexpr int32_t kMaxScan = 256;

bool is_free(const Model& m, int32_t v) { return m.dirichlet[v] < 0; }

// The filters of candidates.hpp, shared by the tree and the brute-force paths. Written with
// bitwise operators: they run on every box overlap, and whether a pair passes is unpredictable.
bool keep_vertex_triangle(const Model& m, int32_t v, int32_t t) {
  const int32_t* tri = &m.surface_triangles[3 * int64_t{t}];
  const bool not_corner = (v != tri[0]) & (v != tri[1]) & (v != tri[2]);
  const bool any_free =
      is_free(m, v) | is_free(m, tri[0]) | is_free(m, tri[1]) | is_free(m, tri[2]);
  return not_corner & any_free;
}

bool keep_edge_edge(const Model& m, int32_t a, int32_t b) {
  const int32_t* ea = &m.surface_edges[2 * int64_t{a}];
  const int32_t* eb = &m.surface_edges[2 * int64_t{b}];
  const bool disjoint = (ea[0] != eb[0]) & (ea[0] != eb[1]) & (ea[1] != eb[0]) & (ea[1] != eb[1]);
  const bool any_free =
      is_free(m, ea[0]) | is_free(m, ea[1]) | is_free(m, eb[0]) | is_free(m, eb[1]);
  return disjoint & any_free;
}

// Per body: the mean of x1 - x0 over its vertices (zero without x1).
std::vector<Eigen::Vector3d> body_shifts(const Model& m, const double* x0, const double* x1) {
  std::vector<Eigen::Vector3d> shift(m.bodies.size(), Eigen::Vector3d::Zero());
  if (!x1) return shift;
  parallel_for(static_cast<int64_t>(m.bodies.size()), [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      const BodyRange& body = m.bodies[b];
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v)
        sum += Eigen::Vector3d::Map(x1 + 3 * int64_t{v}) - Eigen::Vector3d::Map(x0 + 3 * int64_t{v});
      if (body.vertex_count > 0) shift[b] = sum / body.vertex_count;
    }
  }, 1);
  return shift;
}

// Boxes (n x 3 lower, n x 3 upper) of primitives with K vertices each, covering them at x0 and
// at x1 - shift of their body (no shift: shift == nullptr), inflated by r.
template <int K>
void primitive_boxes(const Model& m, const int32_t* ids, int64_t n, const double* x0,
                     const double* x1, const Eigen::Vector3d* shift, double r,
                     std::vector<double>& lower, std::vector<double>& upper) {
  lower.resize(3 * n);
  upper.resize(3 * n);
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const int64_t first = ids[K * i];
      const double* s = shift ? shift[m.vertex_body[first]].data() : nullptr;
      for (int d = 0; d < 3; ++d) {
        double lo = x0[3 * first + d], hi = lo;
        for (int k = 0; k < K; ++k) {
          const int64_t v = ids[K * i + k];
          lo = std::min(lo, x0[3 * v + d]);
          hi = std::max(hi, x0[3 * v + d]);
          if (x1) {
            const double end_position = s ? x1[3 * v + d] - s[d] : x1[3 * v + d];
            lo = std::min(lo, end_position);
            hi = std::max(hi, end_position);
          }
        }
        lower[3 * i + d] = lo - r;
        upper[3 * i + d] = hi + r;
      }
    }
  }, 1024);
}

// Boxes of every surface vertex, edge and triangle in one frame.
struct FrameBoxes {
  std::vector<double> v_lo, v_hi, e_lo, e_hi, t_lo, t_hi;
  FrameBoxes(const Model& m, const double* x0, const double* x1, const Eigen::Vector3d* shift,
             double r) {
    const auto nv = static_cast<int64_t>(m.surface_vertices.size());
    const auto ne = static_cast<int64_t>(m.surface_edges.size() / 2);
    const auto nt = static_cast<int64_t>(m.surface_triangles.size() / 3);
    primitive_boxes<1>(m, m.surface_vertices.data(), nv, x0, x1, shift, r, v_lo, v_hi);
    primitive_boxes<2>(m, m.surface_edges.data(), ne, x0, x1, shift, r, e_lo, e_hi);
    primitive_boxes<3>(m, m.surface_triangles.data(), nt, x0, x1, shift, r, t_lo, t_hi);
  }
};

// Primitive boxes for pairs of different bodies (world frame) and for pairs within one body
// (its co-moving frame). Without motion the two frames are the same boxes.
struct SurfaceBoxes {
  FrameBoxes world;
  std::unique_ptr<FrameBoxes> moving;  // null without x1
  SurfaceBoxes(const Model& m, const double* x0, const double* x1, double r)
      : world(m, x0, x1, nullptr, r) {
    if (!x1) return;
    const std::vector<Eigen::Vector3d> shift = body_shifts(m, x0, x1);
    moving = std::make_unique<FrameBoxes>(m, x0, x1, shift.data(), r);
  }
  const FrameBoxes& body_frame() const { return moving ? *moving : world; }
};

// Index ranges of one body's primitives: surface vertices [sv_begin, sv_end) of
// Model::surface_vertices, its triangles and its edges.
struct BodyPrimitives {
  int32_t sv_begin = 0, sv_end = 0;
  int32_t t_begin = 0, t_end = 0;
  int32_t e_begin = 0, e_end = 0;
  bool any_free = false;  // some vertex of the body is free: its own pairs can matter
};

std::vector<BodyPrimitives> body_primitives(const Model& m) {
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
      p.any_free = is_free(m, v);
  }
  return out;
}

// The pairs of bodies whose world boxes overlap, as a CSR over bodies (found by Embree over the
// body boxes). A body's box is the union of its surface vertices' boxes, which contain its edges'
// and triangles'. Pairs of two bodies without a free vertex are left out.
struct NeighborBodies {
  std::vector<int32_t> ptr;     // body A's entries: [ptr[A], ptr[A + 1])
  std::vector<int32_t> above;   // body A's first entry with a neighbour numbered above A
  std::vector<int32_t> owner;   // entry k: A
  std::vector<int32_t> body;    // entry k: the neighbour B, increasing within A's entries
  std::vector<double> box;      // entry k: B's box (6 numbers: lower, upper)
  std::vector<double> body_lo, body_hi;  // (num_bodies x 3) every body's box

  // Whether box [lo, hi] overlaps the neighbour of entry k.
  bool overlaps(int32_t k, const double* lo, const double* hi) const {
    const double* b = &box[6 * int64_t{k}];
    return (b[0] <= hi[0]) & (lo[0] <= b[3]) & (b[1] <= hi[1]) & (lo[1] <= b[4]) &
           (b[2] <= hi[2]) & (lo[2] <= b[5]);
  }
};

NeighborBodies neighbor_bodies(const Model& m, const std::vector<BodyPrimitives>& prims,
                               const FrameBoxes& world) {
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
      for (int64_t i = prims[b].sv_begin; i < prims[b].sv_end; ++i)
        for (int d = 0; d < 3; ++d) {
          lo[3 * b + d] = std::min(lo[3 * b + d], world.v_lo[3 * i + d]);
          hi[3 * b + d] = std::max(hi[3 * b + d], world.v_hi[3 * i + d]);
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
  out.box.resize(6 * both.size());
  for (size_t k = 0; k < both.size(); ++k) {
    const auto [a, b] = both[k];
    ++out.ptr[a + 1];
    out.above[a] += b < a;
    out.owner[k] = a;
    out.body[k] = b;
    for (int d = 0; d < 3; ++d) {
      out.box[6 * k + d] = lo[3 * size_t(b) + d];
      out.box[6 * k + 3 + d] = hi[3 * size_t(b) + d];
    }
  }
  for (int32_t b = 0; b < nb; ++b) {
    out.ptr[b + 1] += out.ptr[b];
    out.above[b] += out.ptr[b];
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
#if defined(__AVX512F__)
  // Puts the lanes of `pairs` (IndexPair layout) whose bit is set in `keep`, in lane order.
  void put_block(__m512i pairs, __mmask8 keep) {
    _mm512_mask_compressstoreu_epi64(&pairs_[size_], keep, pairs);
    size_ += static_cast<size_t>(std::popcount(unsigned{keep}));
  }
#endif
  size_t size() const { return size_; }
  const IndexPair* data() const { return pairs_.data(); }
  // Sorts the pairs put since size() was `start` (one primitive's partners from a tree query).
  void sort_from(size_t start) {
    std::sort(pairs_.begin() + static_cast<int64_t>(start), pairs_.begin() + static_cast<int64_t>(size_));
  }

 private:
  std::vector<IndexPair> pairs_;
  size_t size_ = 0;
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

// Coordinate arrays of boxes, one per axis and side: the layout of the linear scans, which test
// kLanes boxes per vector compare.
struct BoxColumns {
  std::vector<double> lo[3], hi[3];
  void resize(size_t n) {
    for (int d = 0; d < 3; ++d) {
      lo[d].resize(n);
      hi[d].resize(n);
    }
  }
};

BoxColumns box_columns(const std::vector<double>& lower, const std::vector<double>& upper) {
  BoxColumns c;
  const auto n = static_cast<int64_t>(lower.size() / 3);
  c.resize(static_cast<size_t>(n));
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i)
      for (int d = 0; d < 3; ++d) {
        c.lo[d][i] = lower[3 * i + d];
        c.hi[d][i] = upper[3 * i + d];
      }
  }, 4096);
  return c;
}

// Per primitive of K vertices: whether one of them is free. Primitives of different bodies share
// no vertex, so for them this is the whole filter of candidates.hpp.
template <int K>
std::vector<uint8_t> free_flags(const Model& m, const int32_t* ids, int64_t n) {
  std::vector<uint8_t> out(static_cast<size_t>(n));
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      bool any = false;
      for (int k = 0; k < K; ++k) any |= is_free(m, ids[K * i + k]);
      out[i] = any;
    }
  }, 4096);
  return out;
}

// For each entry k = (body A, neighbour B) of the neighbour CSR: the primitives of B whose world
// boxes overlap A's body box, in increasing id order. A primitive of A only ever meets these, so
// it scans them and gets its partners in B already sorted. They are stored as columns padded to
// whole blocks of kLanes with empty boxes (lower +inf, upper -inf, overlapping nothing). A
// subset larger than kMaxScan is not stored: that entry queries B's tree instead (use_tree), so a
// big body next to a small one costs a log per query, not a long scan.
struct NeighborSubsets {
  std::vector<int64_t> slot_begin;  // entry k: slots [slot_begin[k], slot_begin[k + 1])
  std::vector<uint8_t> use_tree;
  BoxColumns boxes;
  std::vector<int32_t> id;
  std::vector<uint8_t> free_mask;  // per block of kLanes slots, bit j: slot j has a free vertex
};

// range(b) gives body b's primitives [first, last); only entries with wanted(k) get a subset.
template <typename Range, typename Wanted>
NeighborSubsets neighbor_subsets(const NeighborBodies& neighbors, const BoxColumns& boxes,
                                 const std::vector<uint8_t>& free, Range&& range, Wanted&& wanted) {
  const auto entries = static_cast<int64_t>(neighbors.body.size());
  auto overlaps_owner = [&](int64_t k, int32_t p) {
    const double* lo = &neighbors.body_lo[3 * int64_t{neighbors.owner[k]}];
    const double* hi = &neighbors.body_hi[3 * int64_t{neighbors.owner[k]}];
    return (boxes.lo[0][p] <= hi[0]) & (lo[0] <= boxes.hi[0][p]) & (boxes.lo[1][p] <= hi[1]) &
           (lo[1] <= boxes.hi[1][p]) & (boxes.lo[2][p] <= hi[2]) & (lo[2] <= boxes.hi[2][p]);
  };
  NeighborSubsets s;
  std::vector<int32_t> count(static_cast<size_t>(entries), 0);
  s.use_tree.assign(static_cast<size_t>(entries), 0);
  parallel_for(entries, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      if (!wanted(k)) continue;
      const auto [first, last] = range(neighbors.body[k]);
      int32_t n = 0;
      for (int32_t p = first; p < last; ++p) n += overlaps_owner(k, p);
      count[k] = n;
      s.use_tree[k] = n > kMaxScan;
    }
  }, 16);
  s.slot_begin.assign(static_cast<size_t>(entries) + 1, 0);
  for (int64_t k = 0; k < entries; ++k)
    s.slot_begin[k + 1] = s.slot_begin[k] + (s.use_tree[k] ? 0 : (count[k] + kLanes - 1) / kLanes * kLanes);
  const auto slots = static_cast<size_t>(s.slot_begin.back());
  s.boxes.resize(slots);
  s.id.resize(slots);
  s.free_mask.assign(slots / kLanes, 0);
  parallel_for(entries, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      if (s.slot_begin[k + 1] == s.slot_begin[k]) continue;
      int64_t slot = s.slot_begin[k];
      const auto [first, last] = range(neighbors.body[k]);
      for (int32_t p = first; p < last; ++p)
        if (overlaps_owner(k, p)) {
          for (int d = 0; d < 3; ++d) {
            s.boxes.lo[d][slot] = boxes.lo[d][p];
            s.boxes.hi[d][slot] = boxes.hi[d][p];
          }
          s.id[slot] = p;
          s.free_mask[slot / kLanes] |= static_cast<uint8_t>(free[p] << (slot % kLanes));
          ++slot;
        }
      for (; slot < s.slot_begin[k + 1]; ++slot) {
        for (int d = 0; d < 3; ++d) {
          s.boxes.lo[d][slot] = std::numeric_limits<double>::infinity();
          s.boxes.hi[d][slot] = -std::numeric_limits<double>::infinity();
        }
        s.id[slot] = 0;
      }
    }
  }, 16);
  return s;
}

// Puts (first, p) for every primitive p of subset entry k whose box overlaps [lo, hi], in
// increasing p. With AVX-512 a block of kLanes boxes is one compare per bound and one compressed
// store of the kept pairs, no branch; otherwise the same per box.
void scan_subset(const NeighborSubsets& s, int64_t k, const double* lo, const double* hi,
                 int32_t first, bool first_free, PairBuffer& out) {
  const int64_t begin = s.slot_begin[k], end = s.slot_begin[k + 1];
  out.room(static_cast<size_t>(end - begin));
#if defined(__AVX512F__)
  static_assert(kLanes == 8 && sizeof(IndexPair) == 8);
  const __m512d qlo[3] = {_mm512_set1_pd(lo[0]), _mm512_set1_pd(lo[1]), _mm512_set1_pd(lo[2])};
  const __m512d qhi[3] = {_mm512_set1_pd(hi[0]), _mm512_set1_pd(hi[1]), _mm512_set1_pd(hi[2])};
  const __m512i first_lane = _mm512_set1_epi64(static_cast<uint32_t>(first));  // pair.first: low half
  for (int64_t base = begin; base < end; base += kLanes) {
    __mmask8 hits = first_free ? 0xff : s.free_mask[base / kLanes];
    for (int d = 0; d < 3; ++d) {
      hits = _mm512_mask_cmp_pd_mask(hits, _mm512_loadu_pd(&s.boxes.lo[d][base]), qhi[d], _CMP_LE_OQ);
      hits = _mm512_mask_cmp_pd_mask(hits, qlo[d], _mm512_loadu_pd(&s.boxes.hi[d][base]), _CMP_LE_OQ);
    }
    const __m512i ids = _mm512_cvtepu32_epi64(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(&s.id[base])));
    out.put_block(_mm512_or_si512(first_lane, _mm512_slli_epi64(ids, 32)), hits);
  }
#else
  for (int64_t q = begin; q < end; ++q) {
    bool hit = first_free || ((s.free_mask[q / kLanes] >> (q % kLanes)) & 1);
    for (int d = 0; d < 3; ++d) hit &= (s.boxes.lo[d][q] <= hi[d]) & (lo[d] <= s.boxes.hi[d][q]);
    out.put(first, s.id[q], hit);
  }
#endif
}

void find_vertex_plane(const Model& m, const double* x0, const double* x1, double inflation,
                       std::vector<IndexPair>& out) {
  out.clear();
  for (int32_t v : m.surface_vertices) {
    if (!is_free(m, v)) continue;
    for (size_t p = 0; p < m.obstacle_planes.size(); ++p) {
      const ObstaclePlane& plane = m.obstacle_planes[p];
      auto signed_distance = [&](const double* x) {
        return (Eigen::Vector3d::Map(x + 3 * int64_t{v}) - plane.point).dot(plane.normal);
      };
      double s = signed_distance(x0);
      if (x1) s = std::min(s, signed_distance(x1));
      if (s < 2.0 * inflation) out.emplace_back(v, static_cast<int32_t>(p));
    }
  }
}

// Pairs as rows of partners: row i holds the partners of query primitive i (a surface vertex
// index, or an edge), sorted.
struct PairRows {
  std::vector<int64_t> row;  // row i: partner[row[i], row[i + 1])
  std::vector<int32_t> partner;

  // Concatenates per-body lists of (query primitive, partner), sorted, whose query primitives
  // are numbered contiguously per body in body order, into rows over [0, num_rows).
  PairRows(const std::vector<std::vector<IndexPair>>& lists, int64_t num_rows) {
    std::vector<size_t> offset(lists.size() + 1, 0);
    for (size_t b = 0; b < lists.size(); ++b) offset[b + 1] = offset[b] + lists[b].size();
    partner.resize(offset.back());
    row.assign(static_cast<size_t>(num_rows) + 1, 0);
    parallel_for(static_cast<int64_t>(lists.size()), [&](int64_t begin, int64_t end) {
      for (int64_t b = begin; b < end; ++b)
        for (size_t j = 0; j < lists[b].size(); ++j) {
          partner[offset[b] + j] = lists[b][j].second;
          ++row[lists[b][j].first + 1];  // rows of one body are its own
        }
    }, 1);
    for (int64_t i = 0; i < num_rows; ++i) row[i + 1] += row[i];
  }

  // Puts (first, p) for the partners p of row i.
  void put_row(int32_t i, int32_t first, PairBuffer& out) const {
    const int64_t begin = row[i], end = row[i + 1];
    out.room(static_cast<size_t>(end - begin));
    for (int64_t j = begin; j < end; ++j) out.put(first, partner[j], true);
  }
};

// The kept pairs within each body, from its boxes in its own frame: a tree over its vertices
// traversed against one over its triangles, and its edge tree against itself (each pair met
// once). Rows are surface vertex indices and edges; edge pairs (a, b) have a < b.
struct SameBodyPairs {
  PairRows vertex_triangle, edge_edge;
};

SameBodyPairs same_body_pairs(const Model& m, const std::vector<BodyPrimitives>& prims,
                              const FrameBoxes& own) {
  const auto nb = static_cast<int64_t>(m.bodies.size());
  std::vector<std::vector<IndexPair>> vt(nb), ee(nb);
  parallel_for(nb, [&](int64_t begin, int64_t end) {
    BoxTree vertices, triangles, edges;
    for (int64_t b = begin; b < end; ++b) {
      const BodyPrimitives& p = prims[b];
      if (!p.any_free) continue;
      vertices.build(own.v_lo.data(), own.v_hi.data(), p.sv_begin, p.sv_end);
      triangles.build(own.t_lo.data(), own.t_hi.data(), p.t_begin, p.t_end);
      edges.build(own.e_lo.data(), own.e_hi.data(), p.e_begin, p.e_end);
      vertices.pairs_with(triangles, [&](int32_t i, int32_t t) {
        if (keep_vertex_triangle(m, m.surface_vertices[i], t)) vt[b].emplace_back(i, t);
      });
      edges.self_pairs([&](int32_t e, int32_t f) {
        if (keep_edge_edge(m, e, f)) ee[b].emplace_back(std::min(e, f), std::max(e, f));
      });
      std::sort(vt[b].begin(), vt[b].end());
      std::sort(ee[b].begin(), ee[b].end());
    }
  }, 1);
  return {PairRows(vt, static_cast<int64_t>(m.surface_vertices.size())),
          PairRows(ee, static_cast<int64_t>(m.surface_edges.size() / 2))};
}

}  // namespace

void find_contact_candidates(const Model& m, const double* x0, const double* x1, double inflation,
                             ContactCandidates& out) {
  const SurfaceBoxes boxes(m, x0, x1, inflation);
  const FrameBoxes& world = boxes.world;
  const FrameBoxes& own = boxes.body_frame();
  const std::vector<BodyPrimitives> prims = body_primitives(m);
  const auto nb = static_cast<int64_t>(m.bodies.size());
  const NeighborBodies neighbors = neighbor_bodies(m, prims, world);

  const auto nt = static_cast<int64_t>(m.surface_triangles.size() / 3);
  const auto ne = static_cast<int64_t>(m.surface_edges.size() / 2);
  const std::vector<uint8_t> tri_free = free_flags<3>(m, m.surface_triangles.data(), nt);
  const std::vector<uint8_t> edge_free = free_flags<2>(m, m.surface_edges.data(), ne);
  // Vertex-triangle pairs need every neighbour's triangles; edge-edge pairs are found from their
  // lower edge, so only the higher-numbered neighbours' edges.
  const NeighborSubsets tri_near = neighbor_subsets(
      neighbors, box_columns(world.t_lo, world.t_hi), tri_free,
      [&](int32_t b) { return std::pair{prims[b].t_begin, prims[b].t_end}; },
      [](int64_t) { return true; });
  const NeighborSubsets edge_near = neighbor_subsets(
      neighbors, box_columns(world.e_lo, world.e_hi), edge_free,
      [&](int32_t b) { return std::pair{prims[b].e_begin, prims[b].e_end}; },
      [&](int64_t k) { return neighbors.body[k] > neighbors.owner[k]; });

  // Trees over the world boxes of the neighbours too many to scan.
  std::vector<uint8_t> tri_tree_needed(nb, 0), edge_tree_needed(nb, 0);
  for (size_t k = 0; k < neighbors.body.size(); ++k) {
    tri_tree_needed[neighbors.body[k]] |= tri_near.use_tree[k];
    edge_tree_needed[neighbors.body[k]] |= edge_near.use_tree[k];
  }
  std::vector<BoxTree> tri_world(nb), edge_world(nb);
  parallel_for(nb, [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      if (tri_tree_needed[b])
        tri_world[b].build(world.t_lo.data(), world.t_hi.data(), prims[b].t_begin, prims[b].t_end);
      if (edge_tree_needed[b])
        edge_world[b].build(world.e_lo.data(), world.e_hi.data(), prims[b].e_begin, prims[b].e_end);
    }
  }, 1);
  const SameBodyPairs same_body = same_body_pairs(m, prims, own);

  // A primitive's pairs with neighbour entry k: none unless it overlaps that body's box, else a
  // scan of the subset or, for big subsets, a query of the neighbour's tree.
  auto neighbor_pairs = [&](const NeighborSubsets& subsets, const std::vector<BoxTree>& trees,
                            const std::vector<uint8_t>& partner_free, int32_t k, const double* lo,
                            const double* hi, int32_t first, bool first_free, PairBuffer& buffer) {
    if (!neighbors.overlaps(k, lo, hi)) return;
    if (!subsets.use_tree[k]) return scan_subset(subsets, k, lo, hi, first, first_free, buffer);
    const size_t start = buffer.size();
    trees[neighbors.body[k]].query(lo, hi, [&](int32_t p) {
      buffer.room(1);
      buffer.put(first, p, first_free | (partner_free[p] != 0));
    });
    buffer.sort_from(start);
  };

  // Vertex-triangle: each surface vertex against the neighbours below its body, its own body and
  // the neighbours above, so that its partners come out in increasing triangle order.
  collect_pairs(
      static_cast<int64_t>(m.surface_vertices.size()),
      [&](int32_t i, PairBuffer& buffer) {
        const int32_t v = m.surface_vertices[i];
        const int32_t body = m.vertex_body[v];
        const bool v_free = is_free(m, v);
        const double* lo = &world.v_lo[3 * int64_t{i}];
        const double* hi = &world.v_hi[3 * int64_t{i}];
        for (int32_t k = neighbors.ptr[body]; k < neighbors.above[body]; ++k)
          neighbor_pairs(tri_near, tri_world, tri_free, k, lo, hi, v, v_free, buffer);
        same_body.vertex_triangle.put_row(i, v, buffer);
        for (int32_t k = neighbors.above[body]; k < neighbors.ptr[body + 1]; ++k)
          neighbor_pairs(tri_near, tri_world, tri_free, k, lo, hi, v, v_free, buffer);
      },
      out.vertex_triangle);

  // Edge-edge: each edge against the higher-numbered edges of its body, then of the neighbours
  // above its body.
  collect_pairs(
      ne,
      [&](int32_t a, PairBuffer& buffer) {
        const int32_t body = m.vertex_body[m.surface_edges[2 * int64_t{a}]];
        same_body.edge_edge.put_row(a, a, buffer);
        const double* lo = &world.e_lo[3 * int64_t{a}];
        const double* hi = &world.e_hi[3 * int64_t{a}];
        for (int32_t k = neighbors.above[body]; k < neighbors.ptr[body + 1]; ++k)
          neighbor_pairs(edge_near, edge_world, edge_free, k, lo, hi, a, edge_free[a] != 0, buffer);
      },
      out.edge_edge);

  find_vertex_plane(m, x0, x1, inflation, out.vertex_plane);
}

void find_contact_candidates_brute_force(const Model& m, const double* x0, const double* x1,
                                         double inflation, ContactCandidates& out) {
  const SurfaceBoxes boxes(m, x0, x1, inflation);
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
          keep_vertex_triangle(m, v, static_cast<int32_t>(t)))
        out.vertex_triangle.emplace_back(v, static_cast<int32_t>(t));
    }
  }
  for (int64_t e = 0; e < ne; ++e)
    for (int64_t g = e + 1; g < ne; ++g) {
      const FrameBoxes& f =
          frame(m.vertex_body[m.surface_edges[2 * e]], m.vertex_body[m.surface_edges[2 * g]]);
      if (boxes_overlap(f.e_lo.data(), f.e_hi.data(), e, f.e_lo.data(), f.e_hi.data(), g) &&
          keep_edge_edge(m, static_cast<int32_t>(e), static_cast<int32_t>(g)))
        out.edge_edge.emplace_back(static_cast<int32_t>(e), static_cast<int32_t>(g));
    }
  find_vertex_plane(m, x0, x1, inflation, out.vertex_plane);
}

}  // namespace nexdyn

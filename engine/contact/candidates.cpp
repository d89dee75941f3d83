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
#include <limits>
#include <memory>

namespace nexdyn {

namespace {

// Primitives per parallel chunk of the query loops.
constexpr int64_t kQueryGrain = 512;

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

// One primitive's partners. add() stores every id and only advances past the kept ones, so the
// filter costs no branch.
class Partners {
 public:
  void clear() { size_ = 0; }
  void add(int32_t id, bool keep) {
    if (size_ == ids_.size()) ids_.resize(2 * ids_.size() + 64);
    ids_[size_] = id;
    size_ += keep;
  }
  int32_t* begin() { return ids_.data(); }
  int32_t* end() { return ids_.data() + size_; }

 private:
  std::vector<int32_t> ids_;
  size_t size_ = 0;
};

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

// For every body, the other bodies whose world boxes overlap its own (CSR, sorted) and their
// boxes (6 per entry: lower, upper), found by Embree over the body boxes. A body's box is the union of its surface vertices' boxes, which
// contain its edges' and triangles'. Pairs of two bodies without a free vertex are left out.
void neighbor_bodies(const Model& m, const std::vector<BodyPrimitives>& prims,
                     const FrameBoxes& world, std::vector<int32_t>& ptr,
                     std::vector<int32_t>& neighbors, std::vector<double>& neighbor_boxes) {
  const auto nb = static_cast<int32_t>(m.bodies.size());
  std::vector<double> lo(3 * size_t(nb)), hi(3 * size_t(nb));
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

  std::vector<int32_t> count(size_t(nb) + 1, 0);
  std::vector<IndexPair> both;
  both.reserve(2 * pairs.size());
  for (const IndexPair& p : pairs) {
    const int32_t a = with_surface[p.first], b = with_surface[p.second];
    if (!prims[a].any_free && !prims[b].any_free) continue;
    both.emplace_back(a, b);
    both.emplace_back(b, a);
  }
  std::sort(both.begin(), both.end());
  ptr.assign(size_t(nb) + 1, 0);
  neighbors.resize(both.size());
  neighbor_boxes.resize(6 * both.size());
  for (size_t k = 0; k < both.size(); ++k) {
    ++ptr[both[k].first + 1];
    const int32_t b = both[k].second;
    neighbors[k] = b;
    for (int d = 0; d < 3; ++d) {
      neighbor_boxes[6 * k + d] = lo[3 * size_t(b) + d];
      neighbor_boxes[6 * k + 3 + d] = hi[3 * size_t(b) + d];
    }
  }
  for (int32_t b = 0; b < nb; ++b) ptr[b + 1] += ptr[b];
}

// Runs find(i, partners) for every primitive i of [0, n) in parallel, sorts each primitive's
// partners and writes the pairs (i', partner) in order of i, where i' = first_of(i).
template <typename FirstOf, typename Find>
void collect_sorted_pairs(int64_t n, FirstOf&& first_of, Find&& find, std::vector<IndexPair>& out) {
  std::vector<std::vector<IndexPair>> chunks(static_cast<size_t>((n + kQueryGrain - 1) / kQueryGrain));
  for_each_chunk(n, kQueryGrain, [&](int64_t c, int64_t begin, int64_t end) {
    Partners partners;
    std::vector<IndexPair>& local = chunks[c];
    for (int64_t i = begin; i < end; ++i) {
      partners.clear();
      find(static_cast<int32_t>(i), partners);
      std::sort(partners.begin(), partners.end());
      const int32_t first = first_of(static_cast<int32_t>(i));
      for (int32_t p : partners) local.emplace_back(first, p);
    }
  });
  std::vector<size_t> offset(chunks.size() + 1, 0);
  for (size_t c = 0; c < chunks.size(); ++c) offset[c + 1] = offset[c] + chunks[c].size();
  out.resize(offset.back());
  parallel_for(static_cast<int64_t>(chunks.size()), [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c)
      std::copy(chunks[c].begin(), chunks[c].end(), out.begin() + static_cast<int64_t>(offset[c]));
  }, 1);
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

}  // namespace

void find_contact_candidates(const Model& m, const double* x0, const double* x1, double inflation,
                             ContactCandidates& out) {
  const SurfaceBoxes boxes(m, x0, x1, inflation);
  const FrameBoxes& world = boxes.world;
  const FrameBoxes& own = boxes.body_frame();
  const std::vector<BodyPrimitives> prims = body_primitives(m);
  const auto nb = static_cast<int64_t>(m.bodies.size());

  std::vector<int32_t> neighbor_ptr, neighbors;
  std::vector<double> neighbor_boxes;
  neighbor_bodies(m, prims, world, neighbor_ptr, neighbors, neighbor_boxes);
  // A primitive only queries a neighbour's tree when it overlaps that body's box.
  auto near_neighbor = [&](int32_t k, const double* lo, const double* hi) {
    const double* box = &neighbor_boxes[6 * int64_t{k}];
    return (box[0] <= hi[0]) & (lo[0] <= box[3]) & (box[1] <= hi[1]) & (lo[1] <= box[4]) &
           (box[2] <= hi[2]) & (lo[2] <= box[5]);
  };

  // Trees over each body's triangles and edges: in the world frame for the neighbours' queries,
  // in the body frame for its own (the same trees when nothing moves).
  std::vector<BoxTree> tri_world(nb), edge_world(nb), tri_own, edge_own;
  if (boxes.moving) {
    tri_own.resize(nb);
    edge_own.resize(nb);
  }
  parallel_for(nb, [&](int64_t begin, int64_t end) {
    for (int64_t b = begin; b < end; ++b) {
      const BodyPrimitives& p = prims[b];
      const bool for_neighbors = neighbor_ptr[b + 1] > neighbor_ptr[b];
      const bool for_self = p.any_free;
      if (for_neighbors || (for_self && !boxes.moving)) {
        tri_world[b].build(world.t_lo.data(), world.t_hi.data(), p.t_begin, p.t_end);
        edge_world[b].build(world.e_lo.data(), world.e_hi.data(), p.e_begin, p.e_end);
      }
      if (for_self && boxes.moving) {
        tri_own[b].build(own.t_lo.data(), own.t_hi.data(), p.t_begin, p.t_end);
        edge_own[b].build(own.e_lo.data(), own.e_hi.data(), p.e_begin, p.e_end);
      }
    }
  }, 1);
  const std::vector<BoxTree>& tri_self = boxes.moving ? tri_own : tri_world;
  const std::vector<BoxTree>& edge_self = boxes.moving ? edge_own : edge_world;

  // Vertex-triangle: each surface vertex against its body's triangles and its neighbours'.
  collect_sorted_pairs(
      static_cast<int64_t>(m.surface_vertices.size()),
      [&](int32_t i) { return m.surface_vertices[i]; },
      [&](int32_t i, Partners& partners) {
        const int32_t v = m.surface_vertices[i];
        const int32_t body = m.vertex_body[v];
        auto keep = [&](int32_t t) { partners.add(t, keep_vertex_triangle(m, v, t)); };
        if (prims[body].any_free)
          tri_self[body].query(&own.v_lo[3 * int64_t{i}], &own.v_hi[3 * int64_t{i}], keep);
        const double* lo = &world.v_lo[3 * int64_t{i}];
        const double* hi = &world.v_hi[3 * int64_t{i}];
        for (int32_t k = neighbor_ptr[body]; k < neighbor_ptr[body + 1]; ++k)
          if (near_neighbor(k, lo, hi)) tri_world[neighbors[k]].query(lo, hi, keep);
      },
      out.vertex_triangle);

  // Edge-edge: each edge against the higher-numbered edges of its body and its neighbours'.
  collect_sorted_pairs(
      static_cast<int64_t>(m.surface_edges.size() / 2), [](int32_t a) { return a; },
      [&](int32_t a, Partners& partners) {
        const int32_t body = m.vertex_body[m.surface_edges[2 * int64_t{a}]];
        auto keep = [&](int32_t b) { partners.add(b, (b > a) & keep_edge_edge(m, a, b)); };
        if (prims[body].any_free)
          edge_self[body].query(&own.e_lo[3 * int64_t{a}], &own.e_hi[3 * int64_t{a}], keep);
        const double* lo = &world.e_lo[3 * int64_t{a}];
        const double* hi = &world.e_hi[3 * int64_t{a}];
        for (int32_t k = neighbor_ptr[body]; k < neighbor_ptr[body + 1]; ++k) {
          const int32_t other = neighbors[k];
          if (prims[other].e_end - 1 <= a) continue;  // all its edges are numbered below a
          if (near_neighbor(k, lo, hi)) edge_world[other].query(lo, hi, keep);
        }
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

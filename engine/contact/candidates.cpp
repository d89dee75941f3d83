// Broad phase of contact (see candidates.hpp).
#include "engine/contact/candidates.hpp"

#include "engine/parallel.hpp"

#include <algorithm>

namespace nexdyn {

namespace {

// Boxes (n x 3 lower, n x 3 upper) of primitives with K vertices each, covering them at x0 and x1.
template <int K>
void primitive_boxes(const int32_t* ids, int64_t n, const double* x0, const double* x1, double r,
                     std::vector<double>& lower, std::vector<double>& upper) {
  lower.resize(3 * n);
  upper.resize(3 * n);
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      for (int d = 0; d < 3; ++d) {
        double lo = x0[3 * int64_t{ids[K * i]} + d], hi = lo;
        for (int k = 0; k < K; ++k) {
          const int64_t v = ids[K * i + k];
          lo = std::min(lo, x0[3 * v + d]);
          hi = std::max(hi, x0[3 * v + d]);
          if (x1) {
            lo = std::min(lo, x1[3 * v + d]);
            hi = std::max(hi, x1[3 * v + d]);
          }
        }
        lower[3 * i + d] = lo - r;
        upper[3 * i + d] = hi + r;
      }
    }
  }, 1024);
}

// Boxes of every surface vertex, edge and triangle.
struct SurfaceBoxes {
  int64_t nv, ne, nt;
  std::vector<double> v_lo, v_hi, e_lo, e_hi, t_lo, t_hi;
  SurfaceBoxes(const Model& m, const double* x0, const double* x1, double inflation)
      : nv(static_cast<int64_t>(m.surface_vertices.size())),
        ne(static_cast<int64_t>(m.surface_edges.size() / 2)),
        nt(static_cast<int64_t>(m.surface_triangles.size() / 3)) {
    primitive_boxes<1>(m.surface_vertices.data(), nv, x0, x1, inflation, v_lo, v_hi);
    primitive_boxes<2>(m.surface_edges.data(), ne, x0, x1, inflation, e_lo, e_hi);
    primitive_boxes<3>(m.surface_triangles.data(), nt, x0, x1, inflation, t_lo, t_hi);
  }
};

bool is_free(const Model& m, int32_t v) { return m.dirichlet[v] < 0; }

// The filters of candidates.hpp, shared by the BVH and the brute-force paths.
bool keep_vertex_triangle(const Model& m, int32_t v, int32_t t) {
  const int32_t* tri = &m.surface_triangles[3 * int64_t{t}];
  if (v == tri[0] || v == tri[1] || v == tri[2]) return false;
  return is_free(m, v) || is_free(m, tri[0]) || is_free(m, tri[1]) || is_free(m, tri[2]);
}

bool keep_edge_edge(const Model& m, int32_t a, int32_t b) {
  const int32_t* ea = &m.surface_edges[2 * int64_t{a}];
  const int32_t* eb = &m.surface_edges[2 * int64_t{b}];
  if (ea[0] == eb[0] || ea[0] == eb[1] || ea[1] == eb[0] || ea[1] == eb[1]) return false;
  return is_free(m, ea[0]) || is_free(m, ea[1]) || is_free(m, eb[0]) || is_free(m, eb[1]);
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

template <typename Keep>
void filter(std::vector<IndexPair>& pairs, Keep&& keep) {
  pairs.erase(std::remove_if(pairs.begin(), pairs.end(),
                             [&](const IndexPair& p) { return !keep(p.first, p.second); }),
              pairs.end());
}

}  // namespace

void find_contact_candidates(const Model& m, const double* x0, const double* x1, double inflation,
                             ContactCandidates& out) {
  const SurfaceBoxes b(m, x0, x1, inflation);

  out.vertex_triangle = overlapping_pairs(b.v_lo.data(), b.v_hi.data(), static_cast<int32_t>(b.nv),
                                          b.t_lo.data(), b.t_hi.data(), static_cast<int32_t>(b.nt));
  // Surface vertex index -> vertex id keeps the order: surface_vertices is sorted.
  for (IndexPair& p : out.vertex_triangle) p.first = m.surface_vertices[p.first];
  filter(out.vertex_triangle, [&](int32_t v, int32_t t) { return keep_vertex_triangle(m, v, t); });

  out.edge_edge = self_overlapping_pairs(b.e_lo.data(), b.e_hi.data(), static_cast<int32_t>(b.ne));
  filter(out.edge_edge, [&](int32_t a, int32_t b) { return keep_edge_edge(m, a, b); });

  find_vertex_plane(m, x0, x1, inflation, out.vertex_plane);
}

void find_contact_candidates_brute_force(const Model& m, const double* x0, const double* x1,
                                         double inflation, ContactCandidates& out) {
  const SurfaceBoxes b(m, x0, x1, inflation);
  out.clear();
  for (int64_t i = 0; i < b.nv; ++i)
    for (int64_t t = 0; t < b.nt; ++t)
      if (boxes_overlap(b.v_lo.data(), b.v_hi.data(), i, b.t_lo.data(), b.t_hi.data(), t) &&
          keep_vertex_triangle(m, m.surface_vertices[i], static_cast<int32_t>(t)))
        out.vertex_triangle.emplace_back(m.surface_vertices[i], static_cast<int32_t>(t));
  for (int64_t e = 0; e < b.ne; ++e)
    for (int64_t f = e + 1; f < b.ne; ++f)
      if (boxes_overlap(b.e_lo.data(), b.e_hi.data(), e, b.e_lo.data(), b.e_hi.data(), f) &&
          keep_edge_edge(m, static_cast<int32_t>(e), static_cast<int32_t>(f)))
        out.edge_edge.emplace_back(static_cast<int32_t>(e), static_cast<int32_t>(f));
  find_vertex_plane(m, x0, x1, inflation, out.vertex_plane);
}

}  // namespace nexdyn

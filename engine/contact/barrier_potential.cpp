// Barrier potential over contact pairs (see barrier_potential.hpp).
#include "engine/contact/barrier_potential.hpp"

#include "engine/parallel.hpp"
#include "kernels/barrier/barrier.hpp"
#include "kernels/ccd/ccd.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/projection/psd_projection.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int64_t kPairGrain = 256;

// A CCD step stops at a distance of at most this fraction of dhat (and of the starting
// distance): far enough from 0 that the barrier stays finite, close enough not to stall.
constexpr double kCcdGapFraction = 0.1;

// A stencil Hessian whose eigenvalues are all above -kPsdTolerance times its largest diagonal
// entry counts as PSD and is kept unprojected (cholesky_psd_test).
constexpr double kPsdTolerance = 1e-12;

Eigen::Vector3d point(const double* x, int32_t v) { return Eigen::Vector3d::Map(x + 3 * int64_t{v}); }

// The closest feature of a pair within its 4-point stencil: the squared distance is a
// point-point (n = 2), point-line (n = 3), point-plane or line-line (n = 4) distance of the
// stencil points idx[0..n).
struct Feature {
  int n;
  int idx[4];
};

Feature feature_of(PointTriangleCase c) {
  switch (c) {
    case PointTriangleCase::p_t0: return {2, {0, 1}};
    case PointTriangleCase::p_t1: return {2, {0, 2}};
    case PointTriangleCase::p_t2: return {2, {0, 3}};
    case PointTriangleCase::p_e0: return {3, {0, 1, 2}};
    case PointTriangleCase::p_e1: return {3, {0, 2, 3}};
    case PointTriangleCase::p_e2: return {3, {0, 3, 1}};
    case PointTriangleCase::p_t: break;
  }
  return {4, {0, 1, 2, 3}};
}

Feature feature_of(EdgeEdgeCase c) {
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return {2, {0, 2}};
    case EdgeEdgeCase::ea0_eb1: return {2, {0, 3}};
    case EdgeEdgeCase::ea1_eb0: return {2, {1, 2}};
    case EdgeEdgeCase::ea1_eb1: return {2, {1, 3}};
    case EdgeEdgeCase::ea_eb0: return {3, {2, 0, 1}};
    case EdgeEdgeCase::ea_eb1: return {3, {3, 0, 1}};
    case EdgeEdgeCase::ea0_eb: return {3, {0, 2, 3}};
    case EdgeEdgeCase::ea1_eb: return {3, {1, 2, 3}};
    case EdgeEdgeCase::ea_eb: break;
  }
  return {4, {0, 1, 2, 3}};
}

// Gradient and (when H is given) Hessian of the squared distance of an edge-edge pair's closest
// feature, placed into the pair's 12 DOFs (for the product rule of a mollified pair).
void edge_edge_full_derivatives(const Feature& f, const Eigen::Vector3d (&X)[4], Vector12d& g,
                                Matrix12d* H) {
  g.setZero();
  if (H) H->setZero();
  auto scatter = [&](const auto& gr, auto&& hessian, int n) {
    for (int i = 0; i < n; ++i) g.segment<3>(3 * f.idx[i]) = gr.template segment<3>(3 * i);
    if (!H) return;
    const auto hr = hessian();
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        H->block<3, 3>(3 * f.idx[i], 3 * f.idx[j]) = hr.template block<3, 3>(3 * i, 3 * j);
  };
  const Eigen::Vector3d& a = X[f.idx[0]];
  const Eigen::Vector3d& b = X[f.idx[1]];
  if (f.n == 2) {
    scatter(point_point_distance_gradient(a, b), [&] { return point_point_distance_hessian(a, b); }, 2);
  } else if (f.n == 3) {
    const Eigen::Vector3d& c = X[f.idx[2]];
    scatter(point_line_distance_gradient(a, b, c), [&] { return point_line_distance_hessian(a, b, c); }, 3);
  } else {
    g = line_line_distance_gradient(X[0], X[1], X[2], X[3]);
    if (H) *H = line_line_distance_hessian(X[0], X[1], X[2], X[3]);
  }
}

double edge_edge_threshold(const Model& m, const int32_t* ea, const int32_t* eb) {
  const double* r = m.rest_positions.data();
  return edge_edge_mollifier_threshold(point(r, ea[0]), point(r, ea[1]), point(r, eb[0]), point(r, eb[1]));
}

}  // namespace

double bodies_bbox_diagonal(const Model& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf), hi = -lo;
  for (const BodyRange& body : model.bodies) {
    if (body.obstacle) continue;
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
      lo = lo.cwiseMin(point(model.rest_positions.data(), v));
      hi = hi.cwiseMax(point(model.rest_positions.data(), v));
    }
  }
  return (lo.array() <= hi.array()).all() ? (hi - lo).norm() : 0.0;
}

BarrierPotential::BarrierPotential(const Model& model, double dhat)
    : model_(model), dhat_(dhat), dhat2_(dhat * dhat) {
  x1_.resize(model.num_dofs());
  pair_x_.resize(model.num_dofs());
}

void BarrierPotential::find_candidates(const double* x0, const double* x1) {
  const int64_t n = model_.num_dofs();
  // A static search at the positions of the last one (friction lags, then the solve) is a no-op.
  if (!x1 && static_search_ && std::equal(x0, x0 + n, static_x_.begin())) return;
  ProfileScope scope(profile_, StepPhase::broad_phase);
  find_contact_candidates(model_, x0, x1, 0.5 * dhat_, candidates_);
  forget_pairs();
  static_search_ = x1 == nullptr;
  if (static_search_) static_x_.assign(x0, x0 + n);
}

// ---- distances and energy -------------------------------------------------------------------

namespace {

// Squared distance and barrier value of one pair. The value is +inf for d <= 0.
struct PairEval {
  double d = kInf;
  double energy = 0.0;
};

PairEval eval_vertex_triangle(const Model& m, const double* x, const IndexPair& pair, double dhat2) {
  const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
  PairEval e;
  e.d = point_triangle_distance(point(x, pair.first), point(x, t[0]), point(x, t[1]), point(x, t[2]));
  e.energy = e.d < dhat2 ? barrier(e.d, dhat2) : 0.0;
  return e;
}

PairEval eval_edge_edge(const Model& m, const double* x, const IndexPair& pair, double dhat2) {
  const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
  const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
  const Eigen::Vector3d a0 = point(x, ea[0]), a1 = point(x, ea[1]);
  const Eigen::Vector3d b0 = point(x, eb[0]), b1 = point(x, eb[1]);
  PairEval e;
  e.d = edge_edge_distance(a0, a1, b0, b1);
  if (e.d < dhat2) {
    e.energy = barrier(e.d, dhat2);
    if (std::isfinite(e.energy))
      e.energy *= edge_edge_mollifier(a0, a1, b0, b1, edge_edge_threshold(m, ea, eb));
  }
  return e;
}

PairEval eval_vertex_plane(const Model& m, const double* x, const IndexPair& pair, double dhat2) {
  const ObstaclePlane& plane = m.obstacle_planes[pair.second];
  const double s = (point(x, pair.first) - plane.point).dot(plane.normal);
  PairEval e;
  e.d = s > 0.0 ? s * s : 0.0;  // behind the plane counts as touching
  e.energy = e.d < dhat2 ? barrier(e.d, dhat2) : 0.0;
  return e;
}

// Calls f(kind, index, eval) over all candidates in a fixed order; reduces with `combine`.
template <typename Reduce>
double reduce_pairs(const Model& m, const ContactCandidates& c, const double* x, double dhat2,
                    double init, Reduce&& reduce) {
  double result = init;
  auto over = [&](const std::vector<IndexPair>& pairs, auto&& eval) {
    const int64_t n = static_cast<int64_t>(pairs.size());
    const int64_t chunks = (n + kPairGrain - 1) / kPairGrain;
    std::vector<double> partial(chunks, init);
    parallel_for(chunks, [&](int64_t cb, int64_t ce) {
      for (int64_t k = cb; k < ce; ++k) {
        double acc = init;
        for (int64_t i = k * kPairGrain; i < std::min(n, (k + 1) * kPairGrain); ++i)
          acc = reduce(acc, eval(m, x, pairs[i], dhat2));
        partial[k] = acc;
      }
    }, 1);
    for (double p : partial) result = reduce.combine(result, p);
  };
  over(c.vertex_triangle, eval_vertex_triangle);
  over(c.edge_edge, eval_edge_edge);
  over(c.vertex_plane, eval_vertex_plane);
  return result;
}

struct SumEnergy {
  double operator()(double acc, const PairEval& e) const { return acc + e.energy; }
  double combine(double a, double b) const { return a + b; }
};
struct MinDistance {
  double operator()(double acc, const PairEval& e) const { return std::min(acc, e.d); }
  double combine(double a, double b) const { return std::min(a, b); }
};

}  // namespace

double BarrierPotential::energy(const double* x) const {
  return reduce_pairs(model_, candidates_, x, dhat2_, 0.0, SumEnergy{});
}

void BarrierPotential::group_energy(const double* x, const int32_t* group_of_vertex, double* total) const {
  auto first_group = [&](std::initializer_list<int32_t> vertices) {
    for (int32_t v : vertices)
      if (group_of_vertex[v] >= 0) return group_of_vertex[v];
    return -1;
  };
  auto over = [&](const std::vector<IndexPair>& pairs, auto&& group_of, auto&& eval) {
    grouped_sum(static_cast<int64_t>(pairs.size()), kPairGrain, group_of, [&](int64_t b, int64_t e) {
      double sum = 0.0;
      for (int64_t i = b; i < e; ++i) sum += eval(model_, x, pairs[i], dhat2_).energy;
      return sum;
    }, total);
  };
  const ContactCandidates& c = candidates_;
  over(c.vertex_triangle, [&](int64_t i) {
    const int32_t* t = &model_.surface_triangles[3 * int64_t{c.vertex_triangle[i].second}];
    return first_group({c.vertex_triangle[i].first, t[0], t[1], t[2]});
  }, eval_vertex_triangle);
  over(c.edge_edge, [&](int64_t i) {
    const int32_t* ea = &model_.surface_edges[2 * int64_t{c.edge_edge[i].first}];
    const int32_t* eb = &model_.surface_edges[2 * int64_t{c.edge_edge[i].second}];
    return first_group({ea[0], ea[1], eb[0], eb[1]});
  }, eval_edge_edge);
  over(c.vertex_plane, [&](int64_t i) { return first_group({c.vertex_plane[i].first}); }, eval_vertex_plane);
}

double BarrierPotential::min_squared_distance(const double* x) {
  refresh_pairs(x);
  double min_d = kInf;
  for (double d : pair_distance_) min_d = std::min(min_d, d);
  return min_d;
}

BarrierPotential::Summary BarrierPotential::summarize(const double* x) {
  Summary summary;
  find_candidates(x, nullptr);
  const ContactCandidates& near = candidates_;
  summary.barrier = reduce_pairs(model_, near, x, dhat2_, 0.0, SumEnergy{});
  struct CountActive {
    double dhat2;
    double operator()(double acc, const PairEval& e) const { return acc + (e.d < dhat2 ? 1.0 : 0.0); }
    double combine(double a, double b) const { return a + b; }
  };
  summary.active = static_cast<int64_t>(reduce_pairs(model_, near, x, dhat2_, 0.0, CountActive{dhat2_}));

  // Boxes inflated by r overlap for every pair closer than 2 r: a minimum below (2 r)^2 is exact.
  double min_d = reduce_pairs(model_, near, x, dhat2_, kInf, MinDistance{});
  const double limit = 4.0 * bodies_bbox_diagonal(model_) + dhat_;
  ContactCandidates far;
  for (double r = 0.5 * dhat_; min_d > 4.0 * r * r && r < limit;) {
    r *= 2.0;
    find_contact_candidates(model_, x, nullptr, r, far);
    far.vertex_plane.clear();  // planes are handled exactly below
    min_d = std::min(min_d, reduce_pairs(model_, far, x, dhat2_, kInf, MinDistance{}));
  }
  double min_distance = std::sqrt(min_d);
  for (int32_t v : model_.surface_vertices) {
    if (model_.dirichlet[v] >= 0) continue;
    for (const ObstaclePlane& plane : model_.obstacle_planes)
      min_distance = std::min(min_distance, std::max(0.0, (point(x, v) - plane.point).dot(plane.normal)));
  }
  summary.min_distance = min_distance;
  return summary;
}

// ---- active set -------------------------------------------------------------------------------

namespace {

// Candidates per chunk of the active-set passes: fixed, so the output order does not depend on
// the number of threads.
constexpr int64_t kCandidateChunk = 4096;

// candidate_code_: 0 for an inactive pair, else 1 + its closest-feature case (PointTriangleCase
// or EdgeEdgeCase), plus kMollifiedCode for an edge-edge pair inside the mollifier's band.
constexpr uint8_t kMollifiedCode = 32;

int32_t lower(int32_t a, int32_t b) { return a < b ? a : b; }
int32_t upper(int32_t a, int32_t b) { return a < b ? b : a; }

// The vertex ids of candidate i (vertex-triangle: p, t0, t1, t2; edge-edge: ea0, ea1, eb0, eb1,
// the stencil order; vertex-plane: v, then -1s).
void candidate_vertices(const Model& m, const ContactCandidates& c, int64_t i, int32_t (&s)[4]) {
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  if (i < nvt) {
    const IndexPair& pair = c.vertex_triangle[i];
    const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
    s[0] = pair.first; s[1] = t[0]; s[2] = t[1]; s[3] = t[2];
  } else if (i < nvt + nee) {
    const IndexPair& pair = c.edge_edge[i - nvt];
    const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
    const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
    s[0] = ea[0]; s[1] = ea[1]; s[2] = eb[0]; s[3] = eb[1];
  } else {
    s[0] = c.vertex_plane[i - nvt - nee].first;
    s[1] = s[2] = s[3] = -1;
  }
}

}  // namespace

void BarrierPotential::refresh_pairs(const double* x) {
  const ContactCandidates& c = candidates_;
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t num = c.size();
  if (static_cast<int64_t>(pair_known_.size()) != num) forget_pairs();
  pair_distance_.resize(num);
  candidate_code_.resize(num);

  // Vertices whose position differs from the cached one (NaN always does), brought up to date.
  const int64_t nv = model_.num_vertices;
  vertex_changed_.resize(nv);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const double* p = x + 3 * v;
      double* q = &pair_x_[3 * v];
      const bool changed = !(p[0] == q[0] && p[1] == q[1] && p[2] == q[2]);
      vertex_changed_[v] = changed;
      if (changed) std::copy(p, p + 3, q);
    }
  }, 8192);

  parallel_for((num + kCandidateChunk - 1) / kCandidateChunk, [&](int64_t cb, int64_t ce) {
    for (int64_t i = cb * kCandidateChunk; i < std::min(num, ce * kCandidateChunk); ++i) {
      int32_t s[4];
      candidate_vertices(model_, c, i, s);
      if (pair_known_[i] && !vertex_changed_[s[0]] && (s[1] < 0 || !(vertex_changed_[s[1]] |
          vertex_changed_[s[2]] | vertex_changed_[s[3]])))
        continue;
      uint8_t code = 0;
      double d = kInf;
      if (i < nvt + nee) {
        const Eigen::Vector3d X0 = point(x, s[0]), X1 = point(x, s[1]);
        const Eigen::Vector3d X2 = point(x, s[2]), X3 = point(x, s[3]);
        if (i < nvt) {
          const PointTriangleCase pc = point_triangle_case(X0, X1, X2, X3);
          d = point_triangle_distance(X0, X1, X2, X3, pc);
          if (d < dhat2_) code = 1 + static_cast<uint8_t>(pc);
        } else {
          const EdgeEdgeCase ec = edge_edge_case(X0, X1, X2, X3);
          d = edge_edge_distance(X0, X1, X2, X3, ec);
          if (d < dhat2_) {
            code = 1 + static_cast<uint8_t>(ec);
            const double eps_x = edge_edge_threshold(model_, &s[0], &s[2]);
            if (edge_edge_cross_squarednorm(X0, X1, X2, X3) < eps_x) code |= kMollifiedCode;
          }
        }
      } else {
        d = eval_vertex_plane(model_, x, c.vertex_plane[i - nvt - nee], dhat2_).d;
        if (d < dhat2_) code = 1;
      }
      pair_distance_[i] = d;
      candidate_code_[i] = code;
      pair_known_[i] = 1;
    }
  }, 1);
}

void BarrierPotential::build_active_set(const double* x) {
  const ContactCandidates& c = candidates_;
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t num = c.size();
  const int64_t chunks = (num + kCandidateChunk - 1) / kCandidateChunk;

  // The closest feature of an active vertex-triangle or edge-edge candidate, from its code.
  auto feature_of_code = [&](int64_t i, uint8_t code) {
    return i < nvt ? feature_of(static_cast<PointTriangleCase>(code - 1))
                   : feature_of(static_cast<EdgeEdgeCase>((code & ~kMollifiedCode) - 1));
  };
  // Point-point and point-edge features of unmollified pairs are merged; the rest are unique.
  auto mergeable = [&](int64_t i, uint8_t code) {
    if (i >= nvt + nee || (code & kMollifiedCode)) return false;
    return feature_of_code(i, code).n < 4;
  };

  // Pass 1: classify every candidate (refresh_pairs), count unique and mergeable active pairs
  // per chunk.
  refresh_pairs(x);
  chunk_unique_begin_.assign(chunks + 1, 0);
  chunk_feature_begin_.assign(chunks + 1, 0);
  parallel_for(chunks, [&](int64_t cb, int64_t ce) {
    for (int64_t k = cb; k < ce; ++k) {
      int64_t unique = 0, mergeable_pairs = 0;
      for (int64_t i = k * kCandidateChunk; i < std::min(num, (k + 1) * kCandidateChunk); ++i) {
        const uint8_t code = candidate_code_[i];
        if (code == 0) continue;
        if (mergeable(i, code)) ++mergeable_pairs;
        else ++unique;
      }
      chunk_unique_begin_[k + 1] = unique;
      chunk_feature_begin_[k + 1] = mergeable_pairs;
    }
  }, 1);
  for (int64_t k = 0; k < chunks; ++k) {
    chunk_unique_begin_[k + 1] += chunk_unique_begin_[k];
    chunk_feature_begin_[k + 1] += chunk_feature_begin_[k];
  }
  const int64_t num_unique = chunk_unique_begin_[chunks];
  const int64_t num_features = chunk_feature_begin_[chunks];
  num_active_pairs_ = num_unique + num_features;

  // Pass 2: unique pairs become stencils, mergeable ones feature keys, both in candidate order.
  kind_.resize(num_unique);
  vertices_.resize(4 * num_unique);
  multiplicity_.resize(num_unique);
  features_.resize(num_features);
  parallel_for(chunks, [&](int64_t cb, int64_t ce) {
    for (int64_t k = cb; k < ce; ++k) {
      int64_t unique = chunk_unique_begin_[k], feature = chunk_feature_begin_[k];
      for (int64_t i = k * kCandidateChunk; i < std::min(num, (k + 1) * kCandidateChunk); ++i) {
        const uint8_t code = candidate_code_[i];
        if (code == 0) continue;
        if (i >= nvt + nee) {
          const IndexPair& pair = c.vertex_plane[i - nvt - nee];
          kind_[unique] = StencilKind::vertex_plane;
          int32_t* v = &vertices_[4 * unique];
          v[0] = pair.first; v[1] = pair.second; v[2] = v[3] = -1;
          multiplicity_[unique++] = 1;
          continue;
        }
        int32_t s[4];
        candidate_vertices(model_, c, i, s);
        if (mergeable(i, code)) {
          const Feature f = feature_of_code(i, code);
          const int32_t p = s[f.idx[0]], q = s[f.idx[1]];
          features_[feature++] = f.n == 2 ? FeatureKey{lower(p, q), upper(p, q), -1}
                                          : FeatureKey{p, lower(q, s[f.idx[2]]), upper(q, s[f.idx[2]])};
          continue;
        }
        kind_[unique] = i < nvt ? StencilKind::point_triangle
                                : ((code & kMollifiedCode) ? StencilKind::edge_edge_mollified
                                                           : StencilKind::edge_edge);
        std::copy(s, s + 4, &vertices_[4 * unique]);
        multiplicity_[unique++] = 1;
      }
    }
  }, 1);

  // Merge equal features: bucket the keys by their first vertex (a stable counting sort, so the
  // order is fixed), then sort each small bucket and count runs. vertex_feature_begin_ has
  // nv + 2 entries: counting at a + 2 and filling through a + 1 leaves entry a at bucket a's start.
  const int64_t nv = model_.num_vertices;
  std::vector<int64_t>& bucket = vertex_feature_begin_;
  bucket.assign(nv + 2, 0);
  for (const FeatureKey& f : features_) ++bucket[f.a + 2];
  for (int64_t v = 0; v < nv; ++v) bucket[v + 2] += bucket[v + 1];
  features_by_vertex_.resize(num_features);
  for (const FeatureKey& f : features_) features_by_vertex_[bucket[f.a + 1]++] = f;

  auto before = [](const FeatureKey& l, const FeatureKey& r) { return l.b != r.b ? l.b < r.b : l.c < r.c; };
  auto same = [](const FeatureKey& l, const FeatureKey& r) { return l.b == r.b && l.c == r.c; };
  vertex_stencil_begin_.assign(nv + 1, 0);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      FeatureKey* first = features_by_vertex_.data() + bucket[v];
      FeatureKey* last = features_by_vertex_.data() + bucket[v + 1];
      std::sort(first, last, before);
      int64_t runs = 0;
      for (FeatureKey* f = first; f != last; ++f) runs += (f == first || !same(f[-1], *f));
      vertex_stencil_begin_[v + 1] = runs;
    }
  }, 1024);
  vertex_stencil_begin_[0] = num_unique;
  for (int64_t v = 0; v < nv; ++v) vertex_stencil_begin_[v + 1] += vertex_stencil_begin_[v];
  const int64_t num_stencils = vertex_stencil_begin_[nv];
  kind_.resize(num_stencils);
  vertices_.resize(4 * num_stencils);
  multiplicity_.resize(num_stencils);
  parallel_for(nv, [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      int64_t out = vertex_stencil_begin_[v] - 1;
      for (int64_t k = bucket[v]; k < bucket[v + 1]; ++k) {
        const FeatureKey& f = features_by_vertex_[k];
        if (k > bucket[v] && same(features_by_vertex_[k - 1], f)) {
          ++multiplicity_[out];
          continue;
        }
        ++out;
        kind_[out] = f.c < 0 ? StencilKind::point_point : StencilKind::point_edge;
        int32_t* s = &vertices_[4 * out];
        s[0] = f.a; s[1] = f.b; s[2] = f.c; s[3] = -1;
        multiplicity_[out] = 1;
      }
    }
  }, 1024);

  // Stencils as the Newton system sees them (held vertices dropped) and their slab sizes.
  stencils_.resize(4 * num_stencils);
  slab_begin_.resize(num_stencils + 1);
  slab_begin_[0] = 0;
  parallel_for(num_stencils, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const int n = stencil_size(kind_[k]);
      for (int i = 0; i < 4; ++i) {
        const int32_t v = vertices_[4 * k + i];
        stencils_[4 * k + i] = (i < n && !model_.eliminated(v)) ? v : -1;
      }
      slab_begin_[k + 1] = 9 * n * n;
    }
  }, 4096);
  for (int64_t k = 0; k < num_stencils; ++k) slab_begin_[k + 1] += slab_begin_[k];
}

// ---- derivatives ----------------------------------------------------------------------------

namespace {

// Derivatives of w b(d) for d = |a - b|^2, in closed form. With u = a - b the Hessian is
// [K -K; -K K], K = 4 b'' u u^T + 2 b' I, whose eigenvalues are twice K's (and 0): K has
// 4 b'' d + 2 b' along u and 2 b' across it, so the projection clamps those two numbers.
void point_point_stencil(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double dhat2, double w,
                         double* grad, double* hess) {
  const Eigen::Vector3d u = a - b;
  const double d = u.squaredNorm();
  const double b1 = w * barrier_first_derivative(d, dhat2);
  Eigen::Map<Eigen::Vector3d>{grad} = 2.0 * b1 * u;
  Eigen::Map<Eigen::Vector3d>{grad + 3} = -2.0 * b1 * u;
  if (!hess) return;
  const double b2 = w * barrier_second_derivative(d, dhat2);
  const double across = std::max(2.0 * b1, 0.0);
  const double along = std::max(4.0 * b2 * d + 2.0 * b1, 0.0);
  Eigen::Matrix3d K = ((along - across) / d) * u * u.transpose();
  K.diagonal().array() += across;
  Eigen::Map<Matrix6d> H{hess};
  H << K, -K, -K, K;
}

// Derivatives of w b(d) for an affine distance d = min_lambda |X (w0 + B lambda)|^2 of K points
// and M parameters (point-edge, point-triangle, edge-edge interiors; kernels/distance/
// distance_primitives.hpp). d is passed in from the closed-form distance, which is more accurate
// than |r|^2. The Hessian w (b'' g g^T + b' hess d) is V S V^T with V = [w (x) I3, B (x) r/|r|]
// (3K x (3 + M)): g = 2 w (x) r and hess d = 2 w w^T (x) I3 - G (D^T D)^-1 G^T / 2 with
// G = 2 (B (x) r + w (x) D) both lie in range(V), so it is zero outside that (3 + M)-dimensional
// subspace and its exact PSD projection is a (3 + M) x (3 + M) eigenproblem in an orthonormal
// basis Q = V L^-T of it (L L^T = V^T V), instead of a 3K x 3K one.
template <int K, int M>
void affine_stencil(const Eigen::Matrix<double, 3, K>& X, const Eigen::Matrix<double, K, 1>& w0,
                    const Eigen::Matrix<double, K, M>& B, double d, double dhat2, double w,
                    double* grad, double* hess) {
  constexpr int R = 3 + M;
  using MatrixR = Eigen::Matrix<double, R, R>;
  const detail::AffineMinimum<K, M> m = detail::affine_minimum<K, M>(X, w0, B);
  const double b1 = w * barrier_first_derivative(d, dhat2);
  for (int i = 0; i < K; ++i) Eigen::Map<Eigen::Vector3d>{grad + 3 * i} = (2.0 * b1 * m.w(i)) * m.r;
  if (!hess) return;
  const double b2 = w * barrier_second_derivative(d, dhat2);
  const double r_norm = m.r.norm();
  const Eigen::Vector3d r_hat = m.r / r_norm;
  Eigen::Matrix<double, 3 * K, R> V = Eigen::Matrix<double, 3 * K, R>::Zero();
  for (int i = 0; i < K; ++i) {
    V.template block<3, 3>(3 * i, 0).diagonal().setConstant(m.w(i));
    for (int k = 0; k < M; ++k) V.template block<3, 1>(3 * i, 3 + k) = B(i, k) * r_hat;
  }
  Eigen::Matrix<double, R, M> E;  // G = 2 V E
  E.template topRows<3>() = m.D;
  E.template bottomRows<M>() = r_norm * Eigen::Matrix<double, M, M>::Identity();
  MatrixR S = (-2.0 * b1) * E * m.A_inv * E.transpose();
  S.template topLeftCorner<3, 3>() += (4.0 * b2) * m.r * m.r.transpose();
  S.template topLeftCorner<3, 3>().diagonal().array() += 2.0 * b1;

  Eigen::Map<Eigen::Matrix<double, 3 * K, 3 * K>> H{hess};
  const Eigen::LLT<MatrixR> llt(V.transpose() * V);
  if (llt.info() != Eigen::Success) {  // V is full rank for d > 0; kept as a safety net
    Eigen::Matrix<double, 3 * K, 3 * K> full = V * S * V.transpose();
    full = 0.5 * (full + full.transpose()).eval();
    project_psd<3 * K>(full);
    H = full;
    return;
  }
  const MatrixR L = llt.matrixL();
  MatrixR T = L.transpose() * S * L;
  T = 0.5 * (T + T.transpose()).eval();
  project_psd<R>(T);
  const Eigen::Matrix<double, 3 * K, R> Q =
      L.template triangularView<Eigen::Lower>().solve(V.transpose()).transpose();
  const Eigen::Matrix<double, 3 * K, R> QT = Q.lazyProduct(T);
  const Eigen::Matrix<double, 3 * K, 3 * K> full = QT.lazyProduct(Q.transpose());
  H = 0.5 * (full + full.transpose());
}

// Projects the Hessian of a translation-invariant 4-point energy (a mollified edge-edge pair) onto
// the PSD cone. Rigid translations are in its null space, so in the orthonormal basis
// U = [q1 q2 q3] (x) I3, q1 = (1, -1, 0, 0) / sqrt 2, q2 = (1, 1, -2, 0) / sqrt 6,
// q3 = (1, 1, 1, -3) / sqrt 12, of their complement the problem is 9x9 instead of 12x12 (about
// 2.4x cheaper); the translations keep their eigenvalue 0.
void project_psd_translation_free(Matrix12d& H) {
  static const Eigen::Matrix<double, 12, 9> U = [] {
    const double q[3][4] = {{1.0 / std::sqrt(2.0), -1.0 / std::sqrt(2.0), 0.0, 0.0},
                            {1.0 / std::sqrt(6.0), 1.0 / std::sqrt(6.0), -2.0 / std::sqrt(6.0), 0.0},
                            {1.0 / std::sqrt(12.0), 1.0 / std::sqrt(12.0), 1.0 / std::sqrt(12.0), -3.0 / std::sqrt(12.0)}};
    Eigen::Matrix<double, 12, 9> u = Eigen::Matrix<double, 12, 9>::Zero();
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 4; ++i) u.block<3, 3>(3 * i, 3 * k).diagonal().setConstant(q[k][i]);
    return u;
  }();
  // lazyProduct: coefficient-wise small products, not the blocked GEMM path Eigen picks at 12x9.
  const Eigen::Matrix<double, 9, 12> UtH = U.transpose().lazyProduct(H);
  Matrix9d T = UtH.lazyProduct(U);
  T = 0.5 * (T + T.transpose()).eval();
  // Already PSD, as exactly parallel edges are (their Hessian is b m' J^T J there): H keeps its
  // values, without an eigendecomposition.
  if (cholesky_psd_test<9>(T, kPsdTolerance)) return;
  if (project_psd<9>(T) == 0) return;  // nothing clamped: H keeps its exact values
  const Eigen::Matrix<double, 12, 9> UT = U.lazyProduct(T);
  const Matrix12d projected = UT.lazyProduct(U.transpose());
  H = 0.5 * (projected + projected.transpose());
}

}  // namespace

int BarrierPotential::stencil_size(StencilKind kind) {
  switch (kind) {
    case StencilKind::vertex_plane: return 1;
    case StencilKind::point_point: return 2;
    case StencilKind::point_edge: return 3;
    default: return 4;
  }
}

double BarrierPotential::active_set_energy(const double* x) const {
  return deterministic_sum(num_stencils(), [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t k = begin; k < end; ++k) {
      const int32_t* s = &vertices_[4 * k];
      double e = 0.0;
      switch (kind_[k]) {
        case StencilKind::vertex_plane:
          e = eval_vertex_plane(model_, x, {s[0], s[1]}, dhat2_).energy;
          break;
        case StencilKind::point_point:
          e = barrier(point_point_distance(point(x, s[0]), point(x, s[1])), dhat2_);
          break;
        case StencilKind::point_edge:
          e = barrier(point_line_distance(point(x, s[0]), point(x, s[1]), point(x, s[2])), dhat2_);
          break;
        case StencilKind::point_triangle:
          e = barrier(point_plane_distance(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3])), dhat2_);
          break;
        case StencilKind::edge_edge:
          e = barrier(line_line_distance(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3])), dhat2_);
          break;
        case StencilKind::edge_edge_mollified: {
          const Eigen::Vector3d a0 = point(x, s[0]), a1 = point(x, s[1]), b0 = point(x, s[2]), b1 = point(x, s[3]);
          e = barrier(edge_edge_distance(a0, a1, b0, b1), dhat2_) *
              edge_edge_mollifier(a0, a1, b0, b1, edge_edge_threshold(model_, &s[0], &s[2]));
          break;
        }
      }
      sum += multiplicity_[k] * e;
    }
    return sum;
  }, 1024);
}

void BarrierPotential::compute_derivatives(const double* x, double weight, bool with_hessian,
                                           const uint8_t* active) {
  const int64_t ns = num_stencils();
  gradients_.resize(12 * ns);
  if (with_hessian) hessians_.resize(slab_begin_[ns]);
  parallel_for(ns, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const int32_t* s = &vertices_[4 * k];
      const double w = weight * multiplicity_[k];
      double* grad = &gradients_[12 * k];
      if (!touches(&stencils_[4 * k], active)) {
        std::fill(grad, grad + 12, 0.0);
        continue;
      }
      double* hess = with_hessian ? &hessians_[slab_begin_[k]] : nullptr;
      switch (kind_[k]) {
        case StencilKind::vertex_plane: {
          const ObstaclePlane& plane = model_.obstacle_planes[s[1]];
          const double h = (point(x, s[0]) - plane.point).dot(plane.normal);
          const double d = h * h;
          const double b1 = w * barrier_first_derivative(d, dhat2_);
          Eigen::Map<Eigen::Vector3d>{grad} = (2.0 * h * b1) * plane.normal;
          if (hess) {
            // b'' g g^T + b' 2 n n^T = (4 h^2 b'' + 2 b') n n^T: rank one, projected by its sign.
            const double b2 = w * barrier_second_derivative(d, dhat2_);
            const double lambda = std::max(0.0, 4.0 * d * b2 + 2.0 * b1);
            Eigen::Map<Eigen::Matrix3d>{hess} = lambda * plane.normal * plane.normal.transpose();
          }
          break;
        }
        case StencilKind::point_point:
          point_point_stencil(point(x, s[0]), point(x, s[1]), dhat2_, w, grad, hess);
          break;
        case StencilKind::point_edge: {
          const Eigen::Vector3d p = point(x, s[0]), e0 = point(x, s[1]), e1 = point(x, s[2]);
          affine_stencil<3, 1>(detail::columns(p, e0, e1), detail::point_line_w0(), detail::point_line_B(),
                               point_line_distance(p, e0, e1), dhat2_, w, grad, hess);
          break;
        }
        case StencilKind::point_triangle: {
          const Eigen::Vector3d p = point(x, s[0]), t0 = point(x, s[1]), t1 = point(x, s[2]), t2 = point(x, s[3]);
          affine_stencil<4, 2>(detail::columns(p, t0, t1, t2), detail::point_plane_w0(), detail::point_plane_B(),
                               point_plane_distance(p, t0, t1, t2), dhat2_, w, grad, hess);
          break;
        }
        case StencilKind::edge_edge: {
          const Eigen::Vector3d a0 = point(x, s[0]), a1 = point(x, s[1]), b0 = point(x, s[2]), b1 = point(x, s[3]);
          affine_stencil<4, 2>(detail::columns(a0, a1, b0, b1), detail::line_line_w0(), detail::line_line_B(),
                               line_line_distance(a0, a1, b0, b1), dhat2_, w, grad, hess);
          break;
        }
        case StencilKind::edge_edge_mollified: {
          // Nearly parallel: product rule on m(x) b(d(x)) over all 12 DOFs.
          const Eigen::Vector3d X[4] = {point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3])};
          const EdgeEdgeCase ec = edge_edge_case(X[0], X[1], X[2], X[3]);
          const double d = edge_edge_distance(X[0], X[1], X[2], X[3], ec);
          const double eps_x = edge_edge_threshold(model_, &s[0], &s[2]);
          Vector12d gd;
          Matrix12d Hd;
          edge_edge_full_derivatives(feature_of(ec), X, gd, hess ? &Hd : nullptr);
          const double m = edge_edge_mollifier(X[0], X[1], X[2], X[3], eps_x);
          const Vector12d gm = edge_edge_mollifier_gradient(X[0], X[1], X[2], X[3], eps_x);
          const double b = barrier(d, dhat2_);
          const double b1 = barrier_first_derivative(d, dhat2_);
          Eigen::Map<Vector12d>{grad} = w * (m * b1 * gd + b * gm);
          if (hess) {
            const double b2 = barrier_second_derivative(d, dhat2_);
            const Matrix12d Hm = edge_edge_mollifier_hessian(X[0], X[1], X[2], X[3], eps_x);
            Matrix12d H = m * (b2 * gd * gd.transpose() + b1 * Hd) +
                          b1 * (gd * gm.transpose() + gm * gd.transpose()) + b * Hm;
            H *= w;
            project_psd_translation_free(H);
            Eigen::Map<Matrix12d>{hess} = H;
          }
          break;
        }
      }
    }
  }, 256);
}

void add_stencil_gradients(const std::vector<int32_t>& stencils, const std::vector<double>& gradients,
                           double* grad) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  for (int64_t k = 0; k < num; ++k)
    for (int i = 0; i < 4; ++i) {
      const int32_t v = stencils[4 * k + i];
      if (v < 0) continue;
      for (int r = 0; r < 3; ++r) grad[3 * int64_t{v} + r] += gradients[12 * k + 3 * i + r];
    }
}

void BarrierPotential::add_gradient(double* grad) const { add_stencil_gradients(stencils_, gradients_, grad); }

void BarrierPotential::add_gradient_with_held(double* grad) const {
  // vertices_ holds the real ids; a vertex-plane stencil's second entry is the plane's index.
  for (int64_t k = 0; k < num_stencils(); ++k)
    for (int i = 0; i < stencil_size(kind_[k]); ++i) {
      const int32_t v = vertices_[4 * k + i];
      for (int r = 0; r < 3; ++r) grad[3 * int64_t{v} + r] += gradients_[12 * k + 3 * i + r];
    }
}

// ---- CCD --------------------------------------------------------------------------------------

double BarrierPotential::max_step(const double* x, const double* p) {
  sweep(x, p);
  double alpha = 1.0;
  group_max_steps(x, nullptr, &alpha);
  return alpha;
}

void BarrierPotential::sweep(const double* x, const double* p, const uint8_t* moving) {
  ProfileScope scope(profile_, StepPhase::ccd);  // the candidate search inside is broad phase
  const int64_t n = model_.num_dofs();
  parallel_for(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x1_[i] = x[i] + p[i];
  }, 8192);
  if (!moving) return find_candidates(x, x1_.data());
  ProfileScope broad(profile_, StepPhase::broad_phase);
  static_search_ = false;
  // Pairs of vertices that stay put keep their candidates: none of them moved since the last
  // search, and that search covered where they are now. Only pairs with a moving vertex are
  // searched again; the two sets are disjoint, and merging keeps the lists sorted.
  find_contact_candidates(model_, x, x1_.data(), 0.5 * dhat_, fresh_, moving);
  auto still = [&](std::initializer_list<int32_t> vertices) {
    for (int32_t v : vertices)
      if (moving[v]) return false;
    return true;
  };
  // Each list becomes its kept pairs merged with the fresh ones; a kept pair carries its cache
  // entry (refresh_pairs) along, a fresh one starts unknown.
  const int64_t old_size = candidates_.size();
  if (static_cast<int64_t>(pair_known_.size()) != old_size) forget_pairs();
  pair_distance_.resize(old_size);
  candidate_code_.resize(old_size);
  merged_known_.clear();
  merged_code_.clear();
  merged_distance_.clear();
  int64_t old_base = 0;
  auto update = [&](std::vector<IndexPair>& list, const std::vector<IndexPair>& fresh, auto&& keep) {
    kept_.clear();
    kept_index_.clear();
    for (size_t i = 0; i < list.size(); ++i)
      if (keep(list[i])) {
        kept_.push_back(list[i]);
        kept_index_.push_back(old_base + static_cast<int64_t>(i));
      }
    old_base += static_cast<int64_t>(list.size());
    list.resize(kept_.size() + fresh.size());
    size_t a = 0, b = 0;
    for (IndexPair& out : list) {
      if (b == fresh.size() || (a < kept_.size() && kept_[a] < fresh[b])) {
        const int64_t k = kept_index_[a];
        out = kept_[a++];
        merged_known_.push_back(pair_known_[k]);
        merged_code_.push_back(candidate_code_[k]);
        merged_distance_.push_back(pair_distance_[k]);
      } else {
        out = fresh[b++];
        merged_known_.push_back(0);
        merged_code_.push_back(0);
        merged_distance_.push_back(kInf);
      }
    }
  };
  update(candidates_.vertex_triangle, fresh_.vertex_triangle, [&](const IndexPair& pr) {
    const int32_t* t = &model_.surface_triangles[3 * int64_t{pr.second}];
    return still({pr.first, t[0], t[1], t[2]});
  });
  update(candidates_.edge_edge, fresh_.edge_edge, [&](const IndexPair& pr) {
    const int32_t* ea = &model_.surface_edges[2 * int64_t{pr.first}];
    const int32_t* eb = &model_.surface_edges[2 * int64_t{pr.second}];
    return still({ea[0], ea[1], eb[0], eb[1]});
  });
  update(candidates_.vertex_plane, fresh_.vertex_plane,
         [&](const IndexPair& pr) { return still({pr.first}); });
  pair_known_.swap(merged_known_);
  candidate_code_.swap(merged_code_);
  pair_distance_.swap(merged_distance_);
}

void BarrierPotential::group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha) {
  ProfileScope scope(profile_, StepPhase::ccd);
  const double* y = x1_.data();
  const double min_distance = kCcdGapFraction * dhat_;
  const ContactCandidates& c = candidates_;
  // The group a pair belongs to: that of its first moving vertex (all its moving vertices share
  // one, by the caller's promise); -1 when none of them moves.
  auto group_of = [&](std::initializer_list<int32_t> vertices) {
    if (!group_of_vertex) return 0;
    for (int32_t v : vertices)
      if (group_of_vertex[v] >= 0) return group_of_vertex[v];
    return -1;
  };

  // Earliest time of impact per group, per fixed chunk of pairs. Within a chunk, a run of pairs
  // of one group passes its running minimum as tmax to cut work short. Each run leaves one
  // (group, time) result, and the results are combined in chunk order: the same on any thread
  // count.
  auto earliest = [&](int64_t count, auto&& group, auto&& ccd) {
    const int64_t chunks = (count + kPairGrain - 1) / kPairGrain;
    run_minima_.resize(std::max<size_t>(run_minima_.size(), chunks));
    parallel_for(chunks, [&](int64_t cb, int64_t ce) {
      for (int64_t k = cb; k < ce; ++k) {
        std::vector<std::pair<int32_t, double>>& runs = run_minima_[k];
        runs.clear();
        for (int64_t i = k * kPairGrain; i < std::min(count, (k + 1) * kPairGrain); ++i) {
          const int32_t g = group(i);
          if (g < 0) continue;
          if (runs.empty() || runs.back().first != g) runs.emplace_back(g, 1.0);
          double toi = 1.0;
          if (ccd(i, runs.back().second, toi)) runs.back().second = std::min(runs.back().second, toi);
        }
      }
    }, 1);
    for (int64_t k = 0; k < chunks; ++k)
      for (const auto& [g, t] : run_minima_[k]) alpha[g] = std::min(alpha[g], t);
  };
  earliest(static_cast<int64_t>(c.vertex_triangle.size()), [&](int64_t i) {
    const IndexPair& pr = c.vertex_triangle[i];
    const int32_t* t = &model_.surface_triangles[3 * int64_t{pr.second}];
    return group_of({pr.first, t[0], t[1], t[2]});
  }, [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.vertex_triangle[i];
    const int32_t* t = &model_.surface_triangles[3 * int64_t{pr.second}];
    return point_triangle_ccd(point(x, pr.first), point(x, t[0]), point(x, t[1]), point(x, t[2]),
                              point(y, pr.first), point(y, t[0]), point(y, t[1]), point(y, t[2]),
                              min_distance, tmax, toi);
  });
  earliest(static_cast<int64_t>(c.edge_edge.size()), [&](int64_t i) {
    const IndexPair& pr = c.edge_edge[i];
    const int32_t* ea = &model_.surface_edges[2 * int64_t{pr.first}];
    const int32_t* eb = &model_.surface_edges[2 * int64_t{pr.second}];
    return group_of({ea[0], ea[1], eb[0], eb[1]});
  }, [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.edge_edge[i];
    const int32_t* ea = &model_.surface_edges[2 * int64_t{pr.first}];
    const int32_t* eb = &model_.surface_edges[2 * int64_t{pr.second}];
    return edge_edge_ccd(point(x, ea[0]), point(x, ea[1]), point(x, eb[0]), point(x, eb[1]),
                         point(y, ea[0]), point(y, ea[1]), point(y, eb[0]), point(y, eb[1]),
                         min_distance, tmax, toi);
  });
  earliest(static_cast<int64_t>(c.vertex_plane.size()), [&](int64_t i) {
    return group_of({c.vertex_plane[i].first});
  }, [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.vertex_plane[i];
    const ObstaclePlane& plane = model_.obstacle_planes[pr.second];
    return point_plane_ccd(point(x, pr.first), point(y, pr.first), plane.point, plane.normal,
                           min_distance, tmax, toi);
  });
}

}  // namespace nexdyn

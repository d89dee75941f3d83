// Barrier potential over contact pairs (see barrier_potential.hpp).
#include "engine/contact/barrier_potential.hpp"

#include "engine/parallel.hpp"
#include "kernels/barrier/barrier.hpp"
#include "kernels/ccd/ccd.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/projection/psd_projection.hpp"

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

enum PairKind : uint8_t { kVertexTriangle = 0, kEdgeEdge = 1, kVertexPlane = 2 };

Eigen::Vector3d point(const double* x, int32_t v) { return Eigen::Vector3d::Map(x + 3 * int64_t{v}); }

// The closest features of a pair as a reduced stencil: the squared distance is a point-point
// (n = 2), point-line (n = 3), point-plane or line-line (n = 4) distance of the stencil points
// idx[0..n). Computing and projecting at that size is exact and cheaper than at 12x12.
struct Feature {
  enum Kind : uint8_t { point_point, point_line, point_plane, line_line } kind;
  int n;
  int idx[4];
};

Feature feature_of(PointTriangleCase c) {
  switch (c) {
    case PointTriangleCase::p_t0: return {Feature::point_point, 2, {0, 1}};
    case PointTriangleCase::p_t1: return {Feature::point_point, 2, {0, 2}};
    case PointTriangleCase::p_t2: return {Feature::point_point, 2, {0, 3}};
    case PointTriangleCase::p_e0: return {Feature::point_line, 3, {0, 1, 2}};
    case PointTriangleCase::p_e1: return {Feature::point_line, 3, {0, 2, 3}};
    case PointTriangleCase::p_e2: return {Feature::point_line, 3, {0, 3, 1}};
    case PointTriangleCase::p_t: break;
  }
  return {Feature::point_plane, 4, {0, 1, 2, 3}};
}

Feature feature_of(EdgeEdgeCase c) {
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return {Feature::point_point, 2, {0, 2}};
    case EdgeEdgeCase::ea0_eb1: return {Feature::point_point, 2, {0, 3}};
    case EdgeEdgeCase::ea1_eb0: return {Feature::point_point, 2, {1, 2}};
    case EdgeEdgeCase::ea1_eb1: return {Feature::point_point, 2, {1, 3}};
    case EdgeEdgeCase::ea_eb0: return {Feature::point_line, 3, {2, 0, 1}};
    case EdgeEdgeCase::ea_eb1: return {Feature::point_line, 3, {3, 0, 1}};
    case EdgeEdgeCase::ea0_eb: return {Feature::point_line, 3, {0, 2, 3}};
    case EdgeEdgeCase::ea1_eb: return {Feature::point_line, 3, {1, 2, 3}};
    case EdgeEdgeCase::ea_eb: break;
  }
  return {Feature::line_line, 4, {0, 1, 2, 3}};
}

// Gradient and Hessian of the squared distance of a reduced stencil with N points.
template <int N>
void feature_derivatives(const Feature& f, const Eigen::Vector3d (&X)[4],
                         Eigen::Matrix<double, 3 * N, 1>& g, Eigen::Matrix<double, 3 * N, 3 * N>& H) {
  const Eigen::Vector3d& a = X[f.idx[0]];
  const Eigen::Vector3d& b = X[f.idx[1]];
  if constexpr (N == 2) {
    g = point_point_distance_gradient(a, b);
    H = point_point_distance_hessian(a, b);
  } else if constexpr (N == 3) {
    g = point_line_distance_gradient(a, b, X[f.idx[2]]);
    H = point_line_distance_hessian(a, b, X[f.idx[2]]);
  } else if (f.kind == Feature::point_plane) {
    g = point_plane_distance_gradient(a, b, X[f.idx[2]], X[f.idx[3]]);
    H = point_plane_distance_hessian(a, b, X[f.idx[2]], X[f.idx[3]]);
  } else {
    g = line_line_distance_gradient(a, b, X[f.idx[2]], X[f.idx[3]]);
    H = line_line_distance_hessian(a, b, X[f.idx[2]], X[f.idx[3]]);
  }
}

// Writes the derivatives of w b(d) of an unmollified pair into its 12-gradient and 12x12 slab:
//   grad = w b' grad d,   H = project(w (b'' grad d grad d^T + b' hess d)).
template <int N>
void unmollified_pair(const Feature& f, const Eigen::Vector3d (&X)[4], double d, double dhat2,
                      double w, bool with_hessian, double* grad, double* hess) {
  Eigen::Matrix<double, 3 * N, 1> g;
  Eigen::Matrix<double, 3 * N, 3 * N> H;
  feature_derivatives<N>(f, X, g, H);
  const double b1 = w * barrier_first_derivative(d, dhat2);
  for (int i = 0; i < N; ++i)
    for (int r = 0; r < 3; ++r) grad[3 * f.idx[i] + r] = b1 * g[3 * i + r];
  if (!with_hessian) return;
  const double b2 = w * barrier_second_derivative(d, dhat2);
  H = b2 * g * g.transpose() + b1 * H;
  project_psd<3 * N>(H);
  for (int j = 0; j < N; ++j)
    for (int c = 0; c < 3; ++c)
      for (int i = 0; i < N; ++i)
        for (int r = 0; r < 3; ++r)
          hess[(3 * f.idx[j] + c) * 12 + 3 * f.idx[i] + r] = H(3 * i + r, 3 * j + c);
}

// Full 12-DOF gradient and Hessian of the squared distance of an edge-edge pair.
void edge_edge_full_derivatives(const Feature& f, const Eigen::Vector3d (&X)[4], Vector12d& g,
                                Matrix12d& H) {
  g.setZero();
  H.setZero();
  auto scatter = [&](const auto& gr, const auto& hr, int n) {
    for (int i = 0; i < n; ++i) {
      g.segment<3>(3 * f.idx[i]) = gr.template segment<3>(3 * i);
      for (int j = 0; j < n; ++j)
        H.block<3, 3>(3 * f.idx[i], 3 * f.idx[j]) = hr.template block<3, 3>(3 * i, 3 * j);
    }
  };
  if (f.n == 2) {
    Vector6d gr; Matrix6d hr;
    feature_derivatives<2>(f, X, gr, hr);
    scatter(gr, hr, 2);
  } else if (f.n == 3) {
    Vector9d gr; Matrix9d hr;
    feature_derivatives<3>(f, X, gr, hr);
    scatter(gr, hr, 3);
  } else {
    feature_derivatives<4>(f, X, g, H);
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
}

void BarrierPotential::find_candidates(const double* x0, const double* x1) {
  find_contact_candidates(model_, x0, x1, 0.5 * dhat_, candidates_);
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

double BarrierPotential::min_squared_distance(const double* x) const {
  return reduce_pairs(model_, candidates_, x, dhat2_, kInf, MinDistance{});
}

BarrierPotential::Summary BarrierPotential::summarize(const double* x) const {
  Summary summary;
  ContactCandidates near;
  find_contact_candidates(model_, x, nullptr, 0.5 * dhat_, near);
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

// ---- derivatives ----------------------------------------------------------------------------

void BarrierPotential::assemble(const double* x, double weight, bool with_hessian) {
  // Pass 1: which candidates are active (parallel, one flag each); pass 2: compact in order.
  const ContactCandidates& c = candidates_;
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(c.edge_edge.size());
  const int64_t nvp = static_cast<int64_t>(c.vertex_plane.size());
  std::vector<uint8_t>& active = candidate_active_;
  active.resize(nvt + nee + nvp);
  parallel_for(nvt + nee + nvp, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      PairEval e;
      if (i < nvt) e = eval_vertex_triangle(model_, x, c.vertex_triangle[i], dhat2_);
      else if (i < nvt + nee) e = eval_edge_edge(model_, x, c.edge_edge[i - nvt], dhat2_);
      else e = eval_vertex_plane(model_, x, c.vertex_plane[i - nvt - nee], dhat2_);
      active[i] = e.d < dhat2_;
    }
  }, 1024);
  active_kind_.clear();
  active_index_.clear();
  for (int64_t i = 0; i < nvt + nee + nvp; ++i) {
    if (!active[i]) continue;
    const uint8_t kind = i < nvt ? kVertexTriangle : (i < nvt + nee ? kEdgeEdge : kVertexPlane);
    active_kind_.push_back(kind);
    active_index_.push_back(static_cast<int32_t>(kind == kVertexTriangle ? i : (kind == kEdgeEdge ? i - nvt : i - nvt - nee)));
  }
  const int64_t na = static_cast<int64_t>(active_kind_.size());
  stencils_.resize(4 * na);
  gradients_.assign(12 * na, 0.0);
  if (with_hessian) hessians_.assign(144 * na, 0.0);

  parallel_for(na, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      int32_t* s = &stencils_[4 * k];
      double* grad = &gradients_[12 * k];
      double* hess = with_hessian ? &hessians_[144 * k] : nullptr;
      const int32_t idx = active_index_[k];
      if (active_kind_[k] == kVertexPlane) {
        const IndexPair& pair = c.vertex_plane[idx];
        const ObstaclePlane& plane = model_.obstacle_planes[pair.second];
        s[0] = pair.first;
        s[1] = s[2] = s[3] = -1;
        const double h = (point(x, pair.first) - plane.point).dot(plane.normal);
        const double d = h * h;
        const double b1 = weight * barrier_first_derivative(d, dhat2_);
        const Eigen::Vector3d g = 2.0 * h * plane.normal;
        for (int r = 0; r < 3; ++r) grad[r] = b1 * g[r];
        if (hess) {
          // b'' g g^T + b' 2 n n^T = (4 h^2 b'' + 2 b') n n^T: rank one, projected by its sign.
          const double b2 = weight * barrier_second_derivative(d, dhat2_);
          const double lambda = std::max(0.0, 4.0 * d * b2 + 2.0 * b1);
          for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 3; ++i) hess[12 * j + i] = lambda * plane.normal[i] * plane.normal[j];
        }
        continue;
      }
      Eigen::Vector3d X[4];
      if (active_kind_[k] == kVertexTriangle) {
        const IndexPair& pair = c.vertex_triangle[idx];
        const int32_t* t = &model_.surface_triangles[3 * int64_t{pair.second}];
        s[0] = pair.first; s[1] = t[0]; s[2] = t[1]; s[3] = t[2];
        for (int i = 0; i < 4; ++i) X[i] = point(x, s[i]);
        const Feature f = feature_of(point_triangle_case(X[0], X[1], X[2], X[3]));
        const double d = point_triangle_distance(X[0], X[1], X[2], X[3]);
        if (f.n == 2) unmollified_pair<2>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
        else if (f.n == 3) unmollified_pair<3>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
        else unmollified_pair<4>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
      } else {
        const IndexPair& pair = c.edge_edge[idx];
        const int32_t* ea = &model_.surface_edges[2 * int64_t{pair.first}];
        const int32_t* eb = &model_.surface_edges[2 * int64_t{pair.second}];
        s[0] = ea[0]; s[1] = ea[1]; s[2] = eb[0]; s[3] = eb[1];
        for (int i = 0; i < 4; ++i) X[i] = point(x, s[i]);
        const EdgeEdgeCase ec = edge_edge_case(X[0], X[1], X[2], X[3]);
        const Feature f = feature_of(ec);
        const double d = edge_edge_distance(X[0], X[1], X[2], X[3], ec);
        const double eps_x = edge_edge_threshold(model_, ea, eb);
        if (!(edge_edge_cross_squarednorm(X[0], X[1], X[2], X[3]) < eps_x)) {
          // Mollifier = 1 with zero derivatives: an ordinary pair.
          if (f.n == 2) unmollified_pair<2>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
          else if (f.n == 3) unmollified_pair<3>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
          else unmollified_pair<4>(f, X, d, dhat2_, weight, with_hessian, grad, hess);
        } else {
          // Nearly parallel: product rule on m(x) b(d(x)) over all 12 DOFs.
          Vector12d gd;
          Matrix12d Hd;
          edge_edge_full_derivatives(f, X, gd, Hd);
          const double m = edge_edge_mollifier(X[0], X[1], X[2], X[3], eps_x);
          const Vector12d gm = edge_edge_mollifier_gradient(X[0], X[1], X[2], X[3], eps_x);
          const double b = barrier(d, dhat2_);
          const double b1 = barrier_first_derivative(d, dhat2_);
          const Vector12d g = weight * (m * b1 * gd + b * gm);
          Eigen::Map<Vector12d>{grad} = g;
          if (hess) {
            const double b2 = barrier_second_derivative(d, dhat2_);
            const Matrix12d Hm = edge_edge_mollifier_hessian(X[0], X[1], X[2], X[3], eps_x);
            Matrix12d H = m * (b2 * gd * gd.transpose() + b1 * Hd) +
                          b1 * (gd * gm.transpose() + gm * gd.transpose()) + b * Hm;
            H *= weight;
            project_psd<12>(H);
            Eigen::Map<Matrix12d>{hess} = H;
          }
        }
      }
      // Held vertices have no DOFs in the solve: drop them from the stencil.
      for (int i = 0; i < 4; ++i)
        if (model_.dirichlet[s[i]] >= 0) s[i] = -1;
    }
  }, 64);
}

void BarrierPotential::add_gradient(double* grad) const {
  const int64_t na = num_active();
  for (int64_t k = 0; k < na; ++k)
    for (int i = 0; i < 4; ++i) {
      const int32_t v = stencils_[4 * k + i];
      if (v < 0) continue;
      for (int r = 0; r < 3; ++r) grad[3 * int64_t{v} + r] += gradients_[12 * k + 3 * i + r];
    }
}

// ---- CCD --------------------------------------------------------------------------------------

double BarrierPotential::max_step(const double* x, const double* p) {
  const int64_t n = model_.num_dofs();
  parallel_for(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x1_[i] = x[i] + p[i];
  }, 8192);
  find_candidates(x, x1_.data());
  const double* y = x1_.data();
  const double min_distance = kCcdGapFraction * dhat_;
  const ContactCandidates& c = candidates_;

  // Earliest time of impact, per fixed chunk of pairs (each chunk passes its running minimum as
  // tmax to cut work short; chunks are fixed, so the result is the same on any thread count).
  auto earliest = [&](int64_t count, auto&& ccd) {
    const int64_t chunks = (count + kPairGrain - 1) / kPairGrain;
    std::vector<double> partial(chunks, 1.0);
    parallel_for(chunks, [&](int64_t cb, int64_t ce) {
      for (int64_t k = cb; k < ce; ++k) {
        double t = 1.0;
        for (int64_t i = k * kPairGrain; i < std::min(count, (k + 1) * kPairGrain); ++i) {
          double toi = 1.0;
          if (ccd(i, t, toi)) t = std::min(t, toi);
        }
        partial[k] = t;
      }
    }, 1);
    double t = 1.0;
    for (double q : partial) t = std::min(t, q);
    return t;
  };
  const double t_vt = earliest(static_cast<int64_t>(c.vertex_triangle.size()),
                               [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.vertex_triangle[i];
    const int32_t* t = &model_.surface_triangles[3 * int64_t{pr.second}];
    return point_triangle_ccd(point(x, pr.first), point(x, t[0]), point(x, t[1]), point(x, t[2]),
                              point(y, pr.first), point(y, t[0]), point(y, t[1]), point(y, t[2]),
                              min_distance, tmax, toi);
  });
  const double t_ee = earliest(static_cast<int64_t>(c.edge_edge.size()),
                               [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.edge_edge[i];
    const int32_t* ea = &model_.surface_edges[2 * int64_t{pr.first}];
    const int32_t* eb = &model_.surface_edges[2 * int64_t{pr.second}];
    return edge_edge_ccd(point(x, ea[0]), point(x, ea[1]), point(x, eb[0]), point(x, eb[1]),
                         point(y, ea[0]), point(y, ea[1]), point(y, eb[0]), point(y, eb[1]),
                         min_distance, tmax, toi);
  });
  const double t_vp = earliest(static_cast<int64_t>(c.vertex_plane.size()),
                               [&](int64_t i, double tmax, double& toi) {
    const IndexPair& pr = c.vertex_plane[i];
    const ObstaclePlane& plane = model_.obstacle_planes[pr.second];
    return point_plane_ccd(point(x, pr.first), point(y, pr.first), plane.point, plane.normal,
                           min_distance, tmax, toi);
  });
  return std::min({t_vt, t_ee, t_vp});
}

}  // namespace nexdyn

// Barrier potential over contact pairs (see barrier_potential.hpp): the candidate search, the
// energies and the contact summary over every candidate, and the derivatives over the active set
// (active_set.hpp) from the stencil kernels (kernels/barrier/barrier_stencils.hpp). The swept
// search and the collision-free step are in contact_ccd.cpp.
#include "engine/contact/barrier_potential.hpp"

#include "engine/contact/pair_geometry.hpp"
#include "engine/parallel.hpp"
#include "kernels/barrier/barrier.hpp"
#include "kernels/barrier/barrier_stencils.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

using pair_geometry::box_gap_squared;
using pair_geometry::edge_edge_threshold;
using pair_geometry::kFarMargin;
using pair_geometry::kPairGrain;
using pair_geometry::point;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

double bodies_bbox_diagonal(const Model& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInf), hi = -lo;
  for (const BodyRange& body : model.bodies) {
    if (body.obstacle) continue;
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
      if (model.axis_node(v)) continue;  // a coordinate of an affine body, not a point of it
      lo = lo.cwiseMin(point(model.rest_positions.data(), v));
      hi = hi.cwiseMax(point(model.rest_positions.data(), v));
    }
  }
  return (lo.array() <= hi.array()).all() ? (hi - lo).norm() : 0.0;
}

BarrierPotential::BarrierPotential(const Model& model, double dhat)
    : model_(model), dhat_(dhat), dhat2_(dhat * dhat), active_(model, dhat * dhat) {
  x1_.resize(model.num_dofs());
}

void BarrierPotential::find_candidates(const double* x0, const double* x1) {
  const int64_t n = model_.num_dofs();
  // A static search at the positions of the last one (friction lags, then the solve; the measure
  // of the step before) is a no-op, but for the sleepers' pairs it may still hold.
  if (!(!x1 && static_search_ && std::equal(x0, x0 + n, static_x_.begin())) &&
      !(!x1 && !solved_.empty() && incremental_search(x0, nullptr)))
    search_all(x0, x1);
  if (!solved_.empty() && !dropped_) drop_unsolved_pairs(x0);
}

bool BarrierPotential::incremental_search(const double* x, const double* p) {
  if (!covers_) return false;
  // Moved: from where the list covers, or along p. The others' pairs are all in the list. A
  // moved held vertex (a boundary carried to its target) sends the search back to the full one:
  // the masked search takes its mask for the free vertices, and would pair a held vertex with
  // the fixed obstacles, which the full search never does.
  moved_.assign(model_.num_vertices, 0);
  bool any = false;
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * int64_t{v} + d;
      if (x[i] != cover_x_[i] || (p && p[i] != 0.0)) {
        if (model_.dirichlet[v] >= 0) return false;
        moved_[v] = 1;
        any = true;
        break;
      }
    }
  if (!any) return true;
  no_motion_.assign(model_.num_dofs(), 0.0);
  sweep(x, p ? p : no_motion_.data(), moved_.data());
  return true;
}

// ---- distances and energy -------------------------------------------------------------------

namespace {

struct PairEval {
  double d = kInf;
  double energy = 0.0;
};

// Squared distance and barrier value of one pair. The value is +inf for d <= 0. With kEnergyOnly
// (the energy sums), a pair whose boxes are farther apart than dhat (pair_geometry.hpp) gets 0 and
// its box gap as d, a lower bound, without the distance kernel.
template <bool kEnergyOnly>
PairEval eval_vertex_triangle(const Model& m, const double* x, const IndexPair& pair, double dhat2) {
  if (kEnergyOnly) {
    const double gap2 = box_gap_squared(x, nullptr, vertex_triangle_vertices(m, pair), 1);
    if (gap2 > kFarMargin * dhat2) return PairEval{gap2, 0.0};
  }
  const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
  PairEval e;
  e.d = point_triangle_distance(point(x, pair.first), point(x, t[0]), point(x, t[1]), point(x, t[2]));
  e.energy = e.d < dhat2 ? barrier(e.d, dhat2) : 0.0;
  return e;
}

template <bool kEnergyOnly>
PairEval eval_edge_edge(const Model& m, const double* x, const IndexPair& pair, double dhat2) {
  if (kEnergyOnly) {
    const double gap2 = box_gap_squared(x, nullptr, edge_edge_vertices(m, pair), 2);
    if (gap2 > kFarMargin * dhat2) return PairEval{gap2, 0.0};
  }
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
  PairEval e;
  e.d = pair_geometry::vertex_plane_squared_distance(m, x, pair);  // behind the plane: touching
  e.energy = e.d < dhat2 ? barrier(e.d, dhat2) : 0.0;
  return e;
}

// Reduces eval(pair) over all candidates in a fixed order: per fixed chunk of pairs with
// reduce(acc, eval), the chunks combined in order with reduce.combine.
template <typename T, typename Reduce>
T reduce_pairs(const Model& m, const ContactCandidates& c, const double* x, double dhat2, T init, Reduce&& reduce) {
  T result = init;
  auto over = [&](const std::vector<IndexPair>& pairs, auto&& eval) {
    const int64_t n = static_cast<int64_t>(pairs.size());
    const int64_t chunks = (n + kPairGrain - 1) / kPairGrain;
    std::vector<T> partial(chunks, init);
    parallel_for(chunks, [&](int64_t cb, int64_t ce) {
      for (int64_t k = cb; k < ce; ++k) {
        T acc = init;
        for (int64_t i = k * kPairGrain; i < std::min(n, (k + 1) * kPairGrain); ++i)
          acc = reduce(acc, eval(m, x, pairs[i], dhat2));
        partial[k] = acc;
      }
    }, 1);
    for (const T& p : partial) result = reduce.combine(result, p);
  };
  over(c.vertex_triangle, eval_vertex_triangle<Reduce::kEnergyOnly>);
  over(c.edge_edge, eval_edge_edge<Reduce::kEnergyOnly>);
  over(c.vertex_plane, eval_vertex_plane);
  return result;
}

struct SumEnergy {
  static constexpr bool kEnergyOnly = true;
  double operator()(double acc, const PairEval& e) const { return acc + e.energy; }
  double combine(double a, double b) const { return a + b; }
};
struct MinDistance {
  static constexpr bool kEnergyOnly = false;
  double operator()(double acc, const PairEval& e) const { return std::min(acc, e.d); }
  double combine(double a, double b) const { return std::min(a, b); }
};
// The summary's three reductions in one pass over the pairs, each in the order it has alone.
struct Totals {
  double energy = 0.0, active = 0.0, min_d = kInf;
};
struct SumCountMin {
  static constexpr bool kEnergyOnly = false;
  double dhat2;
  Totals operator()(Totals acc, const PairEval& e) const {
    return {acc.energy + e.energy, acc.active + (e.d < dhat2 ? 1.0 : 0.0), std::min(acc.min_d, e.d)};
  }
  Totals combine(Totals a, Totals b) const {
    return {a.energy + b.energy, a.active + b.active, std::min(a.min_d, b.min_d)};
  }
};

}  // namespace

void BarrierPotential::search_all(const double* x0, const double* x1) {
  ProfileScope scope(profile_, StepPhase::broad_phase);
  const int64_t n = model_.num_dofs();
  find_contact_candidates(model_, x0, x1, 0.5 * dhat_, candidates_);
  active_.forget_pairs(candidates_);
  skin_valid_ = false;
  static_search_ = x1 == nullptr;
  if (static_search_) static_x_.assign(x0, x0 + n);
  dropped_ = false;
  dropped_energy_ = 0.0;
  covers_ = true;
  cover_x_.assign(x0, x0 + n);
}

void BarrierPotential::set_asleep(const std::vector<int32_t>& vertices) {
  std::vector<uint8_t> solved;
  if (!vertices.empty()) {
    solved.resize(model_.num_vertices);
    for (int32_t v = 0; v < model_.num_vertices; ++v) {
      const int32_t id = model_.dirichlet[v];
      solved[v] = id < 0 || model_.dirichlet_motions[id].moves();
    }
    for (int32_t v : vertices) solved[v] = 0;
  }
  if (solved == solved_) return;
  solved_.swap(solved);
  // Lists without the pairs of the old sleepers lack those of the ones woken now: search again.
  if (dropped_) static_search_ = covers_ = false;
  skin_valid_ = false;
}

void BarrierPotential::drop_unsolved_pairs(const double* x) {
  // The dropped pairs' energy, summed as energy() sums (in list order per fixed chunk), so that
  // energy() = kept + dropped is the energy of every pair up to rounding.
  ContactCandidates dropped;
  auto solved = [&](const PairVertices& vertices) {
    for (int32_t v : vertices)
      if (v >= 0 && solved_[v]) return true;
    return false;
  };
  for_each_pair_list(model_, [&](auto list, auto&& vertices_of) {
    std::vector<IndexPair>& pairs = candidates_.*list;
    size_t kept = 0;
    for (const IndexPair& pr : pairs) {
      if (solved(vertices_of(pr))) pairs[kept++] = pr;
      else (dropped.*list).push_back(pr);
    }
    pairs.resize(kept);
  });
  active_.forget_pairs(candidates_);
  skin_valid_ = false;
  dropped_energy_ = reduce_pairs(model_, dropped, x, dhat2_, 0.0, SumEnergy{});
  dropped_ = true;
}

double BarrierPotential::energy(const double* x) const {
  return reduce_pairs(model_, candidates_, x, dhat2_, 0.0, SumEnergy{}) + dropped_energy_;
}

void BarrierPotential::group_energy(const double* x, const int32_t* group_of_vertex, double* total) {
  // A pair's group: that of its first moving vertex (all its moving vertices share one).
  auto first_group = [&](const PairVertices& vertices) {
    for (int32_t v : vertices)
      if (v >= 0 && group_of_vertex[v] >= 0) return group_of_vertex[v];
    return -1;
  };
  // The line search's trial points are near the point the active set last refreshed at: a pair
  // whose cached distance, less the motion since, stays beyond dhat has no energy (exactly 0, so
  // the sums keep their bits), and its distance kernel is skipped. `first`: the list's offset in
  // the active set's numbering, `split`: the pair's first side's vertex count.
  active_.motion_since_cache(x, cache_motion_);
  auto beyond_dhat = [&](int64_t i, const PairVertices& s, int split) {
    const double bound = active_.distance_bound(i, s, split, cache_motion_.data());
    return bound > 0.0 && bound * bound > pair_geometry::kFarMargin * dhat2_;
  };
  // The same two questions from the pair's bodies first, without reading its vertices: the
  // bodies' largest motions bound the pair's own (ContactActiveSet::body_distance_bound), and a
  // body whose point vertices share one group gives the pair's first moving vertex's group.
  active_.body_motion_since_cache(cache_motion_, body_cache_motion_);
  body_group_.resize(model_.bodies.size());
  parallel_for(static_cast<int64_t>(model_.bodies.size()), [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      const BodyRange& body = model_.bodies[k];
      int32_t group = kMixedGroups;
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
        if (!model_.follows.empty() && model_.follows[v] < Model::kOwnNode) continue;  // (p or a column of A)
        if (group == kMixedGroups) group = group_of_vertex[v];
        if (group_of_vertex[v] != group) {
          group = kMixedGroups;
          break;
        }
      }
      body_group_[k] = group;
    }
  }, 16);
  auto pair_group = [&](int64_t i, auto&& vertices) {
    if (active_.knows_side_bodies(i)) {
      const ContactActiveSet::SideBodies& b = active_.side_bodies(i);
      const int32_t ga = body_group_[b.first], gb = body_group_[b.second];
      if (ga != kMixedGroups && gb != kMixedGroups) return ga >= 0 ? ga : gb < 0 ? -1 : gb;
    }
    return first_group(vertices());
  };
  auto body_beyond_dhat = [&](int64_t i) {
    const double bound = active_.body_distance_bound(i, body_cache_motion_.data());
    return bound > 0.0 && bound * bound > pair_geometry::kFarMargin * dhat2_;
  };
  auto over = [&](const std::vector<IndexPair>& pairs, int64_t first, int split, auto&& vertices_of, auto&& eval) {
    grouped_sum(static_cast<int64_t>(pairs.size()), kPairGrain,
                [&](int64_t i) {
                  if (split == 0) return first_group(vertices_of(pairs[i]));
                  return pair_group(first + i, [&] { return vertices_of(pairs[i]); });
                },
                [&](int64_t b, int64_t e) {
                  double sum = 0.0;
                  for (int64_t i = b; i < e; ++i)
                    if (split == 0 || (!body_beyond_dhat(first + i) && !beyond_dhat(first + i, vertices_of(pairs[i]), split)))
                      sum += eval(model_, x, pairs[i], dhat2_).energy;
                  return sum;
                },
                total);
  };
  const ContactCandidates& c = candidates_;
  const int64_t nvt = static_cast<int64_t>(c.vertex_triangle.size());
  over(c.vertex_triangle, 0, 1, [&](const IndexPair& pr) { return vertex_triangle_vertices(model_, pr); },
       eval_vertex_triangle<true>);
  over(c.edge_edge, nvt, 2, [&](const IndexPair& pr) { return edge_edge_vertices(model_, pr); },
       eval_edge_edge<true>);
  over(c.vertex_plane, 0, 0, vertex_plane_vertices, eval_vertex_plane);  // (split 0: no skip)
}

double BarrierPotential::min_squared_distance(const double* x) {
  return active_.min_squared_distance(candidates_, x);
}

BarrierPotential::Summary BarrierPotential::summarize(const double* x) {
  Summary summary;
  if (!(static_search_ && !dropped_ && std::equal(x, x + model_.num_dofs(), static_x_.begin()))) search_all(x, nullptr);
  const Totals totals = reduce_pairs(model_, candidates_, x, dhat2_, Totals{}, SumCountMin{dhat2_});
  summary.barrier = totals.energy;
  summary.active = static_cast<int64_t>(totals.active);

  // Boxes inflated by r overlap for every pair closer than 2 r: a minimum below (2 r)^2 is exact.
  double min_d = totals.min_d;
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

// ---- active set and derivatives ---------------------------------------------------------------

void BarrierPotential::build_active_set(const double* x) { active_.build(candidates_, x); }

double BarrierPotential::active_set_energy(const double* x) const {
  const std::vector<StencilKind>& kinds = active_.kinds();
  const std::vector<int32_t>& vertices = active_.vertices();
  const std::vector<int32_t>& multiplicity = active_.multiplicities();
  return deterministic_sum(num_stencils(), [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t k = begin; k < end; ++k) {
      const int32_t* s = &vertices[4 * k];
      double e = 0.0;
      switch (kinds[k]) {
        case StencilKind::vertex_plane:
          e = eval_vertex_plane(model_, x, {s[0], s[1]}, dhat2_).energy;
          break;
        case StencilKind::point_point:
          e = point_point_barrier_energy(point(x, s[0]), point(x, s[1]), dhat2_);
          break;
        case StencilKind::point_edge:
          e = point_line_barrier_energy(point(x, s[0]), point(x, s[1]), point(x, s[2]), dhat2_);
          break;
        case StencilKind::point_triangle:
          e = point_plane_barrier_energy(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3]), dhat2_);
          break;
        case StencilKind::edge_edge:
          e = line_line_barrier_energy(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3]), dhat2_);
          break;
        case StencilKind::edge_edge_mollified:
          e = mollified_edge_edge_barrier_energy(point(x, s[0]), point(x, s[1]), point(x, s[2]), point(x, s[3]),
                                                 edge_edge_threshold(model_, &s[0], &s[2]), dhat2_);
          break;
      }
      sum += multiplicity[k] * e;
    }
    return sum;
  }, 1024);
}

namespace {

// The derivatives of weight * b of one stencil (vertex ids s, real ones) at x: its gradient into
// grad (3n) and, with hess, its projected Hessian into hess (3n x 3n, column-major). edge_case:
// the closest-feature case of an edge-edge stencil, as the active set classified it at this x.
void stencil_derivatives(const Model& m, ContactStencilKind kind, EdgeEdgeCase edge_case, const int32_t* s,
                         const double* x, double dhat2, double weight, double* grad, double* hess) {
  using Kind = ContactStencilKind;
  using Eigen::Map;
  switch (kind) {
    case Kind::vertex_plane: {
      const ObstaclePlane& plane = m.obstacle_planes[s[1]];
      const Eigen::Vector3d p = point(x, s[0]);
      if (hess)
        point_obstacle_plane_barrier_gradient_hessian(p, plane.point, plane.normal, dhat2, weight,
                                                      Map<Eigen::Vector3d>(grad), Map<Eigen::Matrix3d>(hess));
      else
        Map<Eigen::Vector3d>{grad} = point_obstacle_plane_barrier_gradient(p, plane.point, plane.normal, dhat2, weight);
      return;
    }
    case Kind::point_point: {
      const Eigen::Vector3d a = point(x, s[0]), b = point(x, s[1]);
      if (hess) point_point_barrier_gradient_hessian(a, b, dhat2, weight, Map<Vector6d>(grad), Map<Matrix6d>(hess));
      else Map<Vector6d>{grad} = point_point_barrier_gradient(a, b, dhat2, weight);
      return;
    }
    case Kind::point_edge: {
      const Eigen::Vector3d p = point(x, s[0]), e0 = point(x, s[1]), e1 = point(x, s[2]);
      if (hess) point_line_barrier_gradient_hessian(p, e0, e1, dhat2, weight, Map<Vector9d>(grad), Map<Matrix9d>(hess));
      else Map<Vector9d>{grad} = point_line_barrier_gradient(p, e0, e1, dhat2, weight);
      return;
    }
    default: break;
  }
  const Eigen::Vector3d X0 = point(x, s[0]), X1 = point(x, s[1]), X2 = point(x, s[2]), X3 = point(x, s[3]);
  Map<Vector12d> g(grad);
  switch (kind) {
    case Kind::point_triangle:
      if (hess) point_plane_barrier_gradient_hessian(X0, X1, X2, X3, dhat2, weight, g, Map<Matrix12d>(hess));
      else g = point_plane_barrier_gradient(X0, X1, X2, X3, dhat2, weight);
      return;
    case Kind::edge_edge:
      if (hess) line_line_barrier_gradient_hessian(X0, X1, X2, X3, dhat2, weight, g, Map<Matrix12d>(hess));
      else g = line_line_barrier_gradient(X0, X1, X2, X3, dhat2, weight);
      return;
    case Kind::edge_edge_mollified: {
      // Nearly parallel: product rule on m(x) b(d(x)) over all 12 DOFs.
      const double eps_x = edge_edge_threshold(m, &s[0], &s[2]);
      if (hess)
        mollified_edge_edge_barrier_gradient_hessian(X0, X1, X2, X3, edge_case, eps_x, dhat2, weight, g,
                                                     Map<Matrix12d>(hess));
      else
        mollified_edge_edge_barrier_gradient(X0, X1, X2, X3, edge_case, eps_x, dhat2, weight, g);
      return;
    }
    default: return;
  }
}

}  // namespace

void BarrierPotential::compute_derivatives(const double* x, double weight, bool with_hessian,
                                           const uint8_t* active) {
  const int64_t ns = num_stencils();
  const std::vector<StencilKind>& kinds = active_.kinds();
  const std::vector<int32_t>& vertices = active_.vertices();
  const std::vector<int32_t>& stencils = active_.stencils();
  const std::vector<int32_t>& multiplicity = active_.multiplicities();
  const std::vector<uint8_t>& edge_cases = active_.edge_edge_cases();
  const std::vector<int64_t>& slab_begin = active_.slab_begin();
  gradients_.resize(12 * ns);
  if (with_hessian) hessians_.resize(slab_begin[ns]);
  parallel_for(ns, [&](int64_t begin, int64_t end) {
    for (int64_t k = begin; k < end; ++k) {
      double* grad = &gradients_[12 * k];
      if (!touches(&stencils[4 * k], active)) {
        std::fill(grad, grad + 12, 0.0);
        continue;
      }
      double* hess = with_hessian ? &hessians_[slab_begin[k]] : nullptr;
      stencil_derivatives(model_, kinds[k], static_cast<EdgeEdgeCase>(edge_cases[k]), &vertices[4 * k], x, dhat2_,
                          weight * multiplicity[k], grad, hess);
    }
  }, 256);
}

void add_stencil_gradients(const std::vector<int32_t>& stencils, const std::vector<double>& gradients,
                           int64_t num_vertices, double* grad) {
  const int64_t num = static_cast<int64_t>(stencils.size() / 4);
  // One part per thread, each owning a range of vertex ids: every part reads all the stencils'
  // ids but adds only to its own vertices, so no two threads write one entry and each vertex's
  // sum runs in stencil order, as in one serial loop, whatever the number of parts.
  const int64_t parts =
      num < 4096 ? 1
                 : std::max<int64_t>(1, static_cast<int64_t>(tbb::global_control::active_value(
                                            tbb::global_control::max_allowed_parallelism)));
  parallel_for(parts, [&](int64_t part_begin, int64_t part_end) {
    for (int64_t part = part_begin; part < part_end; ++part) {
      const int64_t first = num_vertices * part / parts, count = num_vertices * (part + 1) / parts - first;
      for (int64_t k = 0; k < num; ++k)
        for (int i = 0; i < 4; ++i) {
          const int64_t v = stencils[4 * k + i];  // -1 (absent) falls outside every range
          if (static_cast<uint64_t>(v - first) >= static_cast<uint64_t>(count)) continue;
          for (int r = 0; r < 3; ++r) grad[3 * v + r] += gradients[12 * k + 3 * i + r];
        }
    }
  }, 1);
}

void BarrierPotential::add_gradient(double* grad) const {
  add_stencil_gradients(stencils(), gradients_, model_.num_vertices, grad);
}

void BarrierPotential::add_gradient_with_held(double* grad) const {
  // stencil_vertices() holds the real ids; a vertex-plane stencil's second entry is the plane's index.
  const std::vector<StencilKind>& kinds = active_.kinds();
  const std::vector<int32_t>& vertices = active_.vertices();
  for (int64_t k = 0; k < num_stencils(); ++k)
    for (int i = 0; i < stencil_size(kinds[k]); ++i) {
      const int32_t v = vertices[4 * k + i];
      for (int r = 0; r < 3; ++r) grad[3 * int64_t{v} + r] += gradients_[12 * k + 3 * i + r];
    }
}

}  // namespace nexdyn

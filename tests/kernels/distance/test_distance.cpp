// Tests of kernels/distance: every primitive's gradient and Hessian against central finite
// differences on random inputs; the point-triangle and edge-edge classifications on constructed
// inputs for every case, their per-case derivatives against finite differences, and their values
// against independent minimisations over the barycentric parameters. The random sweeps include
// ill-conditioned stencils (sliver and needle triangles, nearly parallel and short edges), with
// the finite-difference step and tolerance adapted to each stencil (budgets below and
// tests/kernels/finite_differences.hpp). Degenerate inputs (coincident points, points on edges
// and vertices, parallel, nearly parallel and crossing edges, zero-length edges) must give exact
// values and finite derivatives; nearly parallel edges, nearly zero-length edges, sliver and
// needle triangles, and the barrier times the edge-edge mollifier (the product the engine forms
// for nearly parallel pairs) are checked against finite differences; the mollifier's range.
#include "kernels/barrier/barrier.hpp"
#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "tests/kernels/finite_differences.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

namespace nexdyn {
namespace {

using Vec3 = Eigen::Vector3d;

template <int K>
using Stacked = Eigen::Matrix<double, 3 * K, 1>;

Vec3 random_point(std::mt19937_64& rng, double amplitude = 1.0) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  return {u(rng), u(rng), u(rng)};
}

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

// 10^-u with u uniform in [lo, hi]: offsets and lengths spread over decades.
double log_uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::pow(10.0, -std::uniform_real_distribution<double>(lo, hi)(rng));
}

template <int K>
Stacked<K> stack(const std::array<Vec3, K>& x) {
  Stacked<K> s;
  for (int i = 0; i < K; ++i) s.template segment<3>(3 * i) = x[i];
  return s;
}

template <int K>
std::array<Vec3, K> unstack(const Stacked<K>& s) {
  std::array<Vec3, K> x;
  for (int i = 0; i < K; ++i) x[i] = s.template segment<3>(3 * i);
  return x;
}

template <typename A, typename B>
double relative_error(const A& a, const B& b, double floor) {
  return (a - b).norm() / std::max({a.norm(), b.norm(), floor});
}

// Condition number of the 2x2 Gram matrix of two edge vectors: how ill-conditioned a triangle or
// a pair of edges is (~1 / sin^2 of the angle, or the squared ratio of the lengths).
double gram_condition(const Vec3& a, const Vec3& b) {
  Eigen::Matrix<double, 3, 2> E;
  E << a, b;
  const Eigen::Vector2d ev =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(E.transpose() * E).eigenvalues();
  return ev(1) / ev(0);
}

// ------------------------------------------------------------------------------------------------
// Finite-difference budgets of squared distances (tests/kernels/finite_differences.hpp).
//
// Each closest-feature piece is d = |r|^2, r = r0 + D lambda at the minimising lambda, with D the
// 3 x m matrix of the primitive's edge vectors (none for point-point). From it:
//   ell      = sigma_min(D), the feature on which d varies: an edge's length (point-line), a
//              triangle's smallest height (point-plane), |ea x eb| / |ea| for two lines (the
//              offset that turns their common normal); for point-point (d is quadratic, any step
//              is exact up to rounding) the size of the stencil;
//   noise    = 4 eps (d + sqrt(d) (X + |r0| X / ell)): d comes from differences of coordinates
//              (rounded by eps X, X the largest coordinate), whose directions are off by
//              eps X / ell, which moves r by |r0| times that;
//   analytic = eps (cond(D^T D) (1 + |r0| / sqrt(d)) + 4 X / ell), relative: the derivatives
//              solve the normal equations (D^T D) lambda = -D^T r0 for the closest points, which
//              loses eps cond(D^T D) in lambda; r then carries that times |r0|, large against
//              |r| = sqrt(d) for a close pair, and so do the gradient 2 w_i r and the Hessian.
// The gradient that the Hessian check differentiates has `analytic` relative noise. A stencil
// whose budget allows more than kResolvable relative error is beyond what double-precision
// differences can check; the sweeps count those.
constexpr double kResolvable = 1e-3;

enum class Primitive : uint8_t { point_point, point_line, point_plane, line_line };

struct DistanceGeometry {
  double ell = 1.0;     // sigma_min(D), the stencil's size for point-point
  double cond = 1.0;    // cond(D^T D)
  double r0 = 0.0;      // |r0|
  double coords = 1.0;  // X: the largest |coordinate| or the stencil's size, whichever is larger
};

// Points in the primitive's order: [p0, p1], [p, e0, e1], [p, t0, t1, t2], [ea0, ea1, eb0, eb1].
DistanceGeometry geometry(Primitive p, const std::array<Vec3, 4>& v) {
  const int n = p == Primitive::point_point ? 2 : p == Primitive::point_line ? 3 : 4;
  Eigen::Matrix<double, 3, 2> D = Eigen::Matrix<double, 3, 2>::Zero();
  Vec3 r0 = v[0] - v[1];
  switch (p) {
    case Primitive::point_point: break;
    case Primitive::point_line: D.col(0) = v[2] - v[1]; break;
    case Primitive::point_plane: D << v[2] - v[1], v[3] - v[1]; break;
    case Primitive::line_line:
      D << v[1] - v[0], v[3] - v[2];
      r0 = v[0] - v[2];
      break;
  }
  DistanceGeometry g;
  double extent = 0.0, coords = 0.0;
  for (int i = 0; i < n; ++i) {
    coords = std::max(coords, v[i].cwiseAbs().maxCoeff());
    for (int j = 0; j < i; ++j) extent = std::max(extent, (v[i] - v[j]).norm());
  }
  g.coords = std::max({coords, extent, 1e-300});
  g.r0 = r0.norm();
  if (p == Primitive::point_point) {
    g.ell = g.coords;
  } else if (p == Primitive::point_line) {
    g.ell = D.col(0).norm();
  } else {
    const Eigen::Vector2d sv = Eigen::JacobiSVD<Eigen::Matrix<double, 3, 2>>(D).singularValues();
    g.ell = sv(1);
    g.cond = sv(0) * sv(0) / (sv(1) * sv(1));
  }
  return g;
}

struct DistanceBudgets {
  fd::Budget gradient, hessian;
};

DistanceBudgets distance_budgets(const DistanceGeometry& geo, double d, double g_norm) {
  constexpr double eps = fd::kEps;
  const double X = geo.coords;
  const double s = std::sqrt(std::max(d, 0.0));
  DistanceBudgets b;
  b.gradient.ell = geo.ell;
  // Gradients below 1e-6 of the stencil's scale (touching pairs) are compared absolutely.
  b.gradient.floor = 1e-6 * X;
  b.gradient.noise = 4.0 * eps * (d + s * (X + geo.r0 * X / geo.ell));
  b.gradient.analytic =
      eps * (geo.cond * (1.0 + geo.r0 / std::max(s, 1e-6 * X)) + 4.0 * X / geo.ell);
  b.hessian = b.gradient;
  b.hessian.floor = 1.0;  // d's Hessian holds 2 w w^T (x) I3 with |w| >= 1: never small
  b.hessian.noise = (b.gradient.analytic + 4.0 * eps) * std::max(g_norm, b.gradient.floor);
  return b;
}

// Checks f, grad, hess (callables on stacked points) against central differences at x within the
// budgets, plus the structure: symmetric Hessian, translation invariance (gradient blocks sum to
// zero, Hessian rows too) when `translation_invariant`. A derivative whose budget allows more than
// kResolvable (beyond double precision) is not compared; the function then returns false, and
// checks the structure only when both were compared.
template <int K, typename F, typename G, typename H>
bool check_within(const F& f, const G& grad, const H& hess, const Stacked<K>& x,
                  const DistanceBudgets& b, bool translation_invariant = true) {
  const Stacked<K> g = grad(x);
  const Eigen::Matrix<double, 3 * K, 3 * K> Hx = hess(x);
  REQUIRE(g.allFinite());
  REQUIRE(Hx.allFinite());
  const fd::Result rg = fd::check(
      g, [&](double h) { return fd::gradient<3 * K>(f, x, h); }, b.gradient);
  const fd::Result rh = fd::check(
      Hx, [&](double h) { return fd::jacobian<3 * K>(grad, x, h); }, b.hessian);
  CAPTURE(x.transpose());
  CAPTURE(rg);
  CAPTURE(rh);
  const bool g_resolved = rg.tolerance <= kResolvable, h_resolved = rh.tolerance <= kResolvable;
  if (g_resolved) {
    CHECK(rg.ok());
    CHECK(rg.second_order());
  }
  if (h_resolved) {
    CHECK(rh.ok());
    CHECK(rh.second_order());
  }
  if (!g_resolved || !h_resolved) return false;
  CHECK(relative_error(Hx, Hx.transpose().eval(), 1.0) <= 1e-12 + b.hessian.analytic);
  if (translation_invariant) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i = 0; i < K; ++i) sum += g.template segment<3>(3 * i);
    CHECK(sum.norm() <= (1e-10 + b.gradient.analytic) * std::max(g.norm(), b.gradient.floor));
    Eigen::Matrix<double, 3 * K, 3> row_sum = Eigen::Matrix<double, 3 * K, 3>::Zero();
    for (int i = 0; i < K; ++i) row_sum += Hx.template middleCols<3>(3 * i);
    CHECK(row_sum.norm() <= (1e-9 + b.hessian.analytic) * std::max(1.0, Hx.norm()));
  }
  return true;
}

// The same for a squared distance with the budget of its piece's geometry.
template <int K, typename F, typename G, typename H>
bool check_derivatives(const F& f, const G& grad, const H& hess, const Stacked<K>& x,
                       const DistanceGeometry& geo, bool translation_invariant = true) {
  const DistanceBudgets b = distance_budgets(geo, f(x), grad(x).norm());
  return check_within<K>(f, grad, hess, x, b, translation_invariant);
}

// ------------------------------------------------------------------------------------------------
// Independent references for the closest-feature values.

// Euclidean projection of (u, v) onto {u >= 0, v >= 0, u + v <= 1}.
Eigen::Vector2d project_to_unit_triangle(const Eigen::Vector2d& x) {
  if (x(0) >= 0.0 && x(1) >= 0.0 && x(0) + x(1) <= 1.0) return x;
  auto on_segment = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    const Eigen::Vector2d e = b - a;
    const double s = std::clamp((x - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
    return Eigen::Vector2d(a + s * e);
  };
  const Eigen::Vector2d c[3] = {on_segment({0, 0}, {1, 0}), on_segment({1, 0}, {0, 1}),
                                on_segment({0, 1}, {0, 0})};
  int best = 0;
  for (int i = 1; i < 3; ++i) {
    if ((c[i] - x).squaredNorm() < (c[best] - x).squaredNorm()) best = i;
  }
  return c[best];
}

Eigen::Vector2d project_to_unit_square(const Eigen::Vector2d& x) {
  return x.cwiseMax(0.0).cwiseMin(1.0);
}

// min over the parameter set of |r0 + E lambda|^2 (E is 3x2) by a grid search followed by
// projected gradient descent with step 1 / L (convex quadratic). Converges in the iteration
// budget only for well-conditioned E (Gram condition up to a few hundred).
template <typename Project>
double minimise_by_descent(const Vec3& r0, const Eigen::Matrix<double, 3, 2>& E,
                           const Project& project) {
  auto f = [&](const Eigen::Vector2d& l) { return (r0 + E * l).squaredNorm(); };
  Eigen::Vector2d best(0, 0);
  double fbest = f(project(best));
  constexpr int kGrid = 64;
  for (int i = 0; i <= kGrid; ++i) {
    for (int j = 0; j <= kGrid; ++j) {
      const Eigen::Vector2d l = project(Eigen::Vector2d(double(i) / kGrid, double(j) / kGrid));
      const double fl = f(l);
      if (fl < fbest) { fbest = fl; best = l; }
    }
  }
  const Eigen::Matrix2d G = 2.0 * E.transpose() * E;
  const double L = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(G).eigenvalues()(1);
  Eigen::Vector2d l = best;
  for (int it = 0; it < 40000; ++it) {
    const Eigen::Vector2d g = 2.0 * E.transpose() * (r0 + E * l);
    const Eigen::Vector2d next = project(Eigen::Vector2d(l - g / L));
    // At a fixed point up to rounding: the remaining error is below the step times the
    // condition number, far below the 1e-10 the comparisons allow.
    const bool converged = (next - l).norm() <= 1e-16 * (1.0 + l.norm());
    l = next;
    if (converged) break;
  }
  return std::min(fbest, f(l));
}

// min over a convex polygon of parameters (corners in order) of |r0 + E lambda|^2, exactly: the
// unconstrained minimiser if it is inside, else the best of the edges' clamped 1D minimisers.
// Every candidate is a feasible point evaluated directly, so rounding in the 2x2 solve of an
// ill-conditioned E only moves a candidate along the flat direction, where f barely changes.
// Needs no iterations, so it also serves slivers, needles and nearly parallel edges.
template <int N, typename Inside>
double minimise_over_polygon(const Vec3& r0, const Eigen::Matrix<double, 3, 2>& E,
                             const std::array<Eigen::Vector2d, N>& corners, const Inside& inside) {
  auto f = [&](const Eigen::Vector2d& l) { return (r0 + E * l).squaredNorm(); };
  double best = f(corners[0]);
  const Eigen::Matrix2d A = E.transpose() * E;
  if (A.determinant() > 0.0) {
    const Eigen::Vector2d l = A.fullPivLu().solve(-E.transpose() * r0);
    if (inside(l)) best = std::min(best, f(l));
  }
  for (int k = 0; k < N; ++k) {
    const Eigen::Vector2d a = corners[k], b = corners[(k + 1) % N];
    const Vec3 q = r0 + E * a, v = E * (b - a);
    const double vv = v.squaredNorm();
    const double s = vv > 0.0 ? std::clamp(-q.dot(v) / vv, 0.0, 1.0) : 0.0;
    best = std::min(best, f(a + s * (b - a)));
  }
  return best;
}

struct Reference {
  double descent = -1.0;  // projected gradient, well-conditioned stencils only (else -1)
  double exact = 0.0;     // candidate enumeration
};

Reference reference_point_triangle(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2,
                                   bool with_descent) {
  Eigen::Matrix<double, 3, 2> E;
  E << t1 - t0, t2 - t0;
  Reference r;
  if (with_descent) r.descent = minimise_by_descent(t0 - p, E, project_to_unit_triangle);
  r.exact = minimise_over_polygon<3>(
      t0 - p, E, {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1)},
      [](const Eigen::Vector2d& l) { return l(0) >= 0.0 && l(1) >= 0.0 && l(0) + l(1) <= 1.0; });
  return r;
}

Reference reference_edge_edge(const Vec3& ea0, const Vec3& ea1, const Vec3& eb0, const Vec3& eb1,
                              bool with_descent) {
  Eigen::Matrix<double, 3, 2> E;
  E << ea1 - ea0, -(eb1 - eb0);
  Reference r;
  if (with_descent) r.descent = minimise_by_descent(ea0 - eb0, E, project_to_unit_square);
  r.exact = minimise_over_polygon<4>(
      ea0 - eb0, E,
      {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), Eigen::Vector2d(1, 1), Eigen::Vector2d(0, 1)},
      [](const Eigen::Vector2d& l) {
        return (l.array() >= 0.0).all() && (l.array() <= 1.0).all();
      });
  return r;
}

// ------------------------------------------------------------------------------------------------
// The primitive behind each closest-feature case, and per-case derivative checks.

struct Piece {
  Primitive primitive;
  std::array<int, 4> idx;  // the primitive's points in the stencil (unused entries 0)
};

DistanceGeometry geometry(const Piece& piece, const std::array<Vec3, 4>& x) {
  std::array<Vec3, 4> v;
  for (int i = 0; i < 4; ++i) v[i] = x[piece.idx[i]];
  return geometry(piece.primitive, v);
}

Piece piece_of(PointEdgeCase c) {
  switch (c) {
    case PointEdgeCase::p_e0: return {Primitive::point_point, {0, 1, 0, 0}};
    case PointEdgeCase::p_e1: return {Primitive::point_point, {0, 2, 0, 0}};
    case PointEdgeCase::p_e: break;
  }
  return {Primitive::point_line, {0, 1, 2, 0}};
}

Piece piece_of(PointTriangleCase c) {
  switch (c) {
    case PointTriangleCase::p_t0: return {Primitive::point_point, {0, 1, 0, 0}};
    case PointTriangleCase::p_t1: return {Primitive::point_point, {0, 2, 0, 0}};
    case PointTriangleCase::p_t2: return {Primitive::point_point, {0, 3, 0, 0}};
    case PointTriangleCase::p_e0: return {Primitive::point_line, {0, 1, 2, 0}};
    case PointTriangleCase::p_e1: return {Primitive::point_line, {0, 2, 3, 0}};
    case PointTriangleCase::p_e2: return {Primitive::point_line, {0, 3, 1, 0}};
    case PointTriangleCase::p_t: break;
  }
  return {Primitive::point_plane, {0, 1, 2, 3}};
}

Piece piece_of(EdgeEdgeCase c) {
  switch (c) {
    case EdgeEdgeCase::ea0_eb0: return {Primitive::point_point, {0, 2, 0, 0}};
    case EdgeEdgeCase::ea0_eb1: return {Primitive::point_point, {0, 3, 0, 0}};
    case EdgeEdgeCase::ea1_eb0: return {Primitive::point_point, {1, 2, 0, 0}};
    case EdgeEdgeCase::ea1_eb1: return {Primitive::point_point, {1, 3, 0, 0}};
    case EdgeEdgeCase::ea_eb0: return {Primitive::point_line, {2, 0, 1, 0}};
    case EdgeEdgeCase::ea_eb1: return {Primitive::point_line, {3, 0, 1, 0}};
    case EdgeEdgeCase::ea0_eb: return {Primitive::point_line, {0, 2, 3, 0}};
    case EdgeEdgeCase::ea1_eb: return {Primitive::point_line, {1, 2, 3, 0}};
    case EdgeEdgeCase::ea_eb: break;
  }
  return {Primitive::line_line, {0, 1, 2, 3}};
}

bool check_point_edge_case(const std::array<Vec3, 3>& x, PointEdgeCase c) {
  return check_derivatives<3>(
      [c](const Stacked<3>& s) {
        auto v = unstack<3>(s);
        return point_edge_distance(v[0], v[1], v[2], c);
      },
      [c](const Stacked<3>& s) {
        auto v = unstack<3>(s);
        return point_edge_distance_gradient(v[0], v[1], v[2], c);
      },
      [c](const Stacked<3>& s) {
        auto v = unstack<3>(s);
        return point_edge_distance_hessian(v[0], v[1], v[2], c);
      },
      stack<3>(x), geometry(piece_of(c), {x[0], x[1], x[2], x[0]}));
}

bool check_point_triangle_case(const std::array<Vec3, 4>& x, PointTriangleCase c) {
  return check_derivatives<4>(
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return point_triangle_distance(v[0], v[1], v[2], v[3], c);
      },
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return point_triangle_distance_gradient(v[0], v[1], v[2], v[3], c);
      },
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return point_triangle_distance_hessian(v[0], v[1], v[2], v[3], c);
      },
      stack<4>(x), geometry(piece_of(c), x));
}

bool check_edge_edge_case(const std::array<Vec3, 4>& x, EdgeEdgeCase c) {
  return check_derivatives<4>(
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return edge_edge_distance(v[0], v[1], v[2], v[3], c);
      },
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return edge_edge_distance_gradient(v[0], v[1], v[2], v[3], c);
      },
      [c](const Stacked<4>& s) {
        auto v = unstack<4>(s);
        return edge_edge_distance_hessian(v[0], v[1], v[2], v[3], c);
      },
      stack<4>(x), geometry(piece_of(c), x));
}

std::string name(PointTriangleCase c) {
  constexpr const char* kNames[] = {"p_t0", "p_t1", "p_t2", "p_e0", "p_e1", "p_e2", "p_t"};
  return kNames[static_cast<int>(c)];
}

std::string name(EdgeEdgeCase c) {
  constexpr const char* kNames[] = {"ea0_eb0", "ea0_eb1", "ea1_eb0", "ea1_eb1", "ea_eb0",
                                    "ea_eb1",  "ea0_eb",  "ea1_eb",  "ea_eb"};
  return kNames[static_cast<int>(c)];
}

// ------------------------------------------------------------------------------------------------
// Primitives

TEST_CASE("distance: primitives match finite differences on random inputs") {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 200; ++trial) {
    const std::array<Vec3, 4> x = {random_point(rng), random_point(rng), random_point(rng),
                                   random_point(rng)};
    CHECK(check_derivatives<2>(
        [](const Stacked<2>& s) {
          auto v = unstack<2>(s);
          return point_point_distance(v[0], v[1]);
        },
        [](const Stacked<2>& s) {
          auto v = unstack<2>(s);
          return point_point_distance_gradient(v[0], v[1]);
        },
        [](const Stacked<2>& s) {
          auto v = unstack<2>(s);
          return point_point_distance_hessian(v[0], v[1]);
        },
        stack<2>({x[0], x[1]}), geometry(Primitive::point_point, x)));
    CHECK(check_derivatives<3>(
        [](const Stacked<3>& s) {
          auto v = unstack<3>(s);
          return point_line_distance(v[0], v[1], v[2]);
        },
        [](const Stacked<3>& s) {
          auto v = unstack<3>(s);
          return point_line_distance_gradient(v[0], v[1], v[2]);
        },
        [](const Stacked<3>& s) {
          auto v = unstack<3>(s);
          return point_line_distance_hessian(v[0], v[1], v[2]);
        },
        stack<3>({x[0], x[1], x[2]}), geometry(Primitive::point_line, x)));
    CHECK(check_derivatives<4>(
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return point_plane_distance(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return point_plane_distance_gradient(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return point_plane_distance_hessian(v[0], v[1], v[2], v[3]);
        },
        stack<4>(x), geometry(Primitive::point_plane, x)));
    CHECK(check_derivatives<4>(
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return line_line_distance(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return line_line_distance_gradient(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return line_line_distance_hessian(v[0], v[1], v[2], v[3]);
        },
        stack<4>(x), geometry(Primitive::line_line, x)));
  }
}

TEST_CASE("distance: primitive values against explicit closest points") {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 p = random_point(rng), a = random_point(rng), b = random_point(rng),
               c = random_point(rng);
    // Point-line: foot of the perpendicular.
    const double s = (p - a).dot(b - a) / (b - a).squaredNorm();
    CHECK(point_line_distance(p, a, b) ==
          doctest::Approx((p - a - s * (b - a)).squaredNorm()).epsilon(1e-10));
    // Point-plane: residual of the least-squares projection onto span(b - a, c - a).
    Eigen::Matrix<double, 3, 2> E;
    E << b - a, c - a;
    const Eigen::Vector2d uv = (E.transpose() * E).ldlt().solve(E.transpose() * (p - a));
    CHECK(point_plane_distance(p, a, b, c) ==
          doctest::Approx((p - a - E * uv).squaredNorm()).epsilon(1e-9));
    // Line-line: residual of the 2-parameter least squares.
    E << b - p, -(c - a);
    const Eigen::Vector2d st = (E.transpose() * E).ldlt().solve(E.transpose() * (a - p));
    CHECK(line_line_distance(p, b, a, c) ==
          doctest::Approx((p + E * st - a).squaredNorm()).epsilon(1e-9));
  }
}

TEST_CASE("distance: point to obstacle plane") {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 100; ++trial) {
    const Vec3 p = random_point(rng), o = random_point(rng);
    const Vec3 n = random_point(rng).normalized();
    const double h = (p - o).dot(n);
    CHECK(point_obstacle_plane_distance(p, o, n) == doctest::Approx(h * h).epsilon(1e-14));
    // Moving along the plane does not change d; moving along n does by the signed height.
    const Vec3 tangent = n.cross(random_point(rng)).normalized();
    CHECK(point_obstacle_plane_distance(p + 0.3 * tangent, o, n) ==
          doctest::Approx(h * h).epsilon(1e-12));
    // d is quadratic in p: any step is exact up to rounding, like point-point.
    DistanceGeometry geo;
    geo.r0 = (p - o).norm();
    geo.coords = std::max({1.0, p.cwiseAbs().maxCoeff(), o.cwiseAbs().maxCoeff()});
    geo.ell = geo.coords;
    CHECK(check_derivatives<1>(
        [&](const Stacked<1>& s) { return point_obstacle_plane_distance(s, o, n); },
        [&](const Stacked<1>& s) {
          return Stacked<1>(point_obstacle_plane_distance_gradient(s, o, n));
        },
        [&](const Stacked<1>& s) {
          return Eigen::Matrix3d(point_obstacle_plane_distance_hessian(s, o, n));
        },
        Stacked<1>(p), geo, /*translation_invariant=*/false));
  }
}

// ------------------------------------------------------------------------------------------------
// Point-edge

TEST_CASE("distance: point-edge cases, values and derivatives") {
  const Vec3 e0(0, 0, 0), e1(2, 0, 0);
  CHECK(point_edge_case(Vec3(-1, 1, 0), e0, e1) == PointEdgeCase::p_e0);
  CHECK(point_edge_case(Vec3(3, 0, 1), e0, e1) == PointEdgeCase::p_e1);
  CHECK(point_edge_case(Vec3(0.5, 1, 1), e0, e1) == PointEdgeCase::p_e);
  // Exact in binary: a few roundings of small integers and halves, hence 1e-15.
  CHECK(point_edge_distance(Vec3(-1, 1, 0), e0, e1) == doctest::Approx(2.0).epsilon(1e-15));
  CHECK(point_edge_distance(Vec3(3, 0, 1), e0, e1) == doctest::Approx(2.0).epsilon(1e-15));
  CHECK(point_edge_distance(Vec3(0.5, 1, 1), e0, e1) == doctest::Approx(2.0).epsilon(1e-15));

  std::mt19937_64 rng(4);
  int count[3] = {0, 0, 0};
  for (int trial = 0; trial < 600; ++trial) {
    const std::array<Vec3, 3> x = {random_point(rng, 2.0), random_point(rng), random_point(rng)};
    const PointEdgeCase c = point_edge_case(x[0], x[1], x[2]);
    ++count[static_cast<int>(c)];
    // Brute force over s in [0, 1] (golden-section on a convex function is overkill: dense
    // sampling + the exact local minimiser of the quadratic is independent enough).
    double best = 1e300;
    for (int i = 0; i <= 2000; ++i) {
      const double s = i / 2000.0;
      best = std::min(best, (x[0] - x[1] - s * (x[2] - x[1])).squaredNorm());
    }
    const double d = point_edge_distance(x[0], x[1], x[2]);
    CHECK(d <= best * (1.0 + 1e-12) + 1e-300);
    CHECK(d >= best - 1e-6 * (x[2] - x[1]).squaredNorm());
    CHECK(check_point_edge_case(x, c));
  }
  for (int k = 0; k < 3; ++k) CHECK(count[k] > 50);
}

// ------------------------------------------------------------------------------------------------
// Point-triangle

TEST_CASE("distance: point-triangle constructed inputs land in every case") {
  const Vec3 t0(0, 0, 0), t1(1, 0, 0), t2(0, 1, 0);
  struct Expected {
    Vec3 p;
    PointTriangleCase c;
    double d;
  };
  const Expected table[] = {
      {{0.2, 0.2, 0.5}, PointTriangleCase::p_t, 0.25},
      {{-1, -1, 0.5}, PointTriangleCase::p_t0, 2.25},
      {{2, -0.5, 0.5}, PointTriangleCase::p_t1, 1.5},
      {{-0.5, 2, 0.5}, PointTriangleCase::p_t2, 1.5},
      {{0.5, -1, 0.5}, PointTriangleCase::p_e0, 1.25},
      {{1, 1, 0.5}, PointTriangleCase::p_e1, 0.75},
      {{-1, 0.5, 0.5}, PointTriangleCase::p_e2, 1.25},
  };
  for (const Expected& e : table) {
    CAPTURE(name(e.c));
    CHECK(point_triangle_case(e.p, t0, t1, t2) == e.c);
    CHECK(point_triangle_distance(e.p, t0, t1, t2) == doctest::Approx(e.d).epsilon(1e-14));
  }
}

// A point over a corner or an edge of a triangle in general position is only over it up to
// rounding; the classification must still name the corner or the edge (kFeatureTie), every time,
// so that such contacts merge. Also checked: points clearly inside stay inside.
//
// Uniformly random corners include ill-conditioned triangles. The barycentric coordinates of the
// point are computed to about eps cond(Gram) (the 2x2 solve of point_triangle_case), so a tie is
// resolvable only while that stays below kFeatureTie = 1e-12, i.e. cond < ~1e3 (ties start to be
// missed near cond 9e3); triangles beyond are counted, not checked, and must be rare.
TEST_CASE("distance: point-triangle ties go to the corner or edge under the point") {
  std::mt19937_64 rng(17);
  constexpr PointTriangleCase corner[3] = {PointTriangleCase::p_t0, PointTriangleCase::p_t1,
                                           PointTriangleCase::p_t2};
  constexpr PointTriangleCase edge[3] = {PointTriangleCase::p_e0, PointTriangleCase::p_e1,
                                         PointTriangleCase::p_e2};
  int checked = 0, beyond = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3 t[3] = {random_point(rng), random_point(rng), random_point(rng)};
    const double cond = gram_condition(t[1] - t[0], t[2] - t[0]);
    if (fd::kEps * cond > 0.2 * detail::kFeatureTie) {
      ++beyond;
      continue;
    }
    CAPTURE(cond);
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    const double h = 0.01 * (1 + trial % 7);
    for (int k = 0; k < 3; ++k) {
      CHECK(point_triangle_case(t[k] + h * n, t[0], t[1], t[2]) == corner[k]);
      const Vec3 mid = 0.5 * (t[k] + t[(k + 1) % 3]);
      CHECK(point_triangle_case(mid + h * n, t[0], t[1], t[2]) == edge[k]);
    }
    const Vec3 centroid = (t[0] + t[1] + t[2]) / 3.0;
    CHECK(point_triangle_case(centroid + h * n, t[0], t[1], t[2]) == PointTriangleCase::p_t);
    ++checked;
  }
  MESSAGE("point-triangle ties: ", checked, " triangles checked, ", beyond,
          " beyond the tie margin");
  CHECK(beyond <= 20);
  CHECK(checked >= 1980);
}

// Triangles of three shapes: random corners; slivers (t2 within 10^-1..10^-6 of the line t0 t1);
// needles (t1 within 10^-1..10^-6 of t0). The point is random, or, for every other sliver and
// needle, over the face at a height of 10^0..10^-2 (a random point would rarely be closest to the
// face); those shapes stop at 10^-5, since the face piece of a 1e-6 sliver is beyond double
// precision (see the sliver test). Every stencil's per-case derivatives are checked (the first 40
// per case of the random ones, all ill-conditioned ones), and every value against the exact
// enumeration, the well-conditioned ones also against projected gradient descent. Stencils whose
// budget is beyond double precision (the face and line pieces of the thinnest shapes with the
// point close) are counted: about 7% (123 of 1865 ill-conditioned ones with this seed).
TEST_CASE("distance: point-triangle per-case derivatives and reference values") {
  std::mt19937_64 rng(5);
  int count[7] = {};
  int descent_compared = 0, ill_checked = 0, beyond = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 3000; ++trial) {
    Vec3 t0 = random_point(rng), t1 = random_point(rng), t2 = random_point(rng);
    const int shape = trial % 3;
    const bool over_face = shape != 0 && trial % 2 == 0;
    const double delta = log_uniform(rng, 1.0, over_face ? 5.0 : 6.0);
    if (shape == 1) {
      const double u = std::uniform_real_distribution<double>(-0.2, 1.2)(rng);
      t2 = t0 + u * (t1 - t0) + delta * random_point(rng);
    } else if (shape == 2) {
      t1 = t0 + delta * random_point(rng);
    }
    Vec3 p = random_point(rng, 1.5);
    if (over_face) {
      std::uniform_real_distribution<double> unit(0.0, 1.0);
      double b1 = unit(rng), b2 = unit(rng);
      if (b1 + b2 > 1.0) {
        b1 = 1.0 - b1;
        b2 = 1.0 - b2;
      }
      const Vec3 n = (t1 - t0).cross(t2 - t0).normalized();
      p = t0 + b1 * (t1 - t0) + b2 * (t2 - t0) + log_uniform(rng, 0.0, 2.0) * n;
    }
    const double cond = gram_condition(t1 - t0, t2 - t0);
    const bool ill = cond > 200.0;
    const PointTriangleCase c = point_triangle_case(p, t0, t1, t2);
    CAPTURE(name(c));
    CAPTURE(cond);
    if ((shape == 0 && count[static_cast<int>(c)] < 40) || ill) {
      if (check_point_triangle_case({p, t0, t1, t2}, c)) {
        ill_checked += ill;
      } else {
        ++beyond;
      }
    }
    if (shape == 0) ++count[static_cast<int>(c)];
    const double d = point_triangle_distance(p, t0, t1, t2);
    const bool descent = !ill && trial % 3 == 0;
    const Reference ref = reference_point_triangle(p, t0, t1, t2, descent);
    // The kernel's value carries the rounding of its piece (the budget's noise); the references
    // are feasible points evaluated directly (rounding ~eps |r0|^2).
    const DistanceGeometry geo = geometry(piece_of(c), {p, t0, t1, t2});
    const double tol = 1e-10 * ref.exact + 10.0 * distance_budgets(geo, d, 0.0).gradient.noise +
                       1e-15;
    CHECK(d <= ref.exact + tol);  // the classified feature is never farther than the minimum
    CHECK(d >= ref.exact - tol);
    if (descent) {
      CHECK(std::abs(d - ref.descent) <= 1e-10 * ref.descent + 1e-15);
      worst = std::max(worst, std::abs(d - ref.descent) / std::max(ref.descent, 1e-15));
      ++descent_compared;
    }
  }
  MESSAGE("point-triangle: ", descent_compared, " descent comparisons, worst relative gap ", worst,
          "; ", ill_checked, " ill-conditioned stencils checked, ", beyond,
          " beyond double-precision differences");
  for (int k = 0; k < 7; ++k) {
    CAPTURE(k);
    CHECK(count[k] >= 20);
  }
  CHECK(ill_checked >= 1000);
  CHECK(beyond <= ill_checked / 10);
}

TEST_CASE("distance: point-triangle degenerate inputs") {
  const Vec3 t0(0, 0, 0), t1(1, 0, 0), t2(0, 1, 0);
  auto finite = [&](const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
    const double d = point_triangle_distance(p, a, b, c);
    CHECK(std::isfinite(d));
    CHECK(d >= 0.0);
    CHECK(point_triangle_distance_gradient(p, a, b, c).allFinite());
    CHECK(point_triangle_distance_hessian(p, a, b, c).allFinite());
    return d;
  };
  // Relative comparisons (doctest's Approx adds epsilon * 1 absolute by default, which would
  // accept anything for the 1e-24 values below).
  auto relative = [](double value, double tolerance) {
    return doctest::Approx(value).epsilon(tolerance).scale(0.0);
  };
  // On a vertex, on an edge, inside the face, in the plane outside.
  CHECK(finite(t0, t0, t1, t2) == 0.0);
  CHECK(finite(t2, t0, t1, t2) == 0.0);
  CHECK(finite(Vec3(0.5, 0.5, 0), t0, t1, t2) <= 1e-30);
  CHECK(finite(Vec3(0.25, 0, 0), t0, t1, t2) <= 1e-30);
  CHECK(finite(Vec3(0.2, 0.3, 0), t0, t1, t2) <= 1e-30);
  // Exact in binary (a few roundings of small integers and halves), hence 1e-15.
  CHECK(finite(Vec3(2, 0, 0), t0, t1, t2) == relative(1.0, 1e-15));
  // 1e-12 above an edge and a vertex: the offsets are not binary fractions, so the squared
  // distances are the squares of rounded numbers; a few ulps.
  CHECK(finite(Vec3(0.5, 0.5, 1e-12), t0, t1, t2) == relative(1e-24, 1e-14));
  CHECK(finite(Vec3(-1e-12, -1e-12, 0), t0, t1, t2) == relative(2e-24, 1e-14));
  // Degenerate triangles: collinear corners, two and three coincident corners.
  CHECK(finite(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 0, 0)) == relative(1.0, 1e-15));
  CHECK(point_triangle_case(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 0, 0)) != PointTriangleCase::p_t);
  CHECK(finite(Vec3(0, 0, 3), t0, t0, t2) == relative(9.0, 1e-15));
  CHECK(finite(Vec3(0, 0, 3), t0, t0, t0) == relative(9.0, 1e-15));
  // A nearly flat (1e-12) sliver still gives the segment distance: treated as degenerate
  // (sin^2 <= kTriangleDegenerate), or as a plane within ~1e-24 of it.
  CHECK(finite(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 1e-12, 0)) == relative(1.0, 1e-12));
}

// Slivers (height delta over a unit edge) and needles (one edge of length delta), rotated and
// moved at random, with the point over the face (the plane piece, whose normal turns on the
// scale delta), beside the long edges and beyond the short one (the line pieces). The budget
// follows delta: the step is a fraction of it, and the tolerance includes the eps / delta^2
// that the plane piece's normal equations lose.
TEST_CASE("distance: sliver and needle triangles against finite differences") {
  std::mt19937_64 rng(41);
  int checked = 0, beyond = 0;
  for (double delta : {1e-2, 1e-4, 1e-6}) {
    for (double height : {0.3, 1e-3}) {
      const Eigen::Matrix3d R = random_rotation(rng);
      const Vec3 shift = random_point(rng);
      auto place = [&](const Vec3& v) { return Vec3(R * v + shift); };
      const Vec3 z(0, 0, height);
      // Sliver: t2 at height delta over the edge t0 t1. Probes over the face, beside the long
      // edge t0 t1, beside the long edge t1 t2.
      // Needle: t1 at distance delta from t0. Probes over the face, beside the short edge t0 t1
      // (a line piece on the scale delta), beside the long edge t2 t0.
      const std::array<Vec3, 3> points[2] = {{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.4, delta, 0)},
                                             {Vec3(0, 0, 0), Vec3(delta, 0, 0), Vec3(0.3, 1, 0)}};
      const Vec3 probes[2][3] = {
          {Vec3(0.4, delta / 3.0, 0) + z, Vec3(0.5, -0.2, 0) + z, Vec3(0.8, 0.3, 0) + z},
          {Vec3(0.09 + 0.35 * delta, 0.3, 0) + z, Vec3(0.5 * delta, -0.3, 0) + z,
           Vec3(-0.3, 0.4, 0) + z}};
      for (int shape = 0; shape < 2; ++shape) {
        for (int k = 0; k < 3; ++k) {
          const std::array<Vec3, 3>& t = points[shape];
          const std::array<Vec3, 4> x = {place(probes[shape][k]), place(t[0]), place(t[1]),
                                         place(t[2])};
          const PointTriangleCase c = point_triangle_case(x[0], x[1], x[2], x[3]);
          CAPTURE(delta);
          CAPTURE(height);
          CAPTURE(shape);
          CAPTURE(name(c));
          if (k == 0) CHECK(c == PointTriangleCase::p_t);
          if (check_point_triangle_case(x, c)) {
            ++checked;
          } else {
            ++beyond;
          }
        }
      }
    }
  }
  // Beyond double precision, all at delta = 1e-6: the face pieces (normal equations of
  // cond ~1 / delta^2 lose ~eps |r0| / (height delta^2): 3e-5 at height 0.3, 1e-2 at 1e-3,
  // measured against long double) and the needle's short-edge pieces (an edge vector rounded by
  // eps of its O(1) coordinates, eps / delta of itself): six stencils, counted.
  MESSAGE("slivers and needles: ", checked, " checked, ", beyond, " beyond");
  CHECK(beyond <= 6);
  CHECK(checked >= 30);
}

// ------------------------------------------------------------------------------------------------
// Edge-edge

TEST_CASE("distance: edge-edge constructed inputs land in every case") {
  const Vec3 ea0(0, 0, 0), ea1(1, 0, 0);
  struct Expected {
    Vec3 eb0, eb1;
    EdgeEdgeCase c;
    double d;
  };
  const Expected table[] = {
      {{0.5, -1, 1}, {0.5, 1, 1}, EdgeEdgeCase::ea_eb, 1.0},
      {{-1, -1, 1}, {-1, 1, 1}, EdgeEdgeCase::ea0_eb, 2.0},
      {{2, -1, 1}, {2, 1, 1}, EdgeEdgeCase::ea1_eb, 2.0},
      {{0.5, 0, 1}, {0.5, 0, 3}, EdgeEdgeCase::ea_eb0, 1.0},
      {{0.5, 0, 3}, {0.5, 0, 1}, EdgeEdgeCase::ea_eb1, 1.0},
      {{-1, -1, 0}, {-2, -3, 0}, EdgeEdgeCase::ea0_eb0, 2.0},
      {{-2, -3, 0}, {-1, -1, 0}, EdgeEdgeCase::ea0_eb1, 2.0},
      {{2, 1, 0}, {3, 3, 0}, EdgeEdgeCase::ea1_eb0, 2.0},
      {{3, 3, 0}, {2, 1, 0}, EdgeEdgeCase::ea1_eb1, 2.0},
  };
  for (const Expected& e : table) {
    CAPTURE(name(e.c));
    CHECK(edge_edge_case(ea0, ea1, e.eb0, e.eb1) == e.c);
    CHECK(edge_edge_distance(ea0, ea1, e.eb0, e.eb1) == doctest::Approx(e.d).epsilon(1e-14));
  }
}

// Pairs of four shapes: random (edge b 1.5x larger, so that every case occurs); nearly parallel
// (eb = 0.7 ea plus an offset of 10^-1..10^-6; in every other such pair eb is built about a
// point at distance 10^0..10^-3 over ea's interior and turned out of parallel by 10^-1..10^-6
// there, so that the closest points are the two interiors, which random pairs rarely give);
// short edge b (length 10^-1..10^-6); random again. Pairs beyond double precision (mostly the
// line-line piece at theta <= 1e-5 with the edges close) are counted: 17 of 523 with this seed.
// Per-case derivatives of the first 40 well-conditioned pairs per case and of the first 60
// ill-conditioned ones per case; values against the exact enumeration (every 4th pair) and, for
// well-conditioned pairs, projected gradient descent (every 20th).
TEST_CASE("distance: edge-edge per-case derivatives and reference values") {
  std::mt19937_64 rng(6);
  int count[9] = {}, ill_count[9] = {};
  int descent_compared = 0, ill_checked = 0, beyond = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 ea0 = random_point(rng), ea1 = random_point(rng);
    Vec3 eb0 = random_point(rng, 1.5);
    Vec3 eb1 = random_point(rng, 1.5);
    const int shape = trial % 4;
    if (shape == 1 && trial % 8 == 1) {
      eb1 = eb0 + 0.7 * (ea1 - ea0) + log_uniform(rng, 1.0, 6.0) * random_point(rng);
    } else if (shape == 1) {
      const Vec3 a = (ea1 - ea0).normalized();
      Vec3 n = random_point(rng);
      n = (n - n.dot(a) * a).normalized();
      const double theta = log_uniform(rng, 1.0, 6.0);
      const Vec3 dir = std::cos(theta) * a + std::sin(theta) * a.cross(n);
      const double u = std::uniform_real_distribution<double>(0.1, 0.9)(rng);
      const Vec3 mid = ea0 + u * (ea1 - ea0) + log_uniform(rng, 0.0, 3.0) * n;
      const double half = 0.35 * (ea1 - ea0).norm();
      eb0 = mid - half * dir;
      eb1 = mid + half * dir;
    } else if (shape == 2) {
      eb1 = eb0 + log_uniform(rng, 1.0, 6.0) * random_point(rng);
    }
    const double cond = gram_condition(ea1 - ea0, eb1 - eb0);
    const bool ill = cond > 200.0;
    const EdgeEdgeCase c = edge_edge_case(ea0, ea1, eb0, eb1);
    CAPTURE(name(c));
    CAPTURE(cond);
    const int k = static_cast<int>(c);
    if ((!ill && count[k] < 40) || (ill && ill_count[k] < 60)) {
      if (check_edge_edge_case({ea0, ea1, eb0, eb1}, c)) {
        ill_checked += ill;
      } else {
        ++beyond;
      }
    }
    ++(ill ? ill_count : count)[k];
    const bool descent = !ill && trial % 20 == 0;
    if (trial % 4 == 0 || descent) {
      const double d = edge_edge_distance(ea0, ea1, eb0, eb1);
      const Reference ref = reference_edge_edge(ea0, ea1, eb0, eb1, descent);
      const DistanceGeometry geo = geometry(piece_of(c), {ea0, ea1, eb0, eb1});
      const double tol = 1e-10 * ref.exact +
                         10.0 * distance_budgets(geo, d, 0.0).gradient.noise + 1e-15;
      CHECK(d <= ref.exact + tol);
      CHECK(d >= ref.exact - tol);
      if (descent) {
        CHECK(std::abs(d - ref.descent) <= 1e-10 * ref.descent + 1e-15);
        worst = std::max(worst, std::abs(d - ref.descent) / std::max(ref.descent, 1e-15));
        ++descent_compared;
      }
    }
  }
  MESSAGE("edge-edge: ", descent_compared, " descent comparisons, worst relative gap ", worst,
          "; ", ill_checked, " ill-conditioned pairs checked, ", beyond,
          " beyond double-precision differences");
  for (int k = 0; k < 9; ++k) {
    CAPTURE(k);
    CHECK(count[k] >= 20);
  }
  CHECK(ill_checked >= 300);
  CHECK(beyond <= ill_checked / 20);
}

// The closest-feature dispatch of both edge-edge and point-triangle solves r = alpha u + beta v +
// gamma (u x v) for (alpha, beta). Rounding r alone moves alpha by up to eps |r| / (|u| sin theta),
// theta the angle between u and v; the triple-product solve with an accurate u x v stays within
// that, where Cramer's rule on the normal equations (or the same triple products with a plainly
// rounded u x v) loses up to eps |r| / (|u| sin^2 theta): 1e6 times the bound at theta = 1e-7 here,
// and how an edge whose lines cross 1e-4 past its end came to be classified as crossing on
// machines without fused multiply-add. Reference: Cramer's rule on the same double inputs in
// binary128, whose eps / sin^2 is 1e-20 at theta = 1e-7. Measured worst: 0.6.
TEST_CASE("distance: in-plane coordinates lose eps / sin of the angle, not eps / sin^2") {
  using Quad = __float128;
  auto dot = [](const Vec3& a, const Vec3& b) {
    return Quad(a.x()) * Quad(b.x()) + Quad(a.y()) * Quad(b.y()) + Quad(a.z()) * Quad(b.z());
  };
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> coefficient(-2.0, 2.0);
  double worst = 0.0;  // error over eps |r| / sin(theta), unit u and v
  for (double theta : {1e-1, 1e-3, 1e-5, 1e-7}) {
    for (int trial = 0; trial < 50; ++trial) {
      const Eigen::Matrix3d R = random_rotation(rng);
      const Vec3 u = R * Vec3(1, 0, 0);
      const Vec3 v = R * Vec3(std::cos(theta), std::sin(theta), 0);
      const Vec3 r = coefficient(rng) * u + coefficient(rng) * v +
                     coefficient(rng) * (R * Vec3(0, 0, 1));
      const Quad a = dot(u, u), b = dot(u, v), c = dot(v, v), d = dot(u, r), e = dot(v, r);
      const Quad det = a * c - b * b;
      const double alpha = double((c * d - b * e) / det), beta = double((a * e - b * d) / det);
      const Eigen::Vector2d ab = detail::in_plane_coordinates(r, u, v);
      const double scale = fd::kEps * r.norm() / std::sin(theta);
      worst = std::max({worst, std::abs(ab(0) - alpha) / scale, std::abs(ab(1) - beta) / scale});
    }
  }
  MESSAGE("in-plane coordinates: worst error ", worst, " eps |r| / sin(theta)");
  CHECK(worst < 4.0);
}

TEST_CASE("distance: edge-edge parallel, nearly parallel, crossing and zero-length edges") {
  auto finite = [](const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
    const double d = edge_edge_distance(a0, a1, b0, b1);
    CHECK(std::isfinite(d));
    CHECK(d >= 0.0);
    CHECK(edge_edge_distance_gradient(a0, a1, b0, b1).allFinite());
    CHECK(edge_edge_distance_hessian(a0, a1, b0, b1).allFinite());
    // Never farther than any endpoint-to-segment distance (the boundary candidates).
    const double bound = std::min({point_edge_distance(a0, b0, b1), point_edge_distance(a1, b0, b1),
                                   point_edge_distance(b0, a0, a1), point_edge_distance(b1, a0, a1)});
    CHECK(d <= bound * (1.0 + 1e-12));
    return d;
  };
  auto relative = [](double value, double tolerance) {
    return doctest::Approx(value).epsilon(tolerance).scale(0.0);
  };
  const Vec3 ea0(0, 0, 0), ea1(1, 0, 0);
  // Exact values from small integers and halves: a few roundings, hence 1e-15.
  // Exactly parallel, overlapping: distance 1 from an endpoint, not the line-line case.
  CHECK(finite(ea0, ea1, Vec3(0.5, 1, 0), Vec3(1.5, 1, 0)) == relative(1.0, 1e-15));
  CHECK(edge_edge_case(ea0, ea1, Vec3(0.5, 1, 0), Vec3(1.5, 1, 0)) != EdgeEdgeCase::ea_eb);
  // Antiparallel, collinear and overlapping: distance 0.
  CHECK(finite(ea0, ea1, Vec3(1.5, 0, 0), Vec3(0.5, 0, 0)) == 0.0);
  // Parallel, disjoint along the axis: vertex-vertex.
  CHECK(finite(ea0, ea1, Vec3(2, 1, 0), Vec3(3, 1, 0)) == relative(2.0, 1e-15));
  CHECK(edge_edge_case(ea0, ea1, Vec3(2, 1, 0), Vec3(3, 1, 0)) == EdgeEdgeCase::ea1_eb0);
  // Nearly parallel by 1e-12 offsets in every direction, at unit and at 1e-6 separation. The
  // closest points are eb0's foot (exactly sep^2 up to rounding) or a line-line pair, which the
  // 1e-12 tilt moves by at most (1e-12)^2: 1e-12 of sep^2 at sep = 1e-6.
  for (double sep : {1.0, 1e-6}) {
    for (int k = 0; k < 3; ++k) {
      Vec3 off = Vec3::Zero();
      off(k) = 1e-12;
      const double d = finite(ea0, ea1, Vec3(0.25, sep, 0), Vec3(0.75, sep, 0) + off);
      CHECK(d == relative(sep * sep, 1e-11));
    }
  }
  // Crossing edges: distance exactly 0 in the interior case, finite derivatives.
  CHECK(finite(ea0, ea1, Vec3(0.5, -1, 0), Vec3(0.5, 1, 0)) == 0.0);
  CHECK(edge_edge_case(ea0, ea1, Vec3(0.5, -1, 0), Vec3(0.5, 1, 0)) == EdgeEdgeCase::ea_eb);
  // Touching at a vertex, T-junction.
  CHECK(finite(ea0, ea1, ea1, Vec3(1, 1, 1)) == 0.0);
  CHECK(finite(ea0, ea1, Vec3(0.5, 0, 0), Vec3(0.5, 1, 0)) == 0.0);
  // Zero-length edges: reduce to point-segment and point-point.
  CHECK(finite(ea0, ea0, Vec3(0.5, 1, 1), Vec3(0.5, -1, 1)) == relative(1.25, 1e-15));
  CHECK(finite(ea0, ea1, Vec3(0.5, 1, 1), Vec3(0.5, 1, 1)) == relative(2.0, 1e-15));
  CHECK(finite(ea0, ea0, Vec3(0, 1, 1), Vec3(0, 1, 1)) == relative(2.0, 1e-15));
  CHECK(finite(ea0, ea0, ea0, ea0) == 0.0);
  // The point-line primitive on a zero-length edge is the point-point distance, exactly.
  const Vec3 p(0.3, 0.4, 0.5);
  CHECK(point_line_distance(p, ea1, ea1) == point_point_distance(p, ea1));
  CHECK(point_line_distance_gradient(p, ea1, ea1).head<6>() ==
        point_point_distance_gradient(p, ea1));
}

// Nearly parallel edges: ea from the origin along x (length 1), eb of length 0.6 at distance sep
// from it, turned out of parallel by theta within the xz plane about its midpoint (so
// |ea x eb| = 0.6 sin(theta)), then rotated and moved at random. With the midpoint over ea's
// interior the lines' closest points are inside both edges (the line-line piece, whose Hessian
// grows like 1 / theta^2); with the midpoint past ea1, ea1 against eb's interior (point-line).
// The step is a fraction of the offset 0.6 theta on which the common normal turns.
//
// Beyond double precision: the line-line piece's derivatives come from normal equations with
// cond ~ 1 / theta^2 and lose ~eps |ea0 - eb0| / (sep theta^2) (the value uses cross products and
// is accurate): against long double, 4e-4 at theta = 1e-6 and unit distance, 3e-2 at sep = 1e-3.
// With the FD rounding on top, the line-line pieces at theta = 1e-5 and 1e-6 (both distances)
// allow more than kResolvable: four pairs, counted (the derivative that is resolvable is
// still compared).
TEST_CASE("distance: nearly parallel edges against finite differences") {
  std::mt19937_64 rng(31);
  int checked = 0, beyond = 0;
  for (double theta : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6}) {
    for (double sep : {1.0, 1e-3}) {
      for (double centre : {0.5, 1.0 + 0.1 * sep}) {
        const Eigen::Matrix3d R = random_rotation(rng);
        const Vec3 shift = random_point(rng);
        const Vec3 half = 0.3 * Vec3(std::cos(theta), 0.0, std::sin(theta));
        const Vec3 mid(centre, sep, 0.0);
        const std::array<Vec3, 4> x = {shift, Vec3(R * Vec3(1, 0, 0) + shift),
                                       Vec3(R * (mid - half) + shift),
                                       Vec3(R * (mid + half) + shift)};
        const EdgeEdgeCase c = edge_edge_case(x[0], x[1], x[2], x[3]);
        CAPTURE(theta);
        CAPTURE(sep);
        CAPTURE(name(c));
        CHECK(c == (centre == 0.5 ? EdgeEdgeCase::ea_eb : EdgeEdgeCase::ea1_eb));
        if (check_edge_edge_case(x, c)) {
          ++checked;
        } else {
          ++beyond;
        }
      }
    }
  }
  MESSAGE("nearly parallel edges: ", checked, " checked, ", beyond, " beyond");
  CHECK(beyond <= 4);
  CHECK(checked >= 16);
}

// ------------------------------------------------------------------------------------------------
// Barrier times mollifier

// E(x) = m(x) b(d(x)) for an edge-edge pair, the case of d fixed at the point of evaluation, with
// the product-rule derivatives exactly as engine/contact/barrier_potential.cpp forms them for a
// nearly parallel (mollified) stencil: grad E = m b' grad d + b grad m,
// hess E = m (b'' grad d grad d^T + b' hess d) + b' (grad d grad m^T + grad m grad d^T) + b hess m.
struct MollifiedBarrier {
  EdgeEdgeCase c;
  double eps_x;  // from the rest shape
  double dhat;   // squared activation distance

  struct Terms {
    double d, m, b, b1, b2;
    Vector12d gd, gm;
  };

  Terms terms(const Stacked<4>& s) const {
    const auto v = unstack<4>(s);
    Terms t;
    t.d = edge_edge_distance(v[0], v[1], v[2], v[3], c);
    t.m = edge_edge_mollifier(v[0], v[1], v[2], v[3], eps_x);
    t.b = barrier(t.d, dhat);
    t.b1 = barrier_first_derivative(t.d, dhat);
    t.b2 = barrier_second_derivative(t.d, dhat);
    t.gd = edge_edge_distance_gradient(v[0], v[1], v[2], v[3], c);
    t.gm = edge_edge_mollifier_gradient(v[0], v[1], v[2], v[3], eps_x);
    return t;
  }
  double energy(const Stacked<4>& s) const {
    const auto v = unstack<4>(s);
    return edge_edge_mollifier(v[0], v[1], v[2], v[3], eps_x) *
           barrier(edge_edge_distance(v[0], v[1], v[2], v[3], c), dhat);
  }
  Vector12d gradient(const Stacked<4>& s) const {
    const Terms t = terms(s);
    return t.m * t.b1 * t.gd + t.b * t.gm;
  }
  Matrix12d hessian(const Stacked<4>& s) const {
    const auto v = unstack<4>(s);
    const Terms t = terms(s);
    const Matrix12d Hd = edge_edge_distance_hessian(v[0], v[1], v[2], v[3], c);
    const Matrix12d Hm = edge_edge_mollifier_hessian(v[0], v[1], v[2], v[3], eps_x);
    return t.m * (t.b2 * t.gd * t.gd.transpose() + t.b1 * Hd) +
           t.b1 * (t.gd * t.gm.transpose() + t.gm * t.gd.transpose()) + t.b * Hm;
  }
};

// The budgets of E follow from those of its factors by first-order error propagation:
//   ell    = the smaller of d's feature and |ea x eb| / max(|ea|, |eb|), on which c = |ea x eb|^2
//            (hence m) varies;
//   d      : noise and relative analytic error from distance_budgets;
//   c      : rounded like its cross product, 4 eps sqrt(c) X (|ea| + |eb|); grad m and hess m
//            cancel like |eb|^2 ea - (ea . eb) eb, relative 4 eps X / ell;
//   E      : noise m |b'| noise_d + |b| |m'| noise_c; grad E and hess E inherit the factors'
//            analytic errors through the terms they multiply.
struct MollifiedBudgets {
  fd::Budget gradient, hessian;
};

MollifiedBudgets mollified_budgets(const MollifiedBarrier& e, const std::array<Vec3, 4>& x) {
  constexpr double eps = fd::kEps;
  const Stacked<4> s = stack<4>(x);
  const MollifiedBarrier::Terms t = e.terms(s);
  const Vector12d gE = e.gradient(s);
  const Matrix12d HE = e.hessian(s);
  const Matrix12d Hd = edge_edge_distance_hessian(x[0], x[1], x[2], x[3], e.c);
  const DistanceGeometry geo = geometry(piece_of(e.c), x);
  const DistanceBudgets bd = distance_budgets(geo, t.d, t.gd.norm());
  const Vec3 ea = x[1] - x[0], eb = x[3] - x[2];
  const double n = ea.cross(eb).norm();
  const double ell = std::min(geo.ell, n / std::max(ea.norm(), eb.norm()));
  const double X = geo.coords;
  const double c = n * n;
  const double dm = c < e.eps_x ? 2.0 * (1.0 - c / e.eps_x) / e.eps_x : 0.0;
  const double noise_d = bd.gradient.noise, acc_d = bd.gradient.analytic;
  const double noise_m = dm * 4.0 * eps * n * X * (ea.norm() + eb.norm());
  const double acc_m = 4.0 * eps * X / ell;
  const double b = std::abs(t.b), b1 = std::abs(t.b1), b2 = std::abs(t.b2);
  const double gd = t.gd.norm(), gm = t.gm.norm();
  MollifiedBudgets out;
  out.gradient.ell = ell;
  out.gradient.noise = t.m * b1 * noise_d + b * noise_m + 4.0 * eps * std::abs(e.energy(s));
  out.gradient.analytic = (t.m * b1 * gd * acc_d + b * gm * acc_m) / gE.norm() + 4.0 * eps;
  out.hessian.ell = ell;
  out.hessian.noise = b1 * gd * noise_m + t.m * b2 * gd * noise_d + t.m * b1 * gd * acc_d +
                      b1 * gm * noise_d + b * gm * acc_m + 4.0 * eps * gE.norm();
  out.hessian.analytic = (t.m * b1 * Hd.norm() * acc_d + 2.0 * t.m * b2 * gd * gd * acc_d +
                          2.0 * b1 * gd * gm * (acc_d + acc_m)) / HE.norm() + 4.0 * eps;
  return out;
}

// Nearly parallel pairs as in the previous test, from the mollified band's edge (c / eps_x =
// 0.9 at theta = 0.03) down to theta = 1e-6 (c / eps_x ~ 1e-9), in contact (d = sep^2 below
// dhat = 4 sep^2). eps_x is 1e-3 |ea|^2 |eb|^2 of the rest shape, here the same edges.
//
// Where m b' hess d dominates hess E, E inherits the line-line piece's lost accuracy
// (eps |ea0 - eb0| / (sep theta^2), see above) scaled by that share: the budget counts it. It puts
// three line-line pairs beyond double precision: theta = 1e-5 at sep = 1e-3, theta = 1e-6 at both
// distances (hess E is off by ~2e-2 at theta = 1e-6, sep = 1e-3). Counted; their gradients are
// still compared.
TEST_CASE("distance: barrier times edge-edge mollifier on nearly parallel edges against FD") {
  std::mt19937_64 rng(37);
  int checked = 0, beyond = 0;
  for (double theta : {3e-2, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6}) {
    for (double sep : {0.1, 1e-3}) {
      for (double centre : {0.5, 1.0 + 0.1 * sep}) {
        const Eigen::Matrix3d R = random_rotation(rng);
        const Vec3 shift = random_point(rng);
        const Vec3 half = 0.3 * Vec3(std::cos(theta), 0.0, std::sin(theta));
        const Vec3 mid(centre, sep, 0.0);
        const std::array<Vec3, 4> x = {shift, Vec3(R * Vec3(1, 0, 0) + shift),
                                       Vec3(R * (mid - half) + shift),
                                       Vec3(R * (mid + half) + shift)};
        const MollifiedBarrier e{edge_edge_case(x[0], x[1], x[2], x[3]),
                                 edge_edge_mollifier_threshold(x[0], x[1], x[2], x[3]),
                                 4.0 * sep * sep};
        CAPTURE(theta);
        CAPTURE(sep);
        CAPTURE(name(e.c));
        CHECK(e.c == (centre == 0.5 ? EdgeEdgeCase::ea_eb : EdgeEdgeCase::ea1_eb));
        const Stacked<4> s = stack<4>(x);
        const double q = edge_edge_cross_squarednorm(x[0], x[1], x[2], x[3]) / e.eps_x;
        CAPTURE(q);
        REQUIRE(q < 1.0);  // inside the mollified band
        REQUIRE(e.energy(s) > 0.0);  // inside the barrier's reach
        const MollifiedBudgets b = mollified_budgets(e, x);
        auto energy = [&](const Stacked<4>& z) { return e.energy(z); };
        auto gradient = [&](const Stacked<4>& z) { return e.gradient(z); };
        const fd::Result rg = fd::check(
            e.gradient(s), [&](double h) { return fd::gradient<12>(energy, s, h); }, b.gradient);
        const fd::Result rh = fd::check(
            e.hessian(s), [&](double h) { return fd::jacobian<12>(gradient, s, h); }, b.hessian);
        CAPTURE(rg);
        CAPTURE(rh);
        for (const fd::Result& r : {rg, rh}) {
          if (r.tolerance > kResolvable) continue;
          CHECK(r.ok());
          CHECK(r.second_order());
        }
        (std::max(rg.tolerance, rh.tolerance) > kResolvable ? beyond : checked) += 1;
      }
    }
  }
  MESSAGE("mollified barrier: ", checked, " checked, ", beyond, " beyond");
  CHECK(beyond <= 3);
  CHECK(checked >= 21);
}

// ------------------------------------------------------------------------------------------------
// Nearly zero-length edges

// Edge b of length L next to the unit edge ea = [0, e_x], at distance sep = 0.1, rotated and
// moved at random:
//   along  eb points away from ea over its middle: eb0 against ea's interior (a point-line
//          piece on ea, well-conditioned whatever L);
//   beyond eb crosses the line through ea1 just past ea's end: ea1 against eb's interior (a
//          point-line piece whose line turns on the scale L);
//   across eb crosses over ea's middle: the two interiors (line-line, cond(D^T D) = 1 / L^2).
// And a point against an edge of length L (point_edge_distance). L = 0 is defined too: the
// pieces become vertex-vertex or vertex-edge, with the same derivatives as their primitives.
//
// Beyond double precision: the three pieces on the scale L (beyond, across, point-edge) at
// L = 1e-6 and 1e-8 with O(1) coordinates, whose edge vectors are rounded by eps relative to
// O(1), i.e. eps / L relative to L (the line-line piece also loses eps / L^2 in its normal
// equations): six stencils, counted (what is resolvable of them is still compared).
TEST_CASE("distance: nearly zero-length edges against finite differences") {
  std::mt19937_64 rng(43);
  const double sep = 0.1;
  int checked = 0, beyond = 0;
  for (double L : {1e-2, 1e-4, 1e-6, 1e-8, 0.0}) {
    const Eigen::Matrix3d R = random_rotation(rng);
    const Vec3 shift = random_point(rng);
    auto place = [&](const Vec3& v) { return Vec3(R * v + shift); };
    const Vec3 z(0, 0, 0.5 * L);
    const Vec3 beyond_end(1.0 + 0.1 * sep, sep, 0.0);
    const Vec3 over_middle(0.5, sep, 0.0);
    struct Layout {
      std::string name;
      Vec3 eb0, eb1;
      EdgeEdgeCase expected;
    };
    const Layout layouts[] = {
        {"along", over_middle, over_middle + Vec3(0, L, 0), EdgeEdgeCase::ea_eb0},
        {"beyond", beyond_end - z, beyond_end + z,
         L > 0.0 ? EdgeEdgeCase::ea1_eb : EdgeEdgeCase::ea1_eb0},
        {"across", over_middle - z, over_middle + z,
         L > 0.0 ? EdgeEdgeCase::ea_eb : EdgeEdgeCase::ea_eb0},
    };
    for (const Layout& layout : layouts) {
      const std::array<Vec3, 4> x = {place(Vec3::Zero()), place(Vec3(1, 0, 0)),
                                     place(layout.eb0), place(layout.eb1)};
      const EdgeEdgeCase c = edge_edge_case(x[0], x[1], x[2], x[3]);
      CAPTURE(L);
      CAPTURE(layout.name);
      CAPTURE(name(c));
      CHECK(c == layout.expected);
      if (check_edge_edge_case(x, c)) {
        ++checked;
      } else {
        ++beyond;
      }
    }
    // A point over the middle of an edge of length L.
    const std::array<Vec3, 3> pe = {place(Vec3(0.05, sep, 0.0)), place(-z), place(z)};
    const PointEdgeCase c = point_edge_case(pe[0], pe[1], pe[2]);
    CAPTURE(L);
    CHECK(c == (L > 0.0 ? PointEdgeCase::p_e : PointEdgeCase::p_e0));
    if (check_point_edge_case(pe, c)) {
      ++checked;
    } else {
      ++beyond;
    }
  }
  MESSAGE("nearly zero-length edges: ", checked, " checked, ", beyond, " beyond");
  CHECK(beyond <= 6);
  CHECK(checked >= 14);
}

// ------------------------------------------------------------------------------------------------
// Mollifier

// Budgets of f(c) for c = |ea x eb|^2 (f = c or the mollifier m): c varies on the offset
// ell = |ea x eb| / max(|ea|, |eb|) of the two directions and is rounded like its cross product,
// 4 eps |ea x eb| X (|ea| + |eb|), times |df/dc|; its gradient cancels like
// |eb|^2 ea - (ea . eb) eb, relative 4 eps X / ell, and that is the noise of the gradient the
// Hessian check differentiates.
DistanceBudgets cross_budgets(const std::array<Vec3, 4>& x, double f, double df_dc,
                              double g_norm) {
  constexpr double eps = fd::kEps;
  const Vec3 ea = x[1] - x[0], eb = x[3] - x[2];
  const double n = ea.cross(eb).norm();
  const DistanceGeometry geo = geometry(Primitive::line_line, x);
  DistanceBudgets b;
  b.gradient.ell = n / std::max(ea.norm(), eb.norm());
  b.gradient.noise = std::abs(df_dc) * 4.0 * eps * n * geo.coords * (ea.norm() + eb.norm()) +
                     4.0 * eps * std::abs(f);
  b.gradient.analytic = 4.0 * eps * (1.0 + geo.coords / b.gradient.ell);
  b.hessian = b.gradient;
  b.hessian.noise = b.gradient.analytic * g_norm;
  return b;
}


TEST_CASE("distance: edge-edge mollifier range, limits and finite differences") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 ea0 = random_point(rng), ea1 = random_point(rng);
    const Vec3 eb0 = random_point(rng);
    // eb nearly parallel to ea, so that c is small; eps_x chosen so that c / eps_x = q in (0, 1).
    const Vec3 eb1 = eb0 + 0.7 * (ea1 - ea0) + 0.05 * random_point(rng);
    const double c = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
    const double q = u(rng);
    const double eps_x = c / q;
    const double m = edge_edge_mollifier(ea0, ea1, eb0, eb1, eps_x);
    CHECK(m == doctest::Approx((2.0 - q) * q).epsilon(1e-12));
    CHECK(m >= 0.0);
    CHECK(m <= 1.0);
    const std::array<Vec3, 4> x = {ea0, ea1, eb0, eb1};
    const double dm_dc = 2.0 * (1.0 - q) / eps_x;
    CHECK(check_within<4>(
        [eps_x](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_mollifier(v[0], v[1], v[2], v[3], eps_x);
        },
        [eps_x](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_mollifier_gradient(v[0], v[1], v[2], v[3], eps_x);
        },
        [eps_x](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_mollifier_hessian(v[0], v[1], v[2], v[3], eps_x);
        },
        stack<4>(x),
        cross_budgets(x, m, dm_dc,
                      edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x).norm())));
    // c itself: exact derivatives of the cross product's squared norm.
    CHECK(check_within<4>(
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_cross_squarednorm(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_cross_squarednorm_gradient(v[0], v[1], v[2], v[3]);
        },
        [](const Stacked<4>& s) {
          auto v = unstack<4>(s);
          return edge_edge_cross_squarednorm_hessian(v[0], v[1], v[2], v[3]);
        },
        stack<4>(x),
        cross_budgets(x, c, 1.0, edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1).norm())));
  }
  // Non-parallel edges at their own rest shape (angle well above ~1.8 degrees): m = 1 exactly,
  // zero derivatives.
  int non_parallel = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 ea0 = random_point(rng), ea1 = random_point(rng), eb0 = random_point(rng),
               eb1 = random_point(rng);
    const double eps_x = edge_edge_mollifier_threshold(ea0, ea1, eb0, eb1);
    const Vec3 a = (ea1 - ea0).normalized(), b = (eb1 - eb0).normalized();
    const double m = edge_edge_mollifier(ea0, ea1, eb0, eb1, eps_x);
    CHECK(m >= 0.0);
    CHECK(m <= 1.0);
    if (a.cross(b).squaredNorm() > 2e-3) {
      ++non_parallel;
      CHECK(m == 1.0);
      CHECK(edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x).isZero(0.0));
      CHECK(edge_edge_mollifier_hessian(ea0, ea1, eb0, eb1, eps_x).isZero(0.0));
    }
  }
  CHECK(non_parallel > 150);
  // Exactly parallel: m = 0 and dm = 0 (c has a double root there), Hessian finite.
  const Vec3 ea0(0, 0, 0), ea1(1, 0, 0), eb0(0, 1, 0), eb1(2, 1, 0);
  const double eps_x = edge_edge_mollifier_threshold(ea0, ea1, eb0, eb1);
  CHECK(eps_x == doctest::Approx(4e-3).epsilon(1e-15).scale(0.0));  // 1e-3 * 1 * 4: two roundings
  CHECK(edge_edge_mollifier(ea0, ea1, eb0, eb1, eps_x) == 0.0);
  CHECK(edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x).isZero(0.0));
  CHECK(edge_edge_mollifier_hessian(ea0, ea1, eb0, eb1, eps_x).allFinite());
  // C1 at c = eps_x: m -> 1 and dm -> 0 from below.
  const Vec3 tilted = eb1 + Vec3(0, 0, std::sqrt(eps_x * (1.0 - 1e-9)) / 1.0);
  const double m_below = edge_edge_mollifier(ea0, ea1, eb0, tilted, eps_x);
  CHECK(m_below == doctest::Approx(1.0).epsilon(1e-12));
  CHECK(edge_edge_mollifier_gradient(ea0, ea1, eb0, tilted, eps_x).norm() < 1e-6);
}

}  // namespace
}  // namespace nexdyn

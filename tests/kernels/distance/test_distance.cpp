// Tests of kernels/distance: every primitive's gradient and Hessian against central finite
// differences on random inputs; the point-triangle and edge-edge classifications on constructed
// inputs for every case, their per-case derivatives against finite differences, and their values
// against an independent minimisation over the barycentric parameters (grid start + projected
// gradient); degenerate inputs (coincident points, points on edges and vertices, parallel, nearly
// parallel and crossing edges, zero-length edges) must give exact values and finite derivatives;
// the edge-edge mollifier against finite differences and its range.
#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>

namespace nexdyn {
namespace {

using Vec3 = Eigen::Vector3d;

template <int K>
using Stacked = Eigen::Matrix<double, 3 * K, 1>;

Vec3 random_point(std::mt19937_64& rng, double amplitude = 1.0) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  return {u(rng), u(rng), u(rng)};
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

// Central differences of a scalar function of the stacked points.
template <int K, typename F>
Stacked<K> fd_gradient(const F& f, const Stacked<K>& x, double h) {
  Stacked<K> g;
  for (int i = 0; i < 3 * K; ++i) {
    Stacked<K> xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    g(i) = (f(xp) - f(xm)) / (2.0 * h);
  }
  return g;
}

// Central differences of a gradient: column i is d grad / d x_i.
template <int K, typename G>
Eigen::Matrix<double, 3 * K, 3 * K> fd_hessian(const G& grad, const Stacked<K>& x, double h) {
  Eigen::Matrix<double, 3 * K, 3 * K> H;
  for (int i = 0; i < 3 * K; ++i) {
    Stacked<K> xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    H.col(i) = (grad(xp) - grad(xm)) / (2.0 * h);
  }
  return H;
}

template <typename A, typename B>
double relative_error(const A& a, const B& b, double floor) {
  return (a - b).norm() / std::max({a.norm(), b.norm(), floor});
}

// Checks f, grad, hess (callables on stacked points) against central differences at x, plus the
// structural properties: symmetric Hessian, translation invariance (gradient blocks sum to zero,
// Hessian rows too) when `translation_invariant`.
template <int K, typename F, typename G, typename H>
void check_derivatives(const F& f, const G& grad, const H& hess, const Stacked<K>& x,
                       bool translation_invariant = true) {
  const double h = 1e-6 * std::max(1.0, x.cwiseAbs().maxCoeff());
  const Stacked<K> g = grad(x);
  const Eigen::Matrix<double, 3 * K, 3 * K> Hx = hess(x);
  REQUIRE(g.allFinite());
  REQUIRE(Hx.allFinite());
  const double scale = std::max(1e-8, std::abs(f(x)));
  CHECK(relative_error(g, fd_gradient<K>(f, x, h), std::sqrt(scale)) < 1e-6);
  CHECK(relative_error(Hx, fd_hessian<K>(grad, x, h), 1e-3) < 1e-6);
  CHECK(relative_error(Hx, Hx.transpose().eval(), 1.0) < 1e-12);
  if (translation_invariant) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int i = 0; i < K; ++i) sum += g.template segment<3>(3 * i);
    CHECK(sum.norm() <= 1e-10 * std::max(1.0, g.norm()));
    Eigen::Matrix<double, 3 * K, 3> row_sum = Eigen::Matrix<double, 3 * K, 3>::Zero();
    for (int i = 0; i < K; ++i) row_sum += Hx.template middleCols<3>(3 * i);
    CHECK(row_sum.norm() <= 1e-9 * std::max(1.0, Hx.norm()));
  }
}

// ------------------------------------------------------------------------------------------------
// Independent references: minimise the squared distance over the barycentric parameters by a
// grid search followed by projected gradient descent with step 1 / L (convex quadratic).

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

// min over the parameter set of |r0 + E lambda|^2 (E is 3x2), with `project` onto the set.
template <typename Project>
double minimise_over_parameters(const Vec3& r0, const Eigen::Matrix<double, 3, 2>& E,
                                const Eigen::Vector2d& lo, const Eigen::Vector2d& hi,
                                const Project& project) {
  auto f = [&](const Eigen::Vector2d& l) { return (r0 + E * l).squaredNorm(); };
  Eigen::Vector2d best(0, 0);
  double fbest = f(project(best));
  constexpr int kGrid = 64;
  for (int i = 0; i <= kGrid; ++i) {
    for (int j = 0; j <= kGrid; ++j) {
      const Eigen::Vector2d l = project(Eigen::Vector2d(lo(0) + (hi(0) - lo(0)) * i / kGrid,
                                                        lo(1) + (hi(1) - lo(1)) * j / kGrid));
      const double fl = f(l);
      if (fl < fbest) { fbest = fl; best = l; }
    }
  }
  const Eigen::Matrix2d G = 2.0 * E.transpose() * E;
  const double L = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(G).eigenvalues()(1);
  Eigen::Vector2d l = best;
  for (int it = 0; it < 40000; ++it) {
    const Eigen::Vector2d g = 2.0 * E.transpose() * (r0 + E * l);
    l = project(Eigen::Vector2d(l - g / L));
  }
  return std::min(fbest, f(l));
}

double brute_force_point_triangle(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  Eigen::Matrix<double, 3, 2> E;
  E << t1 - t0, t2 - t0;
  return minimise_over_parameters(t0 - p, E, {0, 0}, {1, 1}, project_to_unit_triangle);
}

double brute_force_edge_edge(const Vec3& ea0, const Vec3& ea1, const Vec3& eb0, const Vec3& eb1) {
  Eigen::Matrix<double, 3, 2> E;
  E << ea1 - ea0, -(eb1 - eb0);
  auto clamp01 = [](const Eigen::Vector2d& x) {
    return Eigen::Vector2d(x.cwiseMax(0.0).cwiseMin(1.0));
  };
  return minimise_over_parameters(ea0 - eb0, E, {0, 0}, {1, 1}, clamp01);
}

// Condition number of the 2x2 Gram matrix: the projected-gradient reference converges only for
// reasonably shaped inputs in the iteration budget, so the random sweeps skip slivers.
double gram_condition(const Vec3& a, const Vec3& b) {
  Eigen::Matrix<double, 3, 2> E;
  E << a, b;
  const Eigen::Vector2d ev =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(E.transpose() * E).eigenvalues();
  return ev(1) / ev(0);
}

// ------------------------------------------------------------------------------------------------
// Primitives

TEST_CASE("distance: primitives match finite differences on random inputs") {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 200; ++trial) {
    const std::array<Vec3, 4> x = {random_point(rng), random_point(rng), random_point(rng),
                                   random_point(rng)};
    check_derivatives<2>(
        [](const Stacked<2>& s) { auto v = unstack<2>(s); return point_point_distance(v[0], v[1]); },
        [](const Stacked<2>& s) {
          auto v = unstack<2>(s);
          return point_point_distance_gradient(v[0], v[1]);
        },
        [](const Stacked<2>& s) {
          auto v = unstack<2>(s);
          return point_point_distance_hessian(v[0], v[1]);
        },
        stack<2>({x[0], x[1]}));
    check_derivatives<3>(
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
        stack<3>({x[0], x[1], x[2]}));
    check_derivatives<4>(
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
        stack<4>(x));
    check_derivatives<4>(
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
        stack<4>(x));
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
    check_derivatives<1>(
        [&](const Stacked<1>& s) { return point_obstacle_plane_distance(s, o, n); },
        [&](const Stacked<1>& s) { return Stacked<1>(point_obstacle_plane_distance_gradient(s, o, n)); },
        [&](const Stacked<1>& s) {
          return Eigen::Matrix3d(point_obstacle_plane_distance_hessian(s, o, n));
        },
        Stacked<1>(p), /*translation_invariant=*/false);
  }
}

// ------------------------------------------------------------------------------------------------
// Point-edge

TEST_CASE("distance: point-edge cases, values and derivatives") {
  const Vec3 e0(0, 0, 0), e1(2, 0, 0);
  CHECK(point_edge_case(Vec3(-1, 1, 0), e0, e1) == PointEdgeCase::p_e0);
  CHECK(point_edge_case(Vec3(3, 0, 1), e0, e1) == PointEdgeCase::p_e1);
  CHECK(point_edge_case(Vec3(0.5, 1, 1), e0, e1) == PointEdgeCase::p_e);
  CHECK(point_edge_distance(Vec3(-1, 1, 0), e0, e1) == doctest::Approx(2.0));
  CHECK(point_edge_distance(Vec3(3, 0, 1), e0, e1) == doctest::Approx(2.0));
  CHECK(point_edge_distance(Vec3(0.5, 1, 1), e0, e1) == doctest::Approx(2.0));

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
    check_derivatives<3>(
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
        stack<3>(x));
  }
  for (int k = 0; k < 3; ++k) CHECK(count[k] > 50);
}

// ------------------------------------------------------------------------------------------------
// Point-triangle

const char* name(PointTriangleCase c) {
  constexpr const char* kNames[] = {"p_t0", "p_t1", "p_t2", "p_e0", "p_e1", "p_e2", "p_t"};
  return kNames[static_cast<int>(c)];
}

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
TEST_CASE("distance: point-triangle ties go to the corner or edge under the point") {
  std::mt19937_64 rng(17);
  constexpr PointTriangleCase corner[3] = {PointTriangleCase::p_t0, PointTriangleCase::p_t1,
                                           PointTriangleCase::p_t2};
  constexpr PointTriangleCase edge[3] = {PointTriangleCase::p_e0, PointTriangleCase::p_e1,
                                         PointTriangleCase::p_e2};
  int checked = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Vec3 t[3] = {random_point(rng), random_point(rng), random_point(rng)};
    if (gram_condition(t[1] - t[0], t[2] - t[0]) > 200.0) continue;
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
  CHECK(checked > 500);
}

TEST_CASE("distance: point-triangle per-case derivatives and brute-force values") {
  std::mt19937_64 rng(5);
  int count[7] = {};
  int compared = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Vec3 t0 = random_point(rng), t1 = random_point(rng), t2 = random_point(rng);
    if (gram_condition(t1 - t0, t2 - t0) > 200.0) continue;
    const Vec3 p = random_point(rng, 1.5);
    const PointTriangleCase c = point_triangle_case(p, t0, t1, t2);
    CAPTURE(name(c));
    if (count[static_cast<int>(c)]++ < 40) {
      check_derivatives<4>(
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
          stack<4>({p, t0, t1, t2}));
    }
    if (trial % 3 == 0) {
      const double d = point_triangle_distance(p, t0, t1, t2);
      const double ref = brute_force_point_triangle(p, t0, t1, t2);
      const double tol = 1e-10 * ref + 1e-15;
      CHECK(d <= ref + tol);  // the classified feature is never farther than the true minimum
      CHECK(d >= ref - tol);
      worst = std::max(worst, std::abs(d - ref) / std::max(ref, 1e-15));
      ++compared;
    }
  }
  MESSAGE("point-triangle: ", compared, " brute-force comparisons, worst relative gap ", worst);
  for (int k = 0; k < 7; ++k) {
    CAPTURE(k);
    CHECK(count[k] >= 20);
  }
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
  // On a vertex, on an edge, inside the face, in the plane outside.
  CHECK(finite(t0, t0, t1, t2) == 0.0);
  CHECK(finite(t2, t0, t1, t2) == 0.0);
  CHECK(finite(Vec3(0.5, 0.5, 0), t0, t1, t2) <= 1e-30);
  CHECK(finite(Vec3(0.25, 0, 0), t0, t1, t2) <= 1e-30);
  CHECK(finite(Vec3(0.2, 0.3, 0), t0, t1, t2) <= 1e-30);
  CHECK(finite(Vec3(2, 0, 0), t0, t1, t2) == doctest::Approx(1.0));
  // 1e-12 above an edge and a vertex.
  CHECK(finite(Vec3(0.5, 0.5, 1e-12), t0, t1, t2) == doctest::Approx(1e-24).epsilon(1e-6));
  CHECK(finite(Vec3(-1e-12, -1e-12, 0), t0, t1, t2) == doctest::Approx(2e-24).epsilon(1e-6));
  // Degenerate triangles: collinear corners, two and three coincident corners.
  CHECK(finite(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 0, 0)) == doctest::Approx(1.0));
  CHECK(point_triangle_case(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 0, 0)) != PointTriangleCase::p_t);
  CHECK(finite(Vec3(0, 0, 3), t0, t0, t2) == doctest::Approx(9.0));
  CHECK(finite(Vec3(0, 0, 3), t0, t0, t0) == doctest::Approx(9.0));
  // A nearly flat (1e-12) sliver still gives the segment distance.
  CHECK(finite(Vec3(0.5, 1, 0), t0, t1, Vec3(2, 1e-12, 0)) == doctest::Approx(1.0).epsilon(1e-10));
}

// ------------------------------------------------------------------------------------------------
// Edge-edge

const char* name(EdgeEdgeCase c) {
  constexpr const char* kNames[] = {"ea0_eb0", "ea0_eb1", "ea1_eb0", "ea1_eb1", "ea_eb0",
                                    "ea_eb1",  "ea0_eb",  "ea1_eb",  "ea_eb"};
  return kNames[static_cast<int>(c)];
}

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

TEST_CASE("distance: edge-edge per-case derivatives and brute-force values") {
  std::mt19937_64 rng(6);
  int count[9] = {};
  int compared = 0;
  double worst = 0.0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec3 ea0 = random_point(rng), ea1 = random_point(rng);
    const Vec3 eb0 = random_point(rng, 1.5), eb1 = random_point(rng, 1.5);
    if (gram_condition(ea1 - ea0, eb1 - eb0) > 200.0) continue;
    const EdgeEdgeCase c = edge_edge_case(ea0, ea1, eb0, eb1);
    CAPTURE(name(c));
    if (count[static_cast<int>(c)]++ < 40) {
      check_derivatives<4>(
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
          stack<4>({ea0, ea1, eb0, eb1}));
    }
    if (trial % 20 == 0) {
      const double d = edge_edge_distance(ea0, ea1, eb0, eb1);
      const double ref = brute_force_edge_edge(ea0, ea1, eb0, eb1);
      const double tol = 1e-10 * ref + 1e-15;
      CHECK(d <= ref + tol);
      CHECK(d >= ref - tol);
      worst = std::max(worst, std::abs(d - ref) / std::max(ref, 1e-15));
      ++compared;
    }
  }
  MESSAGE("edge-edge: ", compared, " brute-force comparisons, worst relative gap ", worst);
  for (int k = 0; k < 9; ++k) {
    CAPTURE(k);
    CHECK(count[k] >= 20);
  }
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
  const Vec3 ea0(0, 0, 0), ea1(1, 0, 0);
  // Exactly parallel, overlapping: distance 1 from an endpoint, not the line-line case.
  CHECK(finite(ea0, ea1, Vec3(0.5, 1, 0), Vec3(1.5, 1, 0)) == doctest::Approx(1.0));
  CHECK(edge_edge_case(ea0, ea1, Vec3(0.5, 1, 0), Vec3(1.5, 1, 0)) != EdgeEdgeCase::ea_eb);
  // Antiparallel, collinear and overlapping: distance 0.
  CHECK(finite(ea0, ea1, Vec3(1.5, 0, 0), Vec3(0.5, 0, 0)) == 0.0);
  // Parallel, disjoint along the axis: vertex-vertex.
  CHECK(finite(ea0, ea1, Vec3(2, 1, 0), Vec3(3, 1, 0)) == doctest::Approx(2.0));
  CHECK(edge_edge_case(ea0, ea1, Vec3(2, 1, 0), Vec3(3, 1, 0)) == EdgeEdgeCase::ea1_eb0);
  // Nearly parallel by 1e-12 offsets in every direction, at unit and at 1e-6 separation.
  for (double sep : {1.0, 1e-6}) {
    for (int k = 0; k < 3; ++k) {
      Vec3 off = Vec3::Zero();
      off(k) = 1e-12;
      const double d = finite(ea0, ea1, Vec3(0.25, sep, 0), Vec3(0.75, sep, 0) + off);
      CHECK(d == doctest::Approx(sep * sep).epsilon(1e-6));
    }
  }
  // Crossing edges: distance exactly 0 in the interior case, finite derivatives.
  CHECK(finite(ea0, ea1, Vec3(0.5, -1, 0), Vec3(0.5, 1, 0)) == 0.0);
  CHECK(edge_edge_case(ea0, ea1, Vec3(0.5, -1, 0), Vec3(0.5, 1, 0)) == EdgeEdgeCase::ea_eb);
  // Touching at a vertex, T-junction.
  CHECK(finite(ea0, ea1, ea1, Vec3(1, 1, 1)) == 0.0);
  CHECK(finite(ea0, ea1, Vec3(0.5, 0, 0), Vec3(0.5, 1, 0)) == 0.0);
  // Zero-length edges: reduce to point-segment and point-point.
  CHECK(finite(ea0, ea0, Vec3(0.5, 1, 1), Vec3(0.5, -1, 1)) == doctest::Approx(1.25));
  CHECK(finite(ea0, ea1, Vec3(0.5, 1, 1), Vec3(0.5, 1, 1)) == doctest::Approx(2.0));
  CHECK(finite(ea0, ea0, Vec3(0, 1, 1), Vec3(0, 1, 1)) == doctest::Approx(2.0));
  CHECK(finite(ea0, ea0, ea0, ea0) == 0.0);
  // The point-line primitive on a zero-length edge is the point-point distance, exactly.
  const Vec3 p(0.3, 0.4, 0.5);
  CHECK(point_line_distance(p, ea1, ea1) == point_point_distance(p, ea1));
  CHECK(point_line_distance_gradient(p, ea1, ea1).head<6>() ==
        point_point_distance_gradient(p, ea1));
}

// ------------------------------------------------------------------------------------------------
// Mollifier

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
    check_derivatives<4>(
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
        stack<4>({ea0, ea1, eb0, eb1}));
    // c itself: exact derivatives of the cross product's squared norm.
    check_derivatives<4>(
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
        stack<4>({ea0, ea1, eb0, eb1}));
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
  CHECK(eps_x == doctest::Approx(4e-3));
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

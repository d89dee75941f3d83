// Tests of kernels/barrier/barrier_stencils.hpp, per stencil kind (obstacle plane, point-point,
// point-line, point-plane, line-line, mollified edge-edge), on random rotated and shifted
// configurations with the closest feature at distances from 1e-2 to 0.7 of dhat:
//   * the gradient against central differences of the energy (tests/kernels/finite_differences.hpp);
//   * the Hessian before projection, w (b'' grad d grad d^T + b' hess d) from kernels/distance (the
//     product rule with the mollifier for nearly parallel edges), against central differences of
//     the kernel's gradient: the two derivatives belong to one energy;
//   * the projected Hessian against project_psd of that Hessian (the kernels' subspace and closed
//     form projections are the exact projection), PSD, and, for every stencil but the obstacle
//     plane, translation invariant: gradient blocks sum to zero and rigid translations are in the
//     projected Hessian's null space;
//   * the gradient-only kernels return the gradient of the *_gradient_hessian kernels to a few
//     roundings (the engine calls either; the compiler may fuse their multiply-adds differently);
// closest_feature against the distance kernels' cases; project_psd_translation_free against the
// full 12x12 projection on translation-free matrices, its no-op on PSD ones, and what it does with
// a translational part.
#include "kernels/barrier/barrier_stencils.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "tests/kernels/finite_differences.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>

namespace nexdyn {
namespace {

using Vec3 = Eigen::Vector3d;
template <int N>
using Vector = Eigen::Matrix<double, 3 * N, 1>;
template <int N>
using Matrix = Eigen::Matrix<double, 3 * N, 3 * N>;

constexpr double kEps = fd::kEps;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDhat = 0.05;  // [m]
constexpr double kDhat2 = kDhat * kDhat;

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

double uniform(std::mt19937_64& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }

template <size_t N>
Vector<static_cast<int>(N)> stack(const std::array<Vec3, N>& x) {
  Vector<static_cast<int>(N)> s;
  for (int i = 0; i < static_cast<int>(N); ++i) s.template segment<3>(3 * i) = x[i];
  return s;
}

template <int N>
Vec3 at(const Vector<N>& s, int i) { return s.template segment<3>(3 * i); }

// A stencil configuration: points in stencil order, the squared distance d of its closest
// feature, and what finite differences need to know of its geometry (see budgets()).
template <int N>
struct Configuration {
  std::array<Vec3, N> x;
  double d = 0.0;
  double ell = 1.0;   // smallest length of the feature (edge, triangle height, line-line turn)
  double cond = 1.0;  // condition number of the closest-point solve D^T D
};

// Puts local coordinates into a random frame: rotated, and shifted within [-1, 1]^3.
template <size_t N>
void place(std::mt19937_64& rng, std::array<Vec3, N>& x) {
  const Eigen::Matrix3d R = random_rotation(rng);
  const Vec3 shift(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
  for (Vec3& p : x) p = R * p + shift;
}

// Separation of the closest feature: 10^-u * 0.7 dhat, u in [0, 2], so d <= 0.49 dhat^2, clear of
// the clamp at dhat (where b''' jumps).
double separation(std::mt19937_64& rng) { return 0.7 * kDhat * std::pow(10.0, -uniform(rng, 0.0, 2.0)); }

Configuration<2> point_point_configuration(std::mt19937_64& rng) {
  const double s = separation(rng);
  Configuration<2> c;
  c.x = {Vec3(0, 0, 0), Vec3(s, 0, 0)};
  place(rng, c.x);
  c.d = s * s;
  // No feature length: d = |a - b|^2 is rounded by 2 sqrt(d) X eps, what ell = X gives in
  // budgets() (whose step still follows sqrt(d) / 2).
  c.ell = 2.0;
  return c;
}

// p over the interior of e0 e1 (lengths 0.3 to 1 either side of the foot).
Configuration<3> point_line_configuration(std::mt19937_64& rng) {
  const double s = separation(rng), l0 = uniform(rng, 0.3, 1.0), l1 = uniform(rng, 0.3, 1.0);
  const double phi = uniform(rng, 0.0, 6.28);
  Configuration<3> c;
  c.x = {Vec3(0, s * std::cos(phi), s * std::sin(phi)), Vec3(-l0, 0, 0), Vec3(l1, 0, 0)};
  place(rng, c.x);
  c.d = s * s;
  c.ell = l0 + l1;
  return c;
}

// p over the centroid of a triangle with base 0.5..1 and height 0.4..1.
Configuration<4> point_plane_configuration(std::mt19937_64& rng) {
  const double s = separation(rng), base = uniform(rng, 0.5, 1.0), height = uniform(rng, 0.4, 1.0);
  const Vec3 t0(0, 0, 0), t1(base, 0, 0), t2(uniform(rng, -0.2, 0.8) * base, height, 0);
  Configuration<4> c;
  c.x = {Vec3((t0 + t1 + t2) / 3.0 + Vec3(0, 0, s)), t0, t1, t2};
  place(rng, c.x);
  c.d = s * s;
  c.ell = std::min(height, base * height / (t2 - t1).norm());
  c.cond = 4.0;  // a reasonably shaped triangle's Gram matrix
  return c;
}

// Two unit edges crossing at an angle of 0.7 to 1.5 rad, one s above the other, their closest
// points inside both.
Configuration<4> line_line_configuration(std::mt19937_64& rng) {
  const double s = separation(rng), phi = uniform(rng, 0.7, 1.5);
  const Vec3 half_b(0.5 * std::cos(phi), 0.5 * std::sin(phi), 0.0);
  const Vec3 mid_b(uniform(rng, -0.2, 0.2), uniform(rng, -0.1, 0.1), s);
  Configuration<4> c;
  c.x = {Vec3(-0.5, 0, 0), Vec3(0.5, 0, 0), Vec3(mid_b - half_b), Vec3(mid_b + half_b)};
  place(rng, c.x);
  c.d = s * s;
  c.ell = std::sin(phi);  // the offset that turns the common normal
  c.cond = (1.0 + std::cos(phi)) / (1.0 - std::cos(phi));
  return c;
}

// Nearly parallel edges inside the mollifier's band (angle 0.005 to 0.025 rad against a band edge
// of about 0.032), their interiors closest, s apart.
Configuration<4> nearly_parallel_configuration(std::mt19937_64& rng, double& eps_x) {
  const double s = separation(rng), theta = uniform(rng, 0.005, 0.025);
  const Vec3 half = 0.3 * Vec3(std::cos(theta), 0.0, std::sin(theta));
  const Vec3 mid(uniform(rng, 0.4, 0.6), s, 0.0);
  Configuration<4> c;
  c.x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(mid - half), Vec3(mid + half)};
  place(rng, c.x);
  eps_x = edge_edge_mollifier_threshold(c.x[0], c.x[1], c.x[2], c.x[3]);
  c.d = s * s;
  c.ell = std::sin(theta);  // the offset on which |ea x eb|^2, hence m, varies
  c.cond = 1.0 / (std::sin(theta) * std::sin(theta));
  return c;
}

// ------------------------------------------------------------------------------------------------
// Finite-difference budgets of E = w b(d(x)) (tests/kernels/finite_differences.hpp), from those of
// the squared distance d (tests/kernels/distance/test_distance.cpp) by first-order propagation:
//   ell      the feature's size, or sqrt(d) / 2 if smaller: b varies on the scale d of its
//            logarithm, i.e. over a length sqrt(d) / 2 of motion;
//   noise    of E: eps |E| plus w |b'| times d's rounding 4 eps (d + 2 sqrt(d) X^2 / ell), X the
//            coordinates' size (1-2 here);
//   analytic of the gradient, relative: the closest-point solve loses eps cond(D^T D), r carries
//            that times X / sqrt(d), and the feature's directions are rounded by eps X / ell.
// The Hessian's check differences the analytic gradient, whose rounding is its noise. Factors of
// 8 cover the handful of roundings in each. A check whose tolerance exceeds 1e-5 would not mean
// much: none may, but for nearly parallel edges (see there).
struct Budgets {
  fd::Budget gradient, hessian;
};

Budgets budgets(double energy, double b1, double d, double ell, double cond, double gradient_norm) {
  constexpr double X = 2.0;
  const double s = std::sqrt(d);
  Budgets b;
  b.gradient.ell = std::min(ell, 0.5 * s);
  b.gradient.noise = 8.0 * kEps * (std::abs(energy) + std::abs(b1) * (d + 2.0 * s * X * X / ell));
  b.gradient.analytic = 8.0 * kEps * (cond * (1.0 + X / s) + 4.0 * X / ell);
  b.hessian.ell = b.gradient.ell;
  b.hessian.noise = (b.gradient.analytic + 4.0 * kEps) * gradient_norm;
  b.hessian.analytic = b.gradient.analytic;
  return b;
}

// Translations: T = (1, ..., 1) (x) I3.
template <int N>
Eigen::Matrix<double, 3 * N, 3> translations() {
  Eigen::Matrix<double, 3 * N, 3> T;
  for (int i = 0; i < N; ++i) T.template middleRows<3>(3 * i).setIdentity();
  return T;
}

// Every check of one stencil: `energy`, `gradient` on stacked points; `reference` the
// unprojected Hessian; `g`, `H` the kernel's gradient and projected Hessian at x.
template <int N, typename Energy, typename Gradient>
void check_stencil(const Energy& energy, const Gradient& gradient, const Matrix<N>& reference, const Vector<N>& g,
                   const Matrix<N>& H, const Vector<N>& x, const Budgets& b, bool translation_invariant,
                   double max_tolerance = 1e-5) {
  CAPTURE(x.transpose());
  REQUIRE(g.allFinite());
  REQUIRE(H.allFinite());
  const fd::Result rg = fd::check(g, [&](double h) { return fd::gradient<3 * N>(energy, x, h); }, b.gradient);
  const fd::Result rh =
      fd::check(reference, [&](double h) { return fd::jacobian<3 * N>(gradient, x, h); }, b.hessian);
  CAPTURE(rg);
  CAPTURE(rh);
  CHECK(rg.ok());
  CHECK(rg.second_order());
  CHECK(rh.ok());
  CHECK(rh.second_order());
  CHECK(std::max(rg.tolerance, rh.tolerance) <= max_tolerance);

  // The exact projection, PSD.
  Matrix<N> projected = 0.5 * (reference + reference.transpose());
  project_psd<3 * N>(projected);
  const double scale = reference.norm();
  CHECK((H - projected).norm() <= 1e-9 * scale);
  CHECK(min_eigenvalue<3 * N>(0.5 * (H + H.transpose())) >= -1e-12 * scale);
  CHECK((H - H.transpose()).norm() <= 1e-14 * scale);
  if (!translation_invariant) return;
  Vec3 sum = Vec3::Zero();
  for (int i = 0; i < N; ++i) sum += g.template segment<3>(3 * i);
  CHECK(sum.norm() <= 1e-12 * g.norm());
  CHECK((H * translations<N>()).norm() <= 1e-11 * scale);
}

// w (b'' g g^T + b' H) for d's gradient g and Hessian H.
template <int N>
Matrix<N> chain_rule(double d, const Vector<N>& gd, const Matrix<N>& Hd, double weight) {
  return weight * (barrier_second_derivative(d, kDhat2) * gd * gd.transpose() +
                   barrier_first_derivative(d, kDhat2) * Hd);
}

constexpr int kTrials = 40;

// ------------------------------------------------------------------------------------------------

TEST_CASE("barrier stencils: closest features give each case's squared distance") {
  // The same formulas by two paths, equal up to rounding: where a kernel is inlined decides which
  // products -march=native fuses into FMAs, so the last bits may differ (they did, once this file
  // stopped instantiating the eigensolvers). A wrong feature is off by O(0.1) on these points.
  auto same = [](double a, double b) { return std::abs(a - b) <= 1e-13 * std::max(std::abs(a), std::abs(b)); };
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    std::array<Vec3, 4> x;
    for (Vec3& p : x) p = Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    auto feature_distance = [&](const ClosestFeature& f, bool lines) {
      const Vec3 &a = x[f.idx[0]], &b = x[f.idx[1]];
      if (f.n == 2) return point_point_distance(a, b);
      if (f.n == 3) return point_line_distance(a, b, x[f.idx[2]]);
      REQUIRE(f.n == 4);
      for (int i = 0; i < 4; ++i) REQUIRE(f.idx[i] == i);
      return lines ? line_line_distance(x[0], x[1], x[2], x[3]) : point_plane_distance(x[0], x[1], x[2], x[3]);
    };
    for (int c = 0; c <= static_cast<int>(PointTriangleCase::p_t); ++c) {
      const PointTriangleCase pc = static_cast<PointTriangleCase>(c);
      CAPTURE(c);
      CHECK(same(feature_distance(closest_feature(pc), false), point_triangle_distance(x[0], x[1], x[2], x[3], pc)));
    }
    for (int c = 0; c <= static_cast<int>(EdgeEdgeCase::ea_eb); ++c) {
      const EdgeEdgeCase ec = static_cast<EdgeEdgeCase>(c);
      CAPTURE(c);
      CHECK(same(feature_distance(closest_feature(ec), true), edge_edge_distance(x[0], x[1], x[2], x[3], ec)));
    }
  }
}

TEST_CASE("barrier stencils: point against an obstacle plane") {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < kTrials; ++trial) {
    const Eigen::Matrix3d R = random_rotation(rng);
    const Vec3 origin(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    const Vec3 normal = R.col(1);
    const double h = separation(rng), weight = uniform(rng, 0.5, 3.0);
    const Vector<1> x = origin + uniform(rng, -1, 1) * R.col(0) + uniform(rng, -1, 1) * R.col(2) + h * normal;
    auto energy = [&](const Vector<1>& p) {
      return weight * point_obstacle_plane_barrier_energy(p, origin, normal, kDhat2);
    };
    auto gradient = [&](const Vector<1>& p) {
      return point_obstacle_plane_barrier_gradient(p, origin, normal, kDhat2, weight);
    };
    Vector<1> g;
    Matrix<1> H;
    point_obstacle_plane_barrier_gradient_hessian(x, origin, normal, kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    const Matrix<1> reference = chain_rule<1>(h * h, point_obstacle_plane_distance_gradient(x, origin, normal),
                                              point_obstacle_plane_distance_hessian(x, origin, normal), weight);
    const Budgets b = budgets(energy(x), weight * barrier_first_derivative(h * h, kDhat2), h * h, 1.0, 1.0, g.norm());
    check_stencil<1>(energy, gradient, reference, g, H, x, b, false);
  }
  // On and behind the plane the energy is infinite (touching or crossed).
  CHECK(point_obstacle_plane_barrier_energy(Vec3(0, 0, 0), Vec3::Zero(), Vec3::UnitY(), kDhat2) == kInf);
  CHECK(point_obstacle_plane_barrier_energy(Vec3(0, -1e-3, 0), Vec3::Zero(), Vec3::UnitY(), kDhat2) == kInf);
  CHECK(point_obstacle_plane_barrier_energy(Vec3(0, kDhat, 0), Vec3::Zero(), Vec3::UnitY(), kDhat2) == 0.0);
}

TEST_CASE("barrier stencils: point-point") {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < kTrials; ++trial) {
    const Configuration<2> c = point_point_configuration(rng);
    const double weight = uniform(rng, 0.5, 3.0);
    const Vector<2> x = stack<2>(c.x);
    auto energy = [&](const Vector<2>& s) { return weight * point_point_barrier_energy(at<2>(s, 0), at<2>(s, 1), kDhat2); };
    auto gradient = [&](const Vector<2>& s) {
      return point_point_barrier_gradient(at<2>(s, 0), at<2>(s, 1), kDhat2, weight);
    };
    Vector<2> g;
    Matrix<2> H;
    point_point_barrier_gradient_hessian(c.x[0], c.x[1], kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    const double d = point_point_distance(c.x[0], c.x[1]);
    const Matrix<2> reference = chain_rule<2>(d, point_point_distance_gradient(c.x[0], c.x[1]),
                                              point_point_distance_hessian(c.x[0], c.x[1]), weight);
    const Budgets b = budgets(energy(x), weight * barrier_first_derivative(d, kDhat2), d, c.ell, c.cond, g.norm());
    check_stencil<2>(energy, gradient, reference, g, H, x, b, true);
  }
}

TEST_CASE("barrier stencils: point-line") {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < kTrials; ++trial) {
    const Configuration<3> c = point_line_configuration(rng);
    const double weight = uniform(rng, 0.5, 3.0);
    const Vector<3> x = stack<3>(c.x);
    auto energy = [&](const Vector<3>& s) {
      return weight * point_line_barrier_energy(at<3>(s, 0), at<3>(s, 1), at<3>(s, 2), kDhat2);
    };
    auto gradient = [&](const Vector<3>& s) {
      return point_line_barrier_gradient(at<3>(s, 0), at<3>(s, 1), at<3>(s, 2), kDhat2, weight);
    };
    Vector<3> g;
    Matrix<3> H;
    point_line_barrier_gradient_hessian(c.x[0], c.x[1], c.x[2], kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    const double d = point_line_distance(c.x[0], c.x[1], c.x[2]);
    const Matrix<3> reference = chain_rule<3>(d, point_line_distance_gradient(c.x[0], c.x[1], c.x[2]),
                                              point_line_distance_hessian(c.x[0], c.x[1], c.x[2]), weight);
    const Budgets b = budgets(energy(x), weight * barrier_first_derivative(d, kDhat2), d, c.ell, c.cond, g.norm());
    check_stencil<3>(energy, gradient, reference, g, H, x, b, true);
  }
}

TEST_CASE("barrier stencils: point-plane") {
  std::mt19937_64 rng(13);
  for (int trial = 0; trial < kTrials; ++trial) {
    const Configuration<4> c = point_plane_configuration(rng);
    const double weight = uniform(rng, 0.5, 3.0);
    const Vector<4> x = stack<4>(c.x);
    auto energy = [&](const Vector<4>& s) {
      return weight * point_plane_barrier_energy(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), kDhat2);
    };
    auto gradient = [&](const Vector<4>& s) {
      return point_plane_barrier_gradient(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), kDhat2, weight);
    };
    Vector<4> g;
    Matrix<4> H;
    point_plane_barrier_gradient_hessian(c.x[0], c.x[1], c.x[2], c.x[3], kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    const double d = point_plane_distance(c.x[0], c.x[1], c.x[2], c.x[3]);
    const Matrix<4> reference =
        chain_rule<4>(d, point_plane_distance_gradient(c.x[0], c.x[1], c.x[2], c.x[3]),
                      point_plane_distance_hessian(c.x[0], c.x[1], c.x[2], c.x[3]), weight);
    const Budgets b = budgets(energy(x), weight * barrier_first_derivative(d, kDhat2), d, c.ell, c.cond, g.norm());
    check_stencil<4>(energy, gradient, reference, g, H, x, b, true);
  }
}

TEST_CASE("barrier stencils: line-line") {
  std::mt19937_64 rng(17);
  for (int trial = 0; trial < kTrials; ++trial) {
    const Configuration<4> c = line_line_configuration(rng);
    const double weight = uniform(rng, 0.5, 3.0);
    const Vector<4> x = stack<4>(c.x);
    auto energy = [&](const Vector<4>& s) {
      return weight * line_line_barrier_energy(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), kDhat2);
    };
    auto gradient = [&](const Vector<4>& s) {
      return line_line_barrier_gradient(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), kDhat2, weight);
    };
    Vector<4> g;
    Matrix<4> H;
    line_line_barrier_gradient_hessian(c.x[0], c.x[1], c.x[2], c.x[3], kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    const double d = line_line_distance(c.x[0], c.x[1], c.x[2], c.x[3]);
    const Matrix<4> reference =
        chain_rule<4>(d, line_line_distance_gradient(c.x[0], c.x[1], c.x[2], c.x[3]),
                      line_line_distance_hessian(c.x[0], c.x[1], c.x[2], c.x[3]), weight);
    const Budgets b = budgets(energy(x), weight * barrier_first_derivative(d, kDhat2), d, c.ell, c.cond, g.norm());
    check_stencil<4>(energy, gradient, reference, g, H, x, b, true);
  }
}

// The mollified energy's budget adds m's rounding: c = |ea x eb|^2 is rounded by
// 4 eps sqrt(c) X (|ea| + |eb|), which moves E by w |b| m'(c) times that, and grad m is off by
// 4 eps X / ell relative (ell = the offset on which c varies), which the gradient carries times w b.
TEST_CASE("barrier stencils: mollified edge-edge on nearly parallel edges") {
  std::mt19937_64 rng(19);
  for (int trial = 0; trial < kTrials; ++trial) {
    double eps_x = 0.0;
    const Configuration<4> c = nearly_parallel_configuration(rng, eps_x);
    const std::array<Vec3, 4>& v = c.x;
    const double weight = uniform(rng, 0.5, 3.0);
    const Vector<4> x = stack<4>(v);
    const double cross = edge_edge_cross_squarednorm(v[0], v[1], v[2], v[3]);
    REQUIRE(cross < eps_x);  // inside the band: m < 1
    REQUIRE(edge_edge_case(v[0], v[1], v[2], v[3]) == EdgeEdgeCase::ea_eb);
    auto energy = [&](const Vector<4>& s) {
      return weight * mollified_edge_edge_barrier_energy(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), eps_x,
                                                         kDhat2);
    };
    auto gradient = [&](const Vector<4>& s) {
      return mollified_edge_edge_barrier_gradient(at<4>(s, 0), at<4>(s, 1), at<4>(s, 2), at<4>(s, 3), eps_x, kDhat2,
                                                  weight);
    };
    Vector<4> g;
    Matrix<4> H;
    mollified_edge_edge_barrier_gradient_hessian(v[0], v[1], v[2], v[3], eps_x, kDhat2, weight, g, H);
    CHECK((g - gradient(x)).norm() <= 1e-12 * g.norm());
    // The product rule, from the distance and mollifier kernels.
    const double d = edge_edge_distance(v[0], v[1], v[2], v[3]);
    const Vector<4> gd = edge_edge_distance_gradient(v[0], v[1], v[2], v[3]);
    const double m = edge_edge_mollifier(v[0], v[1], v[2], v[3], eps_x);
    const Vector<4> gm = edge_edge_mollifier_gradient(v[0], v[1], v[2], v[3], eps_x);
    const double b = barrier(d, kDhat2), b1 = barrier_first_derivative(d, kDhat2);
    const Matrix<4> reference =
        m * chain_rule<4>(d, gd, edge_edge_distance_hessian(v[0], v[1], v[2], v[3]), weight) +
        weight * (b1 * (gd * gm.transpose() + gm * gd.transpose()) +
                  b * edge_edge_mollifier_hessian(v[0], v[1], v[2], v[3], eps_x));
    REQUIRE(m < 1.0);
    Budgets budget = budgets(energy(x), weight * m * b1, d, c.ell, c.cond, g.norm());
    const double dm = 2.0 * (1.0 - cross / eps_x) / eps_x;
    const double edges = (v[1] - v[0]).norm() + (v[3] - v[2]).norm();
    budget.gradient.noise += 8.0 * kEps * weight * b * dm * std::sqrt(cross) * 2.0 * edges;
    budget.hessian.noise += 8.0 * kEps * weight * b * gm.norm() * 2.0 / c.ell;
    // The closest points of nearly parallel edges come from a solve with cond = 1 / sin^2 up to
    // 4e4: the Hessian's honest tolerance reaches 2e-4 (errors measured: at most 4e-7).
    check_stencil<4>(energy, gradient, reference, g, H, x, budget, true, 1e-3);
  }
}

// ------------------------------------------------------------------------------------------------
// project_psd_translation_free

// A random symmetric 12x12 matrix with both signs of eigenvalues, restricted to the complement of
// the translations: P A P with P = I - T T^T / 4.
Matrix<4> random_translation_free(std::mt19937_64& rng, bool psd) {
  Matrix<4> A;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) A(i, j) = uniform(rng, -1, 1);
  A = psd ? (A * A.transpose()).eval() : (0.5 * (A + A.transpose())).eval();
  const Eigen::Matrix<double, 12, 3> T = translations<4>();
  const Matrix<4> P = Matrix<4>::Identity() - 0.25 * T * T.transpose();
  const Matrix<4> H = P * A * P;
  return 0.5 * (H + H.transpose());
}

TEST_CASE("barrier stencils: translation-free projection equals the full one and keeps translations null") {
  std::mt19937_64 rng(23);
  const Eigen::Matrix<double, 12, 3> T = translations<4>();
  for (int trial = 0; trial < 50; ++trial) {
    const Matrix<4> H0 = random_translation_free(rng, false);
    REQUIRE(min_eigenvalue<12>(H0) < -0.1);  // there is something to project
    Matrix<4> H = H0;
    project_psd_translation_free(H);
    Matrix<4> full = H0;
    REQUIRE(project_psd<12>(full) > 3);  // the 3 translations' eigenvalues 0 may be clamped too
    CHECK((H - full).norm() <= 1e-13 * H0.norm());
    CHECK(H == H.transpose());
    CHECK(min_eigenvalue<12>(H) >= -1e-14 * H0.norm());
    CHECK((H * T).norm() <= 1e-14 * H0.norm());
    // The eigenvalues that were positive stay, the negative ones go: the trace is their sum.
    const Eigen::VectorXd ev = symmetric_eigen(H0, false).values;
    const double positive = ev.cwiseMax(0.0).sum();
    CHECK(std::abs(H.trace() - positive) <= 1e-12 * positive);
  }
}

TEST_CASE("barrier stencils: translation-free projection leaves PSD matrices bit for bit") {
  std::mt19937_64 rng(29);
  for (int trial = 0; trial < 50; ++trial) {
    const Matrix<4> H0 = random_translation_free(rng, true);
    Matrix<4> H = H0;
    project_psd_translation_free(H);
    CHECK(H == H0);
  }
}

// The projection works in the complement of the translations only (its precondition is a
// translation-invariant energy): a translational part of an indefinite H is dropped.
TEST_CASE("barrier stencils: translation-free projection drops a translational part") {
  std::mt19937_64 rng(31);
  const Eigen::Matrix<double, 12, 3> T = translations<4>();
  for (int trial = 0; trial < 20; ++trial) {
    const Matrix<4> H0 = random_translation_free(rng, false);
    Matrix<4> expected = H0;
    project_psd_translation_free(expected);
    Matrix<4> H = H0 + uniform(rng, 0.5, 2.0) * T * T.transpose();
    project_psd_translation_free(H);
    CHECK((H - expected).norm() <= 1e-13 * H0.norm());
  }
}

}  // namespace
}  // namespace nexdyn

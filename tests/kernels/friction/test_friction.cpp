// Tests of kernels/friction: the smoothing functions f0, f1 and f1 / y; the lagged normal force
// against finite differences of the barrier along the unsquared distance; per stencil kind
// (vertex-plane, point-point, point-edge, point-triangle, edge-edge) on constructed contacts whose
// closest points are known: the closest-point parameters, an orthonormal tangent basis orthogonal
// to the normal (and D unchanged by rotating it in the plane), zero slip under rigid translation
// and under motion along the normal, and the friction potential's gradient and Hessian in x
// against central differences in the static band (|u| < eps_u) and while sliding (|u| > eps_u);
// Coulomb's law while sliding (force of magnitude mu lambda against the slip); static and kinetic
// coefficients (the magnitude from mu_s to mu_k, derivatives again); derivatives at slips down to
// 1e-8 eps_u and on bases of nearly parallel, parallel and zero-length edges and sliver triangles,
// with the step and tolerance following the slip (tests/kernels/finite_differences.hpp); the
// closed-form 2 x 2 Hessian against an eigensolver (PSD); parallel and degenerate edges.
#include "kernels/barrier/barrier.hpp"
#include "kernels/friction/friction.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "tests/kernels/finite_differences.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace nexdyn {
namespace {

using Vec3 = Eigen::Vector3d;
using Mat34 = Eigen::Matrix<double, 3, 4>;

constexpr FrictionStencil kKinds[] = {FrictionStencil::vertex_plane, FrictionStencil::point_point,
                                      FrictionStencil::point_edge, FrictionStencil::point_triangle,
                                      FrictionStencil::edge_edge};

std::string kind_name(FrictionStencil kind) {
  switch (kind) {
    case FrictionStencil::vertex_plane: return "vertex_plane";
    case FrictionStencil::point_point: return "point_point";
    case FrictionStencil::point_edge: return "point_edge";
    case FrictionStencil::point_triangle: return "point_triangle";
    case FrictionStencil::edge_edge: return "edge_edge";
  }
  return "?";
}

Vec3 random_point(std::mt19937_64& rng, double amplitude = 1.0) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  return {u(rng), u(rng), u(rng)};
}

double uniform(std::mt19937_64& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// A contact whose closest points are known by construction: the expected closest-point weights
// w (Gamma = w^T (x) I3) and the expected contact normal, independent of the kernels.
struct Contact {
  FrictionStencil kind;
  Mat34 X = Mat34::Zero();            // lagged positions, DOF order, columns past n zero
  Vec3 plane_normal = Vec3::UnitZ();  // vertex_plane only
  Eigen::Vector4d w = Eigen::Vector4d::Zero();
  Vec3 normal;
};

// Unit vector orthogonal to v, from a random direction.
Vec3 random_perpendicular(std::mt19937_64& rng, const Vec3& v) {
  for (;;) {
    const Vec3 r = random_point(rng);
    const Vec3 p = r - r.dot(v) / v.squaredNorm() * v;
    if (p.norm() > 0.1) return p.normalized();
  }
}

Contact make_contact(FrictionStencil kind, std::mt19937_64& rng) {
  Contact c;
  c.kind = kind;
  const double gap = uniform(rng, 0.01, 0.3) * (uniform(rng, 0, 1) < 0.5 ? -1.0 : 1.0);
  switch (kind) {
    case FrictionStencil::vertex_plane: {
      c.plane_normal = random_point(rng).normalized();
      c.X.col(0) = random_point(rng);
      c.w << 1, 0, 0, 0;
      c.normal = c.plane_normal;
      break;
    }
    case FrictionStencil::point_point: {
      c.X.col(1) = random_point(rng);
      c.normal = random_point(rng).normalized();
      c.X.col(0) = c.X.col(1) + gap * c.normal;
      c.w << 1, -1, 0, 0;
      break;
    }
    case FrictionStencil::point_edge: {
      const Vec3 e0 = random_point(rng);
      Vec3 e1;
      do { e1 = random_point(rng); } while ((e1 - e0).norm() < 0.3);
      const double a = uniform(rng, 0.05, 0.95);
      c.normal = random_perpendicular(rng, e1 - e0);
      c.X << e0 + a * (e1 - e0) + gap * c.normal, e0, e1, Vec3::Zero();
      c.w << 1, -(1 - a), -a, 0;
      break;
    }
    case FrictionStencil::point_triangle: {
      Vec3 t0, t1, t2;
      do {
        t0 = random_point(rng);
        t1 = random_point(rng);
        t2 = random_point(rng);
      } while ((t1 - t0).cross(t2 - t0).norm() < 0.2);
      const double b1 = uniform(rng, 0.05, 0.9);
      const double b2 = uniform(rng, 0.05, 0.95 - b1);
      c.normal = (t1 - t0).cross(t2 - t0).normalized();
      c.X << t0 + b1 * (t1 - t0) + b2 * (t2 - t0) + gap * c.normal, t0, t1, t2;
      c.w << 1, -(1 - b1 - b2), -b1, -b2;
      break;
    }
    case FrictionStencil::edge_edge: {
      Vec3 ea, eb;
      do {
        ea = random_point(rng);
        eb = random_point(rng);
      } while (ea.norm() < 0.3 || eb.norm() < 0.3 ||
               ea.cross(eb).norm() < 0.1 * ea.norm() * eb.norm());
      const double g1 = uniform(rng, 0.05, 0.95);
      const double g2 = uniform(rng, 0.05, 0.95);
      c.normal = ea.cross(eb).normalized();
      const Vec3 qa = random_point(rng);
      const Vec3 qb = qa - gap * c.normal;
      c.X << qa - g1 * ea, qa + (1 - g1) * ea, qb - g2 * eb, qb + (1 - g2) * eb;
      c.w << 1 - g1, g1, -(1 - g2), -g2;
      break;
    }
  }
  return c;
}

FrictionBasis basis_of(const Contact& c) { return friction_basis(c.kind, c.X, c.plane_normal); }

Vector12d stack(const Mat34& X) { return Eigen::Map<const Vector12d>(X.data()); }

// A stencil displacement (zero past 3 n) whose tangential relative part has length y exactly.
Vector12d displacement_with_slip(const FrictionBasis& f, double y, std::mt19937_64& rng) {
  for (;;) {
    Vector12d dx = Vector12d::Zero();
    for (int i = 0; i < 3 * f.num_points; ++i) dx(i) = uniform(rng, -1, 1);
    const double y0 = tangential_displacement(f, dx).norm();
    if (y0 > 0.1) return dx * (y / y0);
  }
}

template <typename A, typename B>
double relative_error(const A& a, const B& b, double floor) {
  return (a - b).norm() / std::max({a.norm(), b.norm(), floor});
}

// ------------------------------------------------------------------------------------------------

TEST_CASE("friction: f0 and f1 are the smoothed Coulomb magnitude and its antiderivative") {
  const double eps_u = 2e-3;
  // Relative comparisons: the values are far from 1, where doctest's default Approx would add
  // its epsilon absolutely.
  auto relative = [](double value, double tolerance) {
    return doctest::Approx(value).epsilon(tolerance).scale(0.0);
  };
  // Closed-form values: f1(0) = 0, f1(eps_u) = 1, f0(eps_u) = eps_u, f0(0) = eps_u / 3, each a
  // branch returning y or a single rounded expression: exact up to an ulp.
  CHECK(friction_f1(0.0, eps_u) == 0.0);
  CHECK(friction_f1(eps_u, eps_u) == 1.0);
  CHECK(friction_f0(eps_u, eps_u) == relative(eps_u, 1e-15));
  CHECK(friction_f0(0.0, eps_u) == relative(eps_u / 3.0, 1e-15));
  CHECK(friction_f1_over_y(0.0, eps_u) == relative(2.0 / eps_u, 1e-15));
  // Continuity at eps_u from below (f0, f1, f1' all continuous: D is C2); f0 is off by
  // f1 eps_u 1e-9 there, 1e-9 relative.
  const double below = eps_u * (1.0 - 1e-9);
  CHECK(friction_f0(below, eps_u) == relative(eps_u, 1e-8));
  CHECK(friction_f1(below, eps_u) == doctest::Approx(1.0).epsilon(1e-8));
  CHECK(std::abs(friction_f1_derivative(below, eps_u)) < 1e-5 / eps_u);
  // f0' = f1, f1' by central differences; f1 / y against the quotient; f1 in [0, 1], increasing.
  for (int i = 1; i < 400; ++i) {
    const double y = 4.0 * eps_u * i / 400.0;
    if (std::abs(y - eps_u) < 1e-3 * eps_u) continue;
    const double h = 1e-6 * eps_u;
    const double df0 = (friction_f0(y + h, eps_u) - friction_f0(y - h, eps_u)) / (2 * h);
    CHECK(friction_f1(y, eps_u) == doctest::Approx(df0).epsilon(1e-7));
    const double df1 = (friction_f1(y + h, eps_u) - friction_f1(y - h, eps_u)) / (2 * h);
    CHECK(friction_f1_derivative(y, eps_u) ==
          doctest::Approx(df1).epsilon(1e-6).scale(1e-6 / eps_u));
    CHECK(friction_f1_over_y(y, eps_u) ==
          doctest::Approx(friction_f1(y, eps_u) / y).epsilon(1e-13));
    CHECK(friction_f1(y, eps_u) >= 0.0);
    CHECK(friction_f1(y, eps_u) <= 1.0);
    CHECK(friction_f1_derivative(y, eps_u) >= 0.0);
  }
}

TEST_CASE("friction: normal force is minus the derivative of kappa b along the distance") {
  std::mt19937_64 rng(3);
  const double kappa = 37.0;
  for (double dhat2 : {1e-6, 1e-2, 1.0}) {
    for (int trial = 0; trial < 100; ++trial) {
      const double d = dhat2 * std::pow(10.0, -6.0 * uniform(rng, 0, 1)) * 0.999;
      const double s = std::sqrt(d);
      const double h = 1e-6 * s;
      const double fd = -kappa * (barrier((s + h) * (s + h), dhat2) -
                                  barrier((s - h) * (s - h), dhat2)) / (2 * h);
      const double lambda = friction_normal_force(d, dhat2, kappa);
      CHECK(lambda > 0.0);
      // Relative: lambda is ~1e-6 for dhat2 = 1e-6, so an absolute 1e-6 would accept anything.
      // Steps of 1e-6 s: truncation ~1e-12, rounding ~eps |ln(d / dhat2)| / 1e-6 ~ 1e-9.
      CHECK(lambda == doctest::Approx(fd).epsilon(1e-6).scale(0.0));
    }
    CHECK(friction_normal_force(dhat2, dhat2, kappa) == 0.0);
    CHECK(friction_normal_force(2 * dhat2, dhat2, kappa) == 0.0);
  }
}

TEST_CASE("friction: closest-point weights and tangent bases per stencil kind") {
  std::mt19937_64 rng(5);
  for (FrictionStencil kind : kKinds) {
    const std::string name = kind_name(kind);
    CAPTURE(name);
    for (int trial = 0; trial < 100; ++trial) {
      const Contact c = make_contact(kind, rng);
      const FrictionBasis f = basis_of(c);
      const int n = friction_stencil_size(kind);
      CHECK(f.num_points == n);
      // The weights of the constructed closest points (padding zero).
      CHECK((f.w - c.w).norm() < 1e-10);
      // P orthonormal, orthogonal to the expected normal.
      CHECK((f.P.transpose() * f.P - Eigen::Matrix2d::Identity()).norm() < 1e-14);
      CHECK((f.P.transpose() * c.normal).norm() < 1e-12);
      // Gamma and T as documented: Gamma = w^T (x) I3, T = Gamma^T P.
      const Eigen::Matrix<double, 3, 12> G = relative_velocity_jacobian(f);
      for (int i = 0; i < 4; ++i) {
        CHECK((G.block<3, 3>(0, 3 * i) - f.w(i) * Eigen::Matrix3d::Identity()).norm() == 0.0);
      }
      CHECK((tangent_jacobian(f) - G.transpose() * f.P).norm() < 1e-15);
      // Only the tangent plane matters: rotating P within it leaves D and its derivatives alone.
      const double angle = uniform(rng, 0, 2 * std::numbers::pi);
      FrictionBasis rotated = f;
      rotated.P = f.P * Eigen::Rotation2Dd(angle).toRotationMatrix();
      const Vector12d dx = displacement_with_slip(f, uniform(rng, 0.0, 3e-3), rng);
      // Relative (the energy is ~1e-3): |u| is the same up to the rotation's rounding.
      CHECK(friction_energy(rotated, dx, 0.5, 2.0, 1e-3) ==
            doctest::Approx(friction_energy(f, dx, 0.5, 2.0, 1e-3)).epsilon(1e-12).scale(0.0));
      CHECK(relative_error(friction_gradient(rotated, dx, 0.5, 2.0, 1e-3),
                           friction_gradient(f, dx, 0.5, 2.0, 1e-3), 1e-12) < 1e-12);
      CHECK(relative_error(friction_hessian(rotated, dx, 0.5, 2.0, 1e-3),
                           friction_hessian(f, dx, 0.5, 2.0, 1e-3), 1e-12) < 1e-12);
    }
  }
}

TEST_CASE("friction: rigid translation and motion along the normal give no slip") {
  std::mt19937_64 rng(7);
  for (FrictionStencil kind : kKinds) {
    const std::string name = kind_name(kind);
    CAPTURE(name);
    const int n = friction_stencil_size(kind);
    for (int trial = 0; trial < 100; ++trial) {
      const Contact c = make_contact(kind, rng);
      const FrictionBasis f = basis_of(c);
      const Vec3 t = random_point(rng);
      // Whole stencil translated: the closest points move together (not for vertex-plane, whose
      // plane stays put).
      Vector12d dx = Vector12d::Zero();
      for (int i = 0; i < n; ++i) dx.segment<3>(3 * i) = t;
      if (kind != FrictionStencil::vertex_plane) {
        CHECK((relative_velocity_jacobian(f) * dx).norm() < 1e-14);
        CHECK(tangential_displacement(f, dx).norm() < 1e-14);
      }
      // Side A (w > 0: the point, or edge a) translated along the normal, side B held: the
      // closest points separate or approach along the normal only.
      const Vec3 along = uniform(rng, -1, 1) * c.normal;
      dx.setZero();
      for (int i = 0; i < n; ++i) {
        if (c.w(i) > 0.0) dx.segment<3>(3 * i) = along;
      }
      CHECK(tangential_displacement(f, dx).norm() < 1e-14);
      // The same with a tangential part: u is exactly its coordinates in P.
      const Vec3 slide = f.P * Eigen::Vector2d(uniform(rng, -1, 1), uniform(rng, -1, 1));
      for (int i = 0; i < n; ++i) {
        if (c.w(i) > 0.0) dx.segment<3>(3 * i) = along + slide;
      }
      CHECK((f.P * tangential_displacement(f, dx) - slide).norm() < 1e-14);
    }
  }
}

// D(x) = lambda F0(|T^T (x - x_prev)|) with the basis lagged at X: gradient and (with_hessian)
// Hessian against central differences in x, at |u| in [y_lo, y_hi] eps_u.
void check_friction_derivatives(double y_lo, double y_hi, uint64_t seed,
                                FrictionCoefficients mu = {0.4, 0.4}, bool with_hessian = true) {
  std::mt19937_64 rng(seed);
  const double eps_u = 1e-3, lambda = 2.5;
  for (FrictionStencil kind : kKinds) {
    const std::string name = kind_name(kind);
    CAPTURE(name);
    for (int trial = 0; trial < 50; ++trial) {
      const Contact c = make_contact(kind, rng);
      const FrictionBasis f = basis_of(c);
      // x_prev: start of the step, near the lagged positions; x = x_prev + dx.
      Vector12d x_prev = stack(c.X);
      for (int i = 0; i < 3 * f.num_points; ++i) x_prev(i) += uniform(rng, -1e-3, 1e-3);
      const double y = uniform(rng, y_lo, y_hi) * eps_u;
      const Vector12d x = x_prev + displacement_with_slip(f, y, rng);
      // x - x_prev is rounded by eps |x| per coordinate: absolute, not relative to y.
      CHECK(std::abs(tangential_displacement(f, x - x_prev).norm() - y) <=
            16.0 * fd::kEps * x.cwiseAbs().maxCoeff());

      auto energy = [&](const Vector12d& z) {
        return friction_energy(f, z - x_prev, mu, lambda, eps_u);
      };
      auto gradient = [&](const Vector12d& z) {
        return friction_gradient(f, z - x_prev, mu, lambda, eps_u);
      };
      const double h = 1e-8;
      Vector12d g_fd;
      Matrix12d H_fd;
      for (int i = 0; i < 12; ++i) {
        Vector12d xp = x, xm = x;
        xp(i) += h;
        xm(i) -= h;
        g_fd(i) = (energy(xp) - energy(xm)) / (2 * h);
        H_fd.col(i) = (gradient(xp) - gradient(xm)) / (2 * h);
      }
      const Vector12d g = gradient(x);
      const Matrix12d H = friction_hessian(f, x - x_prev, mu, lambda, eps_u);
      CHECK(relative_error(g, g_fd, 1e-12) < 1e-6);
      if (with_hessian) CHECK(relative_error(H, H_fd, 1e-12) < 1e-5);
      CHECK((H - H.transpose()).norm() == 0.0);
      // Zero past the stencil's 3 n DOFs.
      double padding = 0.0;
      for (int i = 3 * f.num_points; i < 12; ++i) {
        padding += std::abs(g(i)) + H.row(i).cwiseAbs().sum() + H.col(i).cwiseAbs().sum();
      }
      CHECK(padding == 0.0);
    }
  }
}

TEST_CASE("friction: derivatives match finite differences in the static band") {
  check_friction_derivatives(0.05, 0.95, 11);
}

TEST_CASE("friction: derivatives match finite differences while sliding") {
  check_friction_derivatives(1.05, 20.0, 13);
}

// Static and kinetic coefficients (mu_s 0.6, mu_k 0.4): the same checks in the sticking band and
// past the transition, where g' >= 0 and the Hessian is exact; in the transition g' < 0 is
// clamped, so only the gradient is compared there.
TEST_CASE("friction: static and kinetic coefficients, derivatives match finite differences") {
  const FrictionCoefficients mu{0.6, 0.4};
  check_friction_derivatives(0.05, 0.95, 21, mu);
  check_friction_derivatives(2.05, 20.0, 23, mu);
  check_friction_derivatives(1.05, 1.95, 25, mu, false);
}

// Slips y = |u| from 1e-8 eps_u to 20 eps_u on lagged bases of well-shaped contacts and of
// degenerate ones (nearly parallel edges at sin = 1e-8, exactly parallel and zero-length edges, a
// 1e-8 sliver triangle, a point on an edge's line): T is constant within a lagging iteration, so
// D(x) = lambda F0(|T^T (x - x_prev)|) stays smooth whatever the basis; only the slip sets the
// scale. Budget: |u| turns on the scale ell = y (and f1'' jumps at eps_u: ell <= |y - eps_u|);
// x - x_prev is rounded by eps X (X the largest coordinate), which moves |u| as much; D carries
// the constant lambda mu eps_u / 3 of f0, so it is rounded by ~4 eps lambda mu (eps_u + y +
// f1(y) X) while the gradient is only lambda mu f1(y) |T|, and the gradient by
// ~8 eps lambda mu (f1(y) / y) X |w|^2 against a Hessian of lambda mu (2 / eps_u) |w|^2. Both
// fall below what differences resolve at the smallest slips (counted).
TEST_CASE("friction: derivatives at tiny slips and on degenerate bases") {
  std::mt19937_64 rng(29);
  const double eps_u = 1e-3, lambda = 2.5, mu = 0.4;
  std::vector<FrictionBasis> bases;
  std::vector<std::string> names;
  for (FrictionStencil kind : kKinds) {
    bases.push_back(basis_of(make_contact(kind, rng)));
    names.push_back(kind_name(kind));
  }
  const Vec3 a0(0, 0, 0), a1(1, 0, 0);
  bases.push_back(edge_edge_friction_basis(a0, a1, Vec3(0.2, 1e-3, 0), Vec3(0.8, 1e-3, 6e-9)));
  names.push_back("nearly parallel edges, sin 1e-8");
  bases.push_back(edge_edge_friction_basis(a0, a1, Vec3(0.2, 1e-3, 0), Vec3(0.8, 1e-3, 0)));
  names.push_back("parallel edges");
  bases.push_back(edge_edge_friction_basis(a0, a0, Vec3(0.2, 1e-3, 0), Vec3(0.2, 1e-3, 0)));
  names.push_back("zero-length edges");
  bases.push_back(point_triangle_friction_basis(Vec3(0.3, 1e-9, 1e-3), a0, a1, Vec3(0.5, 1e-8, 0)));
  names.push_back("sliver triangle 1e-8");
  bases.push_back(point_edge_friction_basis(Vec3(0.3, 0, 0), a0, a1));
  names.push_back("point on the edge's line");
  int checked = 0, beyond = 0;
  for (size_t k = 0; k < bases.size(); ++k) {
    const FrictionBasis& f = bases[k];
    REQUIRE(f.P.allFinite());
    REQUIRE(f.w.allFinite());
    for (double y_rel : {1e-8, 1e-6, 1e-4, 1e-2, 0.5, 0.999, 1.001, 3.0, 20.0}) {
      const double y = y_rel * eps_u;
      Vector12d x_prev = Vector12d::Zero();
      for (int i = 0; i < 3 * f.num_points; ++i) x_prev(i) = uniform(rng, -1, 1);
      const Vector12d x = x_prev + displacement_with_slip(f, y, rng);
      auto energy = [&](const Vector12d& z) {
        return friction_energy(f, z - x_prev, mu, lambda, eps_u);
      };
      auto gradient = [&](const Vector12d& z) {
        return friction_gradient(f, z - x_prev, mu, lambda, eps_u);
      };
      const Vector12d g = gradient(x);
      const Matrix12d H = friction_hessian(f, x - x_prev, mu, lambda, eps_u);
      const double w2 = f.w.squaredNorm();
      fd::Budget bg;
      bg.ell = std::min(y, std::abs(y - eps_u));
      // x - x_prev is rounded by eps X (X: the largest coordinate), which moves |u| by as much.
      const double X = x.cwiseAbs().maxCoeff();
      const double f1 = friction_f1(y, eps_u);
      bg.noise = 4.0 * fd::kEps * lambda * mu * (eps_u + y + f1 * X);
      bg.analytic = 8.0 * fd::kEps;
      fd::Budget bh;
      bh.ell = bg.ell;
      bh.noise = 8.0 * fd::kEps * (g.norm() + lambda * mu * (f1 / y) * X * w2);
      bh.analytic = 8.0 * fd::kEps;
      bh.floor = 1e-12 * lambda * mu * w2 / eps_u;
      const fd::Result rg =
          fd::check(g, [&](double h) { return fd::gradient<12>(energy, x, h); }, bg);
      const fd::Result rh =
          fd::check(H, [&](double h) { return fd::jacobian<12>(gradient, x, h); }, bh);
      CAPTURE(names[k]);
      CAPTURE(y_rel);
      CAPTURE(rg);
      CAPTURE(rh);
      for (const fd::Result& r : {rg, rh}) {
        if (r.tolerance > 1e-3) {
          ++beyond;
          continue;
        }
        ++checked;
        CHECK(r.ok());
        CHECK(r.second_order());
      }
    }
  }
  MESSAGE("friction at tiny slips and degenerate bases: ", checked, " checks, ", beyond, " beyond");
  // Beyond, per basis: the energy's differences at y = 1e-8 and 1e-6 eps_u, the gradient's at
  // y = 1e-8 eps_u.
  CHECK(beyond <= 3 * int(bases.size()));
  CHECK(checked >= 15 * int(bases.size()));
}

TEST_CASE("friction: static and kinetic magnitude, from mu_s at the sticking speed to mu_k") {
  const double eps_u = 2e-3;
  const FrictionCoefficients c{0.6, 0.4}, one{0.5, 0.5};
  auto g = [&](double y, const FrictionCoefficients& k) { return y * friction_magnitude(y, k, eps_u).over_y; };
  // The full static force at the edge of the sticking band, the kinetic one from 2 eps_u on.
  CHECK(g(eps_u, c) == doctest::Approx(0.6).epsilon(1e-14));
  CHECK(g(2 * eps_u, c) == doctest::Approx(0.4).epsilon(1e-14));
  CHECK(g(7 * eps_u, c) == doctest::Approx(0.4).epsilon(1e-14));
  // Nowhere above mu_s, and below it in the band only as f1 is.
  for (int i = 1; i < 800; ++i) {
    const double y = 4.0 * eps_u * i / 800.0;
    CAPTURE(y);
    CHECK(g(y, c) <= 0.6 * (1 + 1e-14));
    if (y < eps_u) CHECK(g(y, c) == doctest::Approx(0.6 * friction_f1(y, eps_u)).epsilon(1e-14));
    // F0' = g and g' by central differences away from the joints at eps_u and 2 eps_u; F0 and g
    // continuous across them.
    const double h = 1e-6 * eps_u;
    if (std::abs(y - eps_u) > 1e-3 * eps_u && std::abs(y - 2 * eps_u) > 1e-3 * eps_u) {
      const double dF = (friction_magnitude(y + h, c, eps_u).potential - friction_magnitude(y - h, c, eps_u).potential) / (2 * h);
      CHECK(g(y, c) == doctest::Approx(dF).epsilon(1e-7));
      const double dg = (g(y + h, c) - g(y - h, c)) / (2 * h);
      CHECK(std::abs(friction_magnitude(y, c, eps_u).derivative - dg) <= 1e-6 * (0.6 / eps_u));  // g' ~ mu / eps_u
    }
    // One coefficient: exactly mu f0, mu f1 / y, mu f1'.
    const FrictionMagnitude m = friction_magnitude(y, one, eps_u);
    CHECK(m.potential == 0.5 * friction_f0(y, eps_u));
    CHECK(m.over_y == 0.5 * friction_f1_over_y(y, eps_u));
    CHECK(m.derivative == 0.5 * friction_f1_derivative(y, eps_u));
  }
  for (double joint : {eps_u, 2 * eps_u}) {
    const double below = joint * (1 - 1e-12), above = joint * (1 + 1e-12);
    // Relative (the potential is ~1e-3): across the joint it moves by ~g 2e-12 of the joint.
    CHECK(friction_magnitude(below, c, eps_u).potential ==
          doctest::Approx(friction_magnitude(above, c, eps_u).potential).epsilon(1e-10).scale(0.0));
    CHECK(g(below, c) == doctest::Approx(g(above, c)).epsilon(1e-9));
  }
  // The projected 2 x 2 Hessian stays PSD where g' < 0.
  const Eigen::Matrix2d M = friction_tangent_hessian(Eigen::Vector2d(1.5 * eps_u, 0.0), c, eps_u);
  CHECK(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(M).eigenvalues().minCoeff() >= 0.0);
  CHECK(friction_magnitude(1.5 * eps_u, c, eps_u).derivative < 0.0);
}

TEST_CASE("friction: sliding force has magnitude mu lambda and opposes the slip") {
  std::mt19937_64 rng(17);
  const double eps_u = 1e-4, mu = 0.3, lambda = 7.0;
  for (FrictionStencil kind : kKinds) {
    const std::string name = kind_name(kind);
    CAPTURE(name);
    const int n = friction_stencil_size(kind);
    for (int trial = 0; trial < 100; ++trial) {
      const Contact c = make_contact(kind, rng);
      const FrictionBasis f = basis_of(c);
      const bool sliding = trial % 2 == 0;
      const double y = (sliding ? uniform(rng, 1.0, 100.0) : uniform(rng, 0.01, 0.99)) * eps_u;
      const Vector12d dx = displacement_with_slip(f, y, rng);
      const Vec3 slip = f.P * tangential_displacement(f, dx);  // tangential relative displacement
      const Vector12d force = friction_force(f, dx, mu, lambda, eps_u);
      // Total force on each side of the contact.
      Vec3 on_a = Vec3::Zero(), on_b = Vec3::Zero();
      for (int i = 0; i < n; ++i) (c.w(i) > 0.0 ? on_a : on_b) += force.segment<3>(3 * i);
      if (sliding) {
        // Coulomb: |F_A| = mu lambda, F_A = -mu lambda slip / |slip|.
        CHECK(on_a.norm() == doctest::Approx(mu * lambda).epsilon(1e-12));
        CHECK(on_a.dot(slip) / slip.norm() == doctest::Approx(-mu * lambda).epsilon(1e-12));
      } else {
        // Sticking band: a smaller force, still against the slip.
        CHECK(on_a.norm() < mu * lambda);
        CHECK(on_a.dot(slip) / slip.norm() == doctest::Approx(-on_a.norm()).epsilon(1e-12));
      }
      // Action and reaction (the plane takes the vertex-plane reaction).
      if (kind != FrictionStencil::vertex_plane) CHECK((on_a + on_b).norm() < 1e-12 * mu * lambda);
    }
  }
}

TEST_CASE("friction: closed-form 2x2 Hessian is PSD with eigenvalues f1 prime and f1 over y") {
  std::mt19937_64 rng(19);
  const double eps_u = 1e-3;
  // y = 0: (2 / eps_u) I.
  CHECK((friction_tangent_hessian(Eigen::Vector2d::Zero(), eps_u) -
         (2.0 / eps_u) * Eigen::Matrix2d::Identity()).norm() == 0.0);
  for (int trial = 0; trial < 400; ++trial) {
    const double y = eps_u * std::pow(10.0, uniform(rng, -8.0, 2.0));
    const double angle = uniform(rng, 0, 2 * std::numbers::pi);
    const Eigen::Vector2d u_hat(std::cos(angle), std::sin(angle));
    const Eigen::Matrix2d M = friction_tangent_hessian(y * u_hat, eps_u);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(M);
    const double along = friction_f1_derivative(y, eps_u);
    const double across = friction_f1_over_y(y, eps_u);
    const double scale = 2.0 / eps_u + across;
    CHECK(es.eigenvalues().minCoeff() >= -1e-14 * scale);
    CHECK((M * u_hat - along * u_hat).norm() < 1e-12 * scale);
    const Eigen::Vector2d u_perp(-u_hat(1), u_hat(0));
    CHECK((M * u_perp - across * u_perp).norm() < 1e-12 * scale);
    // The formula (f1' y - f1) / y^3 u u^T + (f1 / y) I, away from y = 0 where it cancels.
    if (y > 1e-3 * eps_u) {
      const Eigen::Vector2d u = y * u_hat;
      const Eigen::Matrix2d M_formula =
          (along * y - friction_f1(y, eps_u)) / (y * y * y) * (u * u.transpose()) +
          across * Eigen::Matrix2d::Identity();
      CHECK((M - M_formula).norm() < 1e-9 * scale);
    }
  }
  // And the stencil Hessian mu lambda T M T^T is PSD.
  for (FrictionStencil kind : kKinds) {
    const std::string name = kind_name(kind);
    CAPTURE(name);
    for (int trial = 0; trial < 50; ++trial) {
      const Contact c = make_contact(kind, rng);
      const FrictionBasis f = basis_of(c);
      const Vector12d dx = displacement_with_slip(f, eps_u * uniform(rng, 0.0, 3.0), rng);
      const Matrix12d H = friction_hessian(f, dx, 0.5, 3.0, eps_u);
      const double min_ev = symmetric_eigen(H, false).values.minCoeff();
      CHECK(min_ev >= -1e-12 * H.norm());
    }
  }
}

TEST_CASE("friction: the majorized Hessian's quadratic lies above the energy, the exact one's not across the kink") {
  // q(d) = D(dx) + grad D . d + d^T H d / 2 with the majorized H bounds D(dx + d) from above for
  // every d (one coefficient and mu_s > mu_k alike); with the exact H (0 along a sliding slip),
  // the step that carries the slip to its mirror image -u is predicted to gain 2 mu lambda |u|
  // that it does not.
  std::mt19937_64 rng(23);
  const double eps_u = 1e-4, lambda = 3.0;
  for (const FrictionCoefficients c : {FrictionCoefficients{0.4, 0.4}, FrictionCoefficients{0.5, 0.3}}) {
    for (FrictionStencil kind : kKinds) {
      const std::string name = kind_name(kind);
      CAPTURE(name);
      for (int trial = 0; trial < 60; ++trial) {
        const Contact contact = make_contact(kind, rng);
        const FrictionBasis f = basis_of(contact);
        const double y = eps_u * std::pow(10.0, uniform(rng, -2.0, 2.0));
        const Vector12d dx = displacement_with_slip(f, y, rng);
        const double energy = friction_energy(f, dx, c, lambda, eps_u);
        const Vector12d grad = friction_gradient(f, dx, c, lambda, eps_u);
        const Matrix12d H = friction_hessian(f, dx, c, lambda, eps_u, true);
        auto model = [&](const Matrix12d& hess, const Vector12d& d) {
          return energy + grad.dot(d) + 0.5 * d.dot(hess * d);
        };
        for (int k = 0; k < 20; ++k) {
          // Steps from a tenth to ten times the slip, and the one to the mirror image.
          const Vector12d d = k == 0 ? Vector12d(-2.0 * dx)
                                     : displacement_with_slip(f, y * std::pow(10.0, uniform(rng, -1.0, 1.0)), rng);
          const double scale = c.mu_s * lambda * (y + tangential_displacement(f, d).norm());
          CHECK(friction_energy(f, dx + d, c, lambda, eps_u) <= model(H, d) + 1e-12 * scale);
        }
        if (y >= 2.0 * eps_u) {
          const Matrix12d exact = friction_hessian(f, dx, c, lambda, eps_u);
          const Vector12d mirror = -2.0 * dx;
          CHECK(model(exact, mirror) < friction_energy(f, dx + mirror, c, lambda, eps_u) - c.mu_k * lambda * y);
        }
      }
    }
  }
}

TEST_CASE("friction: parallel and degenerate edge-edge contacts get a central contact point") {
  // Parallel edges overlapping on ea's parameter range [0.5, 1]: g1 = 0.75, eb's point below it.
  const Vec3 ea0(0, 0, 0), ea1(2, 0, 0), eb0(1, 0.5, 0.1), eb1(4, 0.5, 0.1);
  const Eigen::Vector2d g = edge_edge_closest_parameters(ea0, ea1, eb0, eb1);
  // Binary fractions and one division: exact up to an ulp or two.
  CHECK(g(0) == doctest::Approx(0.75).epsilon(1e-15));
  CHECK(g(1) == doctest::Approx(0.5 / 3.0).epsilon(1e-15).scale(0.0));
  const FrictionBasis f = edge_edge_friction_basis(ea0, ea1, eb0, eb1);
  CHECK(std::abs(f.w.sum()) <= 1e-15);  // 1 - g1 + g1 - (1 - g2) - g2: a few roundings of O(1)
  const Vec3 r = (1 - g(0)) * ea0 + g(0) * ea1 - (1 - g(1)) * eb0 - g(1) * eb1;
  CHECK((f.P.transpose() * f.P - Eigen::Matrix2d::Identity()).norm() < 1e-14);
  CHECK((f.P.transpose() * r).norm() < 1e-14);  // the normal is the closest-point difference
  // Sliding along the edges: x lies in the tangent plane, up to the basis' rounding.
  CHECK((f.P.transpose() * Vec3::UnitX()).norm() == doctest::Approx(1.0).epsilon(1e-15));
  // Parallel, not overlapping: the nearest ends.
  const Eigen::Vector2d g2 =
      edge_edge_closest_parameters(ea0, ea1, Vec3(3, 0.5, 0.1), Vec3(5, 0.5, 0.1));
  CHECK(g2(0) == 1.0);
  CHECK(g2(1) == 0.0);
  // Collinear touching edges and zero-length edges: finite, orthonormal bases.
  for (const FrictionBasis& b :
       {edge_edge_friction_basis(ea0, ea1, Vec3(2, 0, 0), Vec3(3, 0, 0)),
        edge_edge_friction_basis(ea0, ea0, eb0, eb0),
        point_edge_friction_basis(Vec3(1, 0, 0), ea0, ea1),
        point_edge_friction_basis(eb0, ea0, ea0),
        point_point_friction_basis(eb0, eb0),
        point_triangle_friction_basis(eb0, ea0, ea1, Vec3(4, 0, 0))}) {
    CHECK(b.P.allFinite());
    CHECK(b.w.allFinite());
    CHECK((b.P.transpose() * b.P - Eigen::Matrix2d::Identity()).norm() < 1e-14);
  }
}

}  // namespace
}  // namespace nexdyn

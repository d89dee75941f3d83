// Tests of kernels/barrier: the clamped log barrier b(d) (on squared distances) against central
// differences over 12 decades below dhat and up to the clamp, with the step and tolerance
// following d (tests/kernels/finite_differences.hpp), its values at the clamp and its behaviour
// as d -> 0, positivity and monotonicity;
// the adaptive stiffness helpers of the IPC supplemental (clamping, the gradient balance, the
// doubling rule).
#include "kernels/barrier/barrier.hpp"
#include "tests/kernels/finite_differences.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>

#include <cmath>
#include <limits>
#include <random>

namespace nexdyn {
namespace {

// d spread over 12 decades below dhat and up to 1e-6 of dhat below the clamp. b varies on the
// scale ell = min(d, dhat - d) (ln d's singularity at 0, the clamp at dhat), which sets the step
// (tests/kernels/finite_differences.hpp). Rounding, with dd = d - dhat (exact) and ln(d / dhat)
// good to eps absolute: b = -dd^2 ln is off by ~eps dd^2 (1 + |ln|), b' = -2 dd ln - dd^2 / d by
// ~eps (|dd| (1 + |ln|) + dd^2 / d); 4 eps for a few roundings each. Floors: b' and b'' vanish at
// the clamp; below 1e-8 dhat and 1e-8 they are compared absolutely.
TEST_CASE("barrier: derivatives match finite differences") {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  using Scalar = Eigen::Matrix<double, 1, 1>;
  for (double dhat : {1e-6, 1e-2, 1.0, 25.0}) {
    for (int trial = 0; trial < 200; ++trial) {
      // d = dhat 10^(-12 u), every fourth within 10^-6..10^-1 of dhat below the clamp.
      const double d = trial % 4 == 0 ? dhat * (1.0 - std::pow(10.0, -1.0 - 5.0 * u(rng)))
                                      : dhat * std::pow(10.0, -12.0 * u(rng)) * 0.999;
      CAPTURE(dhat);
      CAPTURE(d);
      const double ln = std::abs(std::log(d / dhat));
      const double dd = d - dhat;
      fd::Budget b1;
      b1.ell = std::min(d, dhat - d);
      b1.noise = 4.0 * fd::kEps * dd * dd * (1.0 + ln);
      b1.floor = 1e-8 * dhat;
      const fd::Result r1 = fd::check(
          Scalar(barrier_first_derivative(d, dhat)),
          [&](double h) {
            return fd::gradient<1>([&](const Scalar& x) { return barrier(x(0), dhat); },
                                   Scalar(d), h);
          },
          b1);
      CAPTURE(r1);
      CHECK(r1.ok());
      CHECK(r1.second_order());
      fd::Budget b2;
      b2.ell = b1.ell;
      b2.noise = 4.0 * fd::kEps * (std::abs(dd) * (1.0 + ln) + dd * dd / d);
      b2.floor = 1e-8;
      const fd::Result r2 = fd::check(
          Scalar(barrier_second_derivative(d, dhat)),
          [&](double h) {
            return fd::jacobian<1>(
                [&](const Scalar& x) { return Scalar(barrier_first_derivative(x(0), dhat)); },
                Scalar(d), h);
          },
          b2);
      CAPTURE(r2);
      CHECK(r2.ok());
      CHECK(r2.second_order());
      CHECK(std::max(r1.tolerance, r2.tolerance) <= 1e-6);  // a check that means something
    }
  }
}

TEST_CASE("barrier: clamp, positivity, monotonicity and the d -> 0 limit") {
  const double dhat = 1e-3;
  CHECK(barrier(dhat, dhat) == 0.0);
  CHECK(barrier_first_derivative(dhat, dhat) == 0.0);
  CHECK(barrier_second_derivative(dhat, dhat) == 0.0);
  CHECK(barrier(2.0 * dhat, dhat) == 0.0);
  CHECK(barrier_first_derivative(2.0 * dhat, dhat) == 0.0);
  // Continuity from below: b, b' and b'' all go to 0 at dhat (C2 clamp).
  const double below = dhat * (1.0 - 1e-8);
  CHECK(std::abs(barrier(below, dhat)) < 1e-20);
  CHECK(std::abs(barrier_first_derivative(below, dhat)) < 1e-13);
  CHECK(std::abs(barrier_second_derivative(below, dhat)) < 1e-6);
  // Intersecting or touching pairs.
  CHECK(barrier(0.0, dhat) == std::numeric_limits<double>::infinity());
  CHECK(barrier(-1.0, dhat) == std::numeric_limits<double>::infinity());
  CHECK(barrier_first_derivative(0.0, dhat) == -std::numeric_limits<double>::infinity());
  CHECK(barrier_second_derivative(0.0, dhat) == std::numeric_limits<double>::infinity());
  // Positive, decreasing, convex on (0, dhat) over a log grid; unbounded as d -> 0.
  double previous = std::numeric_limits<double>::infinity();
  for (int i = 300; i >= 1; --i) {
    const double d = dhat * std::pow(10.0, -12.0 * i / 300.0);
    const double b = barrier(d, dhat);
    CHECK(b > 0.0);
    CHECK(b < previous);
    CHECK(barrier_first_derivative(d, dhat) < 0.0);
    CHECK(barrier_second_derivative(d, dhat) > 0.0);
    previous = b;
  }
  CHECK(barrier(1e-300, dhat) > 0.6 * dhat * dhat);  // = dhat^2 ln(dhat / d) ~ 683 dhat^2
  CHECK(barrier(1e-300, dhat) > barrier(1e-200, dhat));
  // Relative (scale 0: doctest's default adds epsilon absolutely, which is 1.5e-9 of this value).
  CHECK(barrier(1e-300, dhat) ==
        doctest::Approx(dhat * dhat * std::log(dhat / 1e-300)).epsilon(1e-12).scale(0.0));
}

TEST_CASE("barrier: initial stiffness balances the gradients within its bounds") {
  const double bbox = 2.0, dhat = 1e-6, mass = 0.1;
  Eigen::VectorXd grad_b(6), grad_e(6);
  grad_b << 1, -2, 0.5, 0, 0, 3;

  // No contact yet: kappa_min, and kappa_max = 100 kappa_min.
  double kappa_max = 0.0;
  const double kappa_min =
      initial_barrier_stiffness(bbox, dhat, mass, grad_e.setOnes(), Eigen::VectorXd::Zero(6),
                                kappa_max);
  CHECK(kappa_min > 0.0);
  CHECK(std::isfinite(kappa_min));
  // Exact up to a few roundings of products and quotients: 1e-15, relative (scale 0; the values
  // are far from 1, so doctest's default absolute term would dominate).
  auto relative = [](double value, double tolerance) {
    return doctest::Approx(value).epsilon(tolerance).scale(0.0);
  };
  CHECK(kappa_max == relative(100.0 * kappa_min, 1e-15));
  // kappa_min is linear in the average mass and in the scale.
  double unused = 0.0;
  CHECK(initial_barrier_stiffness(bbox, dhat, 2.0 * mass, grad_e, Eigen::VectorXd::Zero(6),
                                  unused) == relative(2.0 * kappa_min, 1e-15));
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, Eigen::VectorXd::Zero(6), unused,
                                  1e10) == relative(0.1 * kappa_min, 1e-15));

  // grad E = -k grad B: the balance is k (grad E . grad B) / |grad B|^2 for exactly proportional
  // vectors, two 6-term dot products of the same products: ~7 eps, hence 1e-14.
  for (double k : {2.0 * kappa_min, 10.0 * kappa_min, 99.0 * kappa_min}) {
    grad_e = -k * grad_b;
    CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) ==
          relative(k, 1e-14));
  }
  // Clamped: std::clamp returns the bound itself.
  grad_e = -1e-3 * kappa_min * grad_b;
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) == kappa_min);
  grad_e = 1e3 * kappa_min * grad_b;  // pointing the same way: the balance is negative
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) == kappa_min);
  grad_e = -1e3 * kappa_min * grad_b;
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) == kappa_max);

  // A dhat below the tiny reference gap still gives a finite positive stiffness.
  const double k_small = initial_barrier_stiffness(bbox, 1e-40, mass, grad_e,
                                                   Eigen::VectorXd::Zero(6), kappa_max);
  CHECK(std::isfinite(k_small));
  CHECK(k_small > 0.0);
}

TEST_CASE("barrier: stiffness doubles only while the gap keeps shrinking below dhat_epsilon") {
  const double bbox = 1.0, kappa = 10.0, kappa_max = 35.0;
  const double eps = 1e-9 * bbox;  // dhat_epsilon as a length; the API takes squared distances
  const double small = 0.5 * eps * eps, smaller = 0.25 * eps * eps;
  CHECK(update_barrier_stiffness(small, smaller, kappa_max, kappa, bbox) == 20.0);
  CHECK(update_barrier_stiffness(small, smaller, kappa_max, 20.0, bbox) == 35.0);  // capped
  CHECK(update_barrier_stiffness(smaller, small, kappa_max, kappa, bbox) == kappa);  // growing
  CHECK(update_barrier_stiffness(small, small, kappa_max, kappa, bbox) == kappa);    // stalled
  CHECK(update_barrier_stiffness(4.0 * eps * eps, smaller, kappa_max, kappa, bbox) == kappa);
  CHECK(update_barrier_stiffness(1.0, 0.5, kappa_max, kappa, bbox) == kappa);  // far apart
  // A larger epsilon scale moves the threshold.
  CHECK(update_barrier_stiffness(1e-10, 0.5e-10, kappa_max, kappa, bbox, 1e-4) == 20.0);
}

}  // namespace
}  // namespace nexdyn

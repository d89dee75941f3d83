// Tests of kernels/barrier: the clamped log barrier b(d) (on squared distances) against central
// differences, its values at the clamp and its behaviour as d -> 0, positivity and monotonicity;
// the adaptive stiffness helpers of the IPC supplemental (clamping, the gradient balance, the
// doubling rule).
#include "kernels/barrier/barrier.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>

#include <cmath>
#include <limits>
#include <random>

namespace nexdyn {
namespace {

TEST_CASE("barrier: derivatives match finite differences") {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double dhat : {1e-6, 1e-2, 1.0, 25.0}) {
    for (int trial = 0; trial < 200; ++trial) {
      // Spread d over many decades below dhat: d = dhat * 10^(-6 u), kept away from the clamp.
      const double d = dhat * std::pow(10.0, -6.0 * u(rng)) * 0.999;
      const double h = 1e-6 * d;
      const double db = barrier_first_derivative(d, dhat);
      const double db_fd = (barrier(d + h, dhat) - barrier(d - h, dhat)) / (2.0 * h);
      CHECK(db == doctest::Approx(db_fd).epsilon(1e-6).scale(1e-8 * dhat));
      const double d2b = barrier_second_derivative(d, dhat);
      const double d2b_fd =
          (barrier_first_derivative(d + h, dhat) - barrier_first_derivative(d - h, dhat)) /
          (2.0 * h);
      CHECK(d2b == doctest::Approx(d2b_fd).epsilon(1e-6).scale(1e-8));
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
  CHECK(barrier(1e-300, dhat) == doctest::Approx(dhat * dhat * std::log(dhat / 1e-300)).epsilon(1e-12));
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
  CHECK(kappa_max == doctest::Approx(100.0 * kappa_min));
  // kappa_min is linear in the average mass and in the scale.
  double unused = 0.0;
  CHECK(initial_barrier_stiffness(bbox, dhat, 2.0 * mass, grad_e, Eigen::VectorXd::Zero(6),
                                  unused) == doctest::Approx(2.0 * kappa_min));
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, Eigen::VectorXd::Zero(6), unused,
                                  1e10) == doctest::Approx(0.1 * kappa_min));

  // grad E = -k grad B: the balance is exactly k when k is within [kappa_min, kappa_max].
  for (double k : {2.0 * kappa_min, 10.0 * kappa_min, 99.0 * kappa_min}) {
    grad_e = -k * grad_b;
    CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) ==
          doctest::Approx(k));
  }
  grad_e = -1e-3 * kappa_min * grad_b;
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) ==
        doctest::Approx(kappa_min));
  grad_e = 1e3 * kappa_min * grad_b;  // pointing the same way: the balance is negative
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) ==
        doctest::Approx(kappa_min));
  grad_e = -1e3 * kappa_min * grad_b;
  CHECK(initial_barrier_stiffness(bbox, dhat, mass, grad_e, grad_b, kappa_max) ==
        doctest::Approx(kappa_max));

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

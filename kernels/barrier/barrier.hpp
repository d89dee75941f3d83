// The clamped log barrier of IPC and its adaptive stiffness (Li et al. 2020, "Incremental
// Potential Contact", eq. 6 and supplemental sec. 3 "barrier stiffness"; seed 001, the b(d) of
// "障碍函数").
//
// SQUARED distances throughout: d is a squared distance and dhat the squared activation distance
// (dhat = dhat_length^2), as the distance kernels of kernels/distance return squared values:
//   b(d) = -(d - dhat)^2 ln(d / dhat)  for 0 < d < dhat,   0 for d >= dhat,   +inf for d <= 0.
// b is positive and decreasing on (0, dhat) and unbounded as d -> 0, which is what keeps every
// Newton iterate intersection-free once CCD caps the step.
//   b'(d)  = -2 (d - dhat) ln(d / dhat) - (d - dhat)^2 / d,
//   b''(d) = -2 ln(d / dhat) - 4 (d - dhat) / d + (d - dhat)^2 / d^2.
// At d = dhat: b = b' = 0 and b'' = 0 as well, so the clamp adds no kink up to second order.
// For d <= 0 the derivatives return their limits (b' = -inf, b'' = +inf) so that a caller that
// mistakenly evaluates an intersecting pair sees a non-finite value rather than a silent zero.
#pragma once

#include <Eigen/Core>

#include <cmath>
#include <limits>

namespace nexdyn {

inline double barrier(double d, double dhat) {
  if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
  if (d >= dhat) return 0.0;
  const double dd = d - dhat;
  return -dd * dd * std::log(d / dhat);
}

inline double barrier_first_derivative(double d, double dhat) {
  if (!(d > 0.0)) return -std::numeric_limits<double>::infinity();
  if (d >= dhat) return 0.0;
  const double dd = d - dhat;
  return -2.0 * dd * std::log(d / dhat) - dd * dd / d;
}

// b, b' and b'' at once, from one logarithm (the mollified edge-edge stencil needs them
// together; log is most of their cost). Each is the same expression as in the functions above.
struct BarrierValues {
  double b, b1, b2;
};
inline BarrierValues barrier_values(double d, double dhat) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (!(d > 0.0)) return {kInf, -kInf, kInf};
  if (d >= dhat) return {0.0, 0.0, 0.0};
  const double dd = d - dhat;
  const double log_ratio = std::log(d / dhat);
  const double q = dd / d;
  return {-dd * dd * log_ratio, -2.0 * dd * log_ratio - dd * dd / d, -2.0 * log_ratio - 4.0 * q + q * q};
}

inline double barrier_second_derivative(double d, double dhat) {
  if (!(d > 0.0)) return std::numeric_limits<double>::infinity();
  if (d >= dhat) return 0.0;
  const double dd = d - dhat;
  const double q = dd / d;
  return -2.0 * std::log(d / dhat) - 4.0 * q + q * q;
}

// Initial barrier stiffness kappa_0 (IPC supplemental sec. 3, as in the authors' code):
//   d0 = (1e-8 bbox_diagonal)^2 (a squared distance far below any useful dhat; 0.5 dhat if not),
//   kappa_min = min_barrier_stiffness_scale * average_mass / (4 d0 b''(d0)),
// where 4 d0 b''(d0) ~ the curvature of b(|x|^2) along |x| at |x|^2 = d0, so that kappa_min makes
// the barrier as stiff as the inertia term (mass / dt^2 ~ scale * mass) at a tiny gap;
//   kappa_max = 100 kappa_min (written to max_barrier_stiffness);
//   kappa_0 = clamp(-(grad_energy . grad_barrier) / |grad_barrier|^2, kappa_min, kappa_max),
// the kappa that best balances the incremental potential's gradient against the barrier's
// (least squares on grad E + kappa grad B = 0); kappa_min if grad_barrier = 0 (no contact yet).
// grad_barrier is the gradient of sum_k b(d_k) WITHOUT kappa. Not for inner loops.
double initial_barrier_stiffness(double bbox_diagonal, double dhat, double average_mass,
                                 const Eigen::VectorXd& grad_energy,
                                 const Eigen::VectorXd& grad_barrier,
                                 double& max_barrier_stiffness,
                                 double min_barrier_stiffness_scale = 1e11);

// Stiffness update after each Newton iteration (IPC supplemental sec. 3): with the squared
// threshold dhat_epsilon = (dhat_epsilon_scale * bbox_diagonal)^2, kappa doubles (capped at
// max_barrier_stiffness) when the minimum squared distance is below dhat_epsilon and still
// shrinking, i.e. prev_min_distance < dhat_epsilon, min_distance < dhat_epsilon and
// min_distance < prev_min_distance; otherwise kappa is returned unchanged. prev_min_distance and
// min_distance are SQUARED distances (like everything here).
double update_barrier_stiffness(double prev_min_distance, double min_distance,
                                double max_barrier_stiffness, double kappa, double bbox_diagonal,
                                double dhat_epsilon_scale = 1e-9);

}  // namespace nexdyn

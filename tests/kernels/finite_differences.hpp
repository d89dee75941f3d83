// Central finite differences for the kernel tests (tests/kernels/*), with a step and a tolerance
// that follow the configuration, so that they also work on the ill-conditioned inputs contact and
// elasticity produce: nearly parallel edges, tiny edges, sliver and needle tets, neo-Hookean tets
// close to inversion.
//
// Error model. The central difference D(h) = (f(x + h e) - f(x - h e)) / (2 h) of a smooth f is
//   D(h) = f' + h^2 f'''/6 + h^4 f^(5)/120 + ...  plus rounding of about noise / h,
// where `noise` is the absolute rounding error of the computed f: eps |f| for a benign f, far
// more where f cancels (a distance between nearly parallel edges computed from a normal that is
// the small difference of O(1) products; an energy of a sliver tet whose F is the difference of
// O(1) positions times a large Dm^-1). Richardson's combination R(h) = (4 D(h/2) - D(h)) / 3
// cancels the h^2 term. What is left:
//   truncation  ~h^4 f^(5) / 480, measured rather than guessed: R(h) - R(h/2) is 15/16 of it
//               (one more difference at h/4), and a wrong analytic derivative does not enter it;
//   rounding    ~3 noise / h, from the budget's a-priori noise (10x safety: the noise is an
//               estimate of a worst case, and R(h) - R(h/2) sees only one sample of it).
// The tolerance is 2 |R(h) - R(h/2)| + 30 noise / (h |D|) + the analytic derivative's own
// rounding (`analytic`, relative), which for ill-conditioned inputs can exceed what differences
// resolve. Relative errors are taken in the Frobenius norm against max(|analytic|, |R(h)|, floor):
// the difference estimate in the scale keeps a wrong analytic derivative that is too small from
// inflating the tolerance.
//
// Step. f varies on a length scale ell (the smallest feature of the configuration: a sliver's
// height, the offset of nearly parallel edges, sigma_min of F over |Dm^-1|): the truncation of R
// at h = alpha ell is about alpha^4 / 480 and the rounding 3 noise / (alpha ell |D|), and the
// first step balances the two. Where the measured truncation still dominates the rounding
// allowance (the derivative is small against f's variation on ell, or ell was a guess), the step
// is cut by 4, up to 8 times, each cut dividing the truncation by 256, until that allowance is
// reached or a cut stops paying; the step with the smallest tolerance is kept. Neither the step
// nor the tolerance depends on the analytic derivative beyond its norm, so a wrong one is not
// excused.
//
// Steps are taken as x_i +- h rounded to doubles and the difference is divided by the step
// actually taken, (x_i + h) - (x_i - h), so the rounding of x_i +- h (relative eps |x_i| / h of
// the step) is not an error.
//
// A rate-based check comes with it: where the plain central difference is dominated by truncation,
// halving h must cut its error about 4x (second order). A wrong derivative (error delta) gives a
// ratio near 1 once delta dominates; Result::second_order() tests this.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>
#include <ostream>

namespace nexdyn::fd {

template <int N>
using Vector = Eigen::Matrix<double, N, 1>;

inline constexpr double kEps = std::numeric_limits<double>::epsilon();

// d f / d x_i by central differences; f maps Vector<N> to double.
template <int N, typename F>
Vector<N> gradient(const F& f, const Vector<N>& x, double h) {
  Vector<N> g;
  for (int i = 0; i < N; ++i) {
    Vector<N> xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    g(i) = (f(xp) - f(xm)) / (xp(i) - xm(i));
  }
  return g;
}

// Column i is d g / d x_i; g maps Vector<N> to a fixed-size vector (a gradient).
template <int N, typename G>
auto jacobian(const G& g, const Vector<N>& x, double h) {
  using Out = decltype(g(x));
  Eigen::Matrix<double, Out::RowsAtCompileTime, N> J;
  for (int i = 0; i < N; ++i) {
    Vector<N> xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    J.col(i) = (g(xp) - g(xm)) / (xp(i) - xm(i));
  }
  return J;
}

// What a configuration lets finite differences resolve (see the top).
struct Budget {
  double ell = 1.0;       // length scale on which the differenced function varies
  double noise = 0.0;     // absolute rounding error of the differenced function's values
  double analytic = 0.0;  // relative rounding error of the analytic derivative
  double floor = 0.0;     // errors are relative to max(|analytic derivative|, floor)
};

struct Result {
  double error = 0.0;       // relative error of R(h)
  double tolerance = 0.0;   // what the budget and the measured truncation allow
  double truncation = 0.0;  // |R(h) - R(h/2)|, relative
  double at_h = 0.0;        // relative error of D(h)
  double at_half_h = 0.0;   // relative error of D(h/2)
  double h = 0.0;
  bool ok() const { return error <= tolerance; }
  // Second order where truncation dominates D(h): halving h cuts its error at least 3x.
  bool second_order() const { return at_h <= 30.0 * tolerance || at_half_h <= at_h / 3.0; }
};

inline std::ostream& operator<<(std::ostream& os, const Result& r) {
  return os << "error " << r.error << " (tolerance " << r.tolerance << "; truncation "
            << r.truncation << "), D(h) " << r.at_h << ", D(h/2) " << r.at_half_h << ", h "
            << r.h;
}

// The first step: alpha = (360 noise / (ell |D|))^(1/5) balances the estimates; clamped to
// [1e-4, 0.05] (beyond 0.05 the truncation's series is not to be trusted; below 1e-4 of the
// feature rounding wins anyway).
inline double step(const Budget& b, double derivative_norm) {
  const double d = std::max(derivative_norm, b.floor);
  const double alpha = std::clamp(std::pow(360.0 * b.noise / (b.ell * d), 0.2), 1e-4, 0.05);
  return alpha * b.ell;
}

// Compares `analytic` with the finite-difference estimates fd(h) (a callable returning the same
// shape as `analytic`) at the budget's step.
template <typename A, typename Fd>
Result check(const A& analytic, const Fd& fd, const Budget& b) {
  Result best;
  best.tolerance = std::numeric_limits<double>::infinity();
  double h = step(b, analytic.norm());
  double previous_truncation = std::numeric_limits<double>::infinity();
  for (int attempt = 0; attempt <= 8; ++attempt, h *= 0.25) {
    const auto d1 = fd(h);
    const auto d2 = fd(0.5 * h);
    const auto d4 = fd(0.25 * h);
    const auto r1 = ((4.0 * d2 - d1) / 3.0).eval();
    const auto r2 = ((4.0 * d4 - d2) / 3.0).eval();
    const double scale = std::max({analytic.norm(), r1.norm(), b.floor});
    const double rounding = 30.0 * b.noise / (h * scale);
    Result r;
    r.h = h;
    r.error = (r1 - analytic).norm() / scale;
    r.truncation = (r1 - r2).norm() / scale;
    r.at_h = (d1 - analytic).norm() / scale;
    r.at_half_h = (d2 - analytic).norm() / scale;
    // 1e-12: rounding of the norms and of the combinations themselves.
    r.tolerance = 2.0 * r.truncation + rounding + b.analytic + 1e-12;
    if (r.tolerance < best.tolerance) best = r;
    // Done once the truncation is within the rounding allowance, or once cutting the step stops
    // paying (a truncation-dominated estimate falls 256x per cut; one dominated by rounding
    // grows).
    if (r.truncation <= rounding + 1e-12 || r.truncation > previous_truncation / 16.0) break;
    previous_truncation = r.truncation;
  }
  return best;
}

}  // namespace nexdyn::fd

// Independent reference for the CCD tests (tests/kernels/ccd/test_ccd.cpp): the distance between
// two linearly moving primitives over time, and the first time it comes down to a given level.
//
// The distance comes from the barrier's kernels (kernels/distance: squared distances by
// closest-feature classification, tested there against a direct minimisation over barycentric
// parameters), not from kernels/ccd/ccd_distance.hpp, so a mistake in the CCD's own distance
// bounds shows up as a disagreement instead of being shared by the CCD and its test.
//
// The search samples the time interval on a uniform grid and bisects wherever the samples cannot
// decide, using a Lipschitz bound of the distance along the motion. With x_i(t) = x0_i + t d_i,
// the distance is D(t) = min |a(t) - b(t)| over points a of one primitive and b of the other, each
// a fixed convex combination of the corners, so d/dt (a - b) is a convex combination of the
// corner velocity differences d_i - d_j (i on one primitive, j on the other) and
//   |D'(t)| <= L = max_ij |d_i - d_j|
// (a minimum of L-Lipschitz functions is L-Lipschitz). Two samples D(a), D(b) therefore bound D
// on [a, b] from below by (D(a) + D(b) - L (b - a)) / 2, where the two cones meet; sampling at
// step h misses at most L h / 2 of the minimum. An interval is accepted as "above the level" only
// when that bound proves it, otherwise it is bisected until L (b - a) <= kResolution = 1e-12, so
// "above the level" means D > level - kResolution / 2 (plus the rounding of D, ~1e-15 here): the
// sampling costs no tolerance beyond that. Bisection stops there rather than at a fixed depth
// because the rounding of D would otherwise decide the last steps near a crossing whose slope is
// exactly L. Test code: recursion, and no effort to be fast beyond pruning.
#pragma once

#include "kernels/distance/distance_primitives.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>

namespace nexdyn::ccd_reference {

enum class PairKind { point_triangle, edge_edge, point_plane };

// A CCD query: corners at t = 0 and t = 1, in the argument order of kernels/ccd/ccd.hpp.
//   point_triangle: p, t0, t1, t2.   edge_edge: ea0, ea1, eb0, eb1.
//   point_plane: p (moving); x0[1] = x1[1] = plane point, x0[2] = x1[2] = unit normal (static).
struct LinearMotion {
  PairKind kind = PairKind::point_triangle;
  std::array<Eigen::Vector3d, 4> x0, x1;
};

inline Eigen::Vector3d position(const LinearMotion& m, int i, double t) {
  return m.x0[i] + t * (m.x1[i] - m.x0[i]);
}

// Distance (not squared) at time t, from kernels/distance.
inline double reference_distance(const LinearMotion& m, double t) {
  switch (m.kind) {
    case PairKind::point_triangle:
      return std::sqrt(point_triangle_distance(position(m, 0, t), position(m, 1, t), position(m, 2, t),
                                               position(m, 3, t)));
    case PairKind::edge_edge:
      return std::sqrt(edge_edge_distance(position(m, 0, t), position(m, 1, t), position(m, 2, t),
                                          position(m, 3, t)));
    case PairKind::point_plane:
      return std::sqrt(point_obstacle_plane_distance(position(m, 0, t), m.x0[1], m.x0[2]));
  }
  return 0.0;
}

// L = max |d_i - d_j| over corners i of the first primitive and j of the second (see the top);
// for the static plane, the normal speed of the point.
inline double distance_lipschitz(const LinearMotion& m) {
  if (m.kind == PairKind::point_plane) return std::abs((m.x1[0] - m.x0[0]).dot(m.x0[2]));
  const int num_first = m.kind == PairKind::point_triangle ? 1 : 2;
  double lipschitz = 0.0;
  for (int i = 0; i < num_first; ++i) {
    for (int j = num_first; j < 4; ++j) {
      const Eigen::Vector3d relative = (m.x1[i] - m.x0[i]) - (m.x1[j] - m.x0[j]);
      lipschitz = std::max(lipschitz, relative.norm());
    }
  }
  return lipschitz;
}

enum class Crossing {
  none,       // D > level - kResolution / 2 on the whole interval (certified by the Lipschitz bound)
  found,      // D(t) <= level, and D > level - kResolution / 2 on [t_begin, t)
  undecided,  // the evaluation budget ran out (D grazing the level over a long time)
};

struct CrossingSearch {
  Crossing kind = Crossing::none;
  double t = 0.0;
  long evaluations = 0;
};

namespace detail {

inline constexpr int kGridIntervals = 256;
inline constexpr double kResolution = 1e-12;  // in distance: bisect while L (b - a) exceeds it
inline constexpr long kMaxEvaluations = 2'000'000;

// Earliest t in [a, b] with f(t) <= level, given f(a) = fa > level and f(b) = fb.
template <typename F>
Crossing refine(const F& f, double lipschitz, double level, double a, double b, double fa, double fb,
                CrossingSearch& out) {
  // The cones from (a, fa) and (b, fb) with slope L meet above the level: f > level on [a, b].
  if (fb > level && (fa - level) + (fb - level) > lipschitz * (b - a)) return Crossing::none;
  const double mid = 0.5 * (a + b);
  // Resolved: f >= min(fa, fb) - L (b - a) / 2 on [a, b].
  if (lipschitz * (b - a) <= kResolution || !(a < mid && mid < b)) {
    if (fb > level) return Crossing::none;
    out.t = b;
    return Crossing::found;
  }
  if (out.evaluations >= kMaxEvaluations) return Crossing::undecided;
  const double fmid = f(mid);
  ++out.evaluations;
  const Crossing left = refine(f, lipschitz, level, a, mid, fa, fmid, out);
  if (left != Crossing::none) return left;
  if (fmid <= level) {
    out.t = mid;
    return Crossing::found;
  }
  return refine(f, lipschitz, level, mid, b, fmid, fb, out);
}

}  // namespace detail

// Earliest time in [t_begin, t_end] where f <= level, f being L-Lipschitz (see the top).
template <typename F>
CrossingSearch first_at_or_below(const F& f, double lipschitz, double t_begin, double t_end, double level) {
  CrossingSearch out;
  double a = t_begin;
  double fa = f(a);
  ++out.evaluations;
  if (fa <= level) {
    out.kind = Crossing::found;
    out.t = a;
    return out;
  }
  for (int k = 1; k <= detail::kGridIntervals; ++k) {
    const double b = k == detail::kGridIntervals
                         ? t_end
                         : t_begin + (t_end - t_begin) * double(k) / detail::kGridIntervals;
    const double fb = f(b);
    ++out.evaluations;
    out.kind = detail::refine(f, lipschitz, level, a, b, fa, fb, out);
    if (out.kind != Crossing::none) return out;
    a = b;
    fa = fb;
  }
  return out;
}

}  // namespace nexdyn::ccd_reference

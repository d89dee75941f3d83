// Private distance code of the CCD: point-segment, point-triangle and segment-segment distances,
// each returned as a certified LOWER BOUND of the exact distance (the floating-point estimate minus
// a bound on its rounding error). The CCD only ever needs "the primitives are at least this far
// apart", so underestimating is safe and overestimating is the one thing to avoid: a distance that
// is too large would let the additive CCD step past a contact (a false negative).
//
// Closest-feature handling follows the usual decomposition (Ericson, "Real-Time Collision
// Detection", 2005, sections 5.1.2, 5.1.5, 5.1.9): the interior case is a plane or line distance,
// every other case is the minimum over the boundary features. The error model is a first-order
// bound, with generous constants: differences of coordinates carry ~eps * scale, and the normal of
// a nearly degenerate triangle or of two nearly parallel edges loses ~eps / sin(angle) of relative
// accuracy; below a threshold angle we switch to the boundary features and pay the (bounded) width
// of the degenerate configuration instead.
//
// Deliberately independent of kernels/distance (the barrier's distances): the CCD needs error
// bounds, not derivatives. Internal to kernels/ccd; no allocation, no exceptions.
//
// Templates on the scalar T: double for the CCD itself, long double (x87, 64-bit mantissa on
// x86-64) for the refinement of touching queries (ccd.hpp). The error model is the same in units
// of T's epsilon.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn::ccd_detail {

template <typename T>
using Vec3T = Eigen::Matrix<T, 3, 1>;
using Vec3 = Vec3T<double>;

template <typename T>
inline constexpr T kEpsOf = std::numeric_limits<T>::epsilon();
inline constexpr double kEps = kEpsOf<double>;
// Rounding of one evaluation: positions x0 + t (x1 - x0) (3 roundings per coordinate), one
// difference, a norm. 64 eps * scale is an order of magnitude above the first-order error.
template <typename T>
inline constexpr T kBaseSlackOf = 64 * kEpsOf<T>;
inline constexpr double kBaseSlack = kBaseSlackOf<double>;
// sin^2 of the angle below which a triangle counts as degenerate / two edges as parallel.
// At sin = 3e-8 (double) the two error terms (normal inaccuracy ~eps/sin, width of the degenerate
// configuration ~sin * length) are both ~1e-7 of the scale; for ordinary inputs neither applies.
// In units of eps, so the balance point moves with the precision.
template <typename T>
inline constexpr T kDegenerateSin2Of = T(1e-15) * (kEpsOf<T> / kEpsOf<double>);

// Exact-arithmetic distance from p to segment [a, b] (degenerate segments allowed), as computed.
// The rounding error is O(eps * scale) in every branch; callers add it.
template <typename T>
T point_segment_distance(const Vec3T<T>& p, const Vec3T<T>& a, const Vec3T<T>& b) {
  using Vec3 = Vec3T<T>;
  const Vec3 ab = b - a, ap = p - a;
  const T len2 = ab.squaredNorm();
  const T s = ap.dot(ab);
  if (s <= 0.0 || len2 == 0.0) return ap.norm();
  if (s >= len2) return (p - b).norm();
  // |ap x ab| / |ab| rather than |ap - s ab|: no cancellation in the squared form.
  return ap.cross(ab).norm() / std::sqrt(len2);
}

// Lower bound of the distance from p to triangle (a, b, c); `scale` bounds the absolute value of
// every coordinate involved (it sets the absolute rounding error).
template <typename T>
T point_triangle_distance_lower(const Vec3T<T>& p, const Vec3T<T>& a, const Vec3T<T>& b, const Vec3T<T>& c,
                                T scale) {
  using Vec3 = Vec3T<T>;
  constexpr T eps = kEpsOf<T>;
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Vec3 n = ab.cross(ac);
  const T n2 = n.squaredNorm();
  const T ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
  const T base = kBaseSlackOf<T> * scale;
  if (n2 > kDegenerateSin2Of<T> * ab2 * ac2) {
    // Barycentric signs of p's projection, from the sub-triangle normals dotted with n.
    const T wa = (b - p).cross(c - p).dot(n);
    const T wb = (c - p).cross(a - p).dot(n);
    const T wc = (a - p).cross(b - p).dot(n);
    if (wa >= 0 && wb >= 0 && wc >= 0) {
      const T inv_n = 1 / std::sqrt(n2);
      const T d = std::abs(ap.dot(n)) * inv_n;
      // n carries an absolute error ~4 eps |ab| |ac|, i.e. a relative one of 4 eps / sin(angle a).
      const T err = base + 16 * eps * ap.norm() * std::sqrt(ab2 * ac2) * inv_n;
      return d - err;
    }
    const T d = std::min({point_segment_distance<T>(p, a, b), point_segment_distance<T>(p, b, c),
                          point_segment_distance<T>(p, c, a)});
    return d - base;
  }
  // Degenerate (needle or cap) triangle: the edges are within the triangle's width of any
  // interior point. Width <= |n| / max edge <= sqrt(n2) / sqrt(max(ab2, ac2)).
  const T d = std::min({point_segment_distance<T>(p, a, b), point_segment_distance<T>(p, b, c),
                        point_segment_distance<T>(p, c, a)});
  const T longest = std::sqrt(std::max({ab2, ac2, (c - b).squaredNorm()}));
  const T width = longest > 0 ? std::sqrt(n2) / longest : T(0);
  return d - base - 2 * width;
}

// Lower bound of the distance between segments [a0, a1] and [b0, b1].
template <typename T>
T edge_edge_distance_lower(const Vec3T<T>& a0, const Vec3T<T>& a1, const Vec3T<T>& b0, const Vec3T<T>& b1,
                           T scale) {
  using Vec3 = Vec3T<T>;
  constexpr T eps = kEpsOf<T>;
  const Vec3 da = a1 - a0, db = b1 - b0, w = b0 - a0;
  const Vec3 n = da.cross(db);
  const T n2 = n.squaredNorm();
  const T da2 = da.squaredNorm(), db2 = db.squaredNorm();
  const T base = kBaseSlackOf<T> * scale;
  const T boundary = std::min({point_segment_distance<T>(a0, b0, b1), point_segment_distance<T>(a1, b0, b1),
                               point_segment_distance<T>(b0, a0, a1), point_segment_distance<T>(b1, a0, a1)});
  if (n2 > kDegenerateSin2Of<T> * da2 * db2) {
    // Closest points of the two lines: a0 + s da and b0 + t db, with s n2 = (w x db).n and
    // t n2 = (w x da).n. Inside the unit square the segment distance is the line distance.
    const T s_n2 = w.cross(db).dot(n), t_n2 = w.cross(da).dot(n);
    if (s_n2 >= 0 && s_n2 <= n2 && t_n2 >= 0 && t_n2 <= n2) {
      const T inv_n = 1 / std::sqrt(n2);
      const T d = std::abs(w.dot(n)) * inv_n;
      const T err = base + 16 * eps * w.norm() * std::sqrt(da2 * db2) * inv_n;
      // The boundary minimum is also >= the true distance up to `base`; take the smaller bound.
      return std::min(d - err, boundary - base);
    }
    return boundary - base;
  }
  // Nearly parallel: the interior minimum, if any, is below the boundary minimum by at most the
  // drift of the connecting vector along the overlap, <= max length * sin(angle).
  const T longest = std::sqrt(std::max(da2, db2));
  const T sin_angle = (da2 > 0 && db2 > 0) ? std::sqrt(n2 / (da2 * db2)) : T(0);
  return boundary - base - 2 * longest * sin_angle;
}

}  // namespace nexdyn::ccd_detail

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
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross()

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn::ccd_detail {

using Vec3 = Eigen::Vector3d;

inline constexpr double kEps = std::numeric_limits<double>::epsilon();
// Rounding of one evaluation: positions x0 + t (x1 - x0) (3 roundings per coordinate), one
// difference, a norm. 64 eps * scale is an order of magnitude above the first-order error.
inline constexpr double kBaseSlack = 64.0 * kEps;
// sin^2 of the angle below which a triangle counts as degenerate / two edges as parallel.
// At sin = 3e-8 the two error terms (normal inaccuracy ~eps/sin, width of the degenerate
// configuration ~sin * length) are both ~1e-7 of the scale; for ordinary inputs neither applies.
inline constexpr double kDegenerateSin2 = 1e-15;

// Exact-arithmetic distance from p to segment [a, b] (degenerate segments allowed), as computed.
// The rounding error is O(eps * scale) in every branch; callers add it.
inline double point_segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a, ap = p - a;
  const double len2 = ab.squaredNorm();
  const double s = ap.dot(ab);
  if (s <= 0.0 || len2 == 0.0) return ap.norm();
  if (s >= len2) return (p - b).norm();
  // |ap x ab| / |ab| rather than |ap - s ab|: no cancellation in the squared form.
  return ap.cross(ab).norm() / std::sqrt(len2);
}

// Lower bound of the distance from p to triangle (a, b, c); `scale` bounds the absolute value of
// every coordinate involved (it sets the absolute rounding error).
inline double point_triangle_distance_lower(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                            double scale) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Vec3 n = ab.cross(ac);
  const double n2 = n.squaredNorm();
  const double ab2 = ab.squaredNorm(), ac2 = ac.squaredNorm();
  const double base = kBaseSlack * scale;
  if (n2 > kDegenerateSin2 * ab2 * ac2) {
    // Barycentric signs of p's projection, from the sub-triangle normals dotted with n.
    const double wa = (b - p).cross(c - p).dot(n);
    const double wb = (c - p).cross(a - p).dot(n);
    const double wc = (a - p).cross(b - p).dot(n);
    if (wa >= 0.0 && wb >= 0.0 && wc >= 0.0) {
      const double inv_n = 1.0 / std::sqrt(n2);
      const double d = std::abs(ap.dot(n)) * inv_n;
      // n carries an absolute error ~4 eps |ab| |ac|, i.e. a relative one of 4 eps / sin(angle a).
      const double err = base + 16.0 * kEps * ap.norm() * std::sqrt(ab2 * ac2) * inv_n;
      return d - err;
    }
    const double d = std::min({point_segment_distance(p, a, b), point_segment_distance(p, b, c),
                               point_segment_distance(p, c, a)});
    return d - base;
  }
  // Degenerate (needle or cap) triangle: the edges are within the triangle's width of any
  // interior point. Width <= |n| / max edge <= sqrt(n2) / sqrt(max(ab2, ac2)).
  const double d = std::min({point_segment_distance(p, a, b), point_segment_distance(p, b, c),
                             point_segment_distance(p, c, a)});
  const double longest = std::sqrt(std::max({ab2, ac2, (c - b).squaredNorm()}));
  const double width = longest > 0.0 ? std::sqrt(n2) / longest : 0.0;
  return d - base - 2.0 * width;
}

// Lower bound of the distance between segments [a0, a1] and [b0, b1].
inline double edge_edge_distance_lower(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                                       double scale) {
  const Vec3 da = a1 - a0, db = b1 - b0, w = b0 - a0;
  const Vec3 n = da.cross(db);
  const double n2 = n.squaredNorm();
  const double da2 = da.squaredNorm(), db2 = db.squaredNorm();
  const double base = kBaseSlack * scale;
  const double boundary = std::min({point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
                                    point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)});
  if (n2 > kDegenerateSin2 * da2 * db2) {
    // Closest points of the two lines: a0 + s da and b0 + t db, with s n2 = (w x db).n and
    // t n2 = (w x da).n. Inside the unit square the segment distance is the line distance.
    const double s_n2 = w.cross(db).dot(n), t_n2 = w.cross(da).dot(n);
    if (s_n2 >= 0.0 && s_n2 <= n2 && t_n2 >= 0.0 && t_n2 <= n2) {
      const double inv_n = 1.0 / std::sqrt(n2);
      const double d = std::abs(w.dot(n)) * inv_n;
      const double err = base + 16.0 * kEps * w.norm() * std::sqrt(da2 * db2) * inv_n;
      // The boundary minimum is also >= the true distance up to `base`; take the smaller bound.
      return std::min(d - err, boundary - base);
    }
    return boundary - base;
  }
  // Nearly parallel: the interior minimum, if any, is below the boundary minimum by at most the
  // drift of the connecting vector along the overlap, <= max length * sin(angle).
  const double longest = std::sqrt(std::max(da2, db2));
  const double sin_angle = (da2 > 0.0 && db2 > 0.0) ? std::sqrt(n2 / (da2 * db2)) : 0.0;
  return boundary - base - 2.0 * longest * sin_angle;
}

}  // namespace nexdyn::ccd_detail

// Exact triangle-triangle intersection, the surface self-intersection check built on it, and the
// winding-number inside test.
//
// Why edges: two closed triangles in different planes meet along the line L where the planes
// cross; each triangle cuts L in an interval whose end points lie on the triangle's edges, and
// two intervals that overlap contain an end point of one of them. In a common plane, overlapping
// triangles either have crossing edges or one contains a vertex (an edge end point) of the other.
// So the triangles meet iff one of the 6 edges meets the other closed triangle, and each of those
// tests needs only signs of orientation determinants, no constructed points. With exact signs the
// answer is exact (Shewchuk 1997 for the predicates; the edge-triangle test is the classic
// Plücker/orientation form, e.g. Ericson, "Real-Time Collision Detection", 5.3.4).
#include "engine/mesh/intersection.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "engine/parallel.hpp"

namespace nexdyn {
namespace {

using Eigen::Vector3d;

// ---- Exact arithmetic on floating-point expansions (Shewchuk 1997, sections 2.5-2.8) ----------

constexpr double kEpsilon = 0x1p-53;  // unit round-off of double
// Static error bounds ("errboundA"): when |det| exceeds bound * permanent, the double sign is
// right. They assume plain rounding of every operation; an FMA contracted by the compiler
// (-march=native) rounds less, which the bounds still cover.
constexpr double kOrient3dBound = (7.0 + 56.0 * kEpsilon) * kEpsilon;
constexpr double kOrient2dBound = (3.0 + 16.0 * kEpsilon) * kEpsilon;

// s + e == a + b exactly (Knuth's TwoSum: no assumption on the magnitudes).
inline void two_sum(double a, double b, double& s, double& e) {
  s = a + b;
  const double bv = s - a;
  const double av = s - bv;
  e = (a - av) + (b - bv);
}

// p + e == a * b exactly (barring underflow): the FMA computes the product's rounding error.
inline void two_product(double a, double b, double& p, double& e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

// A sum of doubles kept exactly as a nonoverlapping expansion, components in increasing
// magnitude with zeros eliminated (Grow-Expansion). Capacity N >= number of added doubles.
template <int N>
struct ExactSum {
  double c[N];
  int n = 0;

  void add(double b) {
    int m = 0;
    double q = b;
    for (int i = 0; i < n; ++i) {
      double s;
      double e;
      two_sum(q, c[i], s, e);
      if (e != 0.0) c[m++] = e;
      q = s;
    }
    if (q != 0.0) c[m++] = q;
    n = m;
  }
  // The largest component decides the sign of a nonoverlapping expansion.
  int sign() const { return n == 0 ? 0 : (c[n - 1] > 0.0 ? 1 : -1); }
};

inline int sign_of(double v) { return (v > 0.0) - (v < 0.0); }

// det[u; v; w] of rows whose entries are given as exact two-term sums (hi, lo), for example
// (b - a) from two_sum(b, -a). Every term of the Leibniz formula expands into 8 products of
// three doubles, each exactly 4 doubles: 6 * 8 * 4 = 192 components at most.
int orient3d_exact(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  const Vector3d* points[3] = {&b, &c, &d};
  double rows[3][3][2];
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) two_sum((*points[i])[k], -a[k], rows[i][k][0], rows[i][k][1]);
  // Column permutations: the first three even, the last three odd.
  constexpr int kPermutations[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1},
                                       {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  ExactSum<192> det;
  for (int s = 0; s < 6; ++s) {
    const double sign = s < 3 ? 1.0 : -1.0;
    for (int bits = 0; bits < 8; ++bits) {
      const double x = sign * rows[0][kPermutations[s][0]][bits & 1];
      const double y = rows[1][kPermutations[s][1]][(bits >> 1) & 1];
      const double z = rows[2][kPermutations[s][2]][(bits >> 2) & 1];
      // A zero factor adds nothing. Common: an exact difference has lo = 0, and points on an
      // axis-aligned plane make a whole column 0, which leaves nothing at all to add.
      if (x == 0.0 || y == 0.0 || z == 0.0) continue;
      double p;
      double e;
      two_product(x, y, p, e);
      double t[4];
      two_product(p, z, t[0], t[1]);
      two_product(e, z, t[2], t[3]);
      for (double v : t)
        if (v != 0.0) det.add(v);
    }
  }
  return det.sign();
}

// Points of a plane projected to 2D by dropping one axis.
struct Point2 {
  double x;
  double y;
};

inline Point2 drop_axis(const Vector3d& p, int axis) {
  return {p[(axis + 1) % 3], p[(axis + 2) % 3]};
}

int orient2d_exact(const Point2& a, const Point2& b, const Point2& c) {
  double u[2][2];  // (b - a) as (hi, lo) per coordinate
  double v[2][2];  // (c - a)
  two_sum(b.x, -a.x, u[0][0], u[0][1]);
  two_sum(b.y, -a.y, u[1][0], u[1][1]);
  two_sum(c.x, -a.x, v[0][0], v[0][1]);
  two_sum(c.y, -a.y, v[1][0], v[1][1]);
  ExactSum<16> det;  // u.x v.y - u.y v.x: 2 terms x 4 products x 2 doubles
  for (int bits = 0; bits < 4; ++bits) {
    const int i = bits & 1;
    const int j = bits >> 1;
    double p;
    double e;
    two_product(u[0][i], v[1][j], p, e);
    det.add(p);
    det.add(e);
    two_product(-u[1][i], v[0][j], p, e);
    det.add(p);
    det.add(e);
  }
  return det.sign();
}

// Sign of det[b - a, c - a] in 2D: +1 when (a, b, c) turn counterclockwise.
int orient2d_sign(const Point2& a, const Point2& b, const Point2& c) {
  const double left = (b.x - a.x) * (c.y - a.y);
  const double right = (b.y - a.y) * (c.x - a.x);
  const double det = left - right;
  if (std::abs(det) > kOrient2dBound * (std::abs(left) + std::abs(right))) return sign_of(det);
  // On a line x = const or y = const (grid lines of an axis-aligned mesh): exactly 0.
  if ((b.x == a.x && c.x == a.x) || (b.y == a.y && c.y == a.y)) return 0;
  return orient2d_exact(a, b, c);
}

// ---- Edge against triangle ---------------------------------------------------------------------

// Closed segments pq and rs of a plane share a point.
bool segments_meet_2d(const Point2& p, const Point2& q, const Point2& r, const Point2& s) {
  const int o1 = orient2d_sign(p, q, r);
  const int o2 = orient2d_sign(p, q, s);
  const int o3 = orient2d_sign(r, s, p);
  const int o4 = orient2d_sign(r, s, q);
  if (o1 * o2 > 0 || o3 * o4 > 0) return false;  // one segment strictly on one side of the other
  if (o1 == 0 && o2 == 0) {
    // All four points on one line (or pq is a point): the intervals overlap iff their boxes do.
    return std::max(p.x, q.x) >= std::min(r.x, s.x) && std::max(r.x, s.x) >= std::min(p.x, q.x) &&
           std::max(p.y, q.y) >= std::min(r.y, s.y) && std::max(r.y, s.y) >= std::min(p.y, q.y);
  }
  return true;
}

// Closed triangle abc (non-zero area) contains p: p is on no strict outer side of an edge.
bool triangle_contains_2d(const Point2& a, const Point2& b, const Point2& c, const Point2& p) {
  const int s0 = orient2d_sign(a, b, p);
  const int s1 = orient2d_sign(b, c, p);
  const int s2 = orient2d_sign(c, a, p);
  const bool some_positive = s0 > 0 || s1 > 0 || s2 > 0;
  const bool some_negative = s0 < 0 || s1 < 0 || s2 < 0;
  return !(some_positive && some_negative);
}

// The axes to project triangle abc's plane along, the one of the largest normal component first.
// Any axis whose projection keeps the triangle's area gives the same answers; the largest one is
// the best conditioned, and an axis the plane is parallel to (a zero normal component, as on every
// face of an axis-aligned box) would cost an exact evaluation of a 0 before being skipped.
std::array<int, 3> projection_order(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  const Vector3d n = (b - a).cross(c - a).cwiseAbs();
  std::array<int, 3> order = {0, 1, 2};
  if (n[order[1]] > n[order[0]]) std::swap(order[0], order[1]);
  if (n[order[2]] > n[order[1]]) std::swap(order[1], order[2]);
  if (n[order[1]] > n[order[0]]) std::swap(order[0], order[1]);
  return order;
}

// Segment pq lying exactly in the plane of triangle abc meets the closed triangle. The plane is
// projected along an axis it is not parallel to (exact projected area non-zero), which maps it
// one-to-one onto 2D, so the 2D answer is the 3D one. A zero-area triangle has no such axis:
// false (the caller tests its edges instead).
bool coplanar_segment_meets_triangle(const Vector3d& p, const Vector3d& q, const Vector3d& a,
                                     const Vector3d& b, const Vector3d& c) {
  for (const int axis : projection_order(a, b, c)) {
    const Point2 a2 = drop_axis(a, axis);
    const Point2 b2 = drop_axis(b, axis);
    const Point2 c2 = drop_axis(c, axis);
    if (orient2d_sign(a2, b2, c2) == 0) continue;
    const Point2 p2 = drop_axis(p, axis);
    const Point2 q2 = drop_axis(q, axis);
    // Both ends outside yet touching means crossing the boundary.
    return triangle_contains_2d(a2, b2, c2, p2) || triangle_contains_2d(a2, b2, c2, q2) ||
           segments_meet_2d(p2, q2, a2, b2) || segments_meet_2d(p2, q2, b2, c2) ||
           segments_meet_2d(p2, q2, c2, a2);
  }
  return false;
}

// Closed segment pq meets closed triangle abc; sp, sq: orient3d_sign(a, b, c, p or q).
bool segment_meets_triangle(const Vector3d& p, const Vector3d& q, int sp, int sq,
                            const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  if (sp * sq > 0) return false;  // both ends strictly on one side of the plane
  if (sp == 0 && sq == 0) return coplanar_segment_meets_triangle(p, q, a, b, c);
  // pq reaches the plane in exactly one point X. The line pq passes the three edge lines on the
  // same side (zeros allowed: X on an edge or at a vertex) iff X is in the closed triangle.
  const int s0 = orient3d_sign(p, q, a, b);
  const int s1 = orient3d_sign(p, q, b, c);
  const int s2 = orient3d_sign(p, q, c, a);
  const bool some_positive = s0 > 0 || s1 > 0 || s2 > 0;
  const bool some_negative = s0 < 0 || s1 < 0 || s2 < 0;
  return !(some_positive && some_negative);
}

// x lies in the plane of triangle (v, c, d) (non-zero area): does the ray from v through x start
// into the triangle, i.e. does x - v lie in its closed corner at v? Decided in a projection that
// keeps the plane one-to-one, as in coplanar_segment_meets_triangle.
bool direction_in_corner(const Vector3d& v, const Vector3d& x, const Vector3d& c,
                         const Vector3d& d) {
  for (const int axis : projection_order(v, c, d)) {
    const Point2 v2 = drop_axis(v, axis);
    const Point2 c2 = drop_axis(c, axis);
    const Point2 d2 = drop_axis(d, axis);
    const int turn = orient2d_sign(v2, c2, d2);
    if (turn == 0) continue;
    const Point2 x2 = drop_axis(x, axis);
    // Between the corner's two sides, counted in the triangle's turning sense. The corner is less
    // than a half turn, so the direction opposite a side (0 against that side) fails the other.
    return turn * orient2d_sign(v2, c2, x2) >= 0 && turn * orient2d_sign(v2, x2, d2) >= 0;
  }
  return false;
}

inline Vector3d vertex(const double* x, int32_t v) { return {x[3 * v], x[3 * v + 1], x[3 * v + 2]}; }

}  // namespace

int orient3d_sign(const Vector3d& a, const Vector3d& b, const Vector3d& c, const Vector3d& d) {
  const Vector3d u = b - a;
  const Vector3d v = c - a;
  const Vector3d w = d - a;
  const double vy_wz = v.y() * w.z();
  const double vz_wy = v.z() * w.y();
  const double vz_wx = v.z() * w.x();
  const double vx_wz = v.x() * w.z();
  const double vx_wy = v.x() * w.y();
  const double vy_wx = v.y() * w.x();
  const double det = u.x() * (vy_wz - vz_wy) + u.y() * (vz_wx - vx_wz) + u.z() * (vx_wy - vy_wx);
  const double permanent = std::abs(u.x()) * (std::abs(vy_wz) + std::abs(vz_wy)) +
                           std::abs(u.y()) * (std::abs(vz_wx) + std::abs(vx_wz)) +
                           std::abs(u.z()) * (std::abs(vx_wy) + std::abs(vy_wx));
  if (std::abs(det) > kOrient3dBound * permanent) return sign_of(det);
  // All four points on a plane x_k = const, as on every face of an axis-aligned box: exactly 0
  // without the exact evaluation (a computed difference is 0 only for equal coordinates).
  for (int k = 0; k < 3; ++k)
    if (u[k] == 0.0 && v[k] == 0.0 && w[k] == 0.0) return 0;
  return orient3d_exact(a, b, c, d);
}

bool triangles_intersect(const Vector3d& a0, const Vector3d& a1, const Vector3d& a2,
                         const Vector3d& b0, const Vector3d& b1, const Vector3d& b2) {
  const Vector3d a[3] = {a0, a1, a2};
  const Vector3d b[3] = {b0, b1, b2};
  int side_of_b[3];  // of each b vertex against A's plane
  int side_of_a[3];  // of each a vertex against B's plane
  for (int i = 0; i < 3; ++i) {
    side_of_b[i] = orient3d_sign(a0, a1, a2, b[i]);
    side_of_a[i] = orient3d_sign(b0, b1, b2, a[i]);
  }
  // Most broad-phase candidates end here: one triangle strictly on one side of the other's plane.
  auto strictly_one_side = [](const int* s) {
    return (s[0] > 0 && s[1] > 0 && s[2] > 0) || (s[0] < 0 && s[1] < 0 && s[2] < 0);
  };
  if (strictly_one_side(side_of_b) || strictly_one_side(side_of_a)) return false;
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    if (segment_meets_triangle(a[i], a[j], side_of_a[i], side_of_a[j], b0, b1, b2)) return true;
    if (segment_meets_triangle(b[i], b[j], side_of_b[i], side_of_b[j], a0, a1, a2)) return true;
  }
  return false;
}

bool triangles_overlap_beyond_vertex(const Vector3d& v, const Vector3d& p1, const Vector3d& p2,
                                     const Vector3d& q1, const Vector3d& q2) {
  // If p1 and p2 are strictly on one side of the other triangle's plane, so is every point of
  // (v, p1, p2) but v: the usual answer for two triangles around a vertex of a surface.
  const int a1 = orient3d_sign(v, q1, q2, p1);
  const int a2 = orient3d_sign(v, q1, q2, p2);
  if (a1 * a2 > 0) return false;
  // In one plane, near v each triangle is its corner and the intersection is convex, so they
  // share more than v iff their corners do, iff a side of one corner lies in the other (each is
  // less than a half turn). This is also the common case of neighbours on a flat face.
  if (a1 == 0 && a2 == 0)
    return direction_in_corner(v, p1, q1, q2) || direction_in_corner(v, p2, q1, q2) ||
           direction_in_corner(v, q1, p1, p2) || direction_in_corner(v, q2, p1, p2);
  const int b1 = orient3d_sign(v, p1, p2, q1);
  const int b2 = orient3d_sign(v, p1, p2, q2);
  if (b1 * b2 > 0) return false;
  // The intersection is convex and holds v; if it holds more, it has an extreme point other than
  // v, which lies on an edge of one triangle and in the other (as in triangles_intersect). On the
  // edge opposite v any contact counts, it is not v. On an edge from v, say v p1, a point of the
  // other triangle other than v puts the whole line v p1 in that triangle's plane and the
  // direction p1 - v in its corner at v; conversely such a direction enters both triangles.
  if (segment_meets_triangle(p1, p2, a1, a2, v, q1, q2)) return true;
  if (segment_meets_triangle(q1, q2, b1, b2, v, p1, p2)) return true;
  return (a1 == 0 && direction_in_corner(v, p1, q1, q2)) ||
         (a2 == 0 && direction_in_corner(v, p2, q1, q2)) ||
         (b1 == 0 && direction_in_corner(v, q1, p1, p2)) ||
         (b2 == 0 && direction_in_corner(v, q2, p1, p2));
}

std::vector<IndexPair> intersecting_triangle_pairs(const double* x, const int32_t* triangles,
                                                   int64_t num_triangles) {
  if (num_triangles < 0 || num_triangles > INT32_MAX)
    throw std::invalid_argument("intersecting_triangle_pairs: num_triangles = " +
                                std::to_string(num_triangles) + " does not fit in int32");
  const auto n = static_cast<int32_t>(num_triangles);
  // Exact boxes (min/max of the vertex coordinates): the broad phase loses no touching pair.
  std::vector<double> lower(3 * static_cast<size_t>(n));
  std::vector<double> upper(3 * static_cast<size_t>(n));
  for (int32_t t = 0; t < n; ++t) {
    for (int d = 0; d < 3; ++d) {
      const double c0 = x[3 * triangles[3 * t] + d];
      const double c1 = x[3 * triangles[3 * t + 1] + d];
      const double c2 = x[3 * triangles[3 * t + 2] + d];
      lower[3 * t + d] = std::min({c0, c1, c2});
      upper[3 * t + d] = std::max({c0, c1, c2});
    }
  }
  const std::vector<IndexPair> candidates = self_overlapping_pairs(lower.data(), upper.data(), n);

  // One flag per candidate, filled in parallel, compacted in candidate order: the result is
  // sorted and independent of the thread count.
  std::vector<char> hit(candidates.size(), 0);
  parallel_for(static_cast<int64_t>(candidates.size()), [&](int64_t begin, int64_t end) {
    for (int64_t c = begin; c < end; ++c) {
      const int32_t* ti = triangles + 3 * static_cast<int64_t>(candidates[c].first);
      const int32_t* tj = triangles + 3 * static_cast<int64_t>(candidates[c].second);
      bool share = false;
      for (int k = 0; k < 3; ++k)
        share = share || ti[k] == tj[0] || ti[k] == tj[1] || ti[k] == tj[2];
      hit[c] = !share && triangles_intersect(vertex(x, ti[0]), vertex(x, ti[1]), vertex(x, ti[2]),
                                             vertex(x, tj[0]), vertex(x, tj[1]), vertex(x, tj[2]));
    }
  });
  std::vector<IndexPair> pairs;
  for (size_t c = 0; c < candidates.size(); ++c)
    if (hit[c]) pairs.push_back(candidates[c]);
  return pairs;
}

double winding_number(const Vector3d& p, const double* x, const int32_t* triangles,
                      int64_t num_triangles) {
  // Solid angle of one triangle (Van Oosterom and Strackee, IEEE TBME 1983):
  // tan(omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|), a, b, c from p.
  // atan2 keeps the right branch when the denominator is negative (large solid angles).
  const double total = deterministic_sum(num_triangles, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t t = begin; t < end; ++t) {
      const Vector3d a = vertex(x, triangles[3 * t]) - p;
      const Vector3d b = vertex(x, triangles[3 * t + 1]) - p;
      const Vector3d c = vertex(x, triangles[3 * t + 2]) - p;
      const double la = a.norm();
      const double lb = b.norm();
      const double lc = c.norm();
      const double numerator = a.dot(b.cross(c));
      const double denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
      sum += 2.0 * std::atan2(numerator, denominator);
    }
    return sum;
  });
  return total / (4.0 * std::numbers::pi);
}

bool point_inside_surface(const Vector3d& p, const double* x, const int32_t* triangles,
                          int64_t num_triangles) {
  return std::abs(winding_number(p, x, triangles, num_triangles)) > 0.5;
}

}  // namespace nexdyn

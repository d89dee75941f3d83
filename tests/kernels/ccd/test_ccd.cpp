// Narrow-phase CCD (kernels/ccd): analytic impacts, degenerate inputs (touching at t = 0,
// parallel edges, near misses) and random motions checked against an independent reference.
//
// The reference (ccd_reference.hpp) is the barrier's distance (kernels/distance), not the CCD's
// own distance bounds (kernels/ccd/ccd_distance.hpp, which this file does not include), searched
// along the motion by sampling plus Lipschitz-certified bisection. Every random trial has a
// positive min_distance, so every trial checks all of the contract of ccd.hpp, with the stop gap
// g = min(min_distance, 0.1 d(0)):
//   (a) no step past the floor: the distance stays above 0.1 g on [0, toi] (on [0, tmax] when no
//       collision is reported), since every advancement step keeps it >= 0.1 of a bound > g;
//   (b) no missed collision: if the distance comes down to 0.05 g (half that floor) at some time
//       in [0, tmax], a collision is reported with toi at or before that time;
//   (c) no needless stop: a reported toi has distance <= g (the CCD stops when its lower bound
//       reaches g), so a motion that stays above g is not a collision.
// Both outcomes are counted and required to occur often enough for the checks to mean something.
#include "kernels/ccd/ccd.hpp"
#include "tests/kernels/ccd/ccd_reference.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

using namespace nexdyn;
using Eigen::Vector3d;

namespace {

using ccd_reference::Crossing;
using ccd_reference::LinearMotion;
using ccd_reference::PairKind;

// From ccd.hpp: the stop gap is min(min_distance, kGapFraction d(0)), and each advancement step
// keeps the distance >= kStepFloor of the certified bound at its start.
constexpr double kGapFraction = 0.1;
constexpr double kStepFloor = 0.1;
// Margins between what the CCD guarantees and what is asserted. The CCD's certified rounding
// bounds are 64 eps * scale plus 16 eps |x| / sin(angle) (ccd_distance.hpp): with coordinates
// below 100 (the fastest aimed motions) they stay under 1e-9 unless a triangle angle or the angle
// between two edges falls below ~1e-4 rad, which random corners essentially never do. The
// reference's classification ties and degeneracy cut-offs (kernels/distance: 1e-12 in
// barycentric terms, sin 1e-10) move it by at most ~1e-10 of the edge lengths (< 5), and its
// search along the motion is exact to 1e-12 (ccd_reference.hpp). kAbsoluteSlack = 1e-9 covers
// all three. The relative margin covers the CCD's gap coming from its lower bound of d(0) rather
// than d(0); it is far below any error of interest (a wrong step fraction, speed bound or
// distance scale moves the stop by tens of percent).
constexpr double kRelativeMargin = 1e-3;
constexpr double kAbsoluteSlack = 1e-9;
// Random starts closer than this are redrawn, so that the gap (>= 1e-5) and the floor (>= 1e-6)
// stay well above kAbsoluteSlack.
constexpr double kMinStartDistance = 1e-4;

bool run_ccd(const LinearMotion& m, double min_distance, double tmax, double& toi) {
  const auto& a = m.x0;
  const auto& b = m.x1;
  switch (m.kind) {
    case PairKind::point_triangle:
      return point_triangle_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], min_distance, tmax, toi);
    case PairKind::edge_edge:
      return edge_edge_ccd(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3], min_distance, tmax, toi);
    case PairKind::point_plane: return point_plane_ccd(a[0], b[0], a[1], a[2], min_distance, tmax, toi);
  }
  return false;
}

std::string kind_name(PairKind kind) {
  switch (kind) {
    case PairKind::point_triangle: return "point-triangle";
    case PairKind::edge_edge: return "edge-edge";
    case PairKind::point_plane: return "point-plane";
  }
  return "?";
}

// How a random trial moves: freely (mostly misses); aimed so that the primitives touch at a chosen
// time (possibly past tmax); aimed past the contact point by up to twice the gap (mostly landing
// between the floor and the gap, where either answer is allowed, or just outside); or head on:
// both primitives translate rigidly and close along the contact normal, so that the closing speed
// equals the CCD's speed bound and each advancement step lands exactly on its floor of 0.1 d
// (the one motion that would reveal a step fraction or speed bound slightly too large).
enum class Aim { free, hit, near_miss, head_on };

class TrialMaker {
 public:
  explicit TrialMaker(uint64_t seed) : rng_(seed) {}

  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  Vector3d point(double amplitude) {
    return {uniform(-amplitude, amplitude), uniform(-amplitude, amplitude), uniform(-amplitude, amplitude)};
  }
  Vector3d unit() {
    for (;;) {
      const Vector3d v = point(1.0);
      const double n = v.norm();
      if (n > 0.1 && n <= 1.0) return v / n;
    }
  }
  // A parameter in [0, 1], on an end two times in five: vertex and edge contacts, where the
  // distances pick their closest features from different branches.
  double parameter() {
    const double r = uniform(0.0, 1.0);
    if (r < 0.2) return 0.0;
    if (r < 0.4) return 1.0;
    return uniform(0.0, 1.0);
  }

  // Random positions at t = 0, redrawn until kMinStartDistance apart, and random velocities;
  // returns the start distance.
  double start(LinearMotion& m, double speed) {
    for (;;) {
      for (int i = 0; i < 4; ++i) {
        m.x0[i] = point(1.0);
        m.x1[i] = m.x0[i] + point(speed);
      }
      if (m.kind == PairKind::point_plane) {
        m.x0[1] = m.x1[1] = point(0.5);
        m.x0[2] = m.x1[2] = unit();
      }
      const double d0 = ccd_reference::reference_distance(m, 0.0);
      if (d0 >= kMinStartDistance) return d0;
    }
  }

  // Redirects the aimed corners (the point; edge b) so that at time tc they reach a point of the
  // other primitive, displaced by `miss` in a random direction.
  void aim(LinearMotion& m, double tc, double miss) {
    const Vector3d offset = miss * unit();
    auto at = [&](int i) { return ccd_reference::position(m, i, tc); };
    auto steer = [&](int i, const Vector3d& target) { m.x1[i] = m.x0[i] + (target - m.x0[i]) / tc; };
    switch (m.kind) {
      case PairKind::point_triangle: {
        double u = parameter(), v = parameter();
        if (u + v > 1.0) {
          u = 1.0 - u;
          v = 1.0 - v;
        }
        steer(0, at(1) + u * (at(2) - at(1)) + v * (at(3) - at(1)) + offset);
        break;
      }
      case PairKind::edge_edge: {
        const Vector3d target = at(0) + parameter() * (at(1) - at(0)) + offset;
        const double length = uniform(0.3, 2.0);
        const Vector3d along = length * unit();
        const double s = parameter();
        steer(2, target - s * along);
        steer(3, target + (1.0 - s) * along);
        break;
      }
      case PairKind::point_plane: {
        const Vector3d n = m.x0[2];
        const Vector3d tangent = point(1.0);
        steer(0, m.x0[1] + tangent - tangent.dot(n) * n + offset);
        break;
      }
    }
  }

  // Head-on approach from distance h0 along the normal of the closest features (face, common
  // normal of the edges, plane), interior to interior, touching at tc; returns h0 = d(0).
  double head_on(LinearMotion& m, double tc) {
    const double h0 = uniform(0.02, 1.0);
    const Vector3d drift = point(0.75);  // a common translation, which the CCD's mean removes
    for (int i = 0; i < 4; ++i) m.x0[i] = point(1.0);
    Vector3d normal = Vector3d::Zero();
    int approaching_begin = 0, approaching_end = 1;  // the corners that close in along -normal
    switch (m.kind) {
      case PairKind::point_triangle: {
        const Vector3d e1 = m.x0[2] - m.x0[1], e2 = m.x0[3] - m.x0[1];
        normal = e1.cross(e2).normalized();
        const double u = uniform(0.1, 0.45);  // one draw per statement: a fixed order of draws
        const double v = uniform(0.1, 0.45);
        m.x0[0] = m.x0[1] + u * e1 + v * e2 + h0 * normal;
        break;
      }
      case PairKind::edge_edge: {
        const double length = uniform(0.3, 2.0);
        const Vector3d along = length * unit();
        const Vector3d contact = m.x0[0] + uniform(0.1, 0.9) * (m.x0[1] - m.x0[0]);
        normal = (m.x0[1] - m.x0[0]).cross(along).normalized();
        const double s = uniform(0.1, 0.9);
        m.x0[2] = contact + h0 * normal - s * along;
        m.x0[3] = contact + h0 * normal + (1.0 - s) * along;
        approaching_begin = 2;
        approaching_end = 4;
        break;
      }
      case PairKind::point_plane: {
        normal = unit();
        m.x0[1] = point(0.5);
        m.x0[2] = normal;
        m.x0[0] = m.x0[1] + h0 * normal;
        break;
      }
    }
    for (int i = 0; i < 4; ++i) {
      const bool approaching = i >= approaching_begin && i < approaching_end;
      m.x1[i] = m.x0[i] + drift - (approaching ? h0 / tc : 0.0) * normal;
    }
    if (m.kind == PairKind::point_plane) {  // the plane is static, and so is the point's drift
      m.x1[0] = m.x0[0] - h0 / tc * normal;
      m.x1[1] = m.x0[1];
      m.x1[2] = m.x0[2];
    }
    return h0;
  }

 private:
  std::mt19937_64 rng_;
};

// The distance at a reported toi lies between the floor and the gap (analytic cases, where the
// distance along the motion is known in closed form).
void check_stop_distance(double distance_at_toi, double gap) {
  CHECK(distance_at_toi > kStepFloor * gap * (1.0 - kRelativeMargin));
  CHECK(distance_at_toi <= gap * (1.0 + kRelativeMargin) + kAbsoluteSlack);
}

// What the reference saw in the random trials of one primitive pair.
struct TrialCounts {
  int trials = 0;
  int reported = 0;       // the CCD reported a collision
  int contacts = 0;       // the distance came down to half the floor in [0, tmax]: (b) applied
  int late_contacts = 0;  // ... in the last quarter of [0, tmax]
  int clear = 0;          // the distance stayed above the gap on [0, tmax]: (c) applied to "no"
  int at_floor = 0;       // reported with distance < 0.2 g at toi: (a) nearly binding
  int start_limited = 0;  // the gap was 0.1 d(0) < min_distance
};

}  // namespace

TEST_CASE("ccd: a point falling onto a triangle stops just before the impact time") {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  for (double h : {1.0, 1e-3, 1e-7}) {
    for (double v : {1.0, 3.0, 1e3}) {
      const double t_star = h / v;
      if (t_star > 1.0) continue;
      const Vector3d p0(0.2, 0.3, h), p1(0.2, 0.3, h - v);
      double toi = -1.0;
      REQUIRE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 1.0, toi));
      CHECK(toi > 0.0);
      CHECK(toi <= t_star);
      // Stops once within the rounding slack of the face, 64 eps * max(1, |coordinate|) with the
      // coordinates at t = 1 included (up to 1e3 here).
      const double slack = 1e-13 * std::max(1.0, v);
      CHECK(toi >= (h - slack) / v);
      // With a gap: the step ends between a tenth of the gap and the gap.
      const double gap = 1e-2 * h;
      REQUIRE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, gap, 1.0, toi));
      const double d = h - v * toi;
      CHECK(d > 0.1 * gap * 0.999);
      CHECK(d <= gap * 1.001 + slack);
    }
  }
}

TEST_CASE("ccd: the triangle moving onto a static point is the same impact") {
  const Vector3d p(0.25, 0.25, 0.0);
  const Vector3d a0(0, 0, 0.5), b0(1, 0, 0.5), c0(0, 1, 0.5), down(0, 0, -1);
  double toi = -1.0;
  REQUIRE(point_triangle_ccd(p, a0, b0, c0, p, a0 + down, b0 + down, c0 + down, 0.0, 1.0, toi));
  CHECK(toi <= 0.5);
  CHECK(toi >= 0.5 * (1.0 - 1e-9));
  // With min_distance 1e-2 (< 0.1 d(0) = 0.05, so it is the gap); the distance is 0.5 - t.
  REQUIRE(point_triangle_ccd(p, a0, b0, c0, p, a0 + down, b0 + down, c0 + down, 1e-2, 1.0, toi));
  check_stop_distance(0.5 - toi, 1e-2);
}

TEST_CASE("ccd: tmax cuts the search") {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const Vector3d p0(0.2, 0.2, 0.5), p1(0.2, 0.2, -0.5);  // impact at t = 0.5
  double toi = -1.0;
  CHECK_FALSE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 0.4, toi));
  CHECK(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 0.6, toi));
  CHECK(toi <= 0.5);
  // With a gap of 0.02 the stop can come at t = 0.48 at the earliest: tmax = 0.47 ends at
  // distance 0.03, clear of the gap.
  CHECK_FALSE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.02, 0.47, toi));
  REQUIRE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.02, 0.6, toi));
  check_stop_distance(0.5 - toi, 0.02);
}

TEST_CASE("ccd: exactly touching at t = 0 is a collision at toi = 0") {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  double toi = -1.0;
  // Point on the face, on an edge, on a vertex; moving away, tangentially, or not at all.
  for (const Vector3d& p : {Vector3d(0.2, 0.2, 0), Vector3d(0.5, 0, 0), Vector3d(1, 0, 0)}) {
    for (const Vector3d& move : {Vector3d(0, 0, 1), Vector3d(0.1, 0.1, 0), Vector3d(0, 0, 0)}) {
      toi = -1.0;
      CHECK(point_triangle_ccd(p, a, b, c, p + move, a, b, c, 0.0, 1.0, toi));
      CHECK(toi == 0.0);
    }
  }
  // Crossing edges, touching edges end to end, collinear overlapping edges.
  const Vector3d e0(-1, 0, 0), e1(1, 0, 0);
  const Vector3d up(0, 0, 1);
  for (const auto& [f0, f1] : {std::pair{Vector3d(0, -1, 0), Vector3d(0, 1, 0)},
                               std::pair{Vector3d(1, 0, 0), Vector3d(2, 1, 0)},
                               std::pair{Vector3d(0.5, 0, 0), Vector3d(3, 0, 0)}}) {
    toi = -1.0;
    CHECK(edge_edge_ccd(e0, e1, f0, f1, e0, e1, f0 + up, f1 + up, 0.0, 1.0, toi));
    CHECK(toi == 0.0);
  }
  toi = -1.0;
  CHECK(point_plane_ccd(Vector3d(3, 0, 2), Vector3d(3, 1, 2), Vector3d(0, 0, 0), Vector3d(0, 1, 0), 0.0, 1.0, toi));
  CHECK(toi == 0.0);
}

TEST_CASE("ccd: parallel edges moving side by side never touch") {
  const Vector3d a0(0, 0, 0), a1(1, 0, 0), b0(0, 0.1, 0), b1(1, 0.1, 0);
  const Vector3d shift(5, 0, 0), approach(0, -0.05, 0);
  double toi = -1.0;
  // Both translate together along x (relative motion zero), then b approaches to half the gap.
  CHECK_FALSE(edge_edge_ccd(a0, a1, b0, b1, a0 + shift, a1 + shift, b0 + shift, b1 + shift, 0.0, 1.0, toi));
  CHECK_FALSE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + approach, b1 + approach, 1e-3, 1.0, toi));
  // Sliding along each other in the same line (collinear, offset), never overlapping.
  const Vector3d c0(2, 0, 0), c1(3, 0, 0), slide(0.5, 0, 0);
  CHECK_FALSE(edge_edge_ccd(a0, a1, c0, c1, a0, a1, c0 - slide, c1 - slide, 0.0, 1.0, toi));
  // Parallel edges brought into contact: a collision, toi before the contact at t = 0.5.
  const Vector3d hit(0, -0.2, 0);
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + hit, b1 + hit, 0.0, 1.0, toi));
  CHECK(toi <= 0.5);
  CHECK(toi >= 0.5 * (1.0 - 1e-9));
  // With min_distance 5e-3 (< 0.1 d(0) = 0.01); the distance is 0.1 - 0.2 t.
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + hit, b1 + hit, 5e-3, 1.0, toi));
  check_stop_distance(0.1 - 0.2 * toi, 5e-3);
}

TEST_CASE("ccd: crossing edges report a toi at or before the crossing") {
  const Vector3d a0(-1, 0, 0), a1(1, 0, 0), b0(0, -1, 1), b1(0, 1, 1), down(0, 0, -2);  // cross at 0.5
  double toi = -1.0;
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + down, b1 + down, 0.0, 1.0, toi));
  CHECK(toi <= 0.5);
  CHECK(toi >= 0.5 * (1.0 - 1e-9));
  // With min_distance 1e-2 (< 0.1 d(0) = 0.1); the distance is 1 - 2 t.
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + down, b1 + down, 1e-2, 1.0, toi));
  check_stop_distance(1.0 - 2.0 * toi, 1e-2);
  // With min_distance 1 (> 0.1 d(0)): the gap is 0.1 d(0) = 0.1.
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + down, b1 + down, 1.0, 1.0, toi));
  check_stop_distance(1.0 - 2.0 * toi, 0.1);
}

TEST_CASE("ccd: a miss by a hair is no collision when the hair exceeds the gap") {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const double hair = 1e-9;
  // The point drops past the triangle just outside the edge x + y = 1.
  const Vector3d p0(0.5 + hair, 0.5 + hair, 1.0), p1(0.5 + hair, 0.5 + hair, -1.0);
  double toi = -1.0;
  CHECK_FALSE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 1.0, toi));
  CHECK_FALSE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 1e-10, 1.0, toi));
  CHECK(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 1e-8, 1.0, toi));  // hair < gap: reported
  // Edges: one passes over the other's endpoint by a hair.
  const Vector3d e0(0, 0, 0), e1(1, 0, 0);
  const Vector3d f0(1 + hair, -1, 1), f1(1 + hair, 1, 1), down(0, 0, -2);
  CHECK_FALSE(edge_edge_ccd(e0, e1, f0, f1, e0, e1, f0 + down, f1 + down, 0.0, 1.0, toi));
}

TEST_CASE("touch ccd: a miss by 1e-16 of a size-1 query is told apart from a touch") {
  // A point falls past the corner a of a triangle (edge ab on the x axis, sizes about 1), once
  // 1e-16 outside it on x and z (a miss: the distance never goes below 1.4e-16) and once exactly
  // through it (a touch at t = 0.07 / 0.3). The double CCD's rounding slack (64 eps at scale 1,
  // 1.4e-14) cannot tell them apart and reports both; the touch CCD's long-double pass can.
  const Vector3d a(0, 0.5, 0), b(1, 0.5, 0), c(1.25, -0.5, -0.25);
  const double miss = 1e-16;
  for (const bool touching : {false, true}) {
    CAPTURE(touching);
    const double off = touching ? 0.0 : -miss;
    const Vector3d p0(off, 0.57, -off), p1(off, 0.27, -off);
    double toi = -1.0;
    CHECK(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 1.0, toi));
    toi = -1.0;
    CHECK(point_triangle_touch_ccd(p0, a, b, c, p1, a, b, c, 1.0, toi) == touching);
    if (touching) {
      CHECK(toi > 0.2);
      CHECK(toi <= 0.07 / 0.3);
    }
  }
  // Edges: one sweeps across the endpoint of the other, 1e-16 beyond it or exactly through it.
  const Vector3d e0(0, 0.5, 0), e1(1, 0.5, 0);
  for (const bool touching : {false, true}) {
    CAPTURE(touching);
    const double off = touching ? 0.0 : -miss;
    const Vector3d f0(off, 0.57, -1), f1(off, 0.57, 1), down(0, -0.3, 0);
    double toi = -1.0;
    CHECK(edge_edge_ccd(e0, e1, f0, f1, e0, e1, f0 + down, f1 + down, 0.0, 1.0, toi));
    toi = -1.0;
    CHECK(edge_edge_touch_ccd(e0, e1, f0, f1, e0, e1, f0 + down, f1 + down, 1.0, toi) == touching);
    if (touching) CHECK(toi <= 0.07 / 0.3);
  }
}

TEST_CASE("touch ccd: agrees with the double CCD where that one is certain") {
  // Random motions of size 1 that clearly miss (the double CCD finds no distance below 1e-3) or
  // hit (it reports a possible touch with gap 0, which on such inputs means a touch within its
  // 1e-14 slack): the touch CCD gives the same verdicts.
  std::mt19937 rng(20);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int hits = 0, misses = 0;
  for (int trial = 0; trial < 500; ++trial) {
    Vector3d x[8];
    for (Vector3d& v : x) v = Vector3d(u(rng), u(rng), u(rng));
    double toi = 0.0, touch_toi = 0.0;
    const bool sure_hit = point_triangle_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 0.0, 1.0, toi);
    const bool sure_miss = !point_triangle_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 1e-3, 1.0, toi);
    const bool touch = point_triangle_touch_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], 1.0, touch_toi);
    if (sure_miss) {
      CHECK_FALSE(touch);
      ++misses;
    } else if (sure_hit) {
      CHECK(touch);
      ++hits;
    }
  }
  CHECK(misses > 100);
  CHECK(hits > 20);
}

TEST_CASE("ccd: a point falling onto a plane") {
  double toi = -1.0;
  const Vector3d q(0, 1, 0), n(0, 1, 0);
  REQUIRE(point_plane_ccd(Vector3d(0.3, 2, 0.1), Vector3d(0.3, 0, 0.1), q, n, 0.0, 1.0, toi));
  CHECK(toi <= 0.5);
  CHECK(toi >= 0.5 * (1.0 - 1e-9));
  REQUIRE(point_plane_ccd(Vector3d(0.3, 2, 0.1), Vector3d(0.3, 0, 0.1), q, n, 1e-2, 1.0, toi));
  CHECK(2 - 2 * toi - 1 <= 1e-2 * 1.001);
  CHECK(2 - 2 * toi - 1 >= 1e-3 * 0.999);
  CHECK_FALSE(point_plane_ccd(Vector3d(0.3, 2, 0.1), Vector3d(0.3, 1.5, 0.1), q, n, 1e-2, 1.0, toi));
  CHECK_FALSE(point_plane_ccd(Vector3d(0.3, 2, 0.1), Vector3d(0.3, 0, 0.1), q, n, 0.0, 0.4, toi));
  // From below, crossing upwards.
  REQUIRE(point_plane_ccd(Vector3d(0, 0, 0), Vector3d(0, 4, 0), q, n, 0.0, 1.0, toi));
  CHECK(toi <= 0.25);
}

TEST_CASE("ccd: random motions against the barrier distance sampled along the motion") {
  using ccd_reference::first_at_or_below;
  TrialMaker maker(7);
  constexpr int kTrialsPerCombination = 100;  // x 3 primitive pairs x 4 aims
  TrialCounts counts[3];
  for (int trial = 0; trial < 12 * kTrialsPerCombination; ++trial) {
    LinearMotion m;
    m.kind = static_cast<PairKind>(trial % 3);
    const Aim aim = static_cast<Aim>(trial / 3 % 4);
    // Log-uniform over [3e-4, 0.3]: in about a third of the trials 0.1 d(0) sets the gap instead.
    const double min_distance = std::pow(10.0, maker.uniform(-3.5, -0.5));
    const double tmax = trial % 5 == 4 ? maker.uniform(0.3, 1.0) : 1.0;
    const double tc = maker.uniform(0.1, 1.3);  // contact time of aimed motions
    const double d0 = aim == Aim::head_on ? maker.head_on(m, tc) : maker.start(m, aim == Aim::free ? 1.5 : 0.75);
    const double gap = std::min(min_distance, kGapFraction * d0);
    if (aim == Aim::hit) maker.aim(m, tc, 0.0);  // aiming changes x1 only, not d(0)
    if (aim == Aim::near_miss) maker.aim(m, tc, maker.uniform(0.0, 2.0) * gap);

    double toi = -1.0;
    const bool hit = run_ccd(m, min_distance, tmax, toi);

    const double lipschitz = ccd_reference::distance_lipschitz(m);
    auto distance = [&](double t) { return ccd_reference::reference_distance(m, t); };
    const double floor_level = kStepFloor * gap * (1.0 - kRelativeMargin) - kAbsoluteSlack;
    const double contact_level = 0.5 * kStepFloor * gap;
    const double gap_level = gap * (1.0 + kRelativeMargin) + kAbsoluteSlack;
    INFO("trial " << trial << " (" << kind_name(m.kind) << ", aim " << static_cast<int>(aim)
                  << "): min_distance " << min_distance << ", d(0) " << d0 << ", gap " << gap << ", tmax "
                  << tmax << ", reported " << hit << " at toi " << toi << ", L " << lipschitz);

    TrialCounts& count = counts[trial % 3];
    ++count.trials;
    count.reported += hit;
    count.start_limited += gap < min_distance;
    if (hit) {
      CHECK(toi >= 0.0);
      CHECK(toi <= tmax);
    }
    // (a) Above the floor up to the reported time (the whole interval if nothing was reported).
    const double safe_until = hit ? std::clamp(toi, 0.0, tmax) : tmax;
    const auto dip = first_at_or_below(distance, lipschitz, 0.0, safe_until, floor_level);
    INFO("distance " << distance(dip.t) << " <= floor " << floor_level << " at t = " << dip.t);
    CHECK(dip.kind == Crossing::none);
    // (b) A contact in [0, tmax] is reported, at or before the reference's first contact time.
    const auto contact = first_at_or_below(distance, lipschitz, 0.0, tmax, contact_level);
    INFO("first contact (distance <= " << contact_level << ") at t = " << contact.t);
    REQUIRE(contact.kind != Crossing::undecided);
    if (contact.kind == Crossing::found) {
      ++count.contacts;
      count.late_contacts += contact.t > 0.75 * tmax;
      CHECK(hit);
      CHECK(toi <= contact.t);
    }
    // (c) A reported collision is within the gap; a motion that stays above the gap is none.
    if (hit) {
      const double d_toi = distance(toi);
      count.at_floor += d_toi < 2.0 * kStepFloor * gap;
      CHECK(d_toi <= gap_level);
    }
    const auto near = first_at_or_below(distance, lipschitz, 0.0, tmax, gap_level);
    REQUIRE(near.kind != Crossing::undecided);
    if (near.kind == Crossing::none) {
      ++count.clear;
      CHECK_FALSE(hit);
    }
  }
  for (int k = 0; k < 3; ++k) {
    const PairKind kind = static_cast<PairKind>(k);
    const TrialCounts& count = counts[k];
    MESSAGE(kind_name(kind) << ": " << count.trials << " trials, " << count.reported << " reported collisions, "
                            << count.contacts << " contacts in [0, tmax] (" << count.late_contacts
                            << " in its last quarter), " << count.clear << " clear of the gap, "
                            << count.at_floor << " stopped below twice the floor, " << count.start_limited
                            << " with the gap set by d(0)");
    // Each half of the contract was exercised: contacts that must be reported, late ones (toi
    // near tmax), motions that must not be reported, starts closer than 10 min_distance. The
    // thresholds are about half the counts seen with seed 7 and below the least over seeds 1-300.
    CHECK(count.contacts >= 100);
    CHECK(count.late_contacts >= 25);
    CHECK(count.clear >= 80);
    CHECK(count.start_limited >= 50);
    // Steps that end near the floor, where (a) is nearly binding; the plane's closed form stops
    // at the gap itself, never near the floor.
    if (kind != PairKind::point_plane) CHECK(count.at_floor >= 15);
  }
}

// Narrow-phase CCD (kernels/ccd): analytic impacts, degenerate inputs (touching at t = 0,
// parallel edges, near misses) and, on random motions, the two halves of the contract checked
// against dense sampling of the distance: the distance is positive on [0, toi], and any sampled
// time where the primitives come within a tenth of the gap is at or after the reported toi.
#include "kernels/ccd/ccd.hpp"
#include "kernels/ccd/ccd_distance.hpp"

#include <doctest/doctest.h>

#include <random>

using namespace nexdyn;
using Eigen::Vector3d;

namespace {

// Distance estimate used as reference in the sampling tests (well-conditioned random inputs, where
// the rounding slack is ~1e-14 and irrelevant at the tolerances used).
double pt_distance(const Vector3d& p, const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  return ccd_detail::point_triangle_distance_lower(p, a, b, c, 0.0);
}
double ee_distance(const Vector3d& a0, const Vector3d& a1, const Vector3d& b0, const Vector3d& b1) {
  return ccd_detail::edge_edge_distance_lower(a0, a1, b0, b1, 0.0);
}
Vector3d lerp(const Vector3d& x0, const Vector3d& x1, double t) { return x0 + t * (x1 - x0); }

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
}

TEST_CASE("ccd: tmax cuts the search") {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  const Vector3d p0(0.2, 0.2, 0.5), p1(0.2, 0.2, -0.5);  // impact at t = 0.5
  double toi = -1.0;
  CHECK_FALSE(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 0.4, toi));
  CHECK(point_triangle_ccd(p0, a, b, c, p1, a, b, c, 0.0, 0.6, toi));
  CHECK(toi <= 0.5);
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
}

TEST_CASE("ccd: crossing edges report a toi at or before the crossing") {
  const Vector3d a0(-1, 0, 0), a1(1, 0, 0), b0(0, -1, 1), b1(0, 1, 1), down(0, 0, -2);  // cross at 0.5
  double toi = -1.0;
  REQUIRE(edge_edge_ccd(a0, a1, b0, b1, a0, a1, b0 + down, b1 + down, 0.0, 1.0, toi));
  CHECK(toi <= 0.5);
  CHECK(toi >= 0.5 * (1.0 - 1e-9));
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

TEST_CASE("ccd: random motions are conservative against dense sampling") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> pos(-1.0, 1.0);
  auto rand3 = [&] { return Vector3d(pos(rng), pos(rng), pos(rng)); };
  constexpr int kSamples = 4000;
  int collisions = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const bool vf = trial % 2 == 0;
    Vector3d x0[4], x1[4];
    for (int i = 0; i < 4; ++i) {
      x0[i] = rand3();
      x1[i] = x0[i] + 1.5 * rand3();
    }
    auto dist = [&](double t) {
      const Vector3d y0 = lerp(x0[0], x1[0], t), y1 = lerp(x0[1], x1[1], t), y2 = lerp(x0[2], x1[2], t),
                     y3 = lerp(x0[3], x1[3], t);
      return vf ? pt_distance(y0, y1, y2, y3) : ee_distance(y0, y1, y2, y3);
    };
    const double min_distance = (trial % 4 < 2) ? 0.0 : 0.02;
    double toi = 2.0;
    const bool hit = vf ? point_triangle_ccd(x0[0], x0[1], x0[2], x0[3], x1[0], x1[1], x1[2], x1[3], min_distance,
                                             1.0, toi)
                        : edge_edge_ccd(x0[0], x0[1], x0[2], x0[3], x1[0], x1[1], x1[2], x1[3], min_distance, 1.0,
                                        toi);
    const double d0 = dist(0.0);
    REQUIRE(d0 > 1e-6);  // random starts are separated
    const double gap = std::min(min_distance, 0.1 * d0);
    // First sampled time within a tenth of the gap: the CCD cannot step over it (every step keeps
    // the distance above a tenth of a bound that exceeded the gap).
    const double contact_level = 0.1 * gap;
    double first_contact = 2.0;
    for (int k = 0; k <= kSamples; ++k) {
      const double t = double(k) / kSamples;
      if (dist(t) <= contact_level) {
        first_contact = t;
        break;
      }
    }
    if (hit) {
      ++collisions;
      CHECK(toi >= 0.0);
      CHECK(toi <= 1.0);
      // Positive distance on [0, toi].
      double min_before = dist(0.0);
      for (int k = 1; k <= kSamples; ++k) min_before = std::min(min_before, dist(toi * k / kSamples));
      CHECK(min_before > 0.0);
    }
    if (first_contact <= 1.0 && gap > 0.0) {
      CHECK(hit);
      CHECK(toi <= first_contact);
    }
  }
  MESSAGE("random motions reported colliding: " << collisions << " of 400");
  CHECK(collisions > 20);
}

// Tests of engine/contact/pair_geometry.hpp's box gap, which lets the energy sums, the active set
// and the CCD skip pairs whose primitives are surely farther apart than they look at: it must be
// a lower bound of the pair's distance at every point of the motion, exact where the boxes' gap is
// the distance, and a pair it skips must be one the CCD kernel finds nothing for.
// (That the skips change no result of a whole solve: the cached-distance test of
// test_contact_potential.cpp and the bitwise thread and instruction-set tests of the scenes.)
#include "engine/contact/pair_geometry.hpp"
#include "kernels/ccd/ccd.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <random>
#include <vector>

using namespace nexdyn;
using pair_geometry::box_gap_squared;

namespace {

// Four points' positions (12 values) as the engine's flat arrays hold them, vertex ids 0-3.
constexpr PairVertices kIds = {0, 1, 2, 3};

Eigen::Vector3d at(const std::vector<double>& x, int v) { return Eigen::Vector3d::Map(&x[3 * v]); }

// Squared distance of the pair at x: point 0 to triangle 1-2-3 (na = 1) or edge 0-1 to edge 2-3.
double squared_distance(const std::vector<double>& x, int na) {
  return na == 1 ? point_triangle_distance(at(x, 0), at(x, 1), at(x, 2), at(x, 3))
                 : edge_edge_distance(at(x, 0), at(x, 1), at(x, 2), at(x, 3));
}

}  // namespace

TEST_CASE("box gap of a contact pair: a lower bound of its distance along the motion, exact where the boxes' gap is the distance") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  int separated = 0, overlapping = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const int na = trial % 2 ? 2 : 1;
    CAPTURE(trial);
    // Two primitives in unit boxes whose centres lie up to 0.5 apart on each axis, each vertex
    // moving up to 0.5 on each.
    std::vector<double> x0(12), x1(12);
    Eigen::Vector3d offset;
    for (int d = 0; d < 3; ++d) offset[d] = 0.25 * coordinate(rng);
    for (int v = 0; v < 4; ++v)
      for (int d = 0; d < 3; ++d) {
        x0[3 * v + d] = 0.5 * coordinate(rng) + (v < na ? offset[d] : -offset[d]);
        x1[3 * v + d] = x0[3 * v + d] + 0.5 * coordinate(rng);
      }
    // Where the closest points are box corners the gap is the distance, up to the last bits of
    // either computation: hence kFarMargin in the skips, and a relative 1e-12 here.
    const double rounding = 1.0 + 1e-12;
    const double still = box_gap_squared(x0.data(), nullptr, kIds, na);
    const double swept = box_gap_squared(x0.data(), x1.data(), kIds, na);
    (still > 0.0 ? separated : overlapping) += 1;
    CHECK(still <= rounding * squared_distance(x0, na));
    CHECK(swept <= still);  // the swept boxes hold the boxes at x0 and x1
    CHECK(swept <= box_gap_squared(x1.data(), nullptr, kIds, na));
    for (int k = 0; k <= 10; ++k) {
      std::vector<double> xt(12);
      for (int i = 0; i < 12; ++i) xt[i] = x0[i] + 0.1 * k * (x1[i] - x0[i]);
      CHECK(swept <= rounding * squared_distance(xt, na));
    }
  }
  // Both outcomes are exercised.
  CHECK(separated > 1000);
  CHECK(overlapping > 200);

  // A point straight above a level triangle, an edge above a level edge crossing it: the boxes'
  // gap is the height, exactly.
  const std::vector<double> point_over = {0.25, 0.25, 0.75, 0, 0, 0, 1, 0, 0, 0, 1, 0};
  CHECK(box_gap_squared(point_over.data(), nullptr, kIds, 1) == 0.5625);
  CHECK(squared_distance(point_over, 1) == doctest::Approx(0.5625).epsilon(1e-14));
  const std::vector<double> edges = {-1, 0, 0.5, 1, 0, 0.5, 0, -1, 0, 0, 1, 0};
  CHECK(box_gap_squared(edges.data(), nullptr, kIds, 2) == 0.25);
  CHECK(squared_distance(edges, 2) == doctest::Approx(0.25).epsilon(1e-14));
  // The same edge moving down through the other: the swept boxes overlap.
  const std::vector<double> below = {-1, 0, -0.5, 1, 0, -0.5, 0, -1, 0, 0, 1, 0};
  CHECK(box_gap_squared(edges.data(), below.data(), kIds, 2) == 0.0);
}

TEST_CASE("box gap of a contact pair: the pairs it lets the CCD skip are pairs the CCD finds nothing for") {
  // Primitives a few gaps apart, moving so that their paths' boxes stay from just beyond the
  // CCD's gap to ten times it: the kernels must report no contact for every such pair.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double min_distance = 1e-4;  // the solver's CCD gap at dhat = 1e-3
  const double limit = pair_geometry::kFarMargin * min_distance;
  int skipped = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const int na = trial % 2 ? 2 : 1;
    CAPTURE(trial);
    std::vector<double> x0(12), x1(12);
    const double lift = min_distance * (1.0 + 10.0 * std::abs(unit(rng)));
    for (int v = 0; v < 4; ++v) {
      const bool upper = v < na;
      for (int d = 0; d < 3; ++d) {
        // The upper primitive above z = lift, the lower one below z = 0, both moving sideways
        // and towards each other by less than the lift.
        double c = 0.05 * unit(rng);
        if (d == 2) c = upper ? lift + 0.01 * std::abs(unit(rng)) : -0.01 * std::abs(unit(rng));
        x0[3 * v + d] = c;
        const double move = d == 2 ? (upper ? -1.0 : 1.0) * 0.3 * lift * std::abs(unit(rng)) : 0.02 * unit(rng);
        x1[3 * v + d] = c + move;
      }
    }
    // A triangle spans the lower plane; a point or edge above it.
    if (box_gap_squared(x0.data(), x1.data(), kIds, na) <= limit * limit) continue;
    ++skipped;
    double toi = 1.0;
    const bool hit = na == 1 ? point_triangle_ccd(at(x0, 0), at(x0, 1), at(x0, 2), at(x0, 3), at(x1, 0), at(x1, 1),
                                                  at(x1, 2), at(x1, 3), min_distance, 1.0, toi)
                             : edge_edge_ccd(at(x0, 0), at(x0, 1), at(x0, 2), at(x0, 3), at(x1, 0), at(x1, 1),
                                             at(x1, 2), at(x1, 3), min_distance, 1.0, toi);
    CHECK_FALSE(hit);
  }
  CHECK(skipped > 1000);
}

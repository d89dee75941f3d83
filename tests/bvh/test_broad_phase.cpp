// Tests of bvh/broad_phase: the Embree broad phase must equal the O(n^2) brute force exactly,
// including boxes that only touch (closed intervals) at coordinates that floats cannot represent,
// and must not depend on the number of TBB threads.
#include "bvh/broad_phase.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace {

using nexdyn::IndexPair;

// Boxes as the broad phase takes them: (n x 3) packed lower and upper corners.
struct Boxes {
  std::vector<double> lower;
  std::vector<double> upper;
  int32_t size() const { return static_cast<int32_t>(lower.size() / 3); }
  void add(double x0, double y0, double z0, double x1, double y1, double z1) {
    lower.insert(lower.end(), {x0, y0, z0});
    upper.insert(upper.end(), {x1, y1, z1});
  }
};

// A mix that stresses the float conversion and the closed-interval test:
//  - half the boxes have corners on a grid of step 0.1 (not a float), computed as k * 0.1 so two
//    boxes sharing a grid coordinate share the exact double: many face, edge and corner contacts;
//  - the rest are continuous, with sizes from zero (flat boxes and points) to large.
Boxes random_boxes(int32_t n, uint64_t seed, double offset) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> cell(0, 40);
  std::uniform_int_distribution<int> extent(0, 3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  constexpr double kStep = 0.1;
  Boxes boxes;
  for (int32_t b = 0; b < n; ++b) {
    double lo[3];
    double hi[3];
    if (b % 2 == 0) {
      for (int d = 0; d < 3; ++d) {
        const int k = cell(rng);
        lo[d] = offset + k * kStep;
        hi[d] = offset + (k + extent(rng)) * kStep;
      }
    } else {
      const double scale = std::pow(10.0, -3.0 + 3.0 * unit(rng));  // 1e-3 .. 1
      const bool flat = unit(rng) < 0.1;
      for (int d = 0; d < 3; ++d) {
        lo[d] = offset + 4.0 * unit(rng);
        hi[d] = lo[d] + (flat ? 0.0 : scale * unit(rng));
      }
    }
    boxes.add(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
  }
  return boxes;
}

// Number of pairs whose boxes touch without overlapping in the interior (some interval pair
// shares only an end point): the cases a half-open test or an inward float rounding would lose.
int count_touching(const Boxes& a, const Boxes& b, const std::vector<IndexPair>& pairs) {
  int touching = 0;
  for (const auto& [i, j] : pairs) {
    for (int d = 0; d < 3; ++d) {
      if (a.upper[3 * i + d] == b.lower[3 * j + d] || b.upper[3 * j + d] == a.lower[3 * i + d]) {
        ++touching;
        break;
      }
    }
  }
  return touching;
}

std::vector<IndexPair> self_pairs(const Boxes& b) {
  return nexdyn::self_overlapping_pairs(b.lower.data(), b.upper.data(), b.size());
}

std::vector<IndexPair> cross_pairs(const Boxes& a, const Boxes& b) {
  return nexdyn::overlapping_pairs(a.lower.data(), a.upper.data(), a.size(), b.lower.data(),
                                   b.upper.data(), b.size());
}

}  // namespace

TEST_CASE("broad phase: self overlaps equal brute force on random boxes") {
  for (const double offset : {0.0, 1000.3}) {
    CAPTURE(offset);
    const Boxes boxes = random_boxes(4000, 7, offset);
    const auto expected =
        nexdyn::self_overlapping_pairs_brute_force(boxes.lower.data(), boxes.upper.data(),
                                                   boxes.size());
    const auto found = self_pairs(boxes);
    REQUIRE(expected.size() > 1000);
    CHECK(count_touching(boxes, boxes, expected) > 100);
    CHECK(found.size() == expected.size());
    CHECK(found == expected);
  }
}

TEST_CASE("broad phase: cross overlaps equal brute force on random boxes") {
  for (const double offset : {0.0, 1000.3}) {
    CAPTURE(offset);
    const Boxes a = random_boxes(3000, 11, offset);
    const Boxes b = random_boxes(2500, 13, offset);
    const auto expected = nexdyn::overlapping_pairs_brute_force(
        a.lower.data(), a.upper.data(), a.size(), b.lower.data(), b.upper.data(), b.size());
    const auto found = cross_pairs(a, b);
    REQUIRE(expected.size() > 1000);
    CHECK(count_touching(a, b, expected) > 100);
    CHECK(found.size() == expected.size());
    CHECK(found == expected);
  }
}

TEST_CASE("broad phase: results are identical with 1 and 2 threads") {
  // More boxes than a conversion chunk holds, and enough for Embree to build and collide its
  // trees in parallel tasks.
  const Boxes a = random_boxes(6000, 17, 0.0);
  const Boxes b = random_boxes(5000, 19, 0.0);
  CHECK(a.lower.size() / 3 > nexdyn::kBoxConvertGrain);
  CHECK(b.lower.size() / 3 > nexdyn::kBoxConvertGrain);
  std::vector<IndexPair> self_by_threads[2];
  std::vector<IndexPair> cross_by_threads[2];
  for (int t = 0; t < 2; ++t) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, t + 1);
    self_by_threads[t] = self_pairs(a);
    cross_by_threads[t] = cross_pairs(a, b);
  }
  REQUIRE(!self_by_threads[0].empty());
  REQUIRE(!cross_by_threads[0].empty());
  CHECK(self_by_threads[0] == self_by_threads[1]);
  CHECK(cross_by_threads[0] == cross_by_threads[1]);
}

TEST_CASE("broad phase: empty inputs give no pairs") {
  const Boxes none;
  Boxes one;
  one.add(0, 0, 0, 1, 1, 1);
  CHECK(self_pairs(none).empty());
  CHECK(self_pairs(one).empty());
  CHECK(cross_pairs(none, one).empty());
  CHECK(cross_pairs(one, none).empty());
  CHECK(cross_pairs(none, none).empty());
  CHECK(cross_pairs(one, one) == std::vector<IndexPair>{{0, 0}});
}

TEST_CASE("broad phase: boxes touching at a face edge or corner overlap") {
  // Coordinates 0.1, 0.2, 0.3 are not floats: the float BVH must be widened outwards or it
  // would miss these contacts.
  Boxes boxes;
  boxes.add(0.0, 0.0, 0.0, 0.1, 0.1, 0.1);  // 0
  boxes.add(0.1, 0.0, 0.0, 0.2, 0.1, 0.1);  // 1: shares the face x = 0.1 with 0
  boxes.add(0.1, 0.1, 0.0, 0.2, 0.2, 0.1);  // 2: shares an edge with 0, a face with 1
  boxes.add(0.1, 0.1, 0.1, 0.3, 0.3, 0.3);  // 3: shares a corner with 0
  const double gap = std::nextafter(0.3, 1.0);
  boxes.add(gap, gap, gap, 1.0, 1.0, 1.0);  // 4: one ulp away from 3: no contact
  boxes.add(0.05, 0.05, 0.05, 0.05, 0.05, 0.05);  // 5: a point inside 0
  const std::vector<IndexPair> expected = {{0, 1}, {0, 2}, {0, 3}, {0, 5}, {1, 2}, {1, 3}, {2, 3}};
  CHECK(nexdyn::self_overlapping_pairs_brute_force(boxes.lower.data(), boxes.upper.data(),
                                                   boxes.size()) == expected);
  CHECK(self_pairs(boxes) == expected);

  // The same contacts across two sets: box 0 alone against all the others.
  Boxes first;
  first.add(0.0, 0.0, 0.0, 0.1, 0.1, 0.1);
  CHECK(cross_pairs(first, boxes) == std::vector<IndexPair>{{0, 0}, {0, 1}, {0, 2}, {0, 3}, {0, 5}});
  CHECK(cross_pairs(boxes, first) == std::vector<IndexPair>{{0, 0}, {1, 0}, {2, 0}, {3, 0}, {5, 0}});
}

// The contact pattern (engine/sparse/contact_pattern.hpp): which vertex pairs it holds as contacts
// come and go. It must grow to every pair a stencil needs, keep pairs no longer used (so that a
// contact flickering in and out does not cost a new analysis each time), and drop them at a
// step's start only once it holds more than kShrinkRatio x the pairs in use + kShrinkSlack.
#include "engine/sparse/contact_pattern.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

using namespace nexdyn;

namespace {

// Two-vertex stencils (a, b): one 6x6 slab each, laid out as ContactPattern::update takes them.
struct PairStencils {
  std::vector<int32_t> stencils;
  std::vector<int64_t> slab_begin{0};

  void add(int32_t a, int32_t b) {
    stencils.insert(stencils.end(), {a, b, -1, -1});
    slab_begin.push_back(slab_begin.back() + 36);
  }
};

// Pairs (i, kHalf + i) for i < count: no tet couples them.
constexpr int32_t kVertices = 1000, kHalf = 500;
PairStencils first_pairs(int32_t count) {
  PairStencils s;
  for (int32_t i = 0; i < count; ++i) s.add(i, kHalf + i);
  return s;
}

}  // namespace

TEST_CASE("contact pattern: grows to every stencil pair, keeps stale pairs, shrinks past kShrinkRatio") {
  // One tet among vertices 0..3: its pairs are elastic and never count as contact pairs.
  const HessianPattern elastic = build_tet_hessian_pattern(kVertices, {0, 1, 2, 3});
  std::vector<std::pair<int32_t, int32_t>> pairs;
  uint64_t stamp = 0;
  ContactPattern pattern(elastic, pairs, stamp);
  CHECK(pattern.num_contact_pairs() == 0);

  const int32_t held = 300;
  PairStencils all = first_pairs(held);
  all.add(0, 1);  // an elastic pair in a stencil adds nothing
  CHECK(pattern.update(all.stencils, all.slab_begin, false));
  CHECK(pattern.num_contact_pairs() == held);
  // The upper triangle: the elastic pattern plus one 3x3 block per contact pair.
  CHECK(pattern.pattern().nnz() == elastic.nnz() + 9 * held);
  const int64_t version = pattern.version();
  const uint64_t built_stamp = stamp;

  // The largest number of used pairs at which `held` pairs are dropped.
  const auto shrink_below = static_cast<int32_t>(
      std::floor((held - ContactPattern::kShrinkSlack) / ContactPattern::kShrinkRatio));
  REQUIRE(shrink_below > 0);
  // The boundary itself is exact in double: held > ratio * used + slack.
  CHECK(held > ContactPattern::kShrinkRatio * shrink_below + ContactPattern::kShrinkSlack);
  CHECK_FALSE(held > ContactPattern::kShrinkRatio * (shrink_below + 1) + ContactPattern::kShrinkSlack);

  SUBCASE("within a solve (no shrinking) stale pairs stay, however few are used") {
    const PairStencils few = first_pairs(10);
    CHECK_FALSE(pattern.update(few.stencils, few.slab_begin, false));
    CHECK(pattern.num_contact_pairs() == held);
    CHECK(pattern.version() == version);
    CHECK(stamp == built_stamp);
  }
  SUBCASE("at a step's start, one pair above the line keeps them") {
    const PairStencils used = first_pairs(shrink_below + 1);
    CHECK_FALSE(pattern.update(used.stencils, used.slab_begin, true));
    CHECK(pattern.num_contact_pairs() == held);
    CHECK(pattern.version() == version);
  }
  SUBCASE("at a step's start, on the line they are dropped to the pairs in use") {
    const PairStencils used = first_pairs(shrink_below);
    CHECK(pattern.update(used.stencils, used.slab_begin, true));
    CHECK(pattern.num_contact_pairs() == shrink_below);
    CHECK(pattern.version() > version);
    CHECK(pattern.pattern().nnz() == elastic.nnz() + 9 * shrink_below);
    // The history's pairs are the pattern's, under a new name (a rolled-back history differs).
    CHECK(pairs.size() == static_cast<size_t>(shrink_below));
    CHECK(stamp != built_stamp);
  }
  SUBCASE("a pair the pattern lacks rebuilds it, keeping the stale ones") {
    PairStencils grown = first_pairs(5);
    grown.add(kHalf - 1, kVertices - 1);
    CHECK(pattern.update(grown.stencils, grown.slab_begin, false));
    CHECK(pattern.num_contact_pairs() == held + 1);
  }
}

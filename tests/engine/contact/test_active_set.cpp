// Tests of engine/contact/active_set.hpp: the per-candidate cache carried through a rebuilt
// candidate list (as BarrierPotential::sweep rebuilds it) gives the same stencils as a fresh
// evaluation of every pair, with some vertices moved in between; pairs that move a little keep a
// lower bound on their distance while it stays beyond dhat.
// (The merging against every pair on its own, and the cache through BarrierPotential's masked
// sweeps: test_contact_potential.cpp.)
#include "engine/contact/active_set.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/contact/pair_geometry.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

using namespace nexdyn;

namespace {

// Two stacked boxes 0.01 m apart over a ground plane 0.02 m under the lower one.
Scene stacked_boxes() {
  Scene scene = test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.4, 0.4, 0.4], "cells": [2, 1, 2] }, "material": "a",
                  "translate": [0.03, 0.46, -0.02] } ]
  })", "active_set_boxes");
  ObstaclePlane ground;
  ground.point = Eigen::Vector3d(0.0, -0.27, 0.0);
  ground.normal = Eigen::Vector3d::UnitY();
  scene.model.obstacle_planes.push_back(ground);
  return scene;
}

void check_same(const ContactActiveSet& a, const ContactActiveSet& b) {
  CHECK(a.num_active_pairs() == b.num_active_pairs());
  CHECK(a.kinds() == b.kinds());
  CHECK(a.vertices() == b.vertices());
  CHECK(a.multiplicities() == b.multiplicities());
  CHECK(a.stencils() == b.stencils());
  CHECK(a.slab_begin() == b.slab_begin());
}

}  // namespace

TEST_CASE("active set: cache entries follow their pairs through a rebuilt candidate list") {
  const Scene scene = stacked_boxes();
  const Model& model = scene.model;
  const double dhat = 0.05;
  const std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 5);
  ContactCandidates old_list;
  find_contact_candidates(model, x.data(), nullptr, 0.5 * dhat, old_list);
  ContactActiveSet cached(model, dhat * dhat);
  cached.forget_pairs(old_list);
  cached.build(old_list, x.data());
  REQUIRE(cached.num_active_pairs() > 20);
  const int64_t count = std::accumulate(cached.multiplicities().begin(), cached.multiplicities().end(), int64_t{0});
  CHECK(count == cached.num_active_pairs());

  // Every third pair of each list dropped, every fifth kept one passed on as new (unknown), the
  // rest carried from their old index.
  ContactCandidates new_list;
  std::vector<int64_t> origin;
  int64_t old_index = 0;
  auto rebuild = [&](const std::vector<IndexPair>& from, std::vector<IndexPair>& to) {
    for (size_t i = 0; i < from.size(); ++i, ++old_index) {
      if (i % 3 == 0) continue;
      to.push_back(from[i]);
      origin.push_back(to.size() % 5 == 0 ? -1 : old_index);
    }
  };
  rebuild(old_list.vertex_triangle, new_list.vertex_triangle);
  rebuild(old_list.edge_edge, new_list.edge_edge);
  rebuild(old_list.vertex_plane, new_list.vertex_plane);
  REQUIRE(!new_list.vertex_plane.empty());
  cached.carry_pairs(old_list.size(), origin);

  // The upper box moves a little: its pairs are recomputed, the others come from the cache.
  std::vector<double> y = x;
  const BodyRange& upper = model.bodies[1];
  for (int32_t v = upper.vertex_begin; v < upper.vertex_begin + upper.vertex_count; ++v) y[3 * int64_t{v} + 1] -= 2e-3;
  cached.build(new_list, y.data());

  ContactActiveSet fresh(model, dhat * dhat);
  fresh.forget_pairs(new_list);
  fresh.build(new_list, y.data());
  REQUIRE(fresh.num_active_pairs() > 10);
  check_same(cached, fresh);
  CHECK(cached.min_squared_distance(new_list, y.data()) == fresh.min_squared_distance(new_list, y.data()));

  // A cache carried with the wrong origins (the identity) is caught: its stale entries differ.
  ContactActiveSet misled(model, dhat * dhat);
  misled.forget_pairs(old_list);
  misled.build(old_list, x.data());
  std::vector<int64_t> identity(new_list.size());
  std::iota(identity.begin(), identity.end(), int64_t{0});
  misled.carry_pairs(old_list.size(), identity);
  misled.build(new_list, y.data());
  CHECK(misled.stencils() != fresh.stencils());
}

TEST_CASE("active set: pairs brought within dhat by many small moves are found, the rest keep lower bounds") {
  // The upper box comes down onto the lower one in twelve moves of about 0.8 mm (each vertex
  // jittered by up to 0.2 mm), from 10 mm apart to about 0.4 mm, dhat 4 mm: every move is small
  // against the distances of most pairs, whose cached values are then carried as the old
  // distance less the motion. After each move the stencils must equal a fresh evaluation's, and
  // every cached distance must be exact within dhat and at most the true distance beyond.
  const Scene scene = stacked_boxes();
  const Model& model = scene.model;
  const double dhat = 0.004;
  std::vector<double> x = model.rest_positions;
  ContactCandidates list;
  find_contact_candidates(model, x.data(), nullptr, 0.5 * 0.03, list);  // pairs within 30 mm
  ContactActiveSet cached(model, dhat * dhat);
  cached.forget_pairs(list);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-2e-4, 2e-4);
  const BodyRange& upper = model.bodies[1];
  const int64_t nvt = static_cast<int64_t>(list.vertex_triangle.size());
  const int64_t nee = static_cast<int64_t>(list.edge_edge.size());
  auto p = [&](int32_t v) { return Eigen::Vector3d::Map(&x[3 * int64_t{v}]); };
  std::vector<double> motion, x_cached = x, cached_distance(nvt + nee, -1.0);  // (the cache's, at x_cached)
  for (int move = 0; move <= 12; ++move) {
    CAPTURE(move);
    if (move > 0)
      for (int32_t v = upper.vertex_begin; v < upper.vertex_begin + upper.vertex_count; ++v) {
        x[3 * v] += jitter(rng);
        x[3 * v + 1] += -8e-4 + jitter(rng);
        x[3 * v + 2] += jitter(rng);
      }
    // Before the refresh: the bounds from the cached distances, less the motion since, hold at x,
    // and are the cached distance less the pair's closing reach from the cached point, to the bit.
    // The bodies' bounds are the cached distance less each side's body's largest motion: never
    // above the pair's own bound, equal where the pair's sides hold their bodies' largest motions.
    int64_t bounded = 0, body_bounded = 0;
    cached.motion_since_cache(x.data(), motion);
    std::vector<double> body_motion, largest(model.bodies.size(), 0.0);
    cached.body_motion_since_cache(motion, body_motion);
    for (int32_t v = 0; v < model.num_vertices; ++v)
      largest[model.vertex_body[v]] = std::max(largest[model.vertex_body[v]], motion[v]);
    CHECK(body_motion == largest);
    for (int64_t i = 0; i < nvt + nee; ++i) {
      const PairVertices s = pair_geometry::candidate_vertices(model, list, i);
      const int split = i < nvt ? 1 : 2;
      const double bound = cached.distance_bound(i, s, split, motion.data());
      const double body_bound = cached.body_distance_bound(i, body_motion.data());
      if (body_bound > 0.0) {
        ++body_bounded;
        const int32_t a = model.vertex_body[s[0]], b = model.vertex_body[s[split]];
        CHECK(cached.side_bodies(i).first == a);
        CHECK(cached.side_bodies(i).second == b);
        CHECK(body_bound == cached_distance[i] - (largest[a] + largest[b]));
        CHECK(body_bound <= bound);
      }
      if (bound < 0.0) continue;
      ++bounded;
      CHECK(bound == cached_distance[i] - pair_geometry::closing_reach(s, split, x_cached.data(), x.data()));
      const double exact = i < nvt ? point_triangle_distance(p(s[0]), p(s[1]), p(s[2]), p(s[3]))
                                   : edge_edge_distance(p(s[0]), p(s[1]), p(s[2]), p(s[3]));
      CHECK(bound * bound <= exact * (1.0 + 1e-12));
    }
    if (move > 0) CHECK(bounded > 0);
    if (move > 0) CHECK(body_bounded > 0);
    cached.build(list, x.data());
    ContactActiveSet fresh(model, dhat * dhat);
    fresh.forget_pairs(list);
    fresh.build(list, x.data());
    check_same(cached, fresh);
    int64_t beyond = 0;
    x_cached = x;
    cached.motion_since_cache(x.data(), motion);
    CHECK(std::all_of(motion.begin(), motion.end(), [](double m) { return m == 0.0; }));
    for (int64_t i = 0; i < nvt + nee; ++i) {
      const PairVertices s = pair_geometry::candidate_vertices(model, list, i);
      const double exact = i < nvt ? point_triangle_distance(p(s[0]), p(s[1]), p(s[2]), p(s[3]))
                                   : edge_edge_distance(p(s[0]), p(s[1]), p(s[2]), p(s[3]));
      const double bound = cached.distance_bound(i, s, i < nvt ? 1 : 2, motion.data());  // (the cached one)
      cached_distance[i] = bound;
      const double d = bound * bound;
      if (exact < dhat * dhat) {
        CHECK(d == doctest::Approx(exact).epsilon(1e-12));
      } else {
        CHECK(d >= dhat * dhat);
        CHECK(d <= exact * (1.0 + 1e-12));
        ++beyond;
      }
    }
    CHECK(beyond > 0);
  }
  CHECK(cached.num_active_pairs() > 20);  // the boxes end in contact
}

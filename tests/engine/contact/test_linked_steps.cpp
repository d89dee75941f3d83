// Step caps of groups that pairs may link (BarrierPotential::linked_max_steps), on boxes in a row
// along x whose gaps are known exactly: a group keeps the cap of its own pairs when the pairs
// linking it to another group stay apart along the motion the two caps give together, and takes
// the smaller cap when they would not. The groups' own caps come from the same pairs taken
// alone: group_max_steps over each group's pairs (the others standing still).
#include "engine/contact/barrier_potential.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <limits>
#include <vector>

using namespace nexdyn;

namespace {

constexpr double kDhat = 0.002;  // the CCD stops at 0.1 dhat
constexpr double kSize = 0.1;    // cube edge
// The CCD stops a pair at a distance of about 0.01 to 0.1 dhat (kernels/ccd/ccd.hpp): the
// smallest gap a capped motion may leave, with some room.
constexpr double kClosest = 0.005 * kDhat;

// Cubes of edge 0.1 m (3 x 3 x 3 cells: hundreds of pairs between neighbours) whose lowest x
// faces are at `left` (m), centred on y = z = 0.
Scene cubes_at(const std::vector<double>& left) {
  std::string bodies;
  for (double l : left) {
    if (!bodies.empty()) bodies += ",";
    bodies += R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [3, 3, 3] }, "material": "a", "translate": [)" +
              std::to_string(l + 0.5 * kSize) + ", 0, 0] }";
  }
  return test::scene_from_json(R"({ "time": { "dt": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [)" + bodies + "] }", "linked_steps");
}

// Caps for bodies moving along x by shift[b] m each (0: the body stands still, in no group);
// body b is group b.
struct Caps {
  std::vector<double> own, settled;  // each group's pairs alone (group_max_steps), linked_max_steps
  std::vector<double> x, p;
  std::vector<int32_t> group;
};

Caps caps_for(const Model& model, const std::vector<double>& shift) {
  Caps c;
  c.x = model.rest_positions;
  c.p.assign(model.num_dofs(), 0.0);
  c.group.assign(model.num_vertices, -1);
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    const int32_t b = model.vertex_body[v];
    c.p[3 * v] = shift[b];
    if (shift[b] != 0.0) c.group[v] = b;
  }
  BarrierPotential contact(model, kDhat);
  contact.sweep(c.x.data(), c.p.data());
  c.settled.assign(shift.size(), 1.0);
  contact.linked_max_steps(c.x.data(), c.group.data(), static_cast<int32_t>(shift.size()), c.settled.data());
  // Each group moving alone, its neighbours standing still: the cap of its own motion.
  c.own.assign(shift.size(), 1.0);
  for (size_t b = 0; b < shift.size(); ++b) {
    if (shift[b] == 0.0) continue;
    std::vector<double> p(c.p.size(), 0.0);
    std::vector<int32_t> group(model.num_vertices, -1);
    for (int32_t v = 0; v < model.num_vertices; ++v)
      if (model.vertex_body[v] == static_cast<int32_t>(b)) p[3 * v] = c.p[3 * v], group[v] = 0;
    contact.sweep(c.x.data(), p.data());
    contact.group_max_steps(c.x.data(), group.data(), &c.own[b]);
  }
  return c;
}

// The smallest x gap between consecutive cubes after each moves by its cap (x - x extents of
// their vertices; the cubes stay axis-aligned, so this is their distance).
double smallest_gap_after(const Model& model, const Caps& c) {
  const size_t bodies = model.bodies.size();
  std::vector<double> lo(bodies, std::numeric_limits<double>::infinity());
  std::vector<double> hi(bodies, -std::numeric_limits<double>::infinity());
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    const int32_t b = model.vertex_body[v];
    const double alpha = c.group[v] < 0 ? 0.0 : c.settled[b];
    const double xv = c.x[3 * v] + alpha * c.p[3 * v];
    lo[b] = std::min(lo[b], xv);
    hi[b] = std::max(hi[b], xv);
  }
  double gap = std::numeric_limits<double>::infinity();
  for (size_t b = 0; b + 1 < bodies; ++b) gap = std::min(gap, lo[b + 1] - hi[b]);
  return gap;
}

}  // namespace

TEST_CASE("linked step caps: a group moving away from a capped neighbour keeps its own cap") {
  // A still wall W, then F 0.01 m from it, then E 0.01 m from F. F moves 0.5 m into the wall
  // (capped near 0.02), E 0.5 m away from F: their linking pairs open up, so E takes its whole
  // step. One cap for both (the groups joined over their pairs) would hold E to F's 0.02.
  const Scene scene = cubes_at({-0.05, 0.06, 0.17});
  const Caps c = caps_for(scene.model, {0.0, -0.5, 0.5});
  CHECK(c.own[1] > 0.015);
  CHECK(c.own[1] < 0.02);
  CHECK(c.own[2] == 1.0);
  CHECK(c.settled == c.own);
  CHECK(smallest_gap_after(scene.model, c) > kClosest);
}

TEST_CASE("linked step caps: a group whose own cap would run it into a slower neighbour takes that neighbour's cap") {
  // A, then B 0.01 m from it, then a still C 0.02 m from B. A and B both move 0.5 m towards C:
  // B hits C after 0.02 m (cap near 0.04). A's pairs with C allow it 0.13 m (cap near 0.26) and
  // its pairs with B, which moves with it, do not close; but with B held to 0.04, A would run
  // 0.11 m into B. Settled, A takes B's cap: further than A alone would go (0.01 m into a still
  // B, cap near 0.02), and along the motion the two caps give, every gap stays open.
  const Scene scene = cubes_at({-0.05, 0.06, 0.18});
  const Caps c = caps_for(scene.model, {0.5, 0.5, 0.0});
  CHECK(c.own[1] > 0.035);
  CHECK(c.own[1] < 0.04);
  CHECK(c.settled[1] == c.own[1]);
  CHECK(c.settled[0] == c.settled[1]);
  CHECK(c.own[0] < 0.02);
  CHECK(smallest_gap_after(scene.model, c) > kClosest);
}

TEST_CASE("linked step caps: a chain settles link by link, the same on 1 and 2 threads") {
  // Five cubes 0.01 m apart moving towards a still sixth 0.03 m beyond the last, each 0.05 m
  // slower than the one behind it: each pair of neighbours closes its gap at 0.2 of the step,
  // the front cube reaches the sixth at 0.1. Each cube behind would then run into the one ahead,
  // so the front cube's cap reaches down the chain over several rounds, and no gap closes.
  const Scene scene = cubes_at({0.0, 0.11, 0.22, 0.33, 0.44, 0.57});
  const std::vector<double> shift = {0.5, 0.45, 0.4, 0.35, 0.3, 0.0};
  std::vector<Caps> runs;
  for (int threads : {1, 2}) {
    test::ThreadsScope scope(threads);
    runs.push_back(caps_for(scene.model, shift));
  }
  const Caps& c = runs[0];
  CHECK(runs[1].settled == c.settled);
  CHECK(runs[1].own == c.own);
  CHECK(smallest_gap_after(scene.model, c) > kClosest);
  // All five take the front cube's cap, each further than it would go behind a still neighbour.
  CHECK(c.settled[4] == c.own[4]);
  CHECK(c.own[4] > 0.095);
  CHECK(c.own[4] < 0.1);
  for (int b = 0; b < 4; ++b) {
    CHECK(c.settled[b] == c.settled[4]);
    CHECK(c.own[b] < 0.03);
  }
}

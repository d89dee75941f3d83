// The skin of the solver's masked sweeps (BarrierPotential::sweep): a sweep whose moving vertices
// stay within the skin of the last search's segments keeps the list as it is, and that list must
// still hold every pair the motion brings within dhat (the brute-force search of the same motion),
// so that the CCD caps it as a fresh search would. Two affine cubes side by side along x; the
// left one moves towards the right one. The CCD over such a list skips the pairs that the active
// set's distances at the start show cannot close in (BarrierPotential::pair_ccd): its caps must be
// those of the CCD run on every pair.
#include "engine/contact/barrier_potential.hpp"
#include "engine/contact/candidates.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

constexpr double kDhat = 0.002;
constexpr double kSize = 0.1;  // cube edge

// Two affine cubes of 2 x 2 x 2 cells, the second `gap` m beyond the first along x.
Scene two_cubes(double gap) {
  auto body = [](double centre) {
    return R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [2, 2, 2] }, "material": "a", "translate": [)" +
           std::to_string(centre) + ", 0, 0] }";
  };
  return test::scene_from_json(R"({ "time": { "dt": 0.01 },
    "materials": { "a": { "model": "affine", "density": 1000 } },
    "bodies": [)" + body(0.0) + "," + body(kSize + gap) + "] }", "sweep_skin");
}

// The first cube's points (its followers) move by dx along x; its nodes and the second cube stay.
struct Motion {
  std::vector<double> p;
  std::vector<uint8_t> moving;
};
Motion first_cube_by(const Model& model, double dx) {
  Motion m;
  m.p.assign(model.num_dofs(), 0.0);
  m.moving.assign(model.num_vertices, 0);
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (model.vertex_body[v] != 0) continue;
    m.moving[v] = 1;
    if (model.follows_body(v)) m.p[3 * v] = dx;
  }
  return m;
}

// Whether every pair of `needed` is in `list` (both sorted).
bool holds_all(const ContactCandidates& list, const ContactCandidates& needed) {
  return std::includes(list.vertex_triangle.begin(), list.vertex_triangle.end(), needed.vertex_triangle.begin(),
                       needed.vertex_triangle.end()) &&
         std::includes(list.edge_edge.begin(), list.edge_edge.end(), needed.edge_edge.begin(),
                       needed.edge_edge.end()) &&
         std::includes(list.vertex_plane.begin(), list.vertex_plane.end(), needed.vertex_plane.begin(),
                       needed.vertex_plane.end());
}

bool same(const ContactCandidates& a, const ContactCandidates& b) {
  return a.vertex_triangle == b.vertex_triangle && a.edge_edge == b.edge_edge && a.vertex_plane == b.vertex_plane;
}

// x moved by `motion`.
std::vector<double> moved(const std::vector<double>& x, const Motion& motion) {
  std::vector<double> y = x;
  for (size_t i = 0; i < y.size(); ++i) y[i] += motion.p[i];
  return y;
}

// The CCD cap of `motion` from x over the pairs `contact` holds, its moving vertices one group.
double cap_over(BarrierPotential& contact, const std::vector<double>& x, const Motion& motion) {
  std::vector<int32_t> group(motion.moving.size(), -1);
  for (size_t v = 0; v < group.size(); ++v)
    if (motion.moving[v]) group[v] = 0;
  double alpha = 1.0;
  contact.group_max_steps(x.data(), group.data(), &alpha);
  return alpha;
}

// Every pair `motion` brings within dhat from x (the brute-force search).
ContactCandidates pairs_near(const Model& model, const std::vector<double>& x, const Motion& motion) {
  const std::vector<double> x1 = moved(x, motion);
  ContactCandidates pairs;
  find_contact_candidates_brute_force(model, x.data(), x1.data(), 0.5 * kDhat, pairs, motion.moving.data());
  return pairs;
}

// The two cubes 1.9 dhat apart, their pairs searched at rest; then a first sweep of `first`.
struct AfterFirstSweep {
  Scene scene = two_cubes(1.9 * kDhat);
  std::vector<double> x = scene.model.rest_positions;
  BarrierPotential contact{scene.model, kDhat};
  ContactCandidates after_first;
  explicit AfterFirstSweep(double first_dx) {
    contact.find_candidates(x.data(), nullptr);
    const Motion first = first_cube_by(scene.model, first_dx);
    contact.sweep(x.data(), first.p.data(), first.moving.data());
    after_first = contact.candidates();
  }
};

}  // namespace

TEST_CASE("sweep skin: a motion inside the last sweep's skin keeps its list, which holds every pair it brings near") {
  // Faces 1.9 dhat apart. The first sweep moves the left cube 0.5 dhat closer (1.4 dhat at its
  // end: no pair within dhat, but within dhat plus the 0.5 dhat skin). The cube stops there;
  // the next sweep moves it 0.45 dhat more, to 0.95 dhat: pairs come within dhat. That motion
  // stays inside the skin of the first segment, so the list is kept as it was, and it must hold
  // those pairs (the first search found them only through the skin).
  AfterFirstSweep s(0.5 * kDhat);
  const Model& model = s.scene.model;
  const std::vector<double> x = moved(s.x, first_cube_by(model, 0.5 * kDhat));  // where it stopped
  const Motion closer = first_cube_by(model, 0.45 * kDhat);
  const ContactCandidates needed = pairs_near(model, x, closer);
  REQUIRE(!needed.vertex_triangle.empty());
  s.contact.sweep(x.data(), closer.p.data(), closer.moving.data());
  CHECK(same(s.contact.candidates(), s.after_first));  // no search: the list as the first sweep left it
  CHECK(holds_all(s.contact.candidates(), needed));
  // The CCD over the kept list caps the motion as over a fresh search of it alone.
  BarrierPotential fresh(model, kDhat);
  fresh.sweep(x.data(), closer.p.data());
  CHECK(cap_over(s.contact, x, closer) == cap_over(fresh, x, closer));
}

TEST_CASE("sweep skin: a motion beyond the skin is searched again") {
  // The same cubes; a first sweep that opens the gap (no pair near), then a motion of 1.2 dhat
  // from rest into contact, beyond the first segment's skin: the list is searched again, so it
  // changes and holds every pair of the new motion.
  AfterFirstSweep s(-0.5 * kDhat);  // opening the gap: no pair near
  CHECK(s.after_first.vertex_triangle.empty());
  const Motion into = first_cube_by(s.scene.model, 1.2 * kDhat);
  const ContactCandidates needed = pairs_near(s.scene.model, s.x, into);
  REQUIRE(!needed.vertex_triangle.empty());
  s.contact.sweep(s.x.data(), into.p.data(), into.moving.data());
  CHECK(!same(s.contact.candidates(), s.after_first));
  CHECK(holds_all(s.contact.candidates(), needed));
}

TEST_CASE("sweep skin: the CCD answered from the active set's distances caps as the CCD of every pair") {
  // Cubes 0.5 dhat apart: their facing pairs are within dhat (exact distances in the active set),
  // the rest beyond (box-gap bounds). The left cube moves by -0.5 to 1.5 dhat along x, each point
  // jittered by up to 0.3 dhat: motions that stay clear, graze and run into the right cube. The
  // caps over the same list must be equal bit for bit whether the active set knows the pairs'
  // distances (at x, or bounds from where they were cached: the pairs the motion cannot bring
  // close skip the CCD) or not (a fresh potential: every pair runs it).
  const Scene scene = two_cubes(0.5 * kDhat);
  const Model& model = scene.model;
  const std::vector<double> x = model.rest_positions;
  std::vector<double> elsewhere = x;  // (the left cube one dhat to the left)
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.vertex_body[v] == 0) elsewhere[3 * v] -= kDhat;
  BarrierPotential contact(model, kDhat);
  uint64_t seed = 12345;
  auto jitter = [&] {  // in [-1, 1)
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(seed >> 11) * 0x1.0p-52 - 1.0;
  };
  int capped = 0, clear = 0;
  for (int k = 0; k <= 40; ++k) {
    Motion motion = first_cube_by(model, (-0.5 + 0.05 * k) * kDhat);
    for (int32_t v = 0; v < model.num_vertices; ++v)
      if (motion.moving[v] && model.follows_body(v))
        for (int d = 0; d < 3; ++d) motion.p[3 * v + d] += 0.3 * kDhat * jitter();
    contact.sweep(x.data(), motion.p.data());
    BarrierPotential fresh(model, kDhat);
    fresh.sweep(x.data(), motion.p.data());
    REQUIRE(same(contact.candidates(), fresh.candidates()));
    const double every_pair = cap_over(fresh, x, motion);
    contact.build_active_set(x.data());
    REQUIRE(contact.num_active_pairs() > 0);
    CHECK(cap_over(contact, x, motion) == every_pair);
    contact.build_active_set(elsewhere.data());
    CHECK(cap_over(contact, x, motion) == every_pair);
    (every_pair < 1.0 ? capped : clear) += 1;
  }
  CHECK(capped >= 10);  // the motions run into the cube and graze it, as well as stay clear
  CHECK(clear >= 5);
}

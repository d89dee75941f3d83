// Contact candidates (engine/contact/candidates) against the O(n^2) reference on the same boxes,
// static and swept, plus the property the co-moving frame of same-body pairs must keep: every
// pair that comes within 2 r at some time of the motion is a candidate of the sweep. Also the
// scans of bvh/blocked_boxes.hpp the broad phase is built on.
#include "engine/contact/candidates.hpp"
#include "bvh/blocked_boxes.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <random>
#include <string>

using namespace nexdyn;

namespace {

// A 3 x 2 x 1 array of boxes 0.02 m apart, a second body resting on them whose top is held by
// a boundary condition, a bowl obstacle mesh around the array and a ground plane: pairs within a
// body, across bodies, against a static mesh, between held vertices, and vertex-plane pairs.
Scene many_bodies() {
  const std::string bowl = std::string(NEXDYN_SOURCE_DIR) + "/scenes/meshes/bowl.obj";
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 }, "contact": { "dhat": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [
      { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a",
        "translate": [-0.2, -0.3, -0.1],
        "array": { "count": [3, 2, 1], "spacing": [0.22, 0.22, 0.22] } },
      { "box": { "size": [0.5, 0.1, 0.2], "cells": [4, 1, 2] }, "material": "a",
        "translate": [0.02, 0.075, 0.0] } ],
    "boundary": [ { "body": 1, "box_min": [-1, 0.12, -1], "box_max": [1, 1, 1], "fix": true } ],
    "obstacles": [ { "plane": { "point": [0, -0.405, 0], "normal": [0, 1, 0] } },
                   { "mesh": ")" + bowl + R"(", "scale": 1.8 } ]
  })", "candidates_many_bodies");
  return scene;
}

// Two plates of 32 x 32 cells, one resting 4 mm above the other: more than 2048 triangles and
// edges per body and per face, so same-body pairs and pairs across the gap take the tree paths
// that bodies too big to scan go through.
Scene two_plates() {
  return test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 }, "contact": { "dhat": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [
      { "box": { "size": [1, 0.05, 1], "cells": [32, 1, 32] }, "material": "a" },
      { "box": { "size": [1, 0.05, 1], "cells": [32, 1, 32] }, "material": "a",
        "translate": [0.01, 0.054, 0.0] } ]
  })", "candidates_two_plates");
}

// x0 -> x1: every free body moves by its own large translation (the co-moving frame's case) and
// jiggles; held vertices stay.
std::vector<double> moved(const Model& model, const std::vector<double>& x0, unsigned seed) {
  std::vector<double> x1 = test::perturbed(x0, 0.01, seed);
  std::mt19937 rng(seed + 7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::vector<Eigen::Vector3d> shift(model.bodies.size());
  for (auto& s : shift) s = Eigen::Vector3d(u(rng), u(rng) - 0.2, u(rng));
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (model.dirichlet[v] >= 0) {
      for (int d = 0; d < 3; ++d) x1[3 * v + d] = x0[3 * v + d];
      continue;
    }
    for (int d = 0; d < 3; ++d) x1[3 * v + d] += shift[model.vertex_body[v]][d];
  }
  return x1;
}

void check_equal(const ContactCandidates& a, const ContactCandidates& b) {
  CHECK(a.vertex_triangle == b.vertex_triangle);
  CHECK(a.edge_edge == b.edge_edge);
  CHECK(a.vertex_plane == b.vertex_plane);
}

bool contains(const std::vector<IndexPair>& sorted, const IndexPair& p) {
  return std::binary_search(sorted.begin(), sorted.end(), p);
}

}  // namespace

TEST_CASE("contact candidates equal the brute force, static and swept, on 1 and 2 threads") {
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 1);
  const std::vector<double> x1 = moved(model, x0, 2);
  for (const double* end : {static_cast<const double*>(nullptr), x1.data()}) {
    for (double inflation : {0.0, 0.005, 0.05}) {
      CAPTURE(inflation);
      CAPTURE(end != nullptr);
      ContactCandidates reference;
      find_contact_candidates_brute_force(model, x0.data(), end, inflation, reference);
      for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
        ContactCandidates fast;
        find_contact_candidates(model, x0.data(), end, inflation, fast);
        check_equal(fast, reference);
      }
      if (inflation > 0.0) {
        CHECK(!reference.vertex_triangle.empty());
        CHECK(!reference.edge_edge.empty());
        CHECK(!reference.vertex_plane.empty());
      }
      // The filters: no vertex against its own triangle, no edges sharing a vertex, and no pair
      // whose four vertices are all held (the bowl's triangles among themselves).
      for (const IndexPair& p : reference.vertex_triangle) {
        const int32_t* t = &model.surface_triangles[3 * int64_t{p.second}];
        CHECK((t[0] != p.first && t[1] != p.first && t[2] != p.first));
        CHECK((model.dirichlet[p.first] < 0 || model.dirichlet[t[0]] < 0 ||
               model.dirichlet[t[1]] < 0 || model.dirichlet[t[2]] < 0));
      }
    }
  }
}

TEST_CASE("contact candidates of bodies too big to scan equal the brute force") {
  const Scene scene = two_plates();
  const Model& model = scene.model;
  REQUIRE(model.bodies.size() == 2);
  CHECK(model.bodies[0].triangle_count > 4000);
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-4, 5);
  const std::vector<double> x1 = moved(model, x0, 6);
  for (const double* end : {static_cast<const double*>(nullptr), x1.data()}) {
    CAPTURE(end != nullptr);
    ContactCandidates reference;
    find_contact_candidates_brute_force(model, x0.data(), end, 0.005, reference);
    CHECK(!reference.vertex_triangle.empty());
    CHECK(!reference.edge_edge.empty());
    for (int threads : {1, 2}) {
      tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
      ContactCandidates fast;
      find_contact_candidates(model, x0.data(), end, 0.005, fast);
      check_equal(fast, reference);
    }
  }
}

TEST_CASE("a swept candidate list holds every pair close at some time of the motion") {
  // Bodies translating fast are where the co-moving frame of same-body pairs matters: sample the
  // motion and check that each pair close at a sample is in the swept list.
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 3);
  const std::vector<double> x1 = moved(model, x0, 4);
  constexpr double r = 0.005;
  ContactCandidates swept;
  find_contact_candidates(model, x0.data(), x1.data(), r, swept);
  int64_t checked = 0;
  for (double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
    std::vector<double> xt(x0.size());
    for (size_t i = 0; i < xt.size(); ++i) xt[i] = (1.0 - t) * x0[i] + t * x1[i];
    ContactCandidates at_t;
    find_contact_candidates(model, xt.data(), nullptr, r, at_t);
    for (const IndexPair& p : at_t.vertex_triangle) CHECK(contains(swept.vertex_triangle, p));
    for (const IndexPair& p : at_t.edge_edge) CHECK(contains(swept.edge_edge, p));
    for (const IndexPair& p : at_t.vertex_plane) CHECK(contains(swept.vertex_plane, p));
    checked += at_t.size();
  }
  CHECK(checked > 1000);
  // And the co-moving frame does prune: swept 0.3 m in the world frame, a body's primitives
  // would pair with every other one along their path; in its own frame the sweep only adds the
  // 0.01 m jiggle to what the start already has.
  auto same_body_pairs = [&](const ContactCandidates& c) {
    int64_t count = 0;
    for (const IndexPair& p : c.vertex_triangle)
      count += model.vertex_body[p.first] == model.vertex_body[model.surface_triangles[3 * int64_t{p.second}]];
    for (const IndexPair& p : c.edge_edge)
      count += model.vertex_body[model.surface_edges[2 * int64_t{p.first}]] ==
               model.vertex_body[model.surface_edges[2 * int64_t{p.second}]];
    return count;
  };
  ContactCandidates at_start;
  find_contact_candidates(model, x0.data(), nullptr, r, at_start);
  MESSAGE("same-body pairs: swept ", same_body_pairs(swept), ", at the start ", same_body_pairs(at_start));
  CHECK(same_body_pairs(swept) < 3 * same_body_pairs(at_start));
}

TEST_CASE("a blocked box list scan reports the overlapping boxes from an index on, in order") {
  // The scans behind the candidates: lists of every length around the block size, random boxes
  // and queries, every start index; against a loop over the boxes.
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> corner(0.0, 1.0), size(0.0, 0.1);
  const std::vector<int32_t> sizes = {0, 1, 7, 8, 9, 63, 64, 65, 300};
  std::vector<std::vector<double>> lower(sizes.size()), upper(sizes.size());
  BlockedBoxes lists;
  lists.layout(sizes);
  for (size_t l = 0; l < sizes.size(); ++l) {
    for (int32_t i = 0; i < sizes[l]; ++i) {
      for (int d = 0; d < 3; ++d) {
        lower[l].push_back(corner(rng));
        upper[l].push_back(lower[l].back() + size(rng));
      }
      lists.set(static_cast<int32_t>(l), i, &lower[l][3 * i], &upper[l][3 * i], 1000 * static_cast<int32_t>(l) + i);
    }
    lists.finish(static_cast<int32_t>(l));
  }
  std::vector<int32_t> found(300 + BlockedBoxes::kBlock);
  int64_t hits = 0;
  for (int q = 0; q < 200; ++q) {
    double lo[3], hi[3];
    for (int d = 0; d < 3; ++d) {
      lo[d] = corner(rng);
      hi[d] = lo[d] + 3.0 * size(rng);
    }
    for (size_t l = 0; l < sizes.size(); ++l)
      for (int32_t from = 0; from <= sizes[l]; ++from) {
        std::vector<int32_t> expected;
        for (int32_t i = from; i < sizes[l]; ++i)
          if (boxes_overlap(lower[l].data(), upper[l].data(), i, lo, hi, 0))
            expected.push_back(1000 * static_cast<int32_t>(l) + i);
        const int32_t n = lists.scan(static_cast<int32_t>(l), from, lo, hi, found.data());
        REQUIRE(std::vector<int32_t>(found.begin(), found.begin() + n) == expected);
        hits += n;
      }
  }
  CHECK(hits > 1000);
}

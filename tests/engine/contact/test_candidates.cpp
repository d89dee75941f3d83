// Contact candidates (engine/contact/candidates) against the O(n^2) reference on the same boxes,
// static and swept, plus the property the co-moving frame of same-body pairs must keep: every
// pair that comes within 2 r at some time of the motion is a candidate of the sweep. Also the
// scans of bvh/blocked_boxes.hpp the broad phase is built on, and the searches of a few moving
// bodies (a `moving` mask, BarrierPotential::sweep) against the full search.
#include "engine/contact/candidates.hpp"
#include "bvh/blocked_boxes.hpp"
#include "engine/contact/barrier_potential.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/isa.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <iterator>
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
        test::ThreadsScope limit(threads);
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

TEST_CASE("contact candidates with per-vertex pads equal the brute force, and pads only add pairs") {
  // Pads as the Newton sweep gives them (CoordinateMap::turn_pads): zero on most vertices, up to
  // a few centimetres on some. The search widens each vertex's box by its pad on every path (the
  // body boxes, the neighbour subsets, the planes), as the reference widens its boxes.
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 5);
  const std::vector<double> x1 = moved(model, x0, 6);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> pad(model.num_vertices, 0.0);
  for (double& p : pad)
    if (u(rng) < 0.2) p = 0.03 * u(rng);
  for (const double* end : {static_cast<const double*>(nullptr), x1.data()}) {
    CAPTURE(end != nullptr);
    ContactCandidates reference, padded, plain;
    find_contact_candidates_brute_force(model, x0.data(), end, 0.005, reference, nullptr, pad.data());
    for (int threads : {1, 2}) {
      test::ThreadsScope limit(threads);
      find_contact_candidates(model, x0.data(), end, 0.005, padded, nullptr, pad.data());
      check_equal(padded, reference);
    }
    find_contact_candidates(model, x0.data(), end, 0.005, plain);
    for_each_pair_list(model, [&](auto member, auto&&) {
      const std::vector<IndexPair>& more = padded.*member;
      const std::vector<IndexPair>& fewer = plain.*member;
      CHECK(std::includes(more.begin(), more.end(), fewer.begin(), fewer.end()));
    });
    CHECK(padded.vertex_triangle.size() > plain.vertex_triangle.size());
    CHECK(padded.edge_edge.size() > plain.edge_edge.size());
  }
}

TEST_CASE("contact candidates: none within one affine body, the rest equal the brute force") {
  // Two affine boxes of 2 x 2 x 2 cells and a tet box beside them, 1 cm apart: with a 5 cm
  // inflation every body's own primitives overlap. A rigid body's own pairs never come closer,
  // so the affine boxes have none; the tet box keeps its own, and the pairs across bodies stay.
  // An affine and a tet box far from the rest (no neighbours): the first is not searched at all,
  // the second still has its own pairs.
  const Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 }, "contact": { "dhat": 0.01 },
    "materials": { "a": { "model": "affine", "density": 1000 },
                   "t": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a",
                  "array": { "count": [2, 1, 1], "spacing": [0.21, 0, 0] } },
                { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "t",
                  "translate": [0.42, 0, 0] },
                { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a",
                  "translate": [2, 0, 0] },
                { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "t",
                  "translate": [0, 0, 2] } ]
  })", "candidates_affine");
  const Model& model = scene.model;
  REQUIRE(model.affine_bodies.size() == 3);
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 3);
  const std::vector<double> x1 = moved(model, x0, 4);
  for (const double* end : {static_cast<const double*>(nullptr), x1.data()}) {
    CAPTURE(end != nullptr);
    ContactCandidates reference, fast;
    find_contact_candidates_brute_force(model, x0.data(), end, 0.05, reference);
    find_contact_candidates(model, x0.data(), end, 0.05, fast);
    check_equal(fast, reference);
    const auto body = [&](int32_t v) { return model.vertex_body[v]; };
    const int32_t lone_tet = 4;  // the last body: the two arrayed boxes count as bodies 0 and 1
    REQUIRE(!model.materials[model.bodies[lone_tet].material].affine);
    int64_t own_tet = 0, across = 0, own_lone_tet = 0;
    for (const IndexPair& p : reference.vertex_triangle) {
      const int32_t a = body(p.first), b = body(model.surface_triangles[3 * int64_t{p.second}]);
      CHECK((a != b || !model.materials[model.bodies[a].material].affine));
      own_tet += a == b;
      across += a != b;
      own_lone_tet += a == lone_tet && b == lone_tet;
    }
    for (const IndexPair& p : reference.edge_edge) {
      const int32_t a = body(model.surface_edges[2 * int64_t{p.first}]);
      const int32_t b = body(model.surface_edges[2 * int64_t{p.second}]);
      CHECK((a != b || !model.materials[model.bodies[a].material].affine));
    }
    CHECK(own_tet > own_lone_tet);
    CHECK(own_lone_tet > 0);
    CHECK(across > 0);
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
      test::ThreadsScope limit(threads);
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

namespace {

// Which instruction-set paths of the box scans this CPU runs, and which the tests must skip
// because it lacks them (build.sh prints this line after the suite, so a skip is never silent).
std::string isa_paths_line() {
  std::string ran, skipped;
  for (Isa isa : kAllIsas)
    (static_cast<int>(isa) > static_cast<int>(detected_isa()) ? skipped : ran) += std::string(" ") + isa_name(isa);
  return "instruction-set paths tested:" + ran + "; skipped, as this CPU lacks them:" + (skipped.empty() ? " none" : skipped);
}

}  // namespace

TEST_CASE("a blocked box list scan reports the overlapping boxes from an index on, in order, on every path") {
  // The scans behind the candidates: lists of every length around the block size, random boxes
  // and queries, every start index; against a loop over the boxes. Some queries touch a box
  // exactly (a shared face, edge or corner: closed intervals overlap there). Every
  // instruction-set path this CPU runs (kernels/isa.hpp) must give exactly the loop's ids.
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
  std::vector<std::array<double, 6>> queries;
  for (int q = 0; q < 200; ++q) {
    std::array<double, 6> box;
    for (int d = 0; d < 3; ++d) {
      box[d] = corner(rng);
      box[3 + d] = box[d] + 3.0 * size(rng);
    }
    queries.push_back(box);
  }
  for (int q = 0; q < 100; ++q) {  // boxes of list 8 shifted to touch box q's upper x face
    const double* lo = &lower[8][3 * q];
    const double* hi = &upper[8][3 * q];
    queries.push_back({hi[0], lo[1], lo[2], hi[0] + 0.05, hi[1], hi[2]});
  }
  const Isa restore = active_isa();
  std::vector<int32_t> found(300 + BlockedBoxes::kBlock);
  MESSAGE(isa_paths_line());
  for (Isa isa : kAllIsas) {
    if (static_cast<int>(isa) > static_cast<int>(detected_isa())) continue;
    set_active_isa(isa);
    CAPTURE(isa_name(isa));
    int64_t hits = 0, touching = 0;
    for (const std::array<double, 6>& box : queries) {
      const double* lo = &box[0];
      const double* hi = &box[3];
      for (size_t l = 0; l < sizes.size(); ++l)
        for (int32_t from = 0; from <= sizes[l]; ++from) {
          std::vector<int32_t> expected;
          for (int32_t i = from; i < sizes[l]; ++i)
            if (boxes_overlap(lower[l].data(), upper[l].data(), i, lo, hi, 0)) {
              expected.push_back(1000 * static_cast<int32_t>(l) + i);
              for (int d = 0; d < 3; ++d)
                touching += lower[l][3 * i + d] == hi[d] || upper[l][3 * i + d] == lo[d];
            }
          const int32_t n = lists.scan(static_cast<int32_t>(l), from, lo, hi, found.data());
          REQUIRE(std::vector<int32_t>(found.begin(), found.begin() + n) == expected);
          hits += n;
        }
    }
    CHECK(hits > 1000);
    CHECK(touching > 100);
  }
  set_active_isa(restore);
}

TEST_CASE("contact candidates are the same on every instruction-set path") {
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 3);
  const std::vector<double> x1 = moved(model, x0, 4);
  const Isa restore = active_isa();
  set_active_isa(Isa::scalar);
  ContactCandidates reference;
  find_contact_candidates(model, x0.data(), x1.data(), 0.005, reference);
  CHECK(reference.size() > 1000);
  MESSAGE(isa_paths_line());
  for (Isa isa : kAllIsas) {
    if (static_cast<int>(isa) > static_cast<int>(detected_isa())) continue;
    CAPTURE(isa_name(isa));
    set_active_isa(isa);
    ContactCandidates c;
    find_contact_candidates(model, x0.data(), x1.data(), 0.005, c);
    CHECK(c.vertex_triangle == reference.vertex_triangle);
    CHECK(c.edge_edge == reference.edge_edge);
    CHECK(c.vertex_plane == reference.vertex_plane);
  }
  set_active_isa(restore);
}

// ---- searches of a few moving bodies (the island solver's CCD sweep, solver/newton.cpp) ---------

namespace {

// Whether a candidate pair of each list has a vertex with mask[v] != 0.
struct PairVertices {
  const Model& m;
  bool vertex_triangle(const IndexPair& p, const std::vector<uint8_t>& mask) const {
    const int32_t* t = &m.surface_triangles[3 * int64_t{p.second}];
    return mask[p.first] || mask[t[0]] || mask[t[1]] || mask[t[2]];
  }
  bool edge_edge(const IndexPair& p, const std::vector<uint8_t>& mask) const {
    const int32_t* a = &m.surface_edges[2 * int64_t{p.first}];
    const int32_t* b = &m.surface_edges[2 * int64_t{p.second}];
    return mask[a[0]] || mask[a[1]] || mask[b[0]] || mask[b[1]];
  }
  bool vertex_plane(const IndexPair& p, const std::vector<uint8_t>& mask) const { return mask[p.first] != 0; }
};

// The pairs of c with (touching = true) or without a vertex in the mask, in c's order.
ContactCandidates filtered(const Model& m, const ContactCandidates& c, const std::vector<uint8_t>& mask, bool touching) {
  const PairVertices pv{m};
  ContactCandidates out;
  for (const IndexPair& p : c.vertex_triangle)
    if (pv.vertex_triangle(p, mask) == touching) out.vertex_triangle.push_back(p);
  for (const IndexPair& p : c.edge_edge)
    if (pv.edge_edge(p, mask) == touching) out.edge_edge.push_back(p);
  for (const IndexPair& p : c.vertex_plane)
    if (pv.vertex_plane(p, mask) == touching) out.vertex_plane.push_back(p);
  return out;
}

// The free (not held) vertices of these bodies.
std::vector<uint8_t> free_vertices_of(const Model& m, std::initializer_list<int32_t> bodies) {
  std::vector<uint8_t> mask(m.num_vertices, 0);
  for (int32_t b : bodies)
    for (int32_t v = m.bodies[b].vertex_begin; v < m.bodies[b].vertex_begin + m.bodies[b].vertex_count; ++v)
      mask[v] = m.dirichlet[v] < 0;
  return mask;
}

bool strictly_increasing(const std::vector<IndexPair>& pairs) {
  return std::adjacent_find(pairs.begin(), pairs.end(), [](const IndexPair& a, const IndexPair& b) { return !(a < b); }) ==
         pairs.end();
}

std::vector<IndexPair> difference(const std::vector<IndexPair>& a, const std::vector<IndexPair>& b) {
  std::vector<IndexPair> out;
  std::set_difference(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

}  // namespace

TEST_CASE("contact candidates with a moving mask are the full search's pairs with a moving vertex") {
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  REQUIRE(model.bodies.size() == 8);  // 6 boxes, the partly held plate, the bowl
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 1e-3, 21);
  // Bodies 0, 3, 4 and the plate move; the others stay (x1 = x0 there).
  const std::vector<uint8_t> movers = free_vertices_of(model, {0, 3, 4, 6});
  const std::vector<double> everyone_moved = moved(model, x0, 22);
  std::vector<double> x1 = x0;
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (movers[v])
      for (int d = 0; d < 3; ++d) x1[3 * v + d] = everyone_moved[3 * v + d];
  // Masks: the moving bodies; a random subset of their free vertices; nothing.
  std::mt19937 rng(23);
  std::vector<uint8_t> some_vertices = movers;
  for (uint8_t& m : some_vertices) m = m && (rng() % 3 == 0);
  const std::vector<uint8_t>& some = some_vertices;
  const std::vector<uint8_t> nothing(model.num_vertices, 0);
  for (const double* end : {static_cast<const double*>(nullptr), static_cast<const double*>(x1.data())}) {
    for (double inflation : {0.005, 0.05}) {
      ContactCandidates full;
      find_contact_candidates(model, x0.data(), end, inflation, full);
      for (const std::vector<uint8_t>* mask : {&movers, &some, &nothing}) {
        CAPTURE(end != nullptr);
        CAPTURE(inflation);
        CAPTURE(mask == &movers ? "moving bodies" : mask == &some ? "some vertices" : "nothing");
        const ContactCandidates expected = filtered(model, full, *mask, true);
        if (mask == &nothing) {
          CHECK(expected.size() == 0);
        } else {
          CHECK(!expected.vertex_triangle.empty());
          CHECK(!expected.edge_edge.empty());
          CHECK(!expected.vertex_plane.empty());
          CHECK(expected.size() < full.size());  // the mask does leave pairs out
        }
        ContactCandidates brute;
        find_contact_candidates_brute_force(model, x0.data(), end, inflation, brute, mask->data());
        check_equal(brute, expected);
        for (int threads : {1, 2}) {
          CAPTURE(threads);
          test::ThreadsScope limit(threads);
          ContactCandidates fast;
          find_contact_candidates(model, x0.data(), end, inflation, fast, mask->data());
          check_equal(fast, expected);
        }
      }
    }
  }
}

TEST_CASE("a barrier sweep with a moving mask keeps the still pairs and searches the moving ones") {
  // The previous search covers x0 -> x_prev. Body 4 swept far and is back at its start; the other
  // still bodies are half way along their (small) motions: none of them has moved since that
  // search covered where it is. Bodies 0, 2 and the plate then sweep x -> x + p.
  const Scene scene = many_bodies();
  const Model& model = scene.model;
  const double dhat = 0.01;
  const std::vector<uint8_t> moving = free_vertices_of(model, {0, 2, 6});
  const std::vector<double> x0 = test::perturbed(model.rest_positions, 5e-4, 31);
  std::vector<double> x_prev = test::perturbed(x0, 5e-4, 32), x = x0, p(model.num_dofs(), 0.0);
  std::mt19937 rng(33);
  std::uniform_real_distribution<double> u(-1.5e-3, 1.5e-3);
  for (size_t b = 0; b < model.bodies.size(); ++b) {
    const Eigen::Vector3d shift = b == 4 ? Eigen::Vector3d(-0.03, 0.15, 0.02) : Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d step(u(rng), u(rng), u(rng));
    const double t = b == 4 ? 0.0 : 0.5;
    const BodyRange& body = model.bodies[b];
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * int64_t{v} + d;
        if (model.dirichlet[v] >= 0) {
          x_prev[i] = x0[i];
          continue;
        }
        x_prev[i] += shift[d];
        x[i] = x0[i] + t * (x_prev[i] - x0[i]);
        if (moving[v]) p[i] = step[d] + 0.3 * u(rng);
      }
  }

  BarrierPotential contact(model, dhat);
  contact.find_candidates(x0.data(), x_prev.data());
  const ContactCandidates previous = contact.candidates();
  contact.sweep(x.data(), p.data(), moving.data());
  const ContactCandidates& masked = contact.candidates();
  BarrierPotential reference(model, dhat);
  reference.sweep(x.data(), p.data());
  const ContactCandidates& full = reference.candidates();

  // Exactly: the pairs with a moving vertex are the full sweep's, the others the previous search's.
  const ContactCandidates fresh = filtered(model, masked, moving, true), kept = filtered(model, masked, moving, false);
  check_equal(fresh, filtered(model, full, moving, true));
  check_equal(kept, filtered(model, previous, moving, false));
  CHECK(!fresh.vertex_triangle.empty());
  CHECK(!fresh.edge_edge.empty());
  CHECK(!fresh.vertex_plane.empty());
  CHECK(!kept.vertex_triangle.empty());
  CHECK(!kept.edge_edge.empty());
  CHECK(!kept.vertex_plane.empty());

  // So the lists stay sorted, nothing of the full sweep is missing, and what the full sweep does
  // not have are still pairs of the previous search, farther than dhat apart at x (and, still, on
  // the whole sweep): they cannot change an energy, a gradient or a CCD bound.
  const double dhat2 = dhat * dhat;
  auto pt = [&](int32_t v) { return Eigen::Vector3d::Map(&x[3 * int64_t{v}]); };
  const std::vector<IndexPair> vt = difference(masked.vertex_triangle, full.vertex_triangle);
  const std::vector<IndexPair> ee = difference(masked.edge_edge, full.edge_edge);
  const std::vector<IndexPair> vp = difference(masked.vertex_plane, full.vertex_plane);
  CHECK(strictly_increasing(masked.vertex_triangle));
  CHECK(strictly_increasing(masked.edge_edge));
  CHECK(strictly_increasing(masked.vertex_plane));
  CHECK(masked.vertex_triangle.size() == full.vertex_triangle.size() + vt.size());
  CHECK(masked.edge_edge.size() == full.edge_edge.size() + ee.size());
  CHECK(masked.vertex_plane.size() == full.vertex_plane.size() + vp.size());
  for (const IndexPair& pr : vt) {
    const int32_t* t = &model.surface_triangles[3 * int64_t{pr.second}];
    CHECK(point_triangle_distance(pt(pr.first), pt(t[0]), pt(t[1]), pt(t[2])) > dhat2);
    CHECK(contains(kept.vertex_triangle, pr));
  }
  for (const IndexPair& pr : ee) {
    const int32_t* a = &model.surface_edges[2 * int64_t{pr.first}];
    const int32_t* b = &model.surface_edges[2 * int64_t{pr.second}];
    CHECK(edge_edge_distance(pt(a[0]), pt(a[1]), pt(b[0]), pt(b[1])) > dhat2);
    CHECK(contains(kept.edge_edge, pr));
  }
  for (const IndexPair& pr : vp) {
    const ObstaclePlane& plane = model.obstacle_planes[pr.second];
    CHECK((pt(pr.first) - plane.point).dot(plane.normal) > dhat);
    CHECK(contains(kept.vertex_plane, pr));
  }
  CHECK(vt.size() > 0);  // body 4's long sweep left pairs with body 5 that are out of range now
  CHECK(ee.size() > 0);

  // The barrier along the sweep is the full sweep's.
  for (double t : {0.0, 0.5, 1.0}) {
    CAPTURE(t);
    std::vector<double> y(x.size());
    for (size_t i = 0; i < y.size(); ++i) y[i] = x[i] + t * p[i];
    const double a = contact.energy(y.data()), b = reference.energy(y.data());
    REQUIRE(std::isfinite(b));
    CHECK(b > 0.0);
    CHECK(std::abs(a - b) <= 1e-12 * b);
  }
}

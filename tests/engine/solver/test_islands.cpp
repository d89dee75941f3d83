// Islands of the Newton system (engine/sparse/islands.hpp) and their linear systems
// (engine/sparse/island_system.hpp), against independent references: the union-find against a
// naive relabelling and a breadth-first search on random graphs, the islands of real multi-body
// models against a breadth-first search over tets and stencils, and every island's solve
// (dense, simplicial and supernodal CHOLMOD) against an Eigen LDL^T of the whole matrix.
// Indefinite blocks must be refused on every path: CHOLMOD's simplicial factor is an LDL^T
// unless common->final_ll asks for LL^T, and an LDL^T accepts an indefinite matrix.
#include "engine/potential/elastic_assembly.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "engine/sparse/island_system.hpp"
#include "engine/sparse/islands.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <queue>
#include <random>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

// Connected components of an undirected graph by breadth-first search; each vertex is labelled
// with the smallest vertex of its component.
std::vector<int32_t> smallest_member_labels(const std::vector<std::vector<int32_t>>& adjacency) {
  const int32_t n = static_cast<int32_t>(adjacency.size());
  std::vector<int32_t> label(n, -1);
  for (int32_t s = 0; s < n; ++s) {
    if (label[s] >= 0) continue;
    // s is the smallest unvisited vertex, so the smallest of its component.
    std::queue<int32_t> queue;
    queue.push(s);
    label[s] = s;
    while (!queue.empty()) {
      const int32_t v = queue.front();
      queue.pop();
      for (int32_t w : adjacency[v])
        if (label[w] < 0) {
          label[w] = s;
          queue.push(w);
        }
    }
  }
  return label;
}

}  // namespace

TEST_CASE("disjoint sets: the root is the smallest member after any joins, components equal a BFS") {
  std::mt19937 rng(20261201);
  int64_t merges = 0;
  for (int trial = 0; trial < 40; ++trial) {
    CAPTURE(trial);
    const int32_t n = 1 + static_cast<int32_t>(rng() % 400);
    // From a few edges to well past the giant component; self loops and repeats included.
    const int32_t num_edges = static_cast<int32_t>(rng() % (2 * n + 1));
    std::uniform_int_distribution<int32_t> vertex(0, n - 1);
    DisjointSets sets;
    sets.reset(n);
    REQUIRE(sets.size() == n);
    std::vector<int32_t> naive(n);  // smallest member, relabelled on every join
    std::iota(naive.begin(), naive.end(), 0);
    std::vector<std::vector<int32_t>> adjacency(n);
    for (int32_t e = 0; e < num_edges; ++e) {
      // Some trials join in decreasing order (every new root smaller than the old one).
      int32_t a = vertex(rng), b = vertex(rng);
      if (trial % 4 == 1) {
        a = n - 1 - e % n;
        b = std::max(0, a - 1);
      }
      sets.join(a, b);
      adjacency[a].push_back(b);
      adjacency[b].push_back(a);
      const int32_t from = std::max(naive[a], naive[b]), to = std::min(naive[a], naive[b]);
      if (from != to) {
        ++merges;
        for (int32_t& l : naive)
          if (l == from) l = to;
      }
      REQUIRE(sets.find(a) == naive[a]);
      REQUIRE(sets.find(b) == naive[b]);
    }
    const std::vector<int32_t> reference = smallest_member_labels(adjacency);
    CHECK(reference == naive);
    std::vector<int32_t> found(n);
    for (int32_t v = 0; v < n; ++v) found[v] = sets.find(v);
    CHECK(found == reference);
    // Every root is its own parent, and the parents stay inside the component.
    for (int32_t v = 0; v < n; ++v) {
      CHECK(sets.parents()[reference[v]] == reference[v]);
      CHECK(reference[sets.parents()[v]] == reference[v]);
    }
  }
  CHECK(merges > 1000);
}

namespace {

// Four bodies well apart: three boxes of 2^3 cells (27 vertices each) and a 1 x 1 x 2 column
// (12 vertices) whose middle layer of vertices, once held, cuts it in two.
Scene four_bodies() {
  return test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a",
                  "array": { "count": [3, 1, 1], "spacing": [0.5, 0.5, 0.5] } },
                { "box": { "size": [0.1, 0.1, 0.2], "cells": [1, 1, 2] }, "material": "a",
                  "translate": [0, 1, 0] } ]
  })", "islands_four_bodies");
}

// The islands by definition: components of the moving vertices linked by a tet or by a stencil
// (num x 4, -1 = none) through moving vertices only, numbered by their smallest vertex; -1 for
// a vertex that does not move.
std::vector<int32_t> reference_islands(const Model& model, const std::vector<uint8_t>& moving,
                                       const std::vector<std::vector<int32_t>>& stencil_lists) {
  std::vector<std::vector<int32_t>> adjacency(model.num_vertices);
  auto link = [&](const int32_t* ids, int count) {
    for (int a = 0; a < count; ++a)
      for (int b = 0; b < count; ++b)
        if (ids[a] >= 0 && ids[b] >= 0 && ids[a] != ids[b] && moving[ids[a]] && moving[ids[b]])
          adjacency[ids[a]].push_back(ids[b]);
  };
  for (int32_t t = 0; t < model.num_tets; ++t) link(&model.tets[4 * int64_t{t}], 4);
  for (const std::vector<int32_t>& list : stencil_lists)
    for (size_t k = 0; k + 4 <= list.size(); k += 4) link(&list[k], 4);
  const std::vector<int32_t> root = smallest_member_labels(adjacency);
  std::vector<int32_t> island(model.num_vertices, -1), number(model.num_vertices, -1);
  int32_t count = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (!moving[v]) continue;
    if (number[root[v]] < 0) number[root[v]] = count++;
    island[v] = number[root[v]];
  }
  return island;
}

// Islands' own bookkeeping: every moving vertex in exactly one island, lists increasing, islands
// ordered by their first vertex, local_index its place in the list, -1 for the rest.
void check_consistent(const Islands& islands, const std::vector<uint8_t>& moving) {
  const int32_t n = static_cast<int32_t>(moving.size());
  const std::vector<int32_t>& ptr = islands.vertex_ptr();
  const std::vector<int32_t>& vertices = islands.vertices();
  REQUIRE(static_cast<int32_t>(ptr.size()) == islands.num_islands() + 1);
  CHECK(ptr.front() == 0);
  CHECK(ptr.back() == std::count(moving.begin(), moving.end(), uint8_t{1}));
  REQUIRE(static_cast<int32_t>(vertices.size()) == ptr.back());
  std::vector<int32_t> seen(n, 0);
  for (int32_t i = 0; i < islands.num_islands(); ++i) {
    CAPTURE(i);
    REQUIRE(ptr[i] < ptr[i + 1]);  // no empty island
    CHECK(islands.island_size(i) == ptr[i + 1] - ptr[i]);
    if (i > 0) CHECK(vertices[ptr[i - 1]] < vertices[ptr[i]]);  // numbered by smallest vertex
    for (int32_t k = ptr[i]; k < ptr[i + 1]; ++k) {
      const int32_t v = vertices[k];
      if (k > ptr[i]) CHECK(vertices[k - 1] < v);
      CHECK(moving[v]);
      CHECK(islands.island_of(v) == i);
      CHECK(islands.local_index(v) == k - ptr[i]);
      ++seen[v];
    }
  }
  for (int32_t v = 0; v < n; ++v) {
    CHECK(seen[v] == (moving[v] ? 1 : 0));
    if (!moving[v]) {
      CHECK(islands.island_of(v) == -1);
      CHECK(islands.local_index(v) == -1);
    }
  }
  CHECK(islands.island_of_vertex().size() == moving.size());
  CHECK(islands.local_indices().size() == moving.size());
}

// Builds the islands with these stencil lists and checks them against the reference.
void build_and_check(Islands& islands, const Model& model, const std::vector<uint8_t>& moving,
                     const std::vector<std::vector<int32_t>>& lists) {
  std::vector<const std::vector<int32_t>*> pointers;
  for (const auto& list : lists) pointers.push_back(&list);
  islands.build(pointers);
  check_consistent(islands, moving);
  CHECK(islands.island_of_vertex() == reference_islands(model, moving, lists));
}

int32_t vertex_of(const Model& model, int32_t body, int32_t k) { return model.bodies[body].vertex_begin + k; }

}  // namespace

TEST_CASE("islands: one per body, joined by stencils, numbered by smallest vertex") {
  const Scene scene = four_bodies();
  const Model& model = scene.model;
  REQUIRE(model.bodies.size() == 4);
  const ElasticAssembly elastic(model);
  Islands islands(elastic.pattern(), model.num_vertices);
  const std::vector<uint8_t> all(model.num_vertices, 1);

  build_and_check(islands, model, all, {});
  REQUIRE(islands.num_islands() == 4);
  for (int32_t b = 0; b < 4; ++b)
    for (int32_t v = 0; v < model.bodies[b].vertex_count; ++v) CHECK(islands.island_of(vertex_of(model, b, v)) == b);

  // A vertex-vertex stencil between bodies 0 and 2 merges them; body 1 keeps the next number.
  const int32_t a = vertex_of(model, 0, 5), c = vertex_of(model, 2, 20);
  build_and_check(islands, model, all, {{a, c, -1, -1}});
  CHECK(islands.num_islands() == 3);
  CHECK(islands.island_of(a) == 0);
  CHECK(islands.island_of(c) == 0);
  CHECK(islands.island_of(vertex_of(model, 1, 0)) == 1);
  CHECK(islands.island_of(vertex_of(model, 3, 0)) == 2);
  CHECK(islands.island_size(0) == model.bodies[0].vertex_count + model.bodies[2].vertex_count);

  // Several lists, 3- and 4-vertex stencils, padding at any place: all four bodies become one.
  build_and_check(islands, model, all,
                  {{vertex_of(model, 3, 1), -1, vertex_of(model, 1, 7), -1},
                   {-1, -1, -1, -1, vertex_of(model, 1, 3), vertex_of(model, 1, 4), vertex_of(model, 2, 0), -1},
                   {a, vertex_of(model, 0, 6), vertex_of(model, 0, 7), vertex_of(model, 2, 26)}});
  CHECK(islands.num_islands() == 1);

  // A build starts again from the tets: the stencils of the last one are forgotten.
  build_and_check(islands, model, all, {});
  CHECK(islands.num_islands() == 4);
}

TEST_CASE("islands: vertices that do not move are in no island and couple nothing") {
  const Scene scene = four_bodies();
  const Model& model = scene.model;
  const ElasticAssembly elastic(model);
  Islands islands(elastic.pattern(), model.num_vertices);

  // Body 1 held: its vertices leave, and a stencil through one of them joins nothing.
  std::vector<uint8_t> moving(model.num_vertices, 1);
  for (int32_t v = 0; v < model.bodies[1].vertex_count; ++v) moving[vertex_of(model, 1, v)] = 0;
  islands.set_moving(moving);
  const int32_t a = vertex_of(model, 0, 3), held = vertex_of(model, 1, 2), c = vertex_of(model, 2, 3);
  build_and_check(islands, model, moving, {});
  CHECK(islands.num_islands() == 3);
  build_and_check(islands, model, moving, {{a, held, -1, -1, held, c, -1, -1}});
  CHECK(islands.num_islands() == 3);
  CHECK(islands.island_of(a) != islands.island_of(c));
  CHECK(islands.island_of(held) == -1);
  // Two moving vertices of one stencil are joined even with a held vertex between them.
  build_and_check(islands, model, moving, {{a, held, c, -1}});
  CHECK(islands.num_islands() == 2);
  CHECK(islands.island_of(a) == islands.island_of(c));

  // The column's middle layer held: no tet couples its two ends, so it is two islands.
  const BodyRange& column = model.bodies[3];
  double z_lo = 1e9, z_hi = -1e9;
  for (int32_t k = 0; k < column.vertex_count; ++k) {
    const double z = model.rest_positions[3 * int64_t{vertex_of(model, 3, k)} + 2];
    z_lo = std::min(z_lo, z);
    z_hi = std::max(z_hi, z);
  }
  std::fill(moving.begin(), moving.end(), 1);
  int32_t middle = 0;
  for (int32_t k = 0; k < column.vertex_count; ++k) {
    const int32_t v = vertex_of(model, 3, k);
    if (std::abs(model.rest_positions[3 * int64_t{v} + 2] - 0.5 * (z_lo + z_hi)) < 1e-9) {
      moving[v] = 0;
      ++middle;
    }
  }
  REQUIRE(middle == 4);
  islands.set_moving(moving);
  build_and_check(islands, model, moving, {});
  CHECK(islands.num_islands() == 5);

  // Random held sets and random stencils (with padding) against the reference.
  std::mt19937 rng(77);
  std::uniform_int_distribution<int32_t> any(-1, model.num_vertices - 1);
  for (int trial = 0; trial < 30; ++trial) {
    CAPTURE(trial);
    for (auto& m : moving) m = (rng() % 5) != 0;
    islands.set_moving(moving);
    std::vector<std::vector<int32_t>> lists(1 + rng() % 3);
    for (auto& list : lists) {
      list.resize(4 * (rng() % 6));
      for (int32_t& v : list) v = any(rng);
    }
    build_and_check(islands, model, moving, lists);
  }

  // Everything moving again: the held body is back as its own island.
  std::fill(moving.begin(), moving.end(), 1);
  islands.set_moving(moving);
  build_and_check(islands, model, moving, {});
  CHECK(islands.num_islands() == 4);
}

// ---- IslandSystem ---------------------------------------------------------------------------

namespace {

// A block diagonal SPD matrix on a global pattern: the projected elastic Hessian of a deformed
// state times dt^2 plus the lumped mass (a real Newton matrix), or random diagonally dominant
// values. The global pattern is the tets' plus blocks between bodies (a fake tet per pair of
// bodies, like the stored zeros a contact pattern keeps after the contact is gone): their values
// are 0, and the islands come from the tets alone.
struct IslandProblem {
  Scene scene;
  HessianPattern global;
  std::vector<int32_t> tets_and_links;
  std::vector<double> newton_values, random_values, rhs;
  std::unique_ptr<ElasticAssembly> elastic;
  std::unique_ptr<Islands> islands;
  int64_t cross_entries = 0;  // stored entries between islands

  explicit IslandProblem(Scene s) : scene(std::move(s)) {
    const Model& model = scene.model;
    elastic = std::make_unique<ElasticAssembly>(model);
    islands = std::make_unique<Islands>(elastic->pattern(), model.num_vertices);
    islands->build({});
    tets_and_links = model.tets;
    for (size_t b = 0; b + 1 < model.bodies.size(); ++b) {
      const BodyRange& p = model.bodies[b];
      const BodyRange& q = model.bodies[b + 1];
      tets_and_links.insert(tets_and_links.end(), {p.vertex_begin, p.vertex_begin + p.vertex_count - 1,
                                                   q.vertex_begin + 1, q.vertex_begin + q.vertex_count / 2});
    }
    global = build_tet_hessian_pattern(model.num_vertices, tets_and_links);

    // Newton values: the elastic pattern's values placed into the global one (rows of a column are
    // sorted in both, the global's a superset).
    const std::vector<double> x = test::perturbed(model.rest_positions, 0.01, 3);
    std::vector<double> grad(model.num_dofs()), values(elastic->pattern().nnz());
    elastic->gradient_hessian(x.data(), grad.data(), values.data());
    const CscPattern& e = elastic->pattern();
    newton_values.assign(global.nnz(), 0.0);
    for (int64_t c = 0; c < global.num_dofs; ++c) {
      int64_t k = e.col_ptr[c];
      for (int64_t g = global.col_ptr[c]; g < global.col_ptr[c + 1]; ++g)
        if (k < e.col_ptr[c + 1] && e.row_idx[k] == global.row_idx[g]) newton_values[g] = 1e-4 * values[k++];
      REQUIRE(k == e.col_ptr[c + 1]);
    }
    for (int64_t i = 0; i < global.num_dofs; ++i) newton_values[global.diagonal[i]] += model.mass[i / 3];

    // Random values: off-diagonal entries in [-1, 1] within an island, and a diagonal larger than
    // its row's sum of magnitudes.
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    random_values.assign(global.nnz(), 0.0);
    std::vector<double> row_sum(global.num_dofs, 0.0);
    for (int64_t c = 0; c < global.num_dofs; ++c)
      for (int64_t k = global.col_ptr[c]; k < global.col_ptr[c + 1]; ++k) {
        const int64_t r = global.row_idx[k];
        if (islands->island_of(static_cast<int32_t>(r / 3)) != islands->island_of(static_cast<int32_t>(c / 3))) {
          ++cross_entries;
          continue;
        }
        if (r == c) continue;
        random_values[k] = u(rng);
        row_sum[r] += std::abs(random_values[k]);
        row_sum[c] += std::abs(random_values[k]);
      }
    for (int64_t i = 0; i < global.num_dofs; ++i) random_values[global.diagonal[i]] = row_sum[i] + 1.0 + std::abs(u(rng));

    rhs.resize(global.num_dofs);
    for (double& b : rhs) b = u(rng);
  }
  const Model& model() const { return scene.model; }
  int32_t num_islands() const { return islands->num_islands(); }
  std::vector<int32_t> island_vertices(int32_t i) const {
    return {islands->vertices().begin() + islands->vertex_ptr()[i], islands->vertices().begin() + islands->vertex_ptr()[i + 1]};
  }
  // A system for island i, its pattern taken from the global one (version 1).
  std::unique_ptr<IslandSystem> system(int32_t i) const {
    auto s = std::make_unique<IslandSystem>(island_vertices(i));
    CHECK(s->update_pattern(global, 1, islands->island_of_vertex().data(), islands->local_indices().data(), i));
    return s;
  }
};

enum class Path { dense, simplicial, supernodal };

Path path_of(const IslandSystem& s) {
  if (s.num_dofs() <= IslandSystem::kDenseDofs) return Path::dense;
  return s.num_dofs() <= IslandSystem::kSimplicialDofs ? Path::simplicial : Path::supernodal;
}

double relative_error(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return (a - b).norm() / b.norm(); }

// Factorises and solves every island of the problem; compares with the whole-matrix reference.
void check_island_solves(IslandProblem& problem, const std::vector<double>& values, const Eigen::VectorXd& reference,
                         int (&paths)[3]) {
  const int64_t n = problem.global.num_dofs;
  // The test's premise: the matrix is block diagonal over the islands, with stored zeros between.
  CHECK(problem.cross_entries > 0);
  for (int64_t c = 0; c < n; ++c)
    for (int64_t k = problem.global.col_ptr[c]; k < problem.global.col_ptr[c + 1]; ++k)
      if (problem.islands->island_of(static_cast<int32_t>(problem.global.row_idx[k] / 3)) !=
          problem.islands->island_of(static_cast<int32_t>(c / 3)))
        REQUIRE(values[k] == 0.0);
  std::vector<double> out(n, std::numeric_limits<double>::quiet_NaN());
  for (int32_t i = 0; i < problem.num_islands(); ++i) {
    CAPTURE(i);
    std::unique_ptr<IslandSystem> s = problem.system(i);
    CAPTURE(s->num_dofs());
    ++paths[static_cast<int>(path_of(*s))];
    CHECK(s->must_run_alone() == (path_of(*s) == Path::supernodal && !CholmodSolver::blas_is_thread_safe()));
    REQUIRE(s->factorize(values.data()) == StepStatus::ok);
    // Only the island's entries of out are written.
    std::vector<double> alone(n, std::numeric_limits<double>::quiet_NaN());
    REQUIRE(s->solve(problem.rhs.data(), alone.data()) == StepStatus::ok);
    int64_t written = 0;
    for (double a : alone) written += !std::isnan(a);
    CHECK(written == s->num_dofs());
    REQUIRE(s->solve(problem.rhs.data(), out.data()) == StepStatus::ok);
    Eigen::VectorXd mine(s->num_dofs()), ref(s->num_dofs());
    for (size_t l = 0; l < s->vertices().size(); ++l)
      for (int d = 0; d < 3; ++d) {
        mine[3 * l + d] = out[3 * int64_t{s->vertices()[l]} + d];
        ref[3 * l + d] = reference[3 * int64_t{s->vertices()[l]} + d];
      }
    CHECK(relative_error(mine, ref) <= 1e-10);
  }
  CHECK(relative_error(Eigen::Map<const Eigen::VectorXd>(out.data(), n), reference) <= 1e-10);
}

// Negates one diagonal value of island i (a DOF of a vertex in the middle of its list): the block
// is then indefinite, with a negative pivot that an LDL^T would accept.
std::vector<double> indefinite(const IslandProblem& problem, const std::vector<double>& values, int32_t i) {
  std::vector<double> bad = values;
  const std::vector<int32_t> vertices = problem.island_vertices(i);
  const int64_t dof = 3 * int64_t{vertices[vertices.size() / 2]} + 1;
  bad[problem.global.diagonal[dof]] = -bad[problem.global.diagonal[dof]];
  return bad;
}

// The dense block of island i.
Eigen::MatrixXd island_block(const IslandProblem& problem, const std::vector<double>& values, int32_t i) {
  const std::vector<int32_t> vertices = problem.island_vertices(i);
  const int64_t m = 3 * static_cast<int64_t>(vertices.size());
  Eigen::MatrixXd block = Eigen::MatrixXd::Zero(m, m);
  for (size_t l = 0; l < vertices.size(); ++l)
    for (int d = 0; d < 3; ++d) {
      const int64_t c = 3 * int64_t{vertices[l]} + d;
      for (int64_t k = problem.global.col_ptr[c]; k < problem.global.col_ptr[c + 1]; ++k) {
        const int32_t rv = static_cast<int32_t>(problem.global.row_idx[k] / 3);
        if (problem.islands->island_of(rv) != i) continue;
        const int64_t r = 3 * int64_t{problem.islands->local_index(rv)} + problem.global.row_idx[k] % 3;
        block(r, 3 * l + d) = block(3 * l + d, r) = values[k];
      }
    }
  return block;
}

}  // namespace

TEST_CASE("island systems (dense and simplicial) solve like a dense LDLT of the whole matrix") {
  // Islands of 81, 96 (the last dense size), 108 and 150 DOFs.
  IslandProblem problem(test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.1, 0.1, 0.7], "cells": [1, 1, 7] }, "material": "a", "translate": [1, 0, 0] },
                { "box": { "size": [0.1, 0.1, 0.8], "cells": [1, 1, 8] }, "material": "a", "translate": [2, 0, 0] },
                { "box": { "size": [0.1, 0.4, 0.4], "cells": [1, 4, 4] }, "material": "a", "translate": [3, 0, 0] } ]
  })", "island_systems_small"));
  REQUIRE(problem.num_islands() == 4);
  REQUIRE(problem.island_vertices(1).size() == 32);
  CHECK(3 * 32 == IslandSystem::kDenseDofs);
  int paths[3] = {0, 0, 0};
  for (const std::vector<double>* values : {&problem.newton_values, &problem.random_values}) {
    const Eigen::MatrixXd A = test::dense_from(problem.global, *values);
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(A);
    REQUIRE(ldlt.info() == Eigen::Success);
    REQUIRE(ldlt.isPositive());
    const Eigen::VectorXd reference = ldlt.solve(Eigen::Map<const Eigen::VectorXd>(problem.rhs.data(), A.rows()));
    check_island_solves(problem, *values, reference, paths);
  }
  CHECK(paths[static_cast<int>(Path::dense)] == 4);
  CHECK(paths[static_cast<int>(Path::simplicial)] == 4);
}

TEST_CASE("island systems (simplicial and supernodal) solve like an LDLT of the whole matrix") {
  // Islands of 81, 240 (the last simplicial size) and 3300 DOFs: too big for a dense LDL^T of
  // the whole matrix in a unit test, so the reference is Eigen's sparse LDL^T of it.
  IslandProblem problem(test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.1, 0.3, 0.9], "cells": [1, 3, 9] }, "material": "a", "translate": [2, 0, 0] },
                { "box": { "size": [1.0, 0.9, 0.9], "cells": [10, 9, 9] }, "material": "a", "translate": [4, 0, 0] } ]
  })", "island_systems_large"));
  REQUIRE(problem.num_islands() == 3);
  REQUIRE(3 * static_cast<int64_t>(problem.island_vertices(1).size()) == IslandSystem::kSimplicialDofs);
  int paths[3] = {0, 0, 0};
  for (const std::vector<double>* values : {&problem.newton_values, &problem.random_values}) {
    std::vector<Eigen::Triplet<double>> entries;
    for (int64_t c = 0; c < problem.global.num_dofs; ++c)
      for (int64_t k = problem.global.col_ptr[c]; k < problem.global.col_ptr[c + 1]; ++k)
        entries.emplace_back(static_cast<int>(problem.global.row_idx[k]), static_cast<int>(c), (*values)[k]);
    Eigen::SparseMatrix<double> A(problem.global.num_dofs, problem.global.num_dofs);
    A.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper> ldlt(A);
    REQUIRE(ldlt.info() == Eigen::Success);
    REQUIRE((ldlt.vectorD().array() > 0.0).all());
    const Eigen::VectorXd reference = ldlt.solve(Eigen::Map<const Eigen::VectorXd>(problem.rhs.data(), A.rows()));
    check_island_solves(problem, *values, reference, paths);
  }
  CHECK(paths[static_cast<int>(Path::dense)] == 2);
  CHECK(paths[static_cast<int>(Path::simplicial)] == 2);
  CHECK(paths[static_cast<int>(Path::supernodal)] == 2);
}

TEST_CASE("island systems keep their analysis while their pattern holds and refuse indefinite blocks on every path") {
  IslandProblem problem(test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.1, 0.3, 0.9], "cells": [1, 3, 9] }, "material": "a", "translate": [1, 0, 0] },
                { "box": { "size": [0.4, 0.4, 0.4], "cells": [4, 4, 4] }, "material": "a", "translate": [3, 0, 0] } ]
  })", "island_systems_indefinite"));
  REQUIRE(problem.num_islands() == 3);
  const int64_t n = problem.global.num_dofs;
  const Path expected[3] = {Path::dense, Path::simplicial, Path::supernodal};
  for (int32_t i = 0; i < 3; ++i) {
    CAPTURE(i);
    std::unique_ptr<IslandSystem> s = problem.system(i);
    REQUIRE(path_of(*s) == expected[i]);
    const int32_t* island_of = problem.islands->island_of_vertex().data();
    const int32_t* local = problem.islands->local_indices().data();
    // Same version: nothing to do; a new version with the same block: the analysis is kept.
    CHECK_FALSE(s->update_pattern(problem.global, 1, island_of, local, i));
    CHECK_FALSE(s->update_pattern(problem.global, 2, island_of, local, i));

    // Indefinite: refused, with a reason. For the dense and simplicial islands, check that an
    // LDL^T of the same block succeeds (nonzero pivots, one negative): only LL^T refuses it.
    for (const std::vector<double>* values : {&problem.newton_values, &problem.random_values}) {
      const std::vector<double> bad = indefinite(problem, *values, i);
      if (expected[i] != Path::supernodal) {
        const Eigen::LDLT<Eigen::MatrixXd> ldlt(island_block(problem, bad, i));
        REQUIRE(ldlt.info() == Eigen::Success);
        CHECK(ldlt.isNegative() == false);
        CHECK(ldlt.isPositive() == false);
        CHECK((ldlt.vectorD().array() != 0.0).all());
      }
      CHECK(s->factorize(bad.data()) == StepStatus::factorization_failed);
      CHECK_FALSE(s->error().empty());
      // And the next positive definite values factorise again, solving right.
      REQUIRE(s->factorize(values->data()) == StepStatus::ok);
      std::vector<double> out(n, 0.0);
      REQUIRE(s->solve(problem.rhs.data(), out.data()) == StepStatus::ok);
      const Eigen::MatrixXd block = island_block(problem, *values, i);
      const std::vector<int32_t> vertices = problem.island_vertices(i);
      Eigen::VectorXd b(block.rows()), mine(block.rows());
      for (size_t l = 0; l < vertices.size(); ++l)
        for (int d = 0; d < 3; ++d) {
          b[3 * l + d] = problem.rhs[3 * int64_t{vertices[l]} + d];
          mine[3 * l + d] = out[3 * int64_t{vertices[l]} + d];
        }
      CHECK((block * mine - b).norm() <= 1e-10 * b.norm());
    }
  }
}

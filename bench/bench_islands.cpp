// Factorising one island of the stress piles three ways, to choose IslandSystem's thresholds
// (engine/sparse/island_system.hpp): Eigen's dense LLT, CHOLMOD simplicial and CHOLMOD
// supernodal, each on the Newton matrix of one body (mass plus the projected elastic Hessian of
// a slightly squashed body, implicit Euler at dt = 0.01). Bodies: the 2 x 2 x 2-cell box of the
// piles (81 DOFs), the IPC torus (600 DOFs) and boxes of 4^3 and 8^3 cells (375 and 2,187 DOFs).
// Single-threaded: islands are factorised one per thread.
//
//   ./build/bench/bench_islands
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "engine/scene/scene.hpp"
#include "engine/sparse/cholmod_solver.hpp"

#include <Eigen/Cholesky>
#include <benchmark/benchmark.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>

namespace {

using namespace nexdyn;

struct Body {
  Scene scene;
  std::unique_ptr<ElasticAssembly> elastic;
  StepHistory history;
  std::unique_ptr<IncrementalPotential> potential;
  std::vector<double> x, x_tilde, grad, values;

  explicit Body(const std::string& body_json) {
    const auto file = std::filesystem::temp_directory_path() / "nexdyn_bench_island.json";
    std::ofstream(file) << R"({ "name": "island", "time": { "dt": 0.01 },
      "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.4, "density": 1000 } },
      "bodies": [ )" << body_json << R"( ] })";
    scene = load_scene(file);
    const Model& model = scene.model;
    elastic = std::make_unique<ElasticAssembly>(model);
    potential = std::make_unique<IncrementalPotential>(model, *elastic, history);
    x = model.rest_positions;
    for (int32_t v = 0; v < model.num_vertices; ++v) x[3 * v + 1] *= 0.95;  // squashed by 5%
    x_tilde = model.rest_positions;
    potential->begin_step(x_tilde, weights_context(1e-4, 1e-4, true));
    grad.resize(model.num_dofs());
    values.resize(potential->pattern().nnz());
    potential->gradient_hessian(x.data(), grad.data(), values.data());
  }
  const CscPattern& pattern() const { return potential->pattern(); }
};

Body& body(int which) {
  static std::map<int, std::unique_ptr<Body>> bodies;
  static const char* json[] = {
      R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [2, 2, 2] }, "material": "m" })",
      R"({ "mesh": ")" NEXDYN_SOURCE_DIR R"(/scenes/meshes/torus.msh", "scale": 0.12, "material": "m" })",
      R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [4, 4, 4] }, "material": "m" })",
      R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [8, 8, 8] }, "material": "m" })"};
  auto& b = bodies[which];
  if (!b) b = std::make_unique<Body>(json[which]);
  return *b;
}

void label(benchmark::State& state, const Body& b) {
  state.counters["dofs"] = static_cast<double>(b.pattern().num_dofs);
  state.SetItemsProcessed(state.iterations());
}

void BM_IslandDenseLLT(benchmark::State& state) {
  const Body& b = body(static_cast<int>(state.range(0)));
  const CscPattern& p = b.pattern();
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(p.num_dofs, p.num_dofs);
  Eigen::LLT<Eigen::MatrixXd, Eigen::Upper> llt(p.num_dofs);
  for (auto _ : state) {
    dense.setZero();
    for (int64_t c = 0; c < p.num_dofs; ++c)
      for (int64_t k = p.col_ptr[c]; k < p.col_ptr[c + 1]; ++k) dense(p.row_idx[k], c) = b.values[k];
    llt.compute(dense);
    benchmark::DoNotOptimize(llt.matrixLLT().data());
  }
  label(state, b);
}

void cholmod_factorisation(benchmark::State& state, bool supernodal) {
  const Body& b = body(static_cast<int>(state.range(0)));
  const CscPattern& p = b.pattern();
  CholmodSolver solver(supernodal);
  solver.analyze(p.num_dofs, p.col_ptr.data(), p.row_idx.data());
  for (auto _ : state) benchmark::DoNotOptimize(solver.factorize(b.values.data()));
  label(state, b);
}
void BM_IslandCholmodSimplicial(benchmark::State& state) { cholmod_factorisation(state, false); }
void BM_IslandCholmodSupernodal(benchmark::State& state) { cholmod_factorisation(state, true); }

}  // namespace

// 0: box 2^3 (81 DOFs), 1: torus (600), 2: box 4^3 (375), 3: box 8^3 (2,187)
BENCHMARK(BM_IslandDenseLLT)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_IslandCholmodSimplicial)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_IslandCholmodSupernodal)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();

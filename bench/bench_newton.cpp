// One Newton iteration on a ~100k-tet neo-Hookean bar, split into its stages:
//   assembly       gradient + PSD-projected Hessian of the incremental potential (parallel)
//   factorisation  CHOLMOD numeric factorisation on the cached symbolic analysis
//   solve          forward/backward substitution
//   iteration      the three together, as the Newton driver runs them
// Argument: thread count. Counters: DOFs, tets, non-zeros, and peak resident memory per tet
// (VmHWM of the process after setting up the largest problem, divided by its tets).
//
//   ./build/bench/bench_newton --benchmark_min_time=1
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "engine/scene/scene.hpp"
#include "engine/sparse/cholmod_solver.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>

namespace {

using namespace nexdyn;

// Peak resident set size of this process in bytes (Linux /proc).
double peak_resident_bytes() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) * 1024.0;
  return 0.0;
}

// The bar: 10 m x 1 m x 1 m, 80 x 16 x 13 cells x 6 tets = 99,840 tets, clamped at x = -5.
struct Problem {
  Scene scene;
  std::unique_ptr<ElasticAssembly> elastic;
  StepHistory history;
  std::unique_ptr<IncrementalPotential> potential;
  CholmodSolver cholmod;
  std::vector<double> x, x_tilde, grad, values, direction;
  double memory_per_tet = 0.0;

  Problem() {
    const auto file = std::filesystem::temp_directory_path() / "nexdyn_bench_bar.json";
    std::ofstream(file) << R"({
      "name": "bench_bar", "time": { "dt": 0.01 },
      "materials": { "m": { "model": "neohookean", "youngs": 1e7, "poisson": 0.4, "density": 1000 } },
      "bodies": [ { "box": { "size": [10, 1, 1], "cells": [80, 16, 13] }, "material": "m" } ],
      "boundary": [ { "box_min": [-5.01, -1, -1], "box_max": [-4.99, 1, 1], "fix": true } ] })";
    scene = load_scene(file);
    const Model& model = scene.model;
    elastic = std::make_unique<ElasticAssembly>(model);
    potential = std::make_unique<IncrementalPotential>(model, *elastic, history);
    // A bent state: the bar sags by up to 2 cm, as after a few steps under gravity.
    x = model.rest_positions;
    for (int32_t v = 0; v < model.num_vertices; ++v) {
      const double s = (x[3 * v] + 5.0) / 10.0;
      x[3 * v + 1] -= 0.02 * s * s;
    }
    x_tilde = model.rest_positions;
    potential->begin_step(x_tilde, weights_context(2 * 0.5 * 0.25 * 0.01 * 0.01, 2 * 0.5 * 0.25 * 0.01 * 0.01, true));
    grad.resize(model.num_dofs());
    direction.resize(model.num_dofs());
    values.resize(potential->pattern().nnz());
    cholmod.analyze(model.num_dofs(), potential->pattern().col_ptr.data(), potential->pattern().row_idx.data());
    potential->gradient_hessian(x.data(), grad.data(), values.data());
    cholmod.factorize(values.data());
    memory_per_tet = peak_resident_bytes() / model.num_tets;
  }
};

Problem& problem() {
  static Problem p;
  return p;
}

void set_counters(benchmark::State& state) {
  Problem& p = problem();
  state.counters["dofs"] = static_cast<double>(p.scene.model.num_dofs());
  state.counters["tets"] = p.scene.model.num_tets;
  state.counters["nnz"] = static_cast<double>(p.potential->pattern().nnz());
  state.counters["peak_bytes_per_tet"] = p.memory_per_tet;
  state.counters["factor_nnz"] = p.cholmod.factor_nonzeros();
  state.counters["factor_gflop"] = p.cholmod.factor_flops() * 1e-9;
  state.SetLabel(p.cholmod.ordering_name());
}

void BM_Assembly(benchmark::State& state) {
  Problem& p = problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.potential->gradient_hessian(p.x.data(), p.grad.data(), p.values.data());
    benchmark::DoNotOptimize(p.values.data());
  }
  set_counters(state);
}

void BM_Factorization(benchmark::State& state) {
  Problem& p = problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(p.cholmod.factorize(p.values.data()));
  set_counters(state);
}

void BM_Solve(benchmark::State& state) {
  Problem& p = problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.cholmod.solve(p.grad.data(), p.direction.data());
    benchmark::DoNotOptimize(p.direction.data());
  }
  set_counters(state);
}

void BM_NewtonIteration(benchmark::State& state) {
  Problem& p = problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.potential->gradient_hessian(p.x.data(), p.grad.data(), p.values.data());
    p.cholmod.factorize(p.values.data());
    p.cholmod.solve(p.grad.data(), p.direction.data());
    benchmark::DoNotOptimize(p.direction.data());
  }
  set_counters(state);
}

BENCHMARK(BM_Assembly)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Factorization)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Solve)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_NewtonIteration)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

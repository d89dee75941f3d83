// Projective Dynamics (engine/solver/projective_dynamics.hpp) on two corotated (Poisson 0) beams
// clamped at one end, one step of 0.01 s from rest under gravity (implicit Euler):
//   cantilever  scenes/cantilever.json's mesh, 2 m x 0.2 m x 0.2 m, 40 x 4 x 4 cells, 3,840 tets
//   bar         10 m x 1 m x 1 m, 80 x 16 x 13 cells, 99,840 tets (bench_newton's bar)
// BM_PdIteration: one local-global iteration (items = iterations), with the local step's tets per
//   second and the global step's milliseconds as counters. Arguments: problem, threads.
// BM_PdStep: the whole step to a residual of 1e-5 m/s, plain PD or PD + Chebyshev (rho estimated
//   once per s before timing; its cost is the counter rho_s). Arguments: problem, chebyshev,
//   threads, dt in ms (10: the shipped cantilever's step; 100: a large step, where plain PD needs
//   thousands of iterations and Chebyshev matters; run on 2 threads only).
//
//   ./build/bench/bench_projective_dynamics --benchmark_min_time=1
#include "engine/integrator.hpp"
#include "engine/scene/scene.hpp"
#include "engine/solver/projective_dynamics.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

namespace {

using namespace nexdyn;

struct Problem {
  Scene scene;
  double s = 0.0, dt = 0.01;
  std::vector<double> x_tilde;

  Problem(const std::string& name, const std::string& body, double clamp_x) {
    const auto file = std::filesystem::temp_directory_path() / ("nexdyn_bench_pd_" + name + ".json");
    std::ofstream(file) << R"({
      "name": ")" + name + R"(", "time": { "dt": 0.01, "integrator": "implicit_euler" },
      "materials": { "m": { "model": "corotated", "youngs": 1e7, "poisson": 0, "density": 1000 } },
      "bodies": [ { "box": )" + body + R"(, "material": "m" } ],
      "boundary": [ { "box_min": [)" + std::to_string(clamp_x - 0.01) + R"(, -1, -1], "box_max": [)" +
                               std::to_string(clamp_x + 0.01) + R"(, 1, 1], "fix": true } ] })";
    scene = load_scene(file);
    dt = scene.time.dt;
    s = scene.time.integrator.potential_scale(dt);
    x_tilde = scene.initial.x;  // from rest: x_tilde = x_n
  }
};

Problem& problem(int which) {
  static Problem cantilever("cantilever", R"({ "size": [2.0, 0.2, 0.2], "cells": [40, 4, 4] })", -1.0);
  static Problem bar("bar", R"({ "size": [10, 1, 1], "cells": [80, 16, 13] })", -5.0);
  return which == 0 ? cantilever : bar;
}

void BM_PdIteration(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, state.range(1));
  PdSettings settings;
  settings.chebyshev = false;
  settings.tolerance = 0.0;
  settings.max_iterations = 1;
  ProjectiveDynamics pd(p.scene.model, settings);
  std::vector<double> x = p.x_tilde;
  pd.solve(p.s, p.dt, p.x_tilde, x);  // factorisation outside the timing
  pd.reset_stats();
  for (auto _ : state) {
    pd.solve(p.s, p.dt, p.x_tilde, x);
    benchmark::DoNotOptimize(x.data());
  }
  const PdStats& st = pd.stats();
  state.SetItemsProcessed(state.iterations());
  state.counters["tets"] = p.scene.model.num_tets;
  state.counters["local_tets_per_s"] = double(st.local_tets) / st.local_seconds;
  state.counters["local_ms"] = 1e3 * st.local_seconds / double(st.iterations);
  state.counters["global_ms"] = 1e3 * st.global_seconds / double(st.iterations);
}
BENCHMARK(BM_PdIteration)
    ->ArgNames({"problem", "threads"})
    ->ArgsProduct({{0, 1}, {1, 2}})
    ->Unit(benchmark::kMillisecond);

void BM_PdStep(benchmark::State& state) {
  Problem& p = problem(static_cast<int>(state.range(0)));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, state.range(2));
  const double dt = 1e-3 * double(state.range(3));
  const double s = p.scene.time.integrator.potential_scale(dt);
  PdSettings settings;
  settings.chebyshev = state.range(1) != 0;
  settings.tolerance = 1e-5;
  settings.max_iterations = 100000;
  ProjectiveDynamics pd(p.scene.model, settings);
  const auto start = std::chrono::steady_clock::now();
  const double rho = settings.chebyshev ? pd.spectral_radius(s) : 0.0;
  const double rho_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  PdResult result;
  for (auto _ : state) {
    std::vector<double> x = p.x_tilde;
    result = pd.solve(s, dt, p.x_tilde, x);
    benchmark::DoNotOptimize(x.data());
  }
  if (!result.converged()) state.SkipWithError(result.message.c_str());
  state.counters["iterations"] = result.iterations;
  state.counters["rho"] = rho;
  state.counters["rho_s"] = rho_seconds;
}
BENCHMARK(BM_PdStep)
    ->ArgNames({"problem", "chebyshev", "threads", "dt_ms"})
    ->ArgsProduct({{0, 1}, {0, 1}, {1, 2}, {10}})
    ->ArgsProduct({{0, 1}, {0, 1}, {2}, {100}})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();

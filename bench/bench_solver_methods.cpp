// The three ways to solve an implicit step ("solver.method", docs/scenes.md) on the same scenes
// and the same arap energy, each to the same velocity-scaled tolerance where it iterates:
//   newton               Newton + CHOLMOD, line search (the default)
//   linearized           one CHOLMOD solve of the quadratic model at x_n per step
//   linearized_pcg       the same by matrix-free conjugate gradients
//   pd                   Projective Dynamics, plain local-global iterations
//   pd_chebyshev         Projective Dynamics with Chebyshev acceleration
// Scenes (implicit Euler, tolerance 1e-5 m/s, 2 threads unless the argument says 1):
//   cantilever   2 m beam, 40 x 4 x 4 cells (3,840 tets), clamped, under gravity, dt 0.01
//   bar_100k     10 m bar, 80 x 16 x 13 cells (99,840 tets), clamped, under gravity, dt 0.01
//   mat40x40     the IPC mat (scenes/mat40x40_twist.json) twisted from both ends, no contact, dt 0.04
// Each benchmark runs `steps` steps from the start (the first step's factorisation and
// spectral-radius estimate included). Counters: ms_per_step, iterations per step (Newton
// iterations, CG iterations are not counted, PD iterations), and dev_mm, the largest distance of
// a vertex from where Newton put it after the same steps.
//
//   ./build/bench/bench_solver_methods --benchmark_min_time=0.5
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace {

using namespace nexdyn;

const char* const kMethods[] = {"newton", "linearized", "linearized_pcg", "pd", "pd_chebyshev"};

std::string solver_json(int method) {
  switch (method) {
    case 1: return R"("method": "linearized")";
    case 2: return R"("method": "linearized", "linear": "pcg")";
    case 3: return R"("method": "projective_dynamics", "chebyshev": false)";
    case 4: return R"("method": "projective_dynamics")";
    default: return R"("method": "newton")";
  }
}

struct SceneCase {
  const char* name;
  int steps;
  std::string json;  // with SOLVER where the solver keys go
};

const SceneCase& scene_case(int index) {
  static const SceneCase cases[] = {
      {"cantilever", 20, R"({
        "gravity": [0, -9.81, 0], "time": { "dt": 0.01, "integrator": "implicit_euler" },
        "solver": { "tolerance": 1e-5, "max_iterations": 100, SOLVER },
        "materials": { "m": { "model": "arap", "youngs": 1e7, "poisson": 0.3, "density": 1000 } },
        "bodies": [ { "box": { "size": [2.0, 0.2, 0.2], "cells": [40, 4, 4] }, "material": "m" } ],
        "boundary": [ { "box_min": [-1.001, -1, -1], "box_max": [-0.999, 1, 1], "fix": true } ] })"},
      {"bar_100k", 3, R"({
        "gravity": [0, -9.81, 0], "time": { "dt": 0.01, "integrator": "implicit_euler" },
        "solver": { "tolerance": 1e-5, "max_iterations": 100, SOLVER },
        "materials": { "m": { "model": "arap", "youngs": 1e7, "poisson": 0.4, "density": 1000 } },
        "bodies": [ { "box": { "size": [10, 1, 1], "cells": [80, 16, 13] }, "material": "m" } ],
        "boundary": [ { "box_min": [-5.01, -1, -1], "box_max": [-4.99, 1, 1], "fix": true } ] })"},
      {"mat40x40", 10, R"({
        "gravity": [0, 0, 0], "time": { "dt": 0.04, "integrator": "implicit_euler" },
        "solver": { "tolerance": 1e-5, "max_iterations": 100, SOLVER },
        "materials": { "mat": { "model": "arap", "youngs": 2e4, "poisson": 0.4, "density": 1000 } },
        "bodies": [ { "mesh": "MESH", "material": "mat", "rotate_deg": [90, 0, 0] } ],
        "boundary": [
          { "box_min": [-0.51, -1, -1], "box_max": [-0.49, 1, 1], "angular_velocity": 1.2566370614359172, "axis": [1, 0, 0], "center": [0, 0, 0] },
          { "box_min": [0.49, -1, -1], "box_max": [0.51, 1, 1], "angular_velocity": -1.2566370614359172, "axis": [1, 0, 0], "center": [0, 0, 0] } ] })"},
  };
  return cases[index];
}

Scene load_case(int scene, int method) {
  std::string json = scene_case(scene).json;
  json.replace(json.find("SOLVER"), 6, solver_json(method));
  if (const size_t at = json.find("MESH"); at != std::string::npos)
    json.replace(at, 4, std::string(NEXDYN_SOURCE_DIR) + "/scenes/meshes/mat40x40.msh");
  const auto file = std::filesystem::temp_directory_path() /
                    (std::string("nexdyn_bench_methods_") + scene_case(scene).name + ".json");
  std::ofstream(file) << json;
  return load_scene(file);
}

// x after the scene's steps under one method.
std::vector<double> run_steps(int scene, int method, int* iterations = nullptr) {
  const Scene loaded = load_case(scene, method);
  Simulation sim(loaded);
  int total = 0;
  for (int k = 0; k < scene_case(scene).steps; ++k) {
    if (sim.step().status != StepStatus::ok) return {};
    total += sim.last_stats().newton_iterations;
  }
  if (iterations) *iterations = total;
  return sim.state().x;
}

// Newton's positions after the scene's steps, once per scene.
const std::vector<double>& newton_reference(int scene) {
  static std::map<int, std::vector<double>> cache;
  auto found = cache.find(scene);
  if (found == cache.end()) found = cache.emplace(scene, run_steps(scene, 0)).first;
  return found->second;
}

void BM_SolverMethod(benchmark::State& state) {
  const int scene = static_cast<int>(state.range(0));
  const int method = static_cast<int>(state.range(1));
  const int threads = static_cast<int>(state.range(2));
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  const std::vector<double>& reference = newton_reference(scene);
  std::vector<double> x;
  int iterations = 0;
  double seconds = 0.0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    x = run_steps(scene, method, &iterations);
    seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    state.SetIterationTime(seconds);
  }
  const int steps = scene_case(scene).steps;
  state.SetLabel(std::string(scene_case(scene).name) + " " + kMethods[method] + (x.empty() ? " FAILED" : ""));
  double deviation = 0.0;
  for (size_t v = 0; !x.empty() && 3 * v < x.size(); ++v)
    deviation = std::max(deviation, std::hypot(x[3 * v] - reference[3 * v], x[3 * v + 1] - reference[3 * v + 1],
                                               x[3 * v + 2] - reference[3 * v + 2]));
  state.counters["ms_per_step"] = 1e3 * seconds / steps;
  state.counters["iterations_per_step"] = double(iterations) / steps;
  state.counters["dev_mm"] = 1e3 * deviation;
}

}  // namespace

// Scene x method x threads; one run of all the steps per benchmark iteration.
BENCHMARK(BM_SolverMethod)
    ->ArgsProduct({{0, 1, 2}, {0, 1, 2, 3, 4}, {2}})
    ->Args({0, 0, 1})
    ->Args({0, 4, 1})
    ->UseManualTime()
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();

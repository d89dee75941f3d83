// Whole steps of scenes/pile.json (100 boxes falling into a box of planes, issue 3): the time per
// step and its split by phase (engine/step_profile.hpp), as counters in milliseconds per step,
// plus Newton iterations per step. One iteration runs the scene's 100 steps from the start, so
// the figures cover the fall, the impacts and the settling pile, as `nexdyn run` reports them.
// BM_PileStepsFriction runs the same pile with contact.friction 0.5, lagged once per step
// (friction_iterations 1) or until the normal forces settle (the default), for the whole-step
// cost of friction (issue 4).
//
//   ./build/bench/bench_step            (about five minutes)
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"
#include "engine/step_profile.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <string>

namespace nexdyn {
namespace {

// Runs the pile's steps on `threads` threads with the given friction (0: none) and lagging count
// (-1: until converged), reporting the counters described above.
void run_pile(benchmark::State& state, int threads, double friction, int friction_iterations) {
  Scene scene = load_scene(NEXDYN_SOURCE_DIR "/scenes/pile.json");
  scene.contact.friction = friction;
  scene.contact.friction_iterations = friction_iterations;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
  StepProfile profile;
  double step_seconds = 0.0;
  int64_t steps = 0, newton_iterations = 0;
  for (auto _ : state) {
    Simulation simulation(scene);
    for (int64_t s = 0; s < scene.time.steps; ++s) {
      const auto start = std::chrono::steady_clock::now();
      const StepOutcome outcome = simulation.step();
      step_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (outcome.status != StepStatus::ok) {
        state.SkipWithError(("step failed: " + outcome.message).c_str());
        return;
      }
      newton_iterations += simulation.last_stats().newton_iterations;
      ++steps;
    }
    profile = simulation.profile();
  }
  const double ms_per_step = 1e3 / double(steps / state.iterations());
  double phases = 0.0;
  for (size_t p = 0; p < kStepPhaseNames.size(); ++p) {
    const double seconds = profile.seconds(static_cast<StepPhase>(p));
    phases += seconds;
    state.counters[kStepPhaseNames[p]] = seconds * ms_per_step;
  }
  const double per_run = step_seconds / double(state.iterations());
  state.counters["step"] = per_run * ms_per_step;
  state.counters["other"] = (per_run - phases) * ms_per_step;
  state.counters["newton_its"] = double(newton_iterations) / double(steps);
}

void BM_PileSteps(benchmark::State& state) { run_pile(state, static_cast<int>(state.range(0)), 0.0, 1); }

// Argument: friction_iterations (1, or -1 for "converged"); 2 threads.
void BM_PileStepsFriction(benchmark::State& state) { run_pile(state, 2, 0.5, static_cast<int>(state.range(0))); }

BENCHMARK(BM_PileSteps)->Arg(2)->Arg(1)->ArgName("threads")->Iterations(1)->Unit(benchmark::kSecond)
    ->UseRealTime();
BENCHMARK(BM_PileStepsFriction)->Arg(1)->Arg(-1)->ArgName("lags")->Iterations(1)->Unit(benchmark::kSecond)
    ->UseRealTime();

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

// Whole steps of scenes/pile.json (100 boxes falling into a box of planes, issue 3): the time per
// step and its split by phase (engine/step_profile.hpp), as counters in milliseconds per step,
// plus Newton iterations per step. One iteration runs the scene's 100 steps from the start, so
// the figures cover the fall, the impacts and the settling pile, as `nexdyn run` reports them.
//
//   ./build/bench/bench_step            (about a minute on 2 threads)
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

void BM_PileSteps(benchmark::State& state) {
  const Scene scene = load_scene(NEXDYN_SOURCE_DIR "/scenes/pile.json");
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
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

BENCHMARK(BM_PileSteps)->Arg(2)->Arg(1)->ArgName("threads")->Iterations(1)->Unit(benchmark::kSecond)
    ->UseRealTime();

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

// One implicit MPM step (engine/mpm/mpm_step.hpp) at 100k and 1M particles, on 1 and 2 threads:
// milliseconds per step, and the step's time per Newton iteration per particle.
//
//   build/bench/bench_mpm_step --benchmark_min_time=1
//
// Scene: a neo-Hookean cube (E = 1e5 Pa, nu = 0.3, 1000 kg/m^3) of c^3 cells with 8 particles
// per cell (c = 23: 97,336 particles; c = 50: 1,000,000), h = 2 cm, squeezed 5% along x and
// falling under gravity, Newmark, dt = 5 ms. Each benchmark iteration starts from the same
// particles (copied outside the timed region), so every step is the same work. Counters:
// newton (iterations per step), pcg (conjugate-gradient products per step), ns_per_particle_newton
// (step time / Newton iterations / particles).
#include "engine/mpm/mpm_step.hpp"

#include "bench/mpm_bench_scene.hpp"

#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdint>
#include <memory>

namespace nexdyn {
namespace {

struct StepScene {
  MpmModel model;
  std::unique_ptr<MpmStepper> stepper;
};

StepScene& scene(int64_t target_particles) {
  static std::unique_ptr<StepScene> small, large;
  std::unique_ptr<StepScene>& s = target_particles <= 100000 ? small : large;
  if (s) return *s;
  s = std::make_unique<StepScene>();
  const int cells = static_cast<int>(std::lround(std::cbrt(static_cast<double>(target_particles) / 8.0)));
  s->model = bench::squeezed_cube(cells);
  const MpmModel& m = s->model;
  s->stepper = std::make_unique<MpmStepper>(m);
  return *s;
}

void BM_mpm_step(benchmark::State& state) {
  StepScene& s = scene(state.range(0));
  tbb::task_arena arena(static_cast<int>(state.range(1)));
  MpmStepSettings settings;
  settings.integrator = *integrator_preset("newmark");
  double newton = 0.0, pcg = 0.0, steps = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    Particles particles = s.model.initial;
    MpmParticleHistory history;
    state.ResumeTiming();
    MpmStepResult result;
    arena.execute([&] { result = s.stepper->advance(particles, history, 0.0, 0.005, settings); });
    if (!result.ok) state.SkipWithError(result.message.c_str());
    newton += result.newton_iterations;
    pcg += double(result.pcg_iterations);
    steps += 1.0;
  }
  const double n = double(s.model.initial.size());
  state.counters["particles"] = n;
  state.counters["newton"] = newton / steps;
  state.counters["pcg"] = pcg / steps;
  state.counters["ns_per_particle_newton"] =
      benchmark::Counter(newton * n / 1e9, benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_mpm_step)->Args({100000, 1})->Args({100000, 2})->Args({1000000, 1})->Args({1000000, 2})
    ->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

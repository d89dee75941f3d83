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

#include "kernels/elasticity/material.hpp"

#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <cstdint>
#include <memory>

namespace nexdyn {
namespace {

constexpr double kSpacing = 0.02;

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
  const double size = cells * kSpacing;
  MpmModel& m = s->model;
  m.grid_spacing = kSpacing;
  m.domain_min = Eigen::Vector3d::Zero();
  m.domain_max = Eigen::Vector3d::Constant(size + 6.0 * kSpacing);
  m.gravity = Eigen::Vector3d(0, -9.81, 0);
  Material material;
  material.name = "rubber";
  material.model = MaterialModel::neohookean;
  material.youngs = 1e5;
  material.poisson = 0.3;
  material.density = 1000.0;
  material.lame = lame_from_young_poisson(1e5, 0.3);
  m.materials.push_back(material);
  sample_box_particles(m.initial, Eigen::Vector3d::Constant(3.0 * kSpacing), Eigen::Vector3d::Constant(size), kSpacing,
                       2, 1000.0, Eigen::Vector3d::Zero(), 0);
  for (int64_t p = 0; p < m.initial.size(); ++p) m.initial.F[9 * p] = 0.95;
  m.particle_body.assign(static_cast<size_t>(m.initial.size()), 0);
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

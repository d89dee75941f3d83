// Throughput of the MPM transfers (engine/mpm/transfer.hpp): binning, P2G and G2P (with the F and
// position update from a grid displacement) in particles per second, at 100k and 1M particles,
// on 1 and 2 threads (a tbb::task_arena of that size, as bench_elasticity).
//
//   build/bench/bench_mpm_transfer --benchmark_min_time=0.5
//
// Scene: a cube of c^3 cells with 2 particles per cell per axis (8 per cell), c = 23 (97,336
// particles) or c = 50 (1,000,000), h = 2 cm, with random velocities and affine matrices, in a
// grid with two empty cells of margin on each side. Arguments: {particles, threads}.
#include "engine/mpm/grid.hpp"
#include "engine/mpm/particles.hpp"
#include "engine/mpm/transfer.hpp"

#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace nexdyn {
namespace {

constexpr double kSpacing = 0.02;  // h [m]

struct TransferScene {
  Grid grid;
  Particles particles;
  ParticleBins bins;
  std::vector<double> displacement;  // (num_nodes x 3) a small grid motion for G2P
};

TransferScene make_scene(int64_t target_particles) {
  const int cells = static_cast<int>(std::lround(std::cbrt(static_cast<double>(target_particles) / 8.0)));
  const double size = cells * kSpacing;
  TransferScene s;
  s.grid = make_grid(kSpacing, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(size + 4.0 * kSpacing));
  sample_box_particles(s.particles, Eigen::Vector3d::Constant(2.0 * kSpacing), Eigen::Vector3d::Constant(size),
                       kSpacing, 2, 1000.0, Eigen::Vector3d::Zero(), 0);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (double& v : s.particles.v) v = unit(rng);
  for (double& c : s.particles.C) c = 10.0 * unit(rng);
  bin_particles(s.grid, s.particles, s.bins);
  particles_to_grid(s.particles, s.bins, s.grid);
  s.displacement.resize(s.grid.velocity.size());
  for (size_t k = 0; k < s.displacement.size(); ++k) s.displacement[k] = 1e-4 * s.grid.velocity[k];
  return s;
}

TransferScene& scene(int64_t n) {
  static TransferScene small = make_scene(100000), large = make_scene(1000000);
  return n <= 100000 ? small : large;
}

void BM_bin_particles(benchmark::State& state) {
  TransferScene& s = scene(state.range(0));
  tbb::task_arena arena(static_cast<int>(state.range(1)));
  for (auto _ : state) arena.execute([&] { bin_particles(s.grid, s.particles, s.bins); });
  state.SetItemsProcessed(state.iterations() * s.particles.size());
}

void BM_particles_to_grid(benchmark::State& state) {
  TransferScene& s = scene(state.range(0));
  tbb::task_arena arena(static_cast<int>(state.range(1)));
  for (auto _ : state) arena.execute([&] { particles_to_grid(s.particles, s.bins, s.grid); });
  state.SetItemsProcessed(state.iterations() * s.particles.size());
  state.counters["nodes"] = static_cast<double>(s.grid.num_nodes());
}

void BM_grid_to_particles(benchmark::State& state) {
  TransferScene& s = scene(state.range(0));
  tbb::task_arena arena(static_cast<int>(state.range(1)));
  // G2P moves the particles and changes F; a copy per run keeps every run on the same input.
  const Particles start = s.particles;
  Particles work = start;
  for (auto _ : state) {
    state.PauseTiming();
    work.x = start.x;
    work.F = start.F;
    state.ResumeTiming();
    arena.execute([&] { grid_to_particles(s.grid, s.grid.velocity.data(), s.displacement.data(), work); });
  }
  state.SetItemsProcessed(state.iterations() * s.particles.size());
}

void transfer_args(benchmark::internal::Benchmark* b) {
  for (int64_t n : {100000, 1000000})
    for (int64_t threads : {1, 2}) b->Args({n, threads});
  b->ArgNames({"particles", "threads"})->Unit(benchmark::kMillisecond)->UseRealTime();
}

BENCHMARK(BM_bin_particles)->Apply(transfer_args);
BENCHMARK(BM_particles_to_grid)->Apply(transfer_args);
BENCHMARK(BM_grid_to_particles)->Apply(transfer_args);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

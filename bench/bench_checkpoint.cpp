// What checkpoints and failed-step recovery cost (issue 6): Simulation::save (the copy of the
// state that Simulation::step keeps before every step so that a failed step can be retried),
// restore, and a whole checkpoint file written durably (CRC, fsync, rename), on the 1,000-body
// pile after its first 10 steps (the bodies have landed: contact pattern pairs exist).
//
//   ./build/bench/bench_checkpoint
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"

#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>

namespace nexdyn {
namespace {

// The pile after 10 steps, built once for all benchmarks.
Simulation& landed_pile() {
  static const Scene scene = load_scene(NEXDYN_SOURCE_DIR "/scenes/stress/pile_1000.json");
  static std::unique_ptr<Simulation> simulation = [] {
    auto s = std::make_unique<Simulation>(scene);
    for (int k = 0; k < 10; ++k) s->step();
    return s;
  }();
  return *simulation;
}

void BM_SaveState(benchmark::State& state) {
  Simulation& simulation = landed_pile();
  size_t bytes = 0;
  for (auto _ : state) {
    CheckpointWriter out;
    save_simulation(out, simulation);
    bytes = out.bytes().size();
    benchmark::DoNotOptimize(out.bytes().data());
  }
  state.counters["MB"] = static_cast<double>(bytes) / (1024.0 * 1024.0);
}
BENCHMARK(BM_SaveState)->Unit(benchmark::kMillisecond);

void BM_RestoreState(benchmark::State& state) {
  Simulation& simulation = landed_pile();
  CheckpointWriter out;
  save_simulation(out, simulation);
  for (auto _ : state) {
    CheckpointReader in(out.bytes(), "bench");
    restore_simulation(in, simulation);
  }
}
BENCHMARK(BM_RestoreState)->Unit(benchmark::kMillisecond);

void BM_WriteCheckpointFile(benchmark::State& state) {
  Simulation& simulation = landed_pile();
  CheckpointWriter out;
  save_simulation(out, simulation);
  const std::filesystem::path file = std::filesystem::temp_directory_path() / "nexdyn_bench.ckpt";
  for (auto _ : state) write_checkpoint_file(file, out.bytes());
  std::filesystem::remove(file);
}
BENCHMARK(BM_WriteCheckpointFile)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

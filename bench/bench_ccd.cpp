// Throughput of the narrow-phase CCD (kernels/ccd, additive CCD of Li, Kaufman, Jiang 2021) on
// the shipped query files with exact ground truth (Wang et al. 2021 sample queries, Erleben
// scenes). Items are queries; the argument is the number of threads, run in a tbb::task_arena of
// that size through engine/ccd_queries (the same code path as `nexdyn ccd`).
//
//   build/bench/bench_ccd --benchmark_min_time=1
//
// Reference: Tight-Inclusion runs ~460 queries/s on 2 threads on these sets; target >= 10x.
// Counters fn/fp are false negatives / false positives of the last run (fn must be 0).
#include "engine/ccd_queries.hpp"

#include <benchmark/benchmark.h>
#include <tbb/task_arena.h>

#include <string>

#include "tests/test_data.hpp"

namespace nexdyn {
namespace {

const CcdQuerySet& query_set(const std::string& name) {
  static const CcdQuerySet vf = read_ccd_queries(test::test_data("ccd/vertex-face.txt"));
  static const CcdQuerySet ee = read_ccd_queries(test::test_data("ccd/edge-edge.txt"));
  return name == "vertex-face" ? vf : ee;
}

void run(benchmark::State& state, const std::string& name) {
  const CcdQuerySet& set = query_set(name);
  tbb::task_arena arena(static_cast<int>(state.range(0)));
  CcdQueryStats stats;
  for (auto _ : state) {
    arena.execute([&] { stats = run_ccd_queries(set); });
    benchmark::DoNotOptimize(stats);
  }
  state.SetItemsProcessed(state.iterations() * set.size());
  state.counters["fn"] = double(stats.false_negatives);
  state.counters["fp"] = double(stats.false_positives);
}

void BM_ccd_vertex_face(benchmark::State& state) { run(state, "vertex-face"); }
void BM_ccd_edge_edge(benchmark::State& state) { run(state, "edge-edge"); }

BENCHMARK(BM_ccd_vertex_face)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ccd_edge_edge)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

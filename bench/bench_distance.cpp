// Throughput of the contact distance kernels (kernels/distance): classification + squared
// distance, gradient and exact Hessian for point-triangle and edge-edge pairs, single thread.
// Inputs are 4096 random stencils in the unit cube (all closest-feature cases mixed as they come),
// walked in order, so the numbers include the case switch's branch mispredictions as in the
// engine's contact loop. Items are stencils.
//
//   build/bench/bench_distance --benchmark_min_time=0.5
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Core>

#include <cstdint>
#include <random>
#include <vector>

namespace nexdyn {
namespace {

constexpr int kStencils = 4096;

std::vector<Eigen::Vector3d> random_points(int n) {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> x(n);
  for (auto& p : x) p = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return x;
}

const std::vector<Eigen::Vector3d>& points() {
  static const std::vector<Eigen::Vector3d> x = random_points(4 * kStencils);
  return x;
}

void BM_point_triangle_distance(benchmark::State& state) {
  const auto& x = points();
  for (auto _ : state) {
    double sum = 0.0;
    for (int i = 0; i < kStencils; ++i) {
      sum += point_triangle_distance(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

void BM_point_triangle_hessian(benchmark::State& state) {
  const auto& x = points();
  Matrix12d H;
  for (auto _ : state) {
    for (int i = 0; i < kStencils; ++i) {
      H = point_triangle_distance_hessian(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
      benchmark::DoNotOptimize(H.data());
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

void BM_edge_edge_distance(benchmark::State& state) {
  const auto& x = points();
  for (auto _ : state) {
    double sum = 0.0;
    for (int i = 0; i < kStencils; ++i) {
      sum += edge_edge_distance(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

void BM_edge_edge_hessian(benchmark::State& state) {
  const auto& x = points();
  Matrix12d H;
  for (auto _ : state) {
    for (int i = 0; i < kStencils; ++i) {
      H = edge_edge_distance_hessian(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
      benchmark::DoNotOptimize(H.data());
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

void BM_edge_edge_mollifier_hessian(benchmark::State& state) {
  const auto& x = points();
  Matrix12d H;
  for (auto _ : state) {
    for (int i = 0; i < kStencils; ++i) {
      // eps_x as large as c itself: every stencil takes the mollified branch.
      const double eps_x =
          2.0 * edge_edge_cross_squarednorm(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3]);
      H = edge_edge_mollifier_hessian(x[4 * i], x[4 * i + 1], x[4 * i + 2], x[4 * i + 3], eps_x);
      benchmark::DoNotOptimize(H.data());
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

BENCHMARK(BM_point_triangle_distance);
BENCHMARK(BM_point_triangle_hessian);
BENCHMARK(BM_edge_edge_distance);
BENCHMARK(BM_edge_edge_hessian);
BENCHMARK(BM_edge_edge_mollifier_hessian);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

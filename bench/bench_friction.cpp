// Throughput of the per-contact friction kernels (kernels/friction): gradient + PSD Hessian of
// the lagged friction potential D = mu lambda f0(|T^T dx|) for point-triangle and edge-edge
// stencils, single thread (the engine runs the contact loop in parallel). The lagged bases are
// built once outside the timed loop, as in a Newton iteration; the displacements put half the
// contacts in the static band and half sliding. A second pair of benchmarks times the lagged
// basis construction alone (once per lagging iteration). Items are contacts.
//
//   build/bench/bench_friction --benchmark_min_time=0.5
#include "kernels/friction/friction.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Core>

#include <random>
#include <vector>

namespace nexdyn {
namespace {

constexpr int kContacts = 4096;
constexpr double kEpsU = 1e-3;

struct Inputs {
  std::vector<Eigen::Matrix<double, 3, 4>> X;  // lagged positions per contact
  std::vector<Vector12d> dx;                   // displacement over the step
};

const Inputs& inputs() {
  static const Inputs in = [] {
    std::mt19937_64 rng(42);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Inputs r;
    r.X.resize(kContacts);
    r.dx.resize(kContacts);
    for (int i = 0; i < kContacts; ++i) {
      r.X[i] = Eigen::Matrix<double, 3, 4>::NullaryExpr([&] { return u(rng); });
      // Slips from 0.01 eps_u to 3 eps_u.
      r.dx[i] = Vector12d::NullaryExpr([&] { return 1.5e-3 * u(rng); });
    }
    return r;
  }();
  return in;
}

std::vector<FrictionBasis> bases(FrictionStencil kind) {
  const Inputs& in = inputs();
  std::vector<FrictionBasis> b(kContacts);
  for (int i = 0; i < kContacts; ++i) {
    b[i] = friction_basis(kind, in.X[i], Eigen::Vector3d::UnitZ());
  }
  return b;
}

void run_derivatives(benchmark::State& state, FrictionStencil kind) {
  const Inputs& in = inputs();
  const std::vector<FrictionBasis> b = bases(kind);
  Vector12d g;
  Matrix12d H;
  for (auto _ : state) {
    for (int i = 0; i < kContacts; ++i) {
      g = friction_gradient(b[i], in.dx[i], 0.4, 2.0, kEpsU);
      H = friction_hessian(b[i], in.dx[i], 0.4, 2.0, kEpsU);
      benchmark::DoNotOptimize(g.data());
      benchmark::DoNotOptimize(H.data());
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kContacts);
}

void run_basis(benchmark::State& state, FrictionStencil kind) {
  const Inputs& in = inputs();
  FrictionBasis f;
  for (auto _ : state) {
    for (int i = 0; i < kContacts; ++i) {
      f = friction_basis(kind, in.X[i], Eigen::Vector3d::UnitZ());
      benchmark::DoNotOptimize(f.P.data());
    }
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kContacts);
}

void BM_point_triangle_friction_derivatives(benchmark::State& state) {
  run_derivatives(state, FrictionStencil::point_triangle);
}
void BM_edge_edge_friction_derivatives(benchmark::State& state) {
  run_derivatives(state, FrictionStencil::edge_edge);
}
void BM_point_triangle_friction_basis(benchmark::State& state) {
  run_basis(state, FrictionStencil::point_triangle);
}
void BM_edge_edge_friction_basis(benchmark::State& state) {
  run_basis(state, FrictionStencil::edge_edge);
}

BENCHMARK(BM_point_triangle_friction_derivatives);
BENCHMARK(BM_edge_edge_friction_derivatives);
BENCHMARK(BM_point_triangle_friction_basis);
BENCHMARK(BM_edge_edge_friction_basis);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

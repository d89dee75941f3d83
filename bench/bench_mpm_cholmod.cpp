// Would CHOLMOD pay for MPM's Newton systems? (issue 23's closing note). The grid Hessian
// M + s K_el of a neo-Hookean cube (as in bench_mpm_step: E 1e5 Pa, nu 0.3, squeezed 5%, h 2 cm,
// 8 particles per cell, Newmark s at dt 5 ms), assembled over the active nodes with the
// reference assembly of grid_elasticity.hpp, factorised by the engine's CholmodSolver; beside it
// one implicit step of MpmStepper (PCG) on the same particles.
//
//   build/bench/bench_mpm_cholmod
//
// Arguments: cells per side of the cube (4, 6, 8, 10: 512 to 8,000 particles). Counters of the
// factorisation: dofs, factor non-zeros and flops (CHOLMOD's analysis).
#include "engine/mpm/grid_elasticity.hpp"
#include "engine/mpm/mpm_step.hpp"
#include "engine/sparse/cholmod_solver.hpp"
#include "bench/mpm_bench_scene.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/SparseCore>

#include <map>
#include <memory>

namespace nexdyn {
namespace {

constexpr double kDt = 0.005;

MpmModel cube_model(int cells) { return bench::squeezed_cube(cells); }

struct Assembled {
  Eigen::SparseMatrix<double, Eigen::ColMajor, int64_t> upper;  // over the active DOFs
};

Assembled assemble(const MpmModel& m) {
  Grid grid = make_grid(m.grid_spacing, m.domain_min, m.domain_max);
  ParticleBins bins;
  bin_particles(grid, m.initial, bins);
  particles_to_grid(m.initial, bins, grid);
  const std::vector<double> u(static_cast<size_t>(grid.num_dofs()), 0.0);
  const Eigen::SparseMatrix<double> K = grid_elastic_hessian(grid, m.initial, m.materials, u.data(), true);
  std::vector<int64_t> dof_of(static_cast<size_t>(grid.num_dofs()), -1);
  int64_t n = 0;
  for (int64_t i = 0; i < grid.num_nodes(); ++i)
    if (grid.mass[i] > 0.0)
      for (int d = 0; d < 3; ++d) dof_of[3 * i + d] = n++;
  const double s = 0.25 * kDt * kDt;
  std::vector<Eigen::Triplet<double, int64_t>> triplets;
  for (int64_t col = 0; col < K.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it) {
      const int64_t r = dof_of[it.row()], c = dof_of[it.col()];
      if (r >= 0 && c >= 0 && r <= c) triplets.emplace_back(r, c, s * it.value());
    }
  for (int64_t i = 0; i < grid.num_nodes(); ++i)
    for (int d = 0; d < 3; ++d)
      if (dof_of[3 * i + d] >= 0) triplets.emplace_back(dof_of[3 * i + d], dof_of[3 * i + d], grid.mass[i]);
  Assembled a;
  a.upper.resize(n, n);
  a.upper.setFromTriplets(triplets.begin(), triplets.end());
  a.upper.makeCompressed();
  return a;
}

void BM_mpm_cholmod_factorize(benchmark::State& state) {
  const MpmModel m = cube_model(static_cast<int>(state.range(0)));
  const Assembled a = assemble(m);
  CholmodSolver solver;
  if (solver.analyze(a.upper.rows(), a.upper.outerIndexPtr(), a.upper.innerIndexPtr()) != StepStatus::ok)
    state.SkipWithError("analyze failed");
  for (auto _ : state)
    if (solver.factorize(a.upper.valuePtr()) != StepStatus::ok) state.SkipWithError("factorize failed");
  state.counters["particles"] = double(m.initial.size());
  state.counters["dofs"] = double(a.upper.rows());
  state.counters["matrix_nnz_upper"] = double(a.upper.nonZeros());
  state.counters["factor_nnz"] = solver.factor_nonzeros();
  state.counters["factor_gflop"] = solver.factor_flops() * 1e-9;
}

void BM_mpm_pcg_step(benchmark::State& state) {
  const MpmModel m = cube_model(static_cast<int>(state.range(0)));
  MpmStepper stepper(m);
  MpmStepSettings settings;
  settings.integrator = *integrator_preset("newmark");
  double newton = 0.0, pcg = 0.0, steps = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    Particles particles = m.initial;
    MpmParticleHistory history;
    state.ResumeTiming();
    const MpmStepResult r = stepper.advance(particles, history, 0.0, kDt, settings);
    newton += r.newton_iterations;
    pcg += double(r.pcg_iterations);
    steps += 1.0;
  }
  state.counters["particles"] = double(m.initial.size());
  state.counters["newton"] = newton / steps;
  state.counters["pcg"] = pcg / steps;
}

BENCHMARK(BM_mpm_cholmod_factorize)->Arg(4)->Arg(6)->Arg(8)->Arg(10)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_mpm_pcg_step)->Arg(4)->Arg(6)->Arg(8)->Arg(10)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

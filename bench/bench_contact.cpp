// Contact stages of a Newton iteration on grids of unit cubes (issue 3, "contact" measurements):
//   broad phase     find_contact_candidates at x with inflation dhat / 2 (all pairs within dhat)
//   barrier         active set (candidates closer than dhat, merged by closest feature), then
//                   over that set the gradient (derivatives + add_gradient) and the
//                   PSD-projected Hessian (derivatives + ContactPattern::update + merge into the
//                   Newton matrix), with the candidate list found once outside the timed loop
//   max step        BarrierPotential::max_step: swept broad phase + CCD of a shearing, sinking
//                   cube stack; x + alpha p is checked intersection-free outside the timing
//   friction        over the barrier's active set (issue 4): lagging, and gradient + Hessian
//                   slabs, as contact stencils per second
//
// Scenes: k x k x k unit cubes, each meshed as n^3 hex cells of 6 tets (the scene's "box" body),
// 0.005 apart on every side (spacing 1.005), dhat = 0.01, built by writing a scene JSON and
// calling load_scene, as a user would. The argument is the number of threads (tbb::global_control).
// Counters: surface primitives (sum over cubes of surface vertices + edges + triangles, checked
// against the closed form k^3 (36 n^2 + 2)), candidate and active pair counts, stencils after
// merging equal closest features (by size: point-point, point-edge, 4-point), DOFs.
// The narrow-phase CCD query rate is measured by bench_ccd.
//
//   build/bench/bench_contact --benchmark_min_time=0.5
//
// Each stage runs on every instruction-set path the CPU has (kernels/isa.hpp), widest first;
// NEXDYN_ISA=avx2 (or scalar) leaves out the wider ones. The context lines name the CPU.
//
// References (ipc-toolkit, same scenes) and targets: broad phase 125 cubes 39.6 ms (target 15),
// 1,000 cubes 449 ms (target 180); barrier gradient 30 ms (target 15), Hessian 2,600 ms (target
// 400); max step on 27 cubes: ipc-toolkit did not finish in 300 s (target 50 ms).
#include "engine/contact/barrier_potential.hpp"
#include "engine/contact/friction_potential.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/mesh/intersection.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/scene/scene.hpp"
#include "engine/sparse/contact_pattern.hpp"
#include "kernels/isa.hpp"

#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace nexdyn {
namespace {

constexpr double kGap = 0.005;   // [m] between neighbouring cubes
constexpr double kDhat = 0.01;   // [m]

// A grid of k^3 unit cubes of n^3 cells each.
struct CubeGrid {
  int k = 0, n = 0;
  Scene scene;
  int64_t surface_primitives = 0;  // sum over cubes of V_surf + E_surf + T_surf

  CubeGrid(int k_, int n_) : k(k_), n(n_) {
    const std::string name = "nexdyn_bench_cubes_" + std::to_string(k) + "_" + std::to_string(n);
    const auto file = std::filesystem::temp_directory_path() / (name + ".json");
    const double spacing = 1.0 + kGap;
    char body[512];
    std::snprintf(body, sizeof body,
                  R"({ "box": { "size": [1, 1, 1], "cells": [%d, %d, %d] }, "material": "m",
                       "array": { "count": [%d, %d, %d], "spacing": [%.17g, %.17g, %.17g] } })",
                  n, n, n, k, k, k, spacing, spacing, spacing);
    std::ofstream(file) << R"({ "name": ")" << name << R"(", "contact": { "dhat": 0.01 },
      "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.4, "density": 1000 } },
      "bodies": [ )" << body << " ] }";
    scene = load_scene(file);
    const Model& m = scene.model;
    std::vector<int64_t> surface_vertices_of_body(m.bodies.size(), 0);
    for (int32_t v : m.surface_vertices) ++surface_vertices_of_body[m.vertex_body[v]];
    for (size_t b = 0; b < m.bodies.size(); ++b)
      surface_primitives += surface_vertices_of_body[b] + m.bodies[b].edge_count + m.bodies[b].triangle_count;
  }
  const Model& model() const { return scene.model; }
  // Closed form for a cube of n^3 cells, 2 triangles per boundary cell face: V = 6 n^2 + 2,
  // T = 12 n^2, E = V + T - 2 = 18 n^2 (Euler), so 36 n^2 + 2 per cube.
  int64_t expected_surface_primitives() const { return int64_t{k} * k * k * (36 * int64_t{n} * n + 2); }
};

// Built once per (k, n), on first use.
CubeGrid& grid(int k, int n) {
  static std::map<std::pair<int, int>, std::unique_ptr<CubeGrid>> grids;
  auto& g = grids[{k, n}];
  if (!g) g = std::make_unique<CubeGrid>(k, n);
  return *g;
}

void surface_counters(benchmark::State& state, const CubeGrid& g) {
  state.counters["cubes"] = double(g.k) * g.k * g.k;
  state.counters["surface_prims"] = double(g.surface_primitives);
  state.counters["surface_ok"] = g.surface_primitives == g.expected_surface_primitives() ? 1.0 : 0.0;
  state.counters["dofs"] = double(g.model().num_dofs());
}

// ---- 1. broad phase ---------------------------------------------------------------------------

// The output lists live as long as the grid: the engine keeps its candidate lists from one
// search to the next (BarrierPotential), so a search refills lists that already have the room.
void broad_phase(benchmark::State& state, int k, int n) {
  CubeGrid& g = grid(k, n);
  const double* x = g.model().rest_positions.data();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  static std::map<std::pair<int, int>, ContactCandidates> outputs;
  ContactCandidates& out = outputs[{k, n}];
  for (auto _ : state) {
    find_contact_candidates(g.model(), x, nullptr, 0.5 * kDhat, out);
    benchmark::DoNotOptimize(out.vertex_triangle.data());
  }
  surface_counters(state, g);
  state.counters["vt"] = double(out.vertex_triangle.size());
  state.counters["ee"] = double(out.edge_edge.size());
  state.SetItemsProcessed(state.iterations() * g.surface_primitives);
}

void BM_BroadPhase_125cubes_5cells(benchmark::State& state) { broad_phase(state, 5, 5); }
void BM_BroadPhase_1000cubes_5cells(benchmark::State& state) { broad_phase(state, 10, 5); }

// ---- 2. barrier active set, gradient and Hessian ----------------------------------------------

// 125 cubes of 10^3 cells at rest: every face-to-face pair across a 0.005 gap is active. The
// candidate list is found once; the gradient and Hessian benchmarks time the derivatives over an
// active set built once (as a Newton iteration does after BM_BarrierActiveSet).
struct BarrierProblem {
  CubeGrid& g;
  std::unique_ptr<ElasticAssembly> elastic;
  std::unique_ptr<BarrierPotential> barrier;
  std::vector<std::pair<int32_t, int32_t>> pattern_pairs;
  uint64_t pattern_stamp = 0;
  std::unique_ptr<ContactPattern> pattern;
  std::vector<double> x, grad, elastic_values, values;
  double first_update_ms = 0.0;  // ContactPattern::update that builds the merged pattern

  BarrierProblem() : g(grid(5, 10)) {
    const Model& m = g.model();
    x = m.rest_positions;
    elastic = std::make_unique<ElasticAssembly>(m);
    barrier = std::make_unique<BarrierPotential>(m, kDhat);
    barrier->find_candidates(x.data(), nullptr);
    grad.assign(m.num_dofs(), 0.0);
    elastic_values.resize(elastic->pattern().nnz());
    elastic->gradient_hessian(x.data(), grad.data(), elastic_values.data());
    pattern_pairs.clear();  // a fresh pattern: only the elastic part until the first update
    pattern = std::make_unique<ContactPattern>(elastic->pattern(), pattern_pairs, pattern_stamp);
    barrier->assemble(x.data(), 1.0, true);
    const auto t0 = std::chrono::steady_clock::now();
    pattern->update(barrier->stencils(), barrier->slab_begin(), true);
    first_update_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    values.resize(pattern->pattern().nnz());
  }
};

BarrierProblem& barrier_problem() {
  static BarrierProblem p;
  return p;
}

void barrier_counters(benchmark::State& state, BarrierProblem& p) {
  surface_counters(state, p.g);
  const BarrierPotential& b = *p.barrier;
  state.counters["candidates"] = double(b.candidates().size());
  state.counters["active_pairs"] = double(b.num_active_pairs());
  state.counters["stencils"] = double(b.num_stencils());
  // Stencils by size: 2 point-point, 3 point-edge, 4 point-triangle / edge-edge (slab 9 n^2).
  int64_t by_size[5] = {0, 0, 0, 0, 0};
  for (int64_t s = 0; s < b.num_stencils(); ++s) {
    const int64_t slab = b.slab_begin()[s + 1] - b.slab_begin()[s];
    ++by_size[slab == 9 ? 1 : slab == 36 ? 2 : slab == 81 ? 3 : 4];
  }
  state.counters["stencils_pp"] = double(by_size[2]);
  state.counters["stencils_pe"] = double(by_size[3]);
  state.counters["stencils_4"] = double(by_size[4]);
  state.counters["stencils_mollified"] =
      double(std::count(b.kinds().begin(), b.kinds().end(), ContactStencilKind::edge_edge_mollified));
  state.counters["nnz"] = double(p.pattern->pattern().nnz());
  state.counters["first_update_ms"] = p.first_update_ms;
}

// Classify the candidates at x, keep those closer than dhat, merge equal closest features.
void BM_BarrierActiveSet_125cubes_10cells(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.barrier->build_active_set(p.x.data());
    benchmark::DoNotOptimize(p.barrier->stencils().data());
  }
  barrier_counters(state, p);
}

// Gradient over the active set: derivatives without Hessians, added into the global gradient.
void BM_BarrierGradient_125cubes_10cells(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    std::fill(p.grad.begin(), p.grad.end(), 0.0);
    p.barrier->compute_derivatives(p.x.data(), 1.0, false);
    p.barrier->add_gradient(p.grad.data());
    benchmark::DoNotOptimize(p.grad.data());
  }
  barrier_counters(state, p);
}

// The two parts of BM_BarrierGradient, timed alone: the stencils' gradients, then their sum
// into the global gradient.
void BM_BarrierGradient_part_derivatives(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.barrier->compute_derivatives(p.x.data(), 1.0, false);
    benchmark::ClobberMemory();
  }
  barrier_counters(state, p);
}

void BM_BarrierGradient_part_scatter(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  p.barrier->compute_derivatives(p.x.data(), 1.0, false);
  for (auto _ : state) {
    std::fill(p.grad.begin(), p.grad.end(), 0.0);
    p.barrier->add_gradient(p.grad.data());
    benchmark::DoNotOptimize(p.grad.data());
  }
  barrier_counters(state, p);
}

// What a Newton iteration does for contact's Hessian over a built active set: projected slabs,
// pattern check + gather table, merge into the elastic values.
void BM_BarrierHessian_125cubes_10cells(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.barrier->compute_derivatives(p.x.data(), 1.0, true);
    p.pattern->update(p.barrier->stencils(), p.barrier->slab_begin(), false);
    p.pattern->assemble(p.elastic_values.data(), p.barrier->local_hessians().data(), p.values.data());
    benchmark::DoNotOptimize(p.values.data());
  }
  barrier_counters(state, p);
}

// The three parts of BM_BarrierHessian, timed alone (the inputs of each are left as the full
// sequence leaves them).
void BM_BarrierHessian_part_derivatives(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) {
    p.barrier->compute_derivatives(p.x.data(), 1.0, true);
    benchmark::DoNotOptimize(p.barrier->local_hessians().data());
  }
  barrier_counters(state, p);
}

void BM_BarrierHessian_part_pattern_update(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  p.barrier->compute_derivatives(p.x.data(), 1.0, true);
  for (auto _ : state)
    benchmark::DoNotOptimize(p.pattern->update(p.barrier->stencils(), p.barrier->slab_begin(), false));
  barrier_counters(state, p);
}

void BM_BarrierHessian_part_merge(benchmark::State& state) {
  BarrierProblem& p = barrier_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  p.barrier->compute_derivatives(p.x.data(), 1.0, true);
  p.pattern->update(p.barrier->stencils(), p.barrier->slab_begin(), false);
  for (auto _ : state) {
    p.pattern->assemble(p.elastic_values.data(), p.barrier->local_hessians().data(), p.values.data());
    benchmark::DoNotOptimize(p.values.data());
  }
  barrier_counters(state, p);
}

// ---- 3. collision-free step -------------------------------------------------------------------

// 27 cubes of 3^3 cells at rest; every vertex of a cube in layer l (its z index) moves by
// -2 l gap along z and l / (4 n) along x: each layer sinks into the one below by a gap and
// shears over it by a third of its own cell size per layer.
struct StepProblem {
  CubeGrid& g;
  std::unique_ptr<BarrierPotential> barrier;
  std::vector<double> x, p, x_end;

  StepProblem() : g(grid(3, 3)) {
    const Model& m = g.model();
    x = m.rest_positions;
    p.assign(m.num_dofs(), 0.0);
    const double spacing = 1.0 + kGap;
    for (const BodyRange& body : m.bodies) {
      // The array copies are centred at (i, j, l) * spacing: the layer is the rounded z of the
      // body's centre.
      double z = 0.0;
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) z += x[3 * int64_t{v} + 2];
      const int layer = static_cast<int>(std::lround(z / body.vertex_count / spacing));
      for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
        p[3 * int64_t{v} + 0] = layer / (4.0 * g.n);
        p[3 * int64_t{v} + 2] = -2.0 * layer * kGap;
      }
    }
    barrier = std::make_unique<BarrierPotential>(m, kDhat);
  }
};

StepProblem& step_problem() {
  static StepProblem p;
  return p;
}

void BM_MaxStep_27cubes_3cells(benchmark::State& state) {
  StepProblem& s = step_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  double alpha = 0.0;
  for (auto _ : state) {
    alpha = s.barrier->max_step(s.x.data(), s.p.data());
    benchmark::DoNotOptimize(alpha);
  }
  // Referee outside the timing: the surface at x + alpha p must not intersect itself.
  const Model& m = s.g.model();
  std::vector<double> y(m.num_dofs());
  for (int64_t i = 0; i < m.num_dofs(); ++i) y[i] = s.x[i] + alpha * s.p[i];
  const auto hits = intersecting_triangle_pairs(y.data(), m.surface_triangles.data(),
                                                static_cast<int64_t>(m.surface_triangles.size() / 3));
  // And the full step would have intersected (so alpha < 1 is a real limit, not slack).
  for (int64_t i = 0; i < m.num_dofs(); ++i) y[i] = s.x[i] + s.p[i];
  const auto hits_full = intersecting_triangle_pairs(y.data(), m.surface_triangles.data(),
                                                     static_cast<int64_t>(m.surface_triangles.size() / 3));
  surface_counters(state, s.g);
  state.counters["alpha"] = alpha;
  state.counters["intersections"] = double(hits.size());
  state.counters["intersections_full_step"] = double(hits_full.size());
  state.counters["vt"] = double(s.barrier->candidates().vertex_triangle.size());
  state.counters["ee"] = double(s.barrier->candidates().edge_edge.size());
  if (!hits.empty()) state.SkipWithError("x + alpha p intersects");
}

// Friction over the same active set (issue 4): lagging (tangent bases, closest-point weights,
// normal forces) and the per-iteration derivatives (gradient and PSD Hessian slabs), per contact
// stencil. The lagged state is the rest state, and x slides every vertex by a different small
// tangential amount, so both the sticking and the sliding branch of the smoothed friction occur.
struct FrictionProblem {
  BarrierProblem& b;
  std::unique_ptr<FrictionPotential> friction;
  std::vector<double> x;

  FrictionProblem() : b(barrier_problem()) {
    const Model& m = b.g.model();
    friction = std::make_unique<FrictionPotential>(m, FrictionTable(int32_t(m.materials.size()), {0.5, 0.5}), 1.0);
    friction->lag(*b.barrier, b.x.data(), 1e3, b.x.data(), 1e-3);  // eps_u = 1e-3 m
    x = b.x;
    for (size_t i = 0; i < x.size(); ++i) x[i] += 2e-3 * std::sin(0.37 * double(i));
    friction->compute_derivatives(x.data(), 1.0, true);  // allocate the slabs outside the timing
  }
};

FrictionProblem& friction_problem() {
  static FrictionProblem p;
  return p;
}

void BM_FrictionLag_125cubes_10cells(benchmark::State& state) {
  FrictionProblem& p = friction_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  for (auto _ : state) p.friction->lag(*p.b.barrier, p.b.x.data(), 1e3, p.b.x.data(), 1e-3);
  state.SetItemsProcessed(state.iterations() * p.friction->num_stencils());
  state.counters["stencils"] = double(p.friction->num_stencils());
}

void BM_FrictionDerivatives_125cubes_10cells(benchmark::State& state) {
  FrictionProblem& p = friction_problem();
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, state.range(0));
  std::vector<double>& grad = p.b.grad;
  for (auto _ : state) {
    std::fill(grad.begin(), grad.end(), 0.0);
    p.friction->compute_derivatives(p.x.data(), 1.0, true);
    p.friction->add_gradient(grad.data());
    benchmark::DoNotOptimize(grad.data());
  }
  state.SetItemsProcessed(state.iterations() * p.friction->num_stencils());
  state.counters["stencils"] = double(p.friction->num_stencils());
}

// Every stage on every instruction-set path this CPU runs (kernels/isa.hpp), widest first:
// BM_<stage>/isa:<path>/threads:<n>. NEXDYN_ISA caps the paths (NEXDYN_ISA=avx2: avx2 and scalar).
struct Stage {
  const char* name;
  void (*run)(benchmark::State&);
};
constexpr Stage kStages[] = {
    {"BM_BroadPhase_125cubes_5cells", BM_BroadPhase_125cubes_5cells},
    {"BM_BroadPhase_1000cubes_5cells", BM_BroadPhase_1000cubes_5cells},
    {"BM_BarrierActiveSet_125cubes_10cells", BM_BarrierActiveSet_125cubes_10cells},
    {"BM_BarrierGradient_125cubes_10cells", BM_BarrierGradient_125cubes_10cells},
    {"BM_BarrierGradient_part_derivatives", BM_BarrierGradient_part_derivatives},
    {"BM_BarrierGradient_part_scatter", BM_BarrierGradient_part_scatter},
    {"BM_BarrierHessian_125cubes_10cells", BM_BarrierHessian_125cubes_10cells},
    {"BM_BarrierHessian_part_derivatives", BM_BarrierHessian_part_derivatives},
    {"BM_BarrierHessian_part_pattern_update", BM_BarrierHessian_part_pattern_update},
    {"BM_BarrierHessian_part_merge", BM_BarrierHessian_part_merge},
    {"BM_MaxStep_27cubes_3cells", BM_MaxStep_27cubes_3cells},
    {"BM_FrictionLag_125cubes_10cells", BM_FrictionLag_125cubes_10cells},
    {"BM_FrictionDerivatives_125cubes_10cells", BM_FrictionDerivatives_125cubes_10cells},
};

void register_stages() {
  const Isa widest = active_isa();
  for (int i = static_cast<int>(widest); i >= 0; --i) {
    const auto isa = static_cast<Isa>(i);
    for (const Stage& stage : kStages) {
      const std::string name = std::string(stage.name) + "/isa:" + isa_name(isa);
      benchmark::RegisterBenchmark(name.c_str(), [isa, run = stage.run](benchmark::State& state) {
        set_active_isa(isa);
        run(state);
      })
          ->ArgName("threads")
          ->Arg(1)
          ->Arg(2)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
}

// The CPU's name, for the figures' record.
std::string cpu_model() {
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);)
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

}  // namespace
}  // namespace nexdyn

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::AddCustomContext("cpu_model", nexdyn::cpu_model());
  benchmark::AddCustomContext("isa_detected", nexdyn::isa_name(nexdyn::detected_isa()));
  nexdyn::register_stages();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

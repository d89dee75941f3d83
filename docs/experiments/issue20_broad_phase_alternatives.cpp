// Issue 20 experiment (docs/performance.md, "Contact stages on every instruction set"): Embree's
// rtcCollide, and a sweep and prune on x, over every primitive box of 1,000 cubes of 5^3 cells,
// against the engine's broad phase (bench_contact). Not part of the build. From the repository
// root, after ./build.sh:
//   g++ -O3 -march=native -std=c++20 -I. -I/usr/include/eigen3 docs/experiments/issue20_broad_phase_alternatives.cpp \
//       build/engine/libnexdyn_engine.a build/bvh/libnexdyn_bvh.a build/kernels/libnexdyn_kernels.a \
//       -lembree3 -ltbb -lcholmod -o /tmp/bp_alt
//   /tmp/bp_alt 2          # rtcCollide on 2 threads, 4 repetitions
//   /tmp/bp_alt 1 sap      # sweep and prune on x over the edge boxes, 1 thread
#include "bvh/broad_phase.hpp"
#include "engine/scene/scene.hpp"
#include <tbb/global_control.h>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <vector>
#include <algorithm>
using namespace nexdyn;
int sap_main(const std::vector<double>&, const std::vector<double>&);
int main(int argc, char** argv) {
  int k = 10, n = 5;
  const char* file = "/tmp/issue20_cubes.json";
  std::ofstream(file) << R"({ "name": "c", "contact": { "dhat": 0.01 },
      "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.4, "density": 1000 } },
      "bodies": [ { "box": { "size": [1, 1, 1], "cells": [5, 5, 5] }, "material": "m",
                       "array": { "count": [10, 10, 10], "spacing": [1.005, 1.005, 1.005] } } ] })";
  Scene scene = load_scene(file);
  const Model& m = scene.model;
  const double* x = m.rest_positions.data();
  const double r = 0.005;
  auto boxes = [&](const int32_t* ids, int per, int64_t count, std::vector<double>& lo, std::vector<double>& hi) {
    lo.resize(3 * count); hi.resize(3 * count);
    for (int64_t i = 0; i < count; ++i)
      for (int d = 0; d < 3; ++d) {
        double a = 1e300, b = -1e300;
        for (int j = 0; j < per; ++j) { double c = x[3 * int64_t(ids[per * i + j]) + d]; a = std::min(a, c); b = std::max(b, c); }
        lo[3 * i + d] = a - r; hi[3 * i + d] = b + r;
      }
  };
  std::vector<double> vlo, vhi, elo, ehi, tlo, thi;
  boxes(m.surface_vertices.data(), 1, m.surface_vertices.size(), vlo, vhi);
  boxes(m.surface_edges.data(), 2, m.surface_edges.size() / 2, elo, ehi);
  boxes(m.surface_triangles.data(), 3, m.surface_triangles.size() / 3, tlo, thi);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, argc > 1 ? atoi(argv[1]) : 2);
  if (argc > 2) return sap_main(elo, ehi);
  for (int rep = 0; rep < 4; ++rep) {
    auto t0 = std::chrono::steady_clock::now();
    auto vt = overlapping_pairs(vlo.data(), vhi.data(), vlo.size() / 3, tlo.data(), thi.data(), tlo.size() / 3);
    auto t1 = std::chrono::steady_clock::now();
    auto ee = self_overlapping_pairs(elo.data(), ehi.data(), elo.size() / 3);
    auto t2 = std::chrono::steady_clock::now();
    printf("vt %zu pairs %.1f ms, ee %zu pairs %.1f ms\n", vt.size(),
           std::chrono::duration<double, std::milli>(t1 - t0).count(), ee.size(),
           std::chrono::duration<double, std::milli>(t2 - t1).count());
  }
}
// (appended) sweep and prune on x over the edge boxes, one thread, unsorted output
int sap_main(const std::vector<double>& lo, const std::vector<double>& hi) {
  const int64_t n = lo.size() / 3;
  auto t0 = std::chrono::steady_clock::now();
  std::vector<int32_t> order(n);
  for (int64_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](int32_t a, int32_t b) { return lo[3 * a] < lo[3 * b]; });
  std::vector<std::pair<int32_t, int32_t>> pairs;
  int64_t tested = 0;
  for (int64_t s = 0; s < n; ++s) {
    const int32_t a = order[s];
    for (int64_t u = s + 1; u < n && lo[3 * order[u]] <= hi[3 * a]; ++u) {
      const int32_t b = order[u];
      ++tested;
      if (lo[3 * b + 1] <= hi[3 * a + 1] && lo[3 * a + 1] <= hi[3 * b + 1] && lo[3 * b + 2] <= hi[3 * a + 2] && lo[3 * a + 2] <= hi[3 * b + 2])
        pairs.emplace_back(std::min(a, b), std::max(a, b));
    }
  }
  auto t1 = std::chrono::steady_clock::now();
  std::sort(pairs.begin(), pairs.end());
  auto t2 = std::chrono::steady_clock::now();
  printf("SAP ee: %zu pairs, %lld box tests, sweep %.1f ms, sort of the pairs %.1f ms (1 thread)\n", pairs.size(), (long long)tested,
         std::chrono::duration<double, std::milli>(t1 - t0).count(), std::chrono::duration<double, std::milli>(t2 - t1).count());
  return 0;
}

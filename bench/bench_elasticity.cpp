// Throughput of the elasticity range drivers (kernels/elasticity/elasticity_range.hpp) on a
// structured box mesh of 40 x 40 x 40 cells x 6 tets (384,000 tets, 68,921 vertices), vertices
// randomly perturbed so that every F differs from the identity. Items are tets; the argument is
// the number of threads, run as the engine does: a tbb::task_arena of that size and a
// parallel_for over fixed chunks of tets, each chunk calling the range driver on its slab.
//
//   build/bench/bench_elasticity --benchmark_min_time=0.5
//
// Targets (2 threads): neo-Hookean gradient >= 40 M tets/s, projected Hessian >= 5 M tets/s.
// Memory traffic per tet: gradient ~ 16 B ids + 96 B corners (mostly cache hits) + 80 B rest
// data + 104 B out (+ 104 B read-for-ownership); Hessian adds 1152 B out, written with streaming
// stores (no read-for-ownership). The *_baseline cases run the same kernels one tet at a time
// through the element layer (T = double) instead of four per instruction.
#include "engine/mesh/box_mesher.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "kernels/elasticity/elasticity_range.hpp"

#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <Eigen/Core>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

namespace nexdyn {
namespace {

constexpr int kCells = 40;          // cells per side
constexpr int64_t kChunk = 512;     // tets per parallel chunk (fixed, as in the engine)
constexpr double kPerturbation = 0.08;  // of the cell size: F != I, no tet inverted

struct BoxMesh {
  std::vector<double> x;       // (num_vertices x 3) perturbed positions
  std::vector<int32_t> tets;   // (num_tets x 4)
  std::vector<double> Dm_inv;  // (num_tets x 9)
  std::vector<double> volume;  // (num_tets)
  int64_t num_tets() const { return int64_t(volume.size()); }
  TetRange range() const { return {x.data(), tets.data(), Dm_inv.data(), volume.data()}; }
};

// The engine's box mesher (6 tets per cell around the cell diagonal, conforming), with the rest
// shape data the kernels read and every vertex moved randomly by up to 8% of a cell.
BoxMesh make_bench_mesh() {
  const TetMesh box = make_box_mesh(Eigen::Vector3d(1.0, 1.0, 1.0), {kCells, kCells, kCells});
  BoxMesh mesh;
  mesh.tets = box.tets;
  mesh.Dm_inv.reserve(9 * size_t(box.num_tets()));
  mesh.volume.reserve(box.num_tets());
  for (int32_t t = 0; t < box.num_tets(); ++t) {
    Matrix34d X;
    for (int v = 0; v < 4; ++v)
      X.col(v) = Eigen::Map<const Eigen::Vector3d>(&box.positions[3 * box.tets[4 * t + v]]);
    Eigen::Matrix3d Dm_inv;
    double volume = 0.0;
    tet_rest_shape(X, Dm_inv, volume);  // the mesher orients every tet positively
    mesh.Dm_inv.insert(mesh.Dm_inv.end(), Dm_inv.data(), Dm_inv.data() + 9);
    mesh.volume.push_back(volume);
  }
  const double h = 1.0 / kCells;
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-kPerturbation * h, kPerturbation * h);
  mesh.x = box.positions;
  for (double& v : mesh.x) v += u(rng);
  return mesh;
}

const BoxMesh& box_mesh() {
  static const BoxMesh mesh = [] {
    BoxMesh m = make_bench_mesh();
    // Guard the premise of the benchmark: no inverted tet (neo-Hookean would be +inf).
    std::vector<double> energy(m.num_tets()), gradient(12 * m.num_tets());
    const LameParameters lame = lame_from_young_poisson(1e5, 0.4);
    if (gradient_range<MaterialModel::neohookean>(m.range(), 0, m.num_tets(), lame,
                                                  energy.data(), gradient.data()) != 0) {
      std::fprintf(stderr, "bench_elasticity: inverted tets in the perturbed box mesh\n");
      std::abort();
    }
    return m;
  }();
  return mesh;
}

const LameParameters kLame = lame_from_young_poisson(1e5, 0.4);

// Runs body(begin, end) over all tets in fixed chunks on an arena of `threads` threads.
template <typename Body>
void run_chunks(tbb::task_arena& arena, int64_t num_tets, const Body& body) {
  const int64_t num_chunks = (num_tets + kChunk - 1) / kChunk;
  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<int64_t>(0, num_chunks, 1),
        [&](const tbb::blocked_range<int64_t>& r) {
          for (int64_t c = r.begin(); c < r.end(); ++c)
            body(c * kChunk, std::min(num_tets, (c + 1) * kChunk));
        },
        tbb::simple_partitioner());
  });
}

template <MaterialModel M>
void BM_energy_range(benchmark::State& state) {
  const BoxMesh& mesh = box_mesh();
  const int64_t nt = mesh.num_tets();
  const TetRange range = mesh.range();
  tbb::task_arena arena(int(state.range(0)));
  const int64_t num_chunks = (nt + kChunk - 1) / kChunk;
  std::vector<double> partial(num_chunks);
  for (auto _ : state) {
    run_chunks(arena, nt, [&](int64_t b, int64_t e) {
      partial[b / kChunk] = energy_range<M>(range, b, e, kLame);
    });
    double total = 0.0;
    for (double p : partial) total += p;  // chunk order: deterministic
    benchmark::DoNotOptimize(total);
  }
  state.SetItemsProcessed(state.iterations() * nt);
}

template <MaterialModel M>
void BM_gradient_range(benchmark::State& state) {
  const BoxMesh& mesh = box_mesh();
  const int64_t nt = mesh.num_tets();
  const TetRange range = mesh.range();
  tbb::task_arena arena(int(state.range(0)));
  std::vector<double> energy(nt), gradient(12 * nt);
  for (auto _ : state) {
    run_chunks(arena, nt, [&](int64_t b, int64_t e) {
      gradient_range<M>(range, b, e, kLame, energy.data(), gradient.data());
    });
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * nt);
}

template <MaterialModel M>
void BM_hessian_range(benchmark::State& state) {
  const BoxMesh& mesh = box_mesh();
  const int64_t nt = mesh.num_tets();
  const TetRange range = mesh.range();
  tbb::task_arena arena(int(state.range(0)));
  std::vector<double> gradient(12 * nt), hessian(144 * nt);
  for (auto _ : state) {
    run_chunks(arena, nt, [&](int64_t b, int64_t e) {
      hessian_range<M>(range, b, e, kLame, gradient.data(), hessian.data());
    });
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * nt);
}

// Baselines: the same kernels one tet at a time (T = double, through the element layer), as the
// range drivers ran before they processed four tets per instruction.
Matrix34d corners(const BoxMesh& mesh, int64_t t) {
  Matrix34d x;
  for (int k = 0; k < 4; ++k)
    x.col(k) = Eigen::Map<const Eigen::Vector3d>(&mesh.x[3 * size_t(mesh.tets[4 * t + k])]);
  return x;
}

template <MaterialModel M>
void BM_gradient_range_baseline(benchmark::State& state) {
  const BoxMesh& mesh = box_mesh();
  const int64_t nt = mesh.num_tets();
  tbb::task_arena arena(int(state.range(0)));
  std::vector<double> energy(nt), gradient(12 * nt);
  for (auto _ : state) {
    run_chunks(arena, nt, [&](int64_t b, int64_t e) {
      for (int64_t t = b; t < e; ++t) {
        const Eigen::Map<const Eigen::Matrix3d> Dm_inv(&mesh.Dm_inv[9 * t]);
        Vector12d g;
        energy[t] = tet_energy_gradient<M>(corners(mesh, t), Dm_inv, mesh.volume[t], kLame, g);
        Eigen::Map<Vector12d>(gradient.data() + 12 * t) = g;
      }
    });
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * nt);
}

template <MaterialModel M>
void BM_hessian_range_baseline(benchmark::State& state) {
  const BoxMesh& mesh = box_mesh();
  const int64_t nt = mesh.num_tets();
  tbb::task_arena arena(int(state.range(0)));
  std::vector<double> gradient(12 * nt), hessian(144 * nt);
  for (auto _ : state) {
    run_chunks(arena, nt, [&](int64_t b, int64_t e) {
      for (int64_t t = b; t < e; ++t) {
        const Eigen::Map<const Eigen::Matrix3d> Dm_inv(&mesh.Dm_inv[9 * t]);
        Vector12d g;
        Matrix12d H;
        tet_energy_gradient_hessian<M>(corners(mesh, t), Dm_inv, mesh.volume[t], kLame, g, H);
        Eigen::Map<Vector12d>(gradient.data() + 12 * t) = g;
        Eigen::Map<Matrix12d>(hessian.data() + 144 * t) = H;
      }
    });
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * nt);
}

#define NEXDYN_ELASTICITY_BENCH(fn, model)                                           \
  BENCHMARK_TEMPLATE(fn, MaterialModel::model)->Arg(1)->Arg(2)->UseRealTime()->Unit( \
      benchmark::kMillisecond)

NEXDYN_ELASTICITY_BENCH(BM_energy_range, linear);
NEXDYN_ELASTICITY_BENCH(BM_energy_range, stvk);
NEXDYN_ELASTICITY_BENCH(BM_energy_range, corotated);
NEXDYN_ELASTICITY_BENCH(BM_energy_range, neohookean);
NEXDYN_ELASTICITY_BENCH(BM_gradient_range, linear);
NEXDYN_ELASTICITY_BENCH(BM_gradient_range, stvk);
NEXDYN_ELASTICITY_BENCH(BM_gradient_range, corotated);
NEXDYN_ELASTICITY_BENCH(BM_gradient_range, neohookean);
NEXDYN_ELASTICITY_BENCH(BM_hessian_range, linear);
NEXDYN_ELASTICITY_BENCH(BM_hessian_range, stvk);
NEXDYN_ELASTICITY_BENCH(BM_hessian_range, corotated);
NEXDYN_ELASTICITY_BENCH(BM_hessian_range, neohookean);
NEXDYN_ELASTICITY_BENCH(BM_gradient_range_baseline, neohookean);
NEXDYN_ELASTICITY_BENCH(BM_hessian_range_baseline, neohookean);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

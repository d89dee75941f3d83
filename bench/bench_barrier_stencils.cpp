// Throughput of the barrier stencil kernels (kernels/barrier/barrier_stencils.hpp): per stencil
// kind, the gradient alone (a Newton line search's derivative pass) and the gradient with the
// PSD-projected Hessian (a Newton iteration's), single thread. Inputs are 4096 random stencils of
// the kind, rotated and shifted at random in [-1, 1]^3, with the closest feature 1e-2..0.7 dhat
// apart (all active), walked in order; outputs go to per-stencil slabs as in the engine
// (engine/contact/barrier_potential.cpp). Items are stencils.
//
// The _baseline entries are what the kernels' projections replace: the Hessian formed in full
// (w (b'' g g^T + b' hess d), from kernels/distance, or the mollifier's product rule) and
// projected by a 12x12 eigendecomposition (project_psd<12>), against the (3 + M)-dimensional
// subspace of the affine stencils and the 9x9 translation-free projection of the mollified one.
//
//   build/bench/bench_barrier_stencils --benchmark_min_time=0.5
#include "kernels/barrier/barrier_stencils.hpp"
#include "kernels/projection/psd_projection.hpp"

#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <random>
#include <vector>

namespace nexdyn {
namespace {

using Vec3 = Eigen::Vector3d;

constexpr int kStencils = 4096;
constexpr double kDhat = 0.05;  // [m]
constexpr double kDhat2 = kDhat * kDhat;
constexpr double kWeight = 1.5;

enum class Kind { obstacle_plane, point_point, point_line, point_plane, line_line, mollified };

struct Stencils {
  std::vector<std::array<Vec3, 4>> x;  // (kStencils) points in stencil order
  std::vector<double> eps_x;           // (kStencils) mollifier thresholds (mollified only)
};

double uniform(std::mt19937_64& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }

// Local coordinates of one stencil of the kind, its closest feature s apart (unused points 0).
std::array<Vec3, 4> local_stencil(std::mt19937_64& rng, Kind kind, double s) {
  std::array<Vec3, 4> x;
  x.fill(Vec3::Zero());
  switch (kind) {
    case Kind::obstacle_plane: x[0] = Vec3(uniform(rng, -1, 1), s, uniform(rng, -1, 1)); break;
    case Kind::point_point: x[1] = Vec3(s, 0, 0); break;
    case Kind::point_line: x = {Vec3(uniform(rng, -0.3, 0.3), s, 0), Vec3(-0.6, 0, 0), Vec3(0.6, 0, 0), Vec3::Zero()}; break;
    case Kind::point_plane: x = {Vec3(0.4, 0.3, s), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(uniform(rng, 0, 0.6), 0.9, 0)}; break;
    case Kind::line_line: {
      const double phi = uniform(rng, 0.7, 1.5);
      const Vec3 half(0.5 * std::cos(phi), 0.5 * std::sin(phi), 0.0);
      x = {Vec3(-0.5, 0, 0), Vec3(0.5, 0, 0), Vec3(Vec3(0, 0, s) - half), Vec3(Vec3(0, 0, s) + half)};
      break;
    }
    case Kind::mollified: {
      const double theta = uniform(rng, 0.005, 0.025);
      const Vec3 half = 0.3 * Vec3(std::cos(theta), 0.0, std::sin(theta));
      x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(Vec3(0.5, s, 0) - half), Vec3(Vec3(0.5, s, 0) + half)};
      break;
    }
  }
  return x;
}

const Stencils& stencils(Kind kind) {
  static std::array<Stencils, 6> all;
  Stencils& out = all[static_cast<int>(kind)];
  if (!out.x.empty()) return out;
  std::mt19937_64 rng(42 + static_cast<int>(kind));
  std::normal_distribution<double> normal;
  for (int i = 0; i < kStencils; ++i) {
    const double s = 0.7 * kDhat * std::pow(10.0, -uniform(rng, 0.0, 2.0));
    std::array<Vec3, 4> x = local_stencil(rng, kind, s);
    // The obstacle plane stays y = 0 through the origin: only its point is placed.
    const Eigen::Matrix3d R = kind == Kind::obstacle_plane
                                  ? Eigen::Matrix3d::Identity()
                                  : Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng))
                                        .normalized()
                                        .toRotationMatrix();
    const Vec3 shift = kind == Kind::obstacle_plane ? Vec3::Zero() : Vec3(uniform(rng, -1, 1), uniform(rng, -1, 1), uniform(rng, -1, 1));
    for (Vec3& p : x) p = R * p + shift;
    out.x.push_back(x);
    out.eps_x.push_back(edge_edge_mollifier_threshold(x[0], x[1], x[2], x[3]));
  }
  return out;
}

// Slabs of one kind: gradients (kStencils x 3n) and Hessians (kStencils x 3n x 3n).
template <int N>
struct Slabs {
  std::vector<double> gradients = std::vector<double>(size_t{kStencils} * 3 * N);
  std::vector<double> hessians = std::vector<double>(size_t{kStencils} * 9 * N * N);
  Eigen::Map<Eigen::Matrix<double, 3 * N, 1>> gradient(int i) {
    return Eigen::Map<Eigen::Matrix<double, 3 * N, 1>>(&gradients[size_t{3 * N} * i]);
  }
  Eigen::Map<Eigen::Matrix<double, 3 * N, 3 * N>> hessian(int i) {
    return Eigen::Map<Eigen::Matrix<double, 3 * N, 3 * N>>(&hessians[size_t{9 * N * N} * i]);
  }
};

// Runs kernel(i, slabs) over every stencil of the kind, per iteration.
template <int N, typename Kernel>
void run(benchmark::State& state, Kernel&& kernel) {
  Slabs<N> slabs;
  for (auto _ : state) {
    for (int i = 0; i < kStencils; ++i) kernel(i, slabs);
    benchmark::DoNotOptimize(slabs.gradients.data());
    benchmark::DoNotOptimize(slabs.hessians.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kStencils);
}

const Vec3 kOrigin = Vec3::Zero(), kNormal = Vec3::UnitY();

void BM_ObstaclePlane_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::obstacle_plane);
  run<1>(state, [&](int i, Slabs<1>& out) {
    out.gradient(i) = point_obstacle_plane_barrier_gradient(s.x[i][0], kOrigin, kNormal, kDhat2, kWeight);
  });
}

void BM_ObstaclePlane_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::obstacle_plane);
  run<1>(state, [&](int i, Slabs<1>& out) {
    point_obstacle_plane_barrier_gradient_hessian(s.x[i][0], kOrigin, kNormal, kDhat2, kWeight, out.gradient(i),
                                                  out.hessian(i));
  });
}

void BM_PointPoint_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_point);
  run<2>(state, [&](int i, Slabs<2>& out) {
    out.gradient(i) = point_point_barrier_gradient(s.x[i][0], s.x[i][1], kDhat2, kWeight);
  });
}

void BM_PointPoint_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_point);
  run<2>(state, [&](int i, Slabs<2>& out) {
    point_point_barrier_gradient_hessian(s.x[i][0], s.x[i][1], kDhat2, kWeight, out.gradient(i), out.hessian(i));
  });
}

void BM_PointLine_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_line);
  run<3>(state, [&](int i, Slabs<3>& out) {
    const auto& x = s.x[i];
    out.gradient(i) = point_line_barrier_gradient(x[0], x[1], x[2], kDhat2, kWeight);
  });
}

void BM_PointLine_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_line);
  run<3>(state, [&](int i, Slabs<3>& out) {
    const auto& x = s.x[i];
    point_line_barrier_gradient_hessian(x[0], x[1], x[2], kDhat2, kWeight, out.gradient(i), out.hessian(i));
  });
}

void BM_PointPlane_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_plane);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    out.gradient(i) = point_plane_barrier_gradient(x[0], x[1], x[2], x[3], kDhat2, kWeight);
  });
}

void BM_PointPlane_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_plane);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    point_plane_barrier_gradient_hessian(x[0], x[1], x[2], x[3], kDhat2, kWeight, out.gradient(i), out.hessian(i));
  });
}

// The full 12x12 Hessian from the distance kernels, projected by a 12x12 eigendecomposition.
void BM_PointPlane_hessian_baseline(benchmark::State& state) {
  const Stencils& s = stencils(Kind::point_plane);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    const double d = point_plane_distance(x[0], x[1], x[2], x[3]);
    const Vector12d gd = point_plane_distance_gradient(x[0], x[1], x[2], x[3]);
    const double b1 = kWeight * barrier_first_derivative(d, kDhat2);
    out.gradient(i) = b1 * gd;
    Matrix12d H = (kWeight * barrier_second_derivative(d, kDhat2)) * gd * gd.transpose() +
                  b1 * point_plane_distance_hessian(x[0], x[1], x[2], x[3]);
    project_psd<12>(H);
    out.hessian(i) = H;
  });
}

void BM_LineLine_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::line_line);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    out.gradient(i) = line_line_barrier_gradient(x[0], x[1], x[2], x[3], kDhat2, kWeight);
  });
}

void BM_LineLine_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::line_line);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    line_line_barrier_gradient_hessian(x[0], x[1], x[2], x[3], kDhat2, kWeight, out.gradient(i), out.hessian(i));
  });
}

void BM_MollifiedEdgeEdge_gradient(benchmark::State& state) {
  const Stencils& s = stencils(Kind::mollified);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    out.gradient(i) = mollified_edge_edge_barrier_gradient(x[0], x[1], x[2], x[3], s.eps_x[i], kDhat2, kWeight);
  });
}

void BM_MollifiedEdgeEdge_hessian(benchmark::State& state) {
  const Stencils& s = stencils(Kind::mollified);
  run<4>(state, [&](int i, Slabs<4>& out) {
    const auto& x = s.x[i];
    mollified_edge_edge_barrier_gradient_hessian(x[0], x[1], x[2], x[3], s.eps_x[i], kDhat2, kWeight,
                                                 out.gradient(i), out.hessian(i));
  });
}

// The projection alone, on the mollified stencils' unprojected Hessians: translation-free (9x9)
// against the full 12x12 eigendecomposition.
const std::vector<Matrix12d>& mollified_hessians() {
  static const std::vector<Matrix12d> hessians = [] {
    const Stencils& s = stencils(Kind::mollified);
    std::vector<Matrix12d> out(kStencils);
    for (int i = 0; i < kStencils; ++i) {
      const auto& x = s.x[i];
      const double d = edge_edge_distance(x[0], x[1], x[2], x[3]);
      const Vector12d gd = edge_edge_distance_gradient(x[0], x[1], x[2], x[3]);
      const Vector12d gm = edge_edge_mollifier_gradient(x[0], x[1], x[2], x[3], s.eps_x[i]);
      const double m = edge_edge_mollifier(x[0], x[1], x[2], x[3], s.eps_x[i]);
      const double b = barrier(d, kDhat2), b1 = barrier_first_derivative(d, kDhat2);
      const double b2 = barrier_second_derivative(d, kDhat2);
      out[i] = m * (b2 * gd * gd.transpose() + b1 * edge_edge_distance_hessian(x[0], x[1], x[2], x[3])) +
               b1 * (gd * gm.transpose() + gm * gd.transpose()) +
               b * edge_edge_mollifier_hessian(x[0], x[1], x[2], x[3], s.eps_x[i]);
    }
    return out;
  }();
  return hessians;
}

void BM_ProjectPsdTranslationFree(benchmark::State& state) {
  const std::vector<Matrix12d>& hessians = mollified_hessians();
  run<4>(state, [&](int i, Slabs<4>& out) {
    Matrix12d H = hessians[i];
    project_psd_translation_free(H);
    out.hessian(i) = H;
  });
}

void BM_ProjectPsdTranslationFree_baseline(benchmark::State& state) {
  const std::vector<Matrix12d>& hessians = mollified_hessians();
  run<4>(state, [&](int i, Slabs<4>& out) {
    Matrix12d H = hessians[i];
    project_psd<12>(H);
    out.hessian(i) = H;
  });
}

BENCHMARK(BM_ObstaclePlane_gradient);
BENCHMARK(BM_ObstaclePlane_hessian);
BENCHMARK(BM_PointPoint_gradient);
BENCHMARK(BM_PointPoint_hessian);
BENCHMARK(BM_PointLine_gradient);
BENCHMARK(BM_PointLine_hessian);
BENCHMARK(BM_PointPlane_gradient);
BENCHMARK(BM_PointPlane_hessian);
BENCHMARK(BM_PointPlane_hessian_baseline);
BENCHMARK(BM_LineLine_gradient);
BENCHMARK(BM_LineLine_hessian);
BENCHMARK(BM_MollifiedEdgeEdge_gradient);
BENCHMARK(BM_MollifiedEdgeEdge_hessian);
BENCHMARK(BM_ProjectPsdTranslationFree);
BENCHMARK(BM_ProjectPsdTranslationFree_baseline);

}  // namespace
}  // namespace nexdyn

BENCHMARK_MAIN();

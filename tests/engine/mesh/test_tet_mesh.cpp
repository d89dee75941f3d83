// Tests of the TetMesh helpers: signed volume, orientation repair, degenerate-tet detection.
#include <doctest/doctest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "engine/mesh/tet_mesh.hpp"
#include "tests/engine/mesh/mesh_checks.hpp"
#include "tests/engine/test_support.hpp"

using namespace nexdyn;

namespace {

TetMesh unit_tet(double scale = 1.0, double offset = 0.0) {
  TetMesh mesh;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (double& x : mesh.positions) x = x * scale + offset;
  mesh.tets = {0, 1, 2, 3};
  return mesh;
}

}  // namespace

TEST_SUITE_BEGIN("mesh");

TEST_CASE("signed_tet_volume: sign follows vertex order and scales with size cubed") {
  const Eigen::Vector3d x0(0, 0, 0), x1(1, 0, 0), x2(0, 1, 0), x3(0, 0, 1);
  CHECK(signed_tet_volume(x0, x1, x2, x3) == test::relative(1.0 / 6.0, 1e-12));
  // Odd permutations flip the sign, even ones keep it.
  CHECK(signed_tet_volume(x0, x1, x3, x2) == test::relative(-1.0 / 6.0, 1e-12));
  CHECK(signed_tet_volume(x1, x0, x2, x3) == test::relative(-1.0 / 6.0, 1e-12));
  CHECK(signed_tet_volume(x1, x2, x0, x3) == test::relative(1.0 / 6.0, 1e-12));
  CHECK(signed_tet_volume(x3, x2, x1, x0) == test::relative(1.0 / 6.0, 1e-12));
  // Translation far from the origin keeps the volume (differences are taken first).
  const Eigen::Vector3d far(1e6, -2e6, 3e6);
  CHECK(signed_tet_volume(x0 + far, x1 + far, x2 + far, x3 + far) ==
        test::relative(1.0 / 6.0, 1e-9));
  CHECK(signed_tet_volume(2 * x0, 2 * x1, 2 * x2, 2 * x3) == test::relative(8.0 / 6.0, 1e-12));
  CHECK(signed_tet_volume(unit_tet(3.0), 0) == test::relative(27.0 / 6.0, 1e-12));
}

TEST_CASE("orient_tets_positively: flips exactly the negative tets and keeps their vertices") {
  // Random tets over random points; many are negative.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-1.0, 1.0);
  TetMesh mesh;
  for (int i = 0; i < 3 * 40; ++i) mesh.positions.push_back(coordinate(rng));
  std::uniform_int_distribution<int32_t> vertex(0, 39);
  while (mesh.num_tets() < 200) {
    int32_t t[4] = {vertex(rng), vertex(rng), vertex(rng), vertex(rng)};
    std::vector<int32_t> sorted(t, t + 4);
    std::sort(sorted.begin(), sorted.end());
    if (std::adjacent_find(sorted.begin(), sorted.end()) == sorted.end())
      mesh.tets.insert(mesh.tets.end(), t, t + 4);
  }
  int32_t negative = 0;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) negative += signed_tet_volume(mesh, t) < 0.0;
  REQUIRE(negative > 20);
  const TetMesh before = mesh;

  CHECK(orient_tets_positively(mesh) == negative);
  CHECK(nexdyn::test::count_non_positive_tets(mesh) == 0);
  for (int32_t t = 0; t < mesh.num_tets(); ++t) {
    CHECK(signed_tet_volume(mesh, t) ==
          test::relative(std::abs(signed_tet_volume(before, t)), 1e-12));
    std::vector<int32_t> a(before.tets.begin() + 4 * t, before.tets.begin() + 4 * t + 4);
    std::vector<int32_t> b(mesh.tets.begin() + 4 * t, mesh.tets.begin() + 4 * t + 4);
    CHECK(a[0] == b[0]);  // the first vertex stays: only the last two are swapped
    std::sort(a.begin(), a.end());
    std::sort(b.begin(), b.end());
    CHECK(a == b);
  }
  CHECK(orient_tets_positively(mesh) == 0);  // idempotent
}

TEST_CASE("orient_tets_positively: span overload works on a sub-range of global buffers") {
  TetMesh mesh = unit_tet();
  mesh.tets = {0, 1, 3, 2, 0, 1, 2, 3, 1, 0, 2, 3};
  // Only the first two tets are handed over: one flip, the third tet stays negative.
  CHECK(orient_tets_positively(mesh.positions, std::span<int32_t>(mesh.tets).first(8)) == 1);
  CHECK(signed_tet_volume(mesh, 0) > 0.0);
  CHECK(signed_tet_volume(mesh, 2) < 0.0);
}

TEST_CASE("find_degenerate_tet: flat tets are found whatever the mesh scale") {
  for (const double scale : {1e-6, 1.0, 1e6}) {
    CAPTURE(scale);
    TetMesh mesh = unit_tet(scale, 10.0 * scale);
    CHECK(find_degenerate_tet(mesh) == -1);
    CHECK(tet_relative_volume(mesh, 0) == test::relative(1.0 / (6.0 * 2.0 * std::sqrt(2.0)), 1e-12));

    // Second tet: apex lifted off the base plane by a relative height h.
    const auto add_flat_tet = [&](double h) {
      TetMesh flat = mesh;
      const int32_t apex = flat.num_vertices();
      flat.positions.insert(flat.positions.end(),
                            {(0.3 + 10.0) * scale, (0.3 + 10.0) * scale, (h + 10.0) * scale});
      flat.tets.insert(flat.tets.end(), {0, 1, 2, apex});
      return flat;
    };
    CHECK(find_degenerate_tet(add_flat_tet(0.0)) == 1);
    CHECK(find_degenerate_tet(add_flat_tet(1e-14)) == 1);
    CHECK(find_degenerate_tet(add_flat_tet(1e-8)) == -1);
  }
  // All four vertices at one point.
  TetMesh point;
  point.positions = {1, 2, 3, 1, 2, 3, 1, 2, 3, 1, 2, 3};
  point.tets = {0, 1, 2, 3};
  CHECK(tet_relative_volume(point, 0) == 0.0);
  CHECK(find_degenerate_tet(point) == 0);
}

TEST_SUITE_END();

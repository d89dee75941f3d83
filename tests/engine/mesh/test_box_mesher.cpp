// Tests of make_box_mesh: counts, volume, orientation, closed conforming surface, centring,
// argument validation.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/surface.hpp"
#include "tests/engine/mesh/mesh_checks.hpp"
#include "tests/engine/test_support.hpp"

using namespace nexdyn;

TEST_SUITE_BEGIN("mesh");

TEST_CASE("make_box_mesh: counts and volume and orientation and a closed conforming surface") {
  struct BoxCase {
    Eigen::Vector3d size;
    std::array<int, 3> cells;
  };
  const BoxCase cases[] = {
      {{1.0, 1.0, 1.0}, {1, 1, 1}},
      {{2.0, 0.5, 3.0}, {2, 3, 4}},
      {{0.3, 7.0, 0.01}, {5, 1, 2}},
      {{1.0, 1.0, 1.0}, {7, 6, 5}},
  };
  for (const BoxCase& box : cases) {
    const int nx = box.cells[0], ny = box.cells[1], nz = box.cells[2];
    CAPTURE(nx);
    CAPTURE(ny);
    CAPTURE(nz);
    const TetMesh mesh = make_box_mesh(box.size, box.cells);
    CHECK(mesh.num_tets() == kTetsPerBoxCell * nx * ny * nz);
    CHECK(mesh.num_vertices() == (nx + 1) * (ny + 1) * (nz + 1));
    const double volume = box.size.prod();
    CHECK(mesh_volume(mesh) == test::relative(volume, 1e-12));
    CHECK(nexdyn::test::count_non_positive_tets(mesh) == 0);
    CHECK(find_degenerate_tet(mesh) == -1);
    // Every Kuhn tet is one sixth of its cell.
    const double cell_volume = volume / (nx * ny * nz);
    for (int32_t t = 0; t < mesh.num_tets(); ++t)
      CHECK(signed_tet_volume(mesh, t) == test::relative(cell_volume / 6.0, 1e-12));

    // A non-conforming split would leave unmatched interior faces and break these counts.
    const SurfaceMesh surface = extract_surface(mesh);
    CHECK(surface.num_triangles() == 2 * 2 * (nx * ny + ny * nz + nz * nx));
    CHECK(nexdyn::test::is_closed_and_consistently_wound(surface));
    CHECK(nexdyn::test::euler_characteristic(surface) == 2);
    CHECK(nexdyn::test::count_components(surface, mesh.num_vertices()) == 1);
    CHECK(nexdyn::test::divergence_volume(mesh, surface) == test::relative(volume, 1e-12));

    // Centred: the bounding box is exactly [-size/2, size/2] and the vertices average to 0.
    for (int d = 0; d < 3; ++d) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo, sum = 0.0;
      for (int32_t v = 0; v < mesh.num_vertices(); ++v) {
        const double x = mesh.positions[3 * v + d];
        lo = std::min(lo, x);
        hi = std::max(hi, x);
        sum += x;
      }
      CHECK(lo == -0.5 * box.size[d]);
      CHECK(hi == 0.5 * box.size[d]);
      CHECK(std::abs(sum / mesh.num_vertices()) <= 1e-14 * box.size[d]);
    }
  }
}

TEST_CASE("make_box_mesh: bad arguments throw std::invalid_argument naming the axis") {
  const auto message_of = [](const Eigen::Vector3d& size,
                             const std::array<int, 3>& cells) -> std::string {
    try {
      make_box_mesh(size, cells);
    } catch (const std::invalid_argument& error) {
      return error.what();
    }
    return "<no exception>";
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  CHECK(message_of({1, 1, 1}, {0, 1, 1}).find("cells.x must be >= 1, got 0") != std::string::npos);
  CHECK(message_of({1, 1, 1}, {1, -2, 1}).find("cells.y must be >= 1, got -2") !=
        std::string::npos);
  CHECK(message_of({1, 0, 1}, {1, 1, 1}).find("size.y must be positive") != std::string::npos);
  CHECK(message_of({1, 1, -1}, {1, 1, 1}).find("size.z must be positive") != std::string::npos);
  CHECK(message_of({nan, 1, 1}, {1, 1, 1}).find("size.x") != std::string::npos);
  CHECK(message_of({1, inf, 1}, {1, 1, 1}).find("size.y") != std::string::npos);
  CHECK(message_of({1, 1, 1}, {2000, 2000, 2000}).find("too many") != std::string::npos);
}

TEST_SUITE_END();

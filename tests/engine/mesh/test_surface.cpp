// Tests of extract_surface: exact small cases, outward winding, independence from tet order and
// from the (orientation-preserving) vertex order inside tets, several bodies in one buffer.
#include <doctest/doctest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/surface.hpp"
#include "tests/engine/mesh/mesh_checks.hpp"
#include "tests/engine/test_support.hpp"

using namespace nexdyn;
using nexdyn::test::vertex_at;

TEST_SUITE_BEGIN("mesh");

TEST_CASE("extract_surface: one tet gives its 4 faces wound outward") {
  TetMesh mesh;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  mesh.tets = {0, 1, 2, 3};
  const SurfaceMesh surface = extract_surface(mesh);
  // Faces rotated to start at their smallest id, sorted by sorted triple.
  CHECK(surface.triangles == std::vector<int32_t>{0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3});
  CHECK(surface.edges == std::vector<int32_t>{0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3});
  CHECK(surface.vertices == std::vector<int32_t>{0, 1, 2, 3});
  const Eigen::Vector3d centre(0.25, 0.25, 0.25);
  for (int32_t f = 0; f < surface.num_triangles(); ++f) {
    const Eigen::Vector3d a = vertex_at(mesh, surface.triangles[3 * f]);
    const Eigen::Vector3d b = vertex_at(mesh, surface.triangles[3 * f + 1]);
    const Eigen::Vector3d c = vertex_at(mesh, surface.triangles[3 * f + 2]);
    CHECK((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0);
  }
}

TEST_CASE("extract_surface: a face shared by two tets is interior") {
  TetMesh mesh;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  mesh.tets = {0, 1, 2, 3, 1, 3, 4, 2};
  REQUIRE(nexdyn::test::count_non_positive_tets(mesh) == 0);
  const SurfaceMesh surface = extract_surface(mesh);
  CHECK(surface.num_triangles() == 6);
  CHECK(surface.num_edges() == 9);
  CHECK(surface.vertices.size() == 5);
  CHECK(nexdyn::test::is_closed_and_consistently_wound(surface));
  CHECK(nexdyn::test::divergence_volume(mesh, surface) == test::relative(0.5, 1e-12));
  for (int32_t f = 0; f < surface.num_triangles(); ++f) {
    std::vector<int32_t> ids(surface.triangles.begin() + 3 * f,
                             surface.triangles.begin() + 3 * f + 3);
    std::sort(ids.begin(), ids.end());
    CHECK(ids != std::vector<int32_t>{1, 2, 3});
  }
}

TEST_CASE("extract_surface: a face used by three tets is not a boundary face") {
  TetMesh mesh;
  mesh.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0.1, 0.1, 2};
  mesh.tets = {0, 1, 2, 3, 0, 2, 1, 4, 0, 1, 2, 5};
  REQUIRE(nexdyn::test::count_non_positive_tets(mesh) == 0);
  const SurfaceMesh surface = extract_surface(mesh);
  CHECK(surface.num_triangles() == 9);
  for (int32_t f = 0; f < surface.num_triangles(); ++f) {
    std::vector<int32_t> ids(surface.triangles.begin() + 3 * f,
                             surface.triangles.begin() + 3 * f + 3);
    std::sort(ids.begin(), ids.end());
    CHECK(ids != std::vector<int32_t>{0, 1, 2});
  }
}

TEST_CASE("extract_surface: result does not depend on tet order or on even vertex rotations") {
  const TetMesh box = make_box_mesh({1.0, 2.0, 3.0}, {4, 3, 5});
  const SurfaceMesh reference = extract_surface(box);
  TetMesh shuffled = box;
  std::mt19937 rng(42);
  std::vector<int32_t> order(box.num_tets());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  for (int32_t t = 0; t < box.num_tets(); ++t) {
    int32_t ids[4];
    std::copy_n(&box.tets[4 * order[t]], 4, ids);
    // An even permutation (a 3-cycle of the last three, or a double swap) keeps the orientation.
    const int kind = static_cast<int>(rng() % 3);
    if (kind == 1) std::rotate(ids + 1, ids + 2, ids + 4);
    if (kind == 2) {
      std::swap(ids[0], ids[1]);
      std::swap(ids[2], ids[3]);
    }
    std::copy_n(ids, 4, &shuffled.tets[4 * t]);
  }
  REQUIRE(nexdyn::test::count_non_positive_tets(shuffled) == 0);
  const SurfaceMesh other = extract_surface(shuffled);
  CHECK(other.triangles == reference.triangles);
  CHECK(other.edges == reference.edges);
  CHECK(other.vertices == reference.vertices);
}

TEST_CASE("extract_surface: two bodies in one buffer give the union of their surfaces") {
  const TetMesh a = make_box_mesh({1, 1, 1}, {2, 2, 2});
  TetMesh both = a;
  const TetMesh b = make_box_mesh({1, 1, 1}, {3, 1, 2});
  const int32_t offset = both.num_vertices();
  both.positions.insert(both.positions.end(), b.positions.begin(), b.positions.end());
  for (const int32_t v : b.tets) both.tets.push_back(v + offset);
  const SurfaceMesh surface = extract_surface(both);
  CHECK(surface.num_triangles() ==
        extract_surface(a).num_triangles() + extract_surface(b).num_triangles());
  CHECK(nexdyn::test::count_components(surface, both.num_vertices()) == 2);
  CHECK(nexdyn::test::euler_characteristic(surface) == 4);
  CHECK(nexdyn::test::is_closed_and_consistently_wound(surface));
  CHECK(surface.edges == nexdyn::test::edges_of(surface));
}

TEST_CASE("extract_surface: empty input gives an empty surface") {
  const SurfaceMesh surface = extract_surface(TetMesh{});
  CHECK(surface.triangles.empty());
  CHECK(surface.edges.empty());
  CHECK(surface.vertices.empty());
}

TEST_SUITE_END();

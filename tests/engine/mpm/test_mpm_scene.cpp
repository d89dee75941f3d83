// MPM scene files (issue 23): what the reader builds, what it refuses (one line naming the key),
// and what `nexdyn run` writes for a particle scene.
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/tet_mesh.hpp"
#include "engine/scene/scene.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>

using namespace nexdyn;

namespace {

const char* kGrid = R"("mpm": {"grid_spacing": 0.05, "domain_min": [-0.5, -0.2, -0.5], "domain_max": [0.5, 0.8, 0.5]})";
const char* kMaterials = R"("materials": {"m": {"model": "corotated", "youngs": 1e5, "poisson": 0.3, "density": 800}})";
const char* kBody = R"({"particles": {"box": {"size": [0.2, 0.1, 0.3], "per_cell": 2}}, "material": "m", "translate": [0, 0.3, 0]})";

std::string scene(const std::string& grid, const std::string& bodies, const std::string& extra = "") {
  return "{" + grid + (grid.empty() ? "" : ", ") + kMaterials + R"(, "bodies": [)" + bodies + "]" + extra + "}";
}

std::string load_error(const std::string& json) {
  try {
    test::scene_from_json(json, "mpm_bad");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "<no SceneError>";
}

}  // namespace

TEST_CASE("mpm scene: box and mesh particle bodies, planes and boxes are read") {
  const Scene s = test::scene_from_json(
      scene(kGrid, std::string(kBody) + R"(, {"particles": {"box": {"size": [0.1, 0.1, 0.1], "per_cell": 1}},
              "material": "m", "translate": [0, 0.5, 0], "rotate_deg": [0, 45, 0], "velocity": [1, 0, 0]})",
            R"(, "contact": {"friction": 0.4}, "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 2, 0]}, "condition": "slip"}],
              "boundary": [{"box_min": [-1, 0.33, -1], "box_max": [1, 0.36, 1], "fix": true}])"),
      "mpm_read");
  REQUIRE(s.mpm);
  const MpmModel& m = *s.mpm;
  // 0.2 x 0.1 x 0.3 m at h = 0.05: 4 x 2 x 6 cells, 8 particles each; then 2^3 cells of one.
  CHECK(m.initial.size() == 4 * 2 * 6 * 8 + 8);
  CHECK(total_mass(m.initial) == doctest::Approx(800.0 * (0.2 * 0.1 * 0.3 + 0.001)).epsilon(1e-12));
  CHECK(m.particle_body.back() == 1);
  CHECK(m.initial.velocity(m.initial.size() - 1).x() == 1.0);
  CHECK(m.friction == 0.4);
  REQUIRE(m.planes.size() == 1);
  CHECK(m.planes[0].normal.y() == 1.0);
  CHECK(m.planes[0].condition == PlaneCondition::slip);
  CHECK(m.boxes.size() == 1);
  CHECK(s.initial.x.empty());
}

TEST_CASE("mpm scene: particles sampled in the tets of a mesh carry its volume") {
  const std::string mesh = std::string(NEXDYN_SOURCE_DIR) + "/scenes/meshes/cube.msh";
  for (int per_tet : {1, 4}) {
    const Scene s = test::scene_from_json(
        scene(kGrid, R"({"particles": {"mesh": ")" + mesh + R"(", "per_tet": )" + std::to_string(per_tet) +
                         R"(}, "material": "m", "scale": 0.1, "translate": [0, 0.3, 0]})"),
        "mpm_mesh");
    const TetMesh tets = read_msh(mesh);
    CHECK(s.mpm->initial.size() == per_tet * tets.num_tets());
    CHECK(total_mass(s.mpm->initial) == doctest::Approx(800.0 * 1e-3 * mesh_volume(tets)).epsilon(1e-12));
  }
}

TEST_CASE("mpm scene: what is refused, naming the key") {
  CHECK(load_error(scene("", kBody)).find("bodies[0].particles: particle bodies need the top-level \"mpm\" key") !=
        std::string::npos);
  CHECK(load_error(scene(kGrid, std::string(kBody) + R"(, {"box": {"size": [0.1, 0.1, 0.1], "cells": [1, 1, 1]}, "material": "m"})"))
            .find("bodies[1]: a scene with particle bodies cannot also have tet bodies") != std::string::npos);
  CHECK(load_error(scene(kGrid, kBody, R"(, "contact": {}, "obstacles": [{"mesh": "x.obj"}])"))
            .find("obstacles[0].mesh: MPM scenes take plane obstacles only") != std::string::npos);
  CHECK(load_error(scene(kGrid, kBody, R"(, "contact": {}, "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}, "condition": "glue"}])"))
            .find("obstacles[0].condition: expected \"separating\", \"slip\" or \"sticky\"") != std::string::npos);
  CHECK(load_error(scene(kGrid, kBody, R"(, "contact": {"dhat": 0.001})")).find("contact.dhat: not used by MPM scenes") !=
        std::string::npos);
  CHECK(load_error(scene(R"("mpm": {"grid_spacing": 0.05, "domain_min": [-0.5, -0.2, -0.5], "domain_max": [0.5, 0.3, 0.5]})", kBody))
            .find("is not inside mpm.domain_min .. domain_max") != std::string::npos);
  CHECK(load_error(scene(R"("mpm": {"grid_spacing": 0.0001, "domain_min": [-5, -5, -5], "domain_max": [5, 5, 5]})", kBody))
            .find("mpm.grid_spacing: the grid would have") != std::string::npos);
  CHECK(load_error(scene(kGrid, kBody, R"(, "boundary": [{"box_min": [2, 2, 2], "box_max": [3, 3, 3], "fix": true}])"))
            .find("boundary[0]: the box holds no particle at the start") != std::string::npos);
  CHECK(load_error(scene(kGrid, kBody, R"(, "solver": {"method": "linearized"})")).find("solver.method: MPM scenes are solved by Newton") !=
        std::string::npos);
  CHECK(load_error(scene(kGrid, R"({"particles": {"box": {"size": [0.1, 0.1, 0.1]}, "per_cell": 2}, "material": "m"})"))
            .find("bodies[0].particles.per_cell: unknown key (allowed here: box)") != std::string::npos);
  // An explicit scheme is fine with MPM planes (they hold grid nodes, not a barrier).
  CHECK_NOTHROW(test::scene_from_json(scene(kGrid, kBody, R"(, "time": {"integrator": "central_difference"}, "contact": {},
      "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}}])"), "mpm_explicit"));
}

TEST_CASE("mpm run writes point-cloud frames, scene.pvd and stats.csv, and render draws them") {
  const auto dir = test::temp_dir("mpm_run");
  const auto file = test::write_text(dir / "drop.json", scene(kGrid, kBody, R"(, "time": {"dt": 0.01, "steps": 3},
      "output": {"every": 3}, "contact": {}, "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}}])"));
  const test::CommandResult r = test::run_cli("run " + file.string() + " --out " + (dir / "out").string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  CHECK(r.output.find("MPM: bodies 1, particles 384") != std::string::npos);
  std::ifstream vtu(dir / "out" / "frames" / "frame_000003.vtu");
  std::stringstream text;
  text << vtu.rdbuf();
  CHECK(text.str().find("NumberOfPoints=\"384\" NumberOfCells=\"384\"") != std::string::npos);
  for (const char* name : {"Name=\"velocity\"", "Name=\"J\"", "Name=\"von_mises\"", "Name=\"body\"", "Name=\"radius\""})
    CHECK(text.str().find(name) != std::string::npos);
  std::ifstream stats(dir / "out" / "stats.csv");
  std::string header, line;
  std::getline(stats, header);
  CHECK(header.rfind("step,time,kinetic_energy,elastic_energy,gravity_energy,barrier_energy,total_energy", 0) == 0);
  int rows = 0;
  while (std::getline(stats, line)) ++rows;
  CHECK(rows == 3);
  std::ifstream pvd(dir / "out" / "scene.pvd");
  std::stringstream pvd_text;
  pvd_text << pvd.rdbuf();
  CHECK(pvd_text.str().find("frames/frame_000003.vtu") != std::string::npos);
  // `nexdyn render` draws the particles (a small icosahedron each).
  const test::CommandResult picture =
      test::run_cli("render " + (dir / "out").string() + " --frame 3 --size 64x48 --color speed");
  INFO(picture.output);
  CHECK(picture.exit_code == 0);
  CHECK(std::filesystem::file_size(dir / "out" / "render" / "frame_000003.png") > 100);
}

TEST_CASE("mpm scene: angular_velocity spins a particle body about its centre of mass, with C = [omega]x") {
  const Eigen::Vector3d v0(1, 0, 0), omega(0.5, -1, 2);
  const Scene s = test::scene_from_json(
      scene(kGrid, R"({"particles": {"box": {"size": [0.2, 0.1, 0.3], "per_cell": 2}}, "material": "m",
                       "translate": [0.05, 0.3, 0], "rotate_deg": [0, 30, 0], "velocity": [1, 0, 0],
                       "angular_velocity": [0.5, -1, 2]})"),
      "mpm_spin");
  const Particles& P = s.mpm->initial;
  double M = 0.0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), p = Eigen::Vector3d::Zero(), L = Eigen::Vector3d::Zero();
  for (int64_t q = 0; q < P.size(); ++q) {
    M += P.mass[q];
    c += P.mass[q] * P.position(q);
  }
  c /= M;
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero(), spin;
  spin << 0, -omega.z(), omega.y(), omega.z(), 0, -omega.x(), -omega.y(), omega.x(), 0;
  double largest_C_error = 0.0;
  for (int64_t q = 0; q < P.size(); ++q) {
    const Eigen::Vector3d r = P.position(q) - c;
    I += P.mass[q] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
    p += P.mass[q] * P.velocity(q);
    L += P.mass[q] * r.cross(P.velocity(q));
    largest_C_error = std::max(largest_C_error, (P.affine(q) - spin).norm());
  }
  CHECK((p - M * v0).norm() <= 1e-13 * M);
  CHECK((L - I * omega).norm() <= 1e-12 * (I * omega).norm());
  // C is the gradient of the rigid field v0 + omega x (x - c): [omega]x, for every particle.
  CHECK(largest_C_error == 0.0);
}

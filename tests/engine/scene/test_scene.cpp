// Scene loading: every kind of bad input is one clear error naming the file, the key and the
// value; good scenes build the flat buffers they describe.
#include "engine/output/frame_writer.hpp"
#include "engine/scene/scene.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <sstream>

using namespace nexdyn;

namespace {

const char* kMaterials = R"("materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } })";
const char* kBox = R"({ "box": { "size": [1, 1, 1], "cells": [2, 2, 2] }, "material": "m" })";

std::string scene_with(const std::string& extra, const std::string& materials = kMaterials,
                       const std::string& bodies = std::string("[") + kBox + "]") {
  return "{ " + materials + R"(, "bodies": )" + bodies + (extra.empty() ? "" : ", " + extra) + " }";
}

// Loads the scene and returns the error message (empty if it loaded).
std::string error_of(const std::string& json) {
  try {
    test::scene_from_json(json, "bad");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("scene errors name the file and the key and the value") {
  struct Case { std::string json; std::vector<std::string> must_contain; };
  const std::vector<Case> cases = {
      {scene_with(R"("gravty": [0, 0, 0])"), {"bad.json", "gravty", "unknown key"}},
      {scene_with(R"("time": { "dt": 0 })"), {"time.dt", "positive", "0"}},
      {scene_with(R"("time": { "dt": -0.01 })"), {"time.dt", "-0.01"}},
      {scene_with(R"("time": { "dt": "fast" })"), {"time.dt", "number", "\"fast\""}},
      {scene_with(R"("time": { "integrator": "leapfrog" })"), {"time.integrator", "leapfrog", "newmark"}},
      {scene_with(R"("time": { "steps": 1.5 })"), {"time.steps", "integer"}},
      {scene_with("", R"("materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.5, "density": 1000 } })"),
       {"materials.m.poisson", "0.5"}},
      {scene_with("", R"("materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": -1 } })"),
       {"materials.m.density", "-1"}},
      {scene_with("", R"("materials": { "m": { "model": "mooney", "youngs": 1e5, "poisson": 0.3, "density": 1 } })"),
       {"materials.m.model", "mooney"}},
      {scene_with("", R"("materials": { "m": { "model": "linear", "poisson": 0.3, "density": 1 } })"),
       {"materials.m", "youngs"}},
      {scene_with("", kMaterials, R"([{ "mesh": "no/such/file.msh", "material": "m" }])"),
       {"bodies[0].mesh", "not found", "no/such/file.msh"}},
      {scene_with("", kMaterials, R"([{ "box": { "size": [1, 1, 1], "cells": [0, 1, 1] }, "material": "m" }])"),
       {"bodies[0].box.cells[0]", "0"}},
      {scene_with("", kMaterials, R"([{ "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "steel" }])"),
       {"bodies[0].material", "steel"}},
      {scene_with("", kMaterials, R"([{ "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m", "scale": -2 }])"),
       {"bodies[0].scale", "-2"}},
      {scene_with(R"("boundary": [ { "box_min": [5, 5, 5], "box_max": [6, 6, 6], "fix": true } ])"),
       {"boundary[0]", "selects no vertex"}},
      {scene_with(R"("boundary": [ { "box_min": [-1, -1, -1], "box_max": [1, 1, 1] } ])"),
       {"boundary[0]", "fix"}},
      {scene_with(R"("output": { "formats": ["png"] })"), {"output.formats[0]", "png"}},
      {scene_with(R"("time": { "dt": 0.01, "beta": 0.7 })"), {"time.beta", "0.7"}},
      {scene_with(R"("time": { "integrator": "newmark", "rho_inf": 0.5 })"),
       {"time.rho_inf", "generalized_alpha", "newmark", "0.5"}},
      {scene_with(R"("time": { "integrator": "generalized_alpha", "rho_inf": 1.5 })"), {"time.rho_inf", "1.5"}},
      {scene_with(R"("time": { "alpha_m": 0.3, "alpha_f": 0.2 })"), {"time.alpha_m", "alpha_f", "0.3"}},
      {scene_with(R"("time": { "alpha_f": 0.6 })"), {"time.alpha_f", "0.6"}},
      {scene_with(R"("time": { "alpha_f": 0.1, "beta": 0 })"), {"time.beta", "implicit"}},
      {scene_with(R"("time": { "energy_guard": "yes" })"), {"time.energy_guard", "true or false", "yes"}},
      {scene_with(R"("solver": { "sleep": "yes" })"), {"solver.sleep", "true, false or an object", "yes"}},
      {scene_with(R"("solver": { "sleep": { "velocity": -1 } })"), {"solver.sleep.velocity", "-1"}},
      {scene_with(R"("solver": { "sleep": { "steps": 0 } })"), {"solver.sleep.steps", "0"}},
      {scene_with(R"("solver": { "sleep": { "time": 1 } })"), {"solver.sleep", "time", "unknown key"}},
      {"{ not json", {"bad.json", "JSON"}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.json);
    const std::string message = error_of(c.json);
    REQUIRE_FALSE(message.empty());
    for (const std::string& part : c.must_contain) {
      CAPTURE(message);
      CHECK(message.find(part) != std::string::npos);
    }
  }
}

TEST_CASE("generalized-alpha from rho_inf, and HHT-alpha from alpha_f, take their Newmark parameters") {
  const Scene ga = test::scene_from_json(scene_with(R"("time": { "integrator": "generalized_alpha", "rho_inf": 0.5 })"));
  const IntegratorParams& p = ga.time.integrator;
  CHECK(p.name == "generalized_alpha");
  CHECK(p.rho_inf == 0.5);
  CHECK(p.alpha_m == doctest::Approx(0.0).epsilon(1e-15));  // (2 rho - 1) / (rho + 1)
  CHECK(p.alpha_f == test::relative(1.0 / 3.0, 1e-15));
  CHECK(p.gamma == test::relative(0.5 + 1.0 / 3.0, 1e-15));
  CHECK(2.0 * p.alpha * p.beta == test::relative(0.25 * (4.0 / 3.0) * (4.0 / 3.0), 1e-15));
  // HHT-alpha with its alpha = -0.1: alpha_m = 0, alpha_f = 0.1, gamma = 0.6, beta = 1.1^2 / 4.
  const Scene hht = test::scene_from_json(scene_with(R"("time": { "alpha_f": 0.1 })"));
  const IntegratorParams& q = hht.time.integrator;
  CHECK(q.name == "custom");
  CHECK(q.alpha_m == 0.0);
  CHECK(q.alpha_f == 0.1);
  CHECK(q.gamma == test::relative(0.6, 1e-15));
  CHECK(2.0 * q.alpha * q.beta == test::relative(1.1 * 1.1 / 4.0, 1e-15));
}

TEST_CASE("a good scene builds the buffers it describes") {
  Scene scene = test::scene_from_json(R"({
    "name": "two", "gravity": [0, 0, -1],
    "time": { "dt": 0.005, "steps": 7, "integrator": "implicit_euler" },
    "materials": { "m": { "model": "corotated", "youngs": 2e5, "poisson": 0.25, "density": 800 } },
    "bodies": [ { "box": { "size": [1, 2, 3], "cells": [1, 2, 3] }, "material": "m",
                  "array": { "count": [2, 1, 1], "spacing": [5, 0, 0] }, "velocity": [0, 1, 0] } ],
    "boundary": [ { "body": 0, "box_min": [-1, -2, -2], "box_max": [6, 2, -1.49], "fix": true } ]
  })", "good");
  const Model& m = scene.model;
  CHECK(scene.name == "two");
  CHECK(scene.time.steps == 7);
  CHECK(scene.time.integrator.name == "implicit_euler");
  REQUIRE(m.bodies.size() == 2);
  CHECK(m.num_tets == 2 * 6 * 6);
  CHECK(m.num_vertices == 2 * 2 * 3 * 4);
  double mass = 0.0;
  for (double mi : m.mass) mass += mi;
  CHECK(mass == test::relative(2 * 800.0 * 6.0, 1e-12));
  // Copies are offset by the spacing; the second copy's first vertex is 5 m further along x.
  CHECK(m.rest_positions[3 * m.bodies[1].vertex_begin] ==
        test::relative(m.rest_positions[0] + 5.0, 1e-12));
  // The boundary box at z = -1.5 holds the bottom layer (3 x 2 vertices... per copy: 2 x 3 = 6).
  int fixed = 0;
  for (int32_t d : m.dirichlet) fixed += d >= 0;
  CHECK(fixed == 2 * 6);
  CHECK(scene.initial.v[1] == 1.0);
  CHECK(m.material_batches.size() == 1);
}

TEST_CASE("rotate_deg rotates about x then y then z and scale comes first") {
  Scene scene = test::scene_from_json(R"({
    "materials": { "m": { "model": "linear", "youngs": 1e5, "poisson": 0.3, "density": 1 } },
    "bodies": [ { "box": { "size": [2, 2, 2], "cells": [1, 1, 1] }, "material": "m",
                  "scale": [1, 1, 0.5], "rotate_deg": [90, 0, 90], "translate": [10, 0, 0] } ]
  })", "rotate");
  // The corner (1, 1, 1) scales to (1, 1, 0.5), rotates +90 about x to (1, -0.5, 1), then +90
  // about z to (0.5, 1, 1), then moves to (10.5, 1, 1). Find it among the 8 corners.
  bool found = false;
  const auto& X = scene.model.rest_positions;
  for (size_t v = 0; v < X.size() / 3; ++v)
    found = found || (std::abs(X[3 * v] - 10.5) < 1e-12 && std::abs(X[3 * v + 1] - 1) < 1e-12 &&
                      std::abs(X[3 * v + 2] - 1) < 1e-12);
  CHECK(found);
}

// ---- contact settings and obstacles ----------------------------------------------------------

namespace {

// A unit quad in the plane y = -1 as an OBJ file: 4 vertices, one quad face (fan-split into 2
// triangles) written with the v/vt/vn and negative index forms, plus lines the reader ignores.
const char* kQuadObj = R"(# a quad
mtllib none.mtl
o quad
v -1 -1 -1
v  1 -1 -1
v  1 -1  1
v -1 -1  1
vt 0 0
vn 0 1 0
s off
f 1/1/1 -1//1 3/1 2
)";

// Writes `files` (name -> text) and the scene into one fresh folder and loads the scene, so that
// relative mesh paths resolve against that folder.
Scene scene_with_files(const std::string& json, const std::vector<std::pair<std::string, std::string>>& files,
                       const std::string& tag = "obstacle") {
  const auto dir = test::temp_dir(tag);
  for (const auto& [name, text] : files) test::write_text(dir / name, text);
  return load_scene(test::write_text(dir / (tag + ".json"), json));
}

std::string error_with_files(const std::string& json, const std::vector<std::pair<std::string, std::string>>& files) {
  try {
    scene_with_files(json, files, "bad");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

std::string shipped_mesh(const std::string& name) {
  return (std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes" / "meshes" / name).string();
}

int count_lines_starting_with(const std::string& text, const std::string& prefix) {
  int count = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) count += line.rfind(prefix, 0) == 0;
  return count;
}

}  // namespace

TEST_CASE("a contact object switches contact on unless enabled is false") {
  CHECK_FALSE(test::scene_from_json(scene_with("")).contact.enabled);
  CHECK(test::scene_from_json(scene_with(R"("contact": {})")).contact.enabled);
  const Scene off = test::scene_from_json(scene_with(R"("contact": { "enabled": false, "dhat": 0.01 })"));
  CHECK_FALSE(off.contact.enabled);
  CHECK(off.contact.dhat == 0.01);
  // dhat left out stays 0: the contact code resolves it from the bodies' bounding box.
  CHECK(test::scene_from_json(scene_with(R"("contact": {})")).contact.dhat == 0.0);
  // An empty "obstacles" array needs no contact.
  CHECK(test::scene_from_json(scene_with(R"("obstacles": [])")).model.obstacle_planes.empty());
}

TEST_CASE("an obstacle plane is parsed and its normal normalised") {
  const Scene scene = test::scene_from_json(scene_with(R"("contact": {}, "obstacles": [
      { "plane": { "point": [0, -2, 0], "normal": [0, 3, 4] } },
      { "plane": { "point": [1, 2, 3], "normal": [0, 0, -0.5] } } ])"));
  const Model& m = scene.model;
  REQUIRE(m.obstacle_planes.size() == 2);
  CHECK(m.obstacle_planes[0].point.isApprox(Eigen::Vector3d(0, -2, 0)));
  CHECK(m.obstacle_planes[0].normal.isApprox(Eigen::Vector3d(0, 0.6, 0.8)));
  CHECK(m.obstacle_planes[0].scene_entry == 0);
  CHECK(m.obstacle_planes[1].normal.isApprox(Eigen::Vector3d(0, 0, -1)));
  CHECK(m.obstacle_planes[1].scene_entry == 1);
  // Planes add no vertices, bodies or motions.
  CHECK(m.bodies.size() == 1);
  CHECK(m.num_vertices == 27);
  CHECK(m.dirichlet_motions.empty());
}

TEST_CASE("an obj obstacle becomes a fixed massless body after the bodies") {
  // Obstacles 1 and 2 are the quad; "bodies" 0 and 1 are boxes. The boundary box covers
  // everything in y <= -0.5, the quads included, and must hold only the boxes' bottom layers.
  const std::string json = "{ " + std::string(kMaterials) + R"(,
    "contact": {},
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" },
                { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m",
                  "translate": [3, 0, 0], "velocity": [0, -1, 0] } ],
    "obstacles": [ { "plane": { "point": [0, -5, 0], "normal": [0, 1, 0] } },
                   { "mesh": "quad.obj", "translate": [10, 0, 0], "scale": 2 },
                   { "mesh": "quad.obj", "rotate_deg": [0, 90, 0] } ],
    "boundary": [ { "box_min": [-9, -9, -9], "box_max": [9, -0.5, 9], "fix": true } ]
  })";
  const Scene scene = scene_with_files(json, {{"quad.obj", kQuadObj}});
  const Model& m = scene.model;
  REQUIRE(m.bodies.size() == 4);
  // The "bodies" entries keep their indices and ranges; the obstacles follow.
  for (int b = 0; b < 2; ++b) {
    CHECK_FALSE(m.bodies[b].obstacle);
    CHECK(m.bodies[b].scene_entry == b);
    CHECK(m.bodies[b].vertex_begin == 8 * b);
    CHECK(m.bodies[b].triangle_begin == 12 * b);
  }
  CHECK(m.num_tets == 2 * 6);
  CHECK(m.num_vertices == 2 * 8 + 2 * 4);
  CHECK(m.surface_triangles.size() == 3 * (2 * 12 + 2 * 2));
  CHECK(m.surface_edges.size() == 2 * (2 * 18 + 2 * 5));
  CHECK(m.surface_vertices.size() == size_t(m.num_vertices));
  CHECK(std::is_sorted(m.surface_vertices.begin(), m.surface_vertices.end()));
  REQUIRE(m.obstacle_planes.size() == 1);

  // The boundary is motion 0; both obstacle meshes share motion 1, a fixed one.
  REQUIRE(m.dirichlet_motions.size() == 2);
  CHECK(m.dirichlet_motions[1].velocity.isZero());
  CHECK(m.dirichlet_motions[1].angular_velocity == 0.0);
  int held_by_boundary = 0;
  for (int32_t d : m.dirichlet) held_by_boundary += d == 0;
  CHECK(held_by_boundary == 2 * 4);

  for (int k = 0; k < 2; ++k) {
    const BodyRange& o = m.bodies[2 + k];
    CHECK(o.obstacle);
    CHECK(o.scene_entry == 1 + k);  // its index in "obstacles", planes included
    CHECK(o.tet_count == 0);
    CHECK(o.tet_begin == m.num_tets);
    CHECK(o.vertex_begin == 16 + 4 * k);
    CHECK(o.vertex_count == 4);
    CHECK(o.triangle_begin == 24 + 2 * k);
    CHECK(o.triangle_count == 2);
    CHECK(o.edge_count == 5);
    for (int32_t v = o.vertex_begin; v < o.vertex_begin + o.vertex_count; ++v) {
      CHECK(m.mass[v] == 0.0);
      CHECK(m.dirichlet[v] == 1);
      CHECK(m.vertex_body[v] == 2 + k);
      for (int d = 0; d < 3; ++d) CHECK(scene.initial.v[3 * v + d] == 0.0);
    }
    // Edges are unique, a < b, inside the obstacle's vertex range.
    for (int32_t e = o.edge_begin; e < o.edge_begin + o.edge_count; ++e) {
      CHECK(m.surface_edges[2 * e] < m.surface_edges[2 * e + 1]);
      CHECK(m.surface_edges[2 * e] >= o.vertex_begin);
      CHECK(m.surface_edges[2 * e + 1] < o.vertex_begin + o.vertex_count);
    }
  }
  // The obstacle transform: scale 2 then translate; the first quad vertex (-1,-1,-1) -> (8,-2,-2).
  CHECK(Eigen::Vector3d::Map(&m.rest_positions[3 * 16]).isApprox(Eigen::Vector3d(8, -2, -2)));
  // rotate_deg [0, 90, 0] takes (-1,-1,-1) to (-1,-1,1).
  CHECK(Eigen::Vector3d::Map(&m.rest_positions[3 * 20]).isApprox(Eigen::Vector3d(-1, -1, 1)));
  // Body 1's velocity is untouched by the obstacles appended after it.
  CHECK(scene.initial.v[3 * 8 + 1] == -1.0);
  CHECK(scene.initial.x.size() == 3 * size_t(m.num_vertices));
  CHECK(scene.initial.a.size() == 3 * size_t(m.num_vertices));

  // The quad's fan: f 1 4 3 2 -> triangles (1 4 3) and (1 3 2), 0-based (0 3 2) and (0 2 1).
  const int32_t b = m.bodies[2].vertex_begin;
  const int32_t* tri = &m.surface_triangles[3 * m.bodies[2].triangle_begin];
  CHECK(std::vector<int32_t>(tri, tri + 6) == std::vector<int32_t>{b, b + 3, b + 2, b, b + 2, b + 1});
}

TEST_CASE("a msh obstacle is the boundary surface of its tets") {
  const Scene scene = test::scene_from_json(scene_with(R"("contact": {}, "obstacles": [
      { "mesh": ")" + shipped_mesh("sphere1K.msh") + R"(", "translate": [0, -3, 0] } ])"));
  const Model& m = scene.model;
  REQUIRE(m.bodies.size() == 2);
  const BodyRange& o = m.bodies[1];
  CHECK(o.obstacle);
  CHECK(o.tet_count == 0);
  CHECK(m.num_tets == 6 * 8);  // only the box's tets
  // sphere1K.msh: 1760 nodes, 2474 boundary triangles. A closed genus-0 surface has
  // V = F / 2 + 2 vertices and E = 3 F / 2 edges; the interior nodes are dropped.
  CHECK(o.triangle_count == 2474);
  CHECK(o.vertex_count == 2474 / 2 + 2);
  CHECK(o.edge_count == 3 * 2474 / 2);
  for (int32_t v = o.vertex_begin; v < o.vertex_begin + o.vertex_count; ++v) {
    CHECK(m.mass[v] == 0.0);
    CHECK(m.dirichlet[v] == 0);  // no boundary entries: the shared fixed motion is motion 0
    CHECK(m.rest_positions[3 * v + 1] < -2.4);
  }
  CHECK(m.dirichlet_motions.size() == 1);
}

TEST_CASE("the shipped bowl obj loads as an open shell") {
  // The bowl is moved down, clear of the box at the origin (touching would be refused).
  const Scene scene = test::scene_from_json(scene_with(R"("contact": {}, "obstacles": [
      { "mesh": ")" + shipped_mesh("bowl.obj") + R"(", "translate": [0, -5, 0] } ])"));
  const BodyRange& o = scene.model.bodies.back();
  REQUIRE(o.obstacle);
  CHECK(o.vertex_count == 1 + 24 * 12);
  CHECK(o.triangle_count == 24 + 2 * 24 * 11);
  CHECK(o.edge_count == o.vertex_count + o.triangle_count - 1);  // a disc: V - E + F = 1
  double lowest = 0.0, highest = -1.0;
  for (int32_t v = o.vertex_begin; v < o.vertex_begin + o.vertex_count; ++v) {
    const Eigen::Vector3d p = Eigen::Vector3d::Map(&scene.model.rest_positions[3 * v]);
    // bowl.obj holds its coordinates to 9 significant digits: radii within ~1e-9 of 0.5.
    CHECK((p - Eigen::Vector3d(0, -5, 0)).norm() == test::relative(0.5, 1e-8));
    lowest = std::min(lowest, p.y() + 5.0);
    highest = std::max(highest, p.y() + 5.0);
  }
  CHECK(lowest == test::relative(-0.5, 1e-12));
  CHECK(highest == doctest::Approx(0.0).epsilon(1e-12));
}

TEST_CASE("obstacle and contact errors name the key or the file") {
  struct Case {
    std::string json;
    std::vector<std::pair<std::string, std::string>> files;
    std::vector<std::string> must_contain;
  };
  const std::string contact = R"("contact": {}, )";
  const std::vector<Case> cases = {
      {scene_with(R"("obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ])"), {},
       {"obstacles", "need contact", "\"contact\": {}"}},
      {scene_with(R"("contact": { "enabled": false }, "obstacles": [ { "mesh": "q.obj" } ])"), {},
       {"obstacles", "need contact"}},
      {scene_with(contact + R"("obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 0, 0] } } ])"), {},
       {"obstacles[0].plane.normal", "zero", "[0,0,0]"}},
      {scene_with(contact + R"("obstacles": [ { "plane": { "point": [0, 0, 0] } } ])"), {},
       {"obstacles[0].plane", "normal"}},
      {scene_with(contact + R"("obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] }, "scale": 2 } ])"), {},
       {"obstacles[0].scale", "unknown key"}},
      {scene_with(contact + R"("obstacles": [ { "plane": { "point": [0, -1, 0], "normal": [0, 1, 0] }, "velocity": [0, 1, 0] } ])"), {},
       {"obstacles[0].velocity", "unknown key"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj", "angular_velocity": 1 } ])"), {{"q.obj", kQuadObj}},
       {"obstacles[0]", "needs an \"axis\""}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj", "velocity": [0, 1] } ])"), {{"q.obj", kQuadObj}},
       {"obstacles[0].velocity"}},
      {scene_with(contact + R"("obstacles": [ {} ])"), {}, {"obstacles[0]", "plane", "mesh"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "missing.obj" } ])"), {},
       {"obstacles[0].mesh", "not found", "missing.obj"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.stl" } ])"), {{"q.stl", ""}},
       {"obstacles[0].mesh", "q.stl", ".obj or .msh"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 x\n"}},
       {"obstacles[0].mesh", "q.obj", "line 2", "\"x\""}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n"}},
       {"obstacles[0].mesh", "q.obj", "line 4", "\"4\""}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n"}},
       {"q.obj", "line 3", "at least 3"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n"}},
       {"q.obj", "line 4", "\"0\""}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"}},
       {"obstacles[0].mesh", "q.obj", "line 4", "zero-area"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2\n"}},
       {"q.obj", "line 4", "zero-area"}},
      {scene_with(contact + R"("obstacles": [ { "mesh": "q.obj" } ])"), {{"q.obj", "# nothing\nv 0 0 0\n"}},
       {"obstacles[0].mesh", "q.obj", "no faces"}},
      {scene_with(R"("contact": {}, "time": { "integrator": "central_difference" })"), {},
       {"time.integrator", "central_difference", "explicit"}},
      {scene_with(R"("contact": {}, "time": { "integrator": "symplectic_euler" })"), {},
       {"time.integrator", "symplectic_euler"}},
      {scene_with(R"("contact": {}, "time": { "beta": 0 })"), {}, {"time.integrator", "custom", "beta = 0"}},
      {scene_with(R"("contact": { "friction": 0.3, "friction_iterations": 0 })"), {}, {"contact.friction_iterations", "0"}},
      {scene_with(R"("contact": { "friction": 0.3, "friction_iterations": "forever" })"), {},
       {"contact.friction_iterations", "converged", "forever"}},
      {scene_with(R"("contact": { "friction": 0.3, "epsv": -1e-3 })"), {}, {"contact.epsv", "-0.001"}},
      {scene_with(R"("contact": { "friction": 0.5, "static_friction": 0.3 })"), {},
       {"contact.static_friction", "at least the kinetic", "0.5", "0.3"}},
      {scene_with(R"("contact": { "friction_pairs": [ { "materials": ["m", "steel"], "friction": 0.2 } ] })"), {},
       {"contact.friction_pairs[0].materials[1]", "steel"}},
      {scene_with(R"("contact": { "friction_pairs": [ { "materials": ["m"], "friction": 0.2 } ] })"), {},
       {"contact.friction_pairs[0].materials", "two material names"}},
      {scene_with(R"("contact": { "friction_pairs": [ { "materials": ["m", "m"] } ] })"), {},
       {"contact.friction_pairs[0]", "\"friction\""}},
      {scene_with(R"("contact": { "friction_pairs": [ { "materials": ["m", "m"], "friction": 0.2 },
                                                      { "materials": ["m", "m"], "friction": 0.3 } ] })"), {},
       {"contact.friction_pairs[1].materials", "already given"}},
      {scene_with(R"("contact": { "friction_pairs": [ { "materials": ["m", "m"], "friction": 0.4, "static_friction": 0.1 } ] })"), {},
       {"contact.friction_pairs[0].static_friction", "at least the kinetic"}},
      {scene_with(R"("contact": { "friction": 0.2 }, "obstacles": [ { "plane": { "point": [0, -1, 0], "normal": [0, 1, 0] }, "material": "ice" } ])"), {},
       {"obstacles[0].material", "ice"}},
      {scene_with(R"("contact": { "friction": -1 })"), {}, {"contact.friction", "-1"}},
      {scene_with(R"("joints": [ { "type": "pin", "body": 3, "point": [0, 0, 0] } ])"), {}, {"joints[0].body", "no such body", "3"}},
      {scene_with(R"("joints": { "type": "pin" })"), {}, {"joints", "expected an array"}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.json);
    const std::string message = error_with_files(c.json, c.files);
    REQUIRE_FALSE(message.empty());
    for (const std::string& part : c.must_contain) {
      CAPTURE(message);
      CHECK(message.find(part) != std::string::npos);
    }
  }
  // Without contact an explicit integrator stays allowed; friction 0 and > 0 are accepted.
  CHECK(error_of(scene_with(R"("time": { "integrator": "central_difference" })")).empty());
  CHECK(error_of(scene_with(R"("contact": { "friction": 0 })")).empty());
  CHECK(error_of(scene_with(R"("contact": { "friction": 0.3, "friction_iterations": 2 })")).empty());
  CHECK(error_of(scene_with(R"("contact": { "friction": 0.3, "friction_iterations": "converged" })")).empty());
  CHECK(error_of(scene_with(R"("contact": { "friction": 0.3, "static_friction": 0.3,
    "friction_pairs": [ { "materials": ["m", "m"], "friction": 0.1, "static_friction": 0.2 } ] })")).empty());
}

TEST_CASE("obj frames leave obstacle triangles out and vtu frames keep obstacle points") {
  const std::string json = "{ " + std::string(kMaterials) + R"(, "contact": {},
    "bodies": [ )" + kBox + R"( ], "obstacles": [ { "mesh": "quad.obj" } ] })";
  const Scene scene = scene_with_files(json, {{"quad.obj", kQuadObj}});
  const Model& m = scene.model;
  REQUIRE(m.bodies.size() == 2);
  const std::string obj = obj_document(m, scene.initial.x);
  // Every vertex is listed (global numbering), only the box's 48 boundary triangles are faces.
  CHECK(count_lines_starting_with(obj, "v ") == m.num_vertices);
  CHECK(count_lines_starting_with(obj, "f ") == m.bodies[0].triangle_count);
  CHECK(count_lines_starting_with(obj, "f ") == 48);
  // A face line never refers to an obstacle vertex.
  std::istringstream in(obj);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("f ", 0) != 0) continue;
    std::istringstream f(line.substr(2));
    for (int id; f >> id;) CHECK(id <= m.bodies[0].vertex_count);
  }
  // VTU: obstacle vertices are points used by no cell.
  const std::string vtu = vtu_document(m, scene.initial.x, scene.initial.v);
  CHECK(vtu.find("NumberOfPoints=\"" + std::to_string(m.num_vertices) + "\"") != std::string::npos);
  CHECK(vtu.find("NumberOfCells=\"" + std::to_string(m.num_tets) + "\"") != std::string::npos);
  // Bodies file: the header and the box's row; the obstacle mesh has none.
  const std::string bodies = bodies_document(m, scene.initial.x, scene.initial.v);
  CHECK(bodies.rfind(std::string(kBodiesHeader) + "\n0,tets,", 0) == 0);
  CHECK(count_lines_starting_with(bodies, "") == 2);
}

TEST_CASE("angular_velocity spins each body about its own centre of mass: momentum M v, angular momentum I omega") {
  // Two copies of a turned, off-centre box: each must carry the linear momentum M v and, about
  // its own centre of mass c, the angular momentum I omega with I = sum m (|r|^2 1 - r r^T), and
  // the kinetic energy 1/2 M |v|^2 + 1/2 omega . I omega (no cross term about the centre).
  const Eigen::Vector3d v0(0.5, 0.0, -0.25), omega(1.0, -2.0, 3.0);
  const Scene scene = test::scene_from_json(scene_with("", kMaterials, R"([{ "box": { "size": [0.4, 0.2, 0.3], "cells": [4, 2, 3] },
      "material": "m", "rotate_deg": [10, 20, 30], "translate": [1, 2, 3], "velocity": [0.5, 0, -0.25],
      "angular_velocity": [1, -2, 3], "array": { "count": [2, 1, 1], "spacing": [1, 0, 0] } }])"),
                                            "spin");
  const Model& m = scene.model;
  REQUIRE(m.bodies.size() == 2);
  for (const BodyRange& body : m.bodies) {
    double M = 0.0;
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), p = Eigen::Vector3d::Zero();
    for (int32_t i = body.vertex_begin; i < body.vertex_begin + body.vertex_count; ++i) {
      M += m.mass[i];
      c += m.mass[i] * Eigen::Vector3d::Map(&m.rest_positions[3 * i]);
    }
    c /= M;
    Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
    Eigen::Vector3d L = Eigen::Vector3d::Zero();
    double kinetic = 0.0;
    for (int32_t i = body.vertex_begin; i < body.vertex_begin + body.vertex_count; ++i) {
      const Eigen::Vector3d r = Eigen::Vector3d::Map(&m.rest_positions[3 * i]) - c;
      const Eigen::Vector3d v = Eigen::Vector3d::Map(&scene.initial.v[3 * i]);
      I += m.mass[i] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
      p += m.mass[i] * v;
      L += m.mass[i] * r.cross(v);
      kinetic += 0.5 * m.mass[i] * v.squaredNorm();
    }
    CAPTURE(c.transpose());
    // The bodies file's row: mass, centre of mass and its velocity, 21 cells, the last 12 empty.
    std::istringstream rows(bodies_document(m, scene.initial.x, scene.initial.v));
    std::string line;
    for (size_t row = 0; row <= size_t(&body - m.bodies.data()) + 1; ++row) std::getline(rows, line);
    std::vector<std::string> cells;
    for (size_t start = 0;;) {
      const size_t comma = line.find(',', start);
      cells.push_back(line.substr(start, comma - start));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    REQUIRE(cells.size() == 21);
    CHECK(cells[0] == std::to_string(&body - m.bodies.data()));
    CHECK(cells[1] == "tets");
    CHECK(std::stod(cells[2]) == doctest::Approx(M).epsilon(1e-15));
    for (int k = 0; k < 3; ++k) {
      CHECK(std::stod(cells[3 + k]) == doctest::Approx(c[k]).epsilon(1e-14));
      CHECK(std::abs(std::stod(cells[6 + k]) - v0[k]) <= 1e-13);
    }
    for (int k = 9; k < 21; ++k) CHECK(cells[k].empty());
    CHECK((p - M * v0).norm() <= 1e-13 * M * v0.norm());
    CHECK((L - I * omega).norm() <= 1e-12 * (I * omega).norm());
    const double expected = 0.5 * M * v0.squaredNorm() + 0.5 * omega.dot(I * omega);
    CHECK(std::abs(kinetic - expected) <= 1e-12 * expected);
  }
  // The copies spin about their own centres, 1 m apart: their vertex velocities differ by v0 only
  // through omega x (shift), which is zero.
  const int32_t n = m.bodies[0].vertex_count;
  double largest = 0.0;
  for (int32_t i = 0; i < n; ++i)
    largest = std::max(largest, (Eigen::Vector3d::Map(&scene.initial.v[3 * i]) -
                                 Eigen::Vector3d::Map(&scene.initial.v[3 * (n + i)])).norm());
  CHECK(largest <= 1e-12);
  CHECK(error_of(scene_with("", kMaterials, R"([{ "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m",
      "angular_velocity": [1, 2] }])")).find("angular_velocity") != std::string::npos);
}

TEST_CASE("scene: an affine material refuses what affine bodies do not have, naming the key") {
  const std::string affine = R"("materials": { "m": { "model": "affine", "density": 1000 } })";
  const std::string box = std::string("[") + kBox + "]";
  // Loads as it is, with its stiffness default.
  CHECK(error_of(scene_with("", affine, box)).empty());
  const Scene scene = test::scene_from_json(scene_with("", affine, box), "affine_ok");
  REQUIRE(scene.model.affine_bodies.size() == 1);
  CHECK(scene.model.affine_bodies[0].stiffness == kAffineStiffness);
  struct Case { std::string json; std::vector<std::string> must_contain; };
  const std::vector<Case> cases = {
      {scene_with("", R"("materials": { "m": { "model": "affine", "density": 1000, "youngs": 1e9 } })", box),
       {"materials.m.youngs", "no \"youngs\"", "stiffness"}},
      {scene_with("", R"("materials": { "m": { "model": "affine", "density": 1000, "poisson": 0.3 } })", box),
       {"materials.m.poisson"}},
      {scene_with("", R"("materials": { "m": { "model": "affine", "density": 1000, "damping": { "mass": 1 } } })", box),
       {"materials.m.damping", "affine"}},
      {scene_with("", R"("materials": { "m": { "model": "affine", "stiffness": 1e8 } })", box), {"density"}},
      {scene_with("", R"("materials": { "m": { "model": "affine", "density": 1000, "stiffness": -1 } })", box),
       {"materials.m.stiffness"}},
      {scene_with(R"("time": { "integrator": "static" })", affine, box), {"time.integrator", "dynamic"}},
      {scene_with(R"("time": { "integrator": "central_difference" })", affine, box), {"time.integrator", "implicit"}},
      {scene_with(R"("solver": { "method": "linearized" })", affine, box), {"solver.method", "newton"}},
      {scene_with(R"("boundary": [ { "box_min": [-1, -1, -1], "box_max": [1, 1, 1], "velocity": [0, 1, 0] } ])",
                  affine, box),
       {"boundary[0]", "affine", "fixed"}},
  };
  for (const Case& c : cases) {
    CAPTURE(c.json);
    const std::string message = error_of(c.json);
    REQUIRE_FALSE(message.empty());
    for (const std::string& part : c.must_contain) {
      CAPTURE(part);
      CHECK(message.find(part) != std::string::npos);
    }
  }
}

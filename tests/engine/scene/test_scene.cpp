// Scene loading: every kind of bad input is one clear error naming the file, the key and the
// value; good scenes build the flat buffers they describe.
#include "engine/scene/scene.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <cmath>

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
  CHECK(mass == doctest::Approx(2 * 800.0 * 6.0));
  // Copies are offset by the spacing; the second copy's first vertex is 5 m further along x.
  CHECK(m.rest_positions[3 * m.bodies[1].vertex_begin] ==
        doctest::Approx(m.rest_positions[0] + 5.0));
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

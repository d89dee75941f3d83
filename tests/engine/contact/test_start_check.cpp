// Contact scenes must start intersection-free: load_scene (so both `nexdyn check` and `run`)
// refuses touching, crossing, nested and behind-the-plane starts, naming the bodies.
#include "engine/contact/start_check.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

using namespace nexdyn;

namespace {

std::string load_error(const std::string& bodies, const std::string& extra = "") {
  const std::string json = R"({ "contact": {}, )" + extra + R"(
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": )" + bodies + " }";
  try {
    test::scene_from_json(json, "start");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

const std::string kUnit = R"("box": { "size": [1, 1, 1], "cells": [2, 2, 2] }, "material": "m")";

}  // namespace

TEST_CASE("contact start check: separated bodies load") {
  CHECK(load_error("[{" + kUnit + "}, {" + kUnit + R"(, "translate": [1.001, 0, 0]}])") == "");
  CHECK(load_error("[{" + kUnit + R"(, "array": { "count": [3, 1, 2], "spacing": [1.01, 0, 1.01] }}])") == "");
}

TEST_CASE("contact start check: crossing, touching and nested bodies are refused by name") {
  const std::string crossing = load_error("[{" + kUnit + "}, {" + kUnit + R"(, "translate": [0.9, 0.2, 0.1]}])");
  CHECK(crossing.find("bodies[0] and bodies[1] touch or intersect") != std::string::npos);
  // Exactly touching faces: distance 0 is as bad as crossing for a log barrier.
  const std::string touching = load_error("[{" + kUnit + "}, {" + kUnit + R"(, "translate": [1, 0, 0]}])");
  CHECK(touching.find("bodies[0] and bodies[1] touch or intersect") != std::string::npos);
  const std::string copies = load_error("[{" + kUnit + R"(, "array": { "count": [3, 1, 1], "spacing": [0.99, 0, 0] }}])");
  CHECK(copies.find("bodies[0] (copy 0 of its array) and bodies[0] (copy 1 of its array)") != std::string::npos);
  const std::string nested = load_error("[{" + kUnit + R"(}, { "box": { "size": [0.2, 0.2, 0.2], "cells": [1, 1, 1] }, "material": "m" }])");
  CHECK(nested.find("bodies[1] starts inside bodies[0]") != std::string::npos);
  const std::string behind = load_error("[{" + kUnit + "}]", R"("obstacles": [ { "plane": { "point": [0, -0.4, 0], "normal": [0, 1, 0] } } ],)");
  CHECK(behind.find("bodies[0] starts on or behind obstacles[0] (a plane)") != std::string::npos);
  // Without contact the same overlap is allowed (bodies pass through each other).
  const std::string json = R"({ "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [{)" + kUnit + "}, {" + kUnit + R"(, "translate": [0.9, 0, 0]}] })";
  CHECK_NOTHROW(test::scene_from_json(json, "start_no_contact"));
}

TEST_CASE("nexdyn check refuses a touching start and run refuses an explicit scheme with contact") {
  const auto dir = test::temp_dir("start_cli");
  const std::string head = R"({ "contact": {}, "time": { "dt": 0.01, "steps": 2 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [{)" + kUnit + "}, {" + kUnit;
  test::write_text(dir / "touch.json", head + R"(, "translate": [0, 1, 0]}] })");
  const test::CommandResult check = test::run_cli("check " + (dir / "touch.json").string());
  CHECK(check.exit_code == 1);
  CHECK(check.output.find("bodies[0] and bodies[1] touch or intersect") != std::string::npos);
  test::write_text(dir / "apart.json", head + R"(, "translate": [0, 1.01, 0]}] })");
  const test::CommandResult run = test::run_cli("run " + (dir / "apart.json").string() + " --quiet --out " +
                                                (dir / "out").string() + " --integrator central_difference");
  CHECK(run.exit_code == 1);
  CHECK(run.output.find("explicit") != std::string::npos);
  CHECK(!std::filesystem::exists(dir / "out"));
}

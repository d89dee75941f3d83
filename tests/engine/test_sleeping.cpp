// Sleeping bodies (engine/sleeping.hpp): a cube resting on the floor falls asleep and is held
// exactly still; a second cube falling onto it wakes it before they touch, and the outcome is
// that of the same scene with sleeping off; nothing changes before the first body sleeps; a
// checkpoint carries the sleepers.
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/run.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/stop_support.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

constexpr double kDhat = 1e-3;

// Cube A (body 0) 0.5 mm above the floor; cube B (body 1), when asked for, 1.05 m above A.
std::string two_cubes(bool with_b, const std::string& sleep) {
  std::string bodies =
      R"({ "box": { "size": [0.1, 0.1, 0.1], "cells": [2, 2, 2] }, "material": "rubber", "translate": [0, 0.0505, 0] })";
  if (with_b)
    bodies += R"(, { "box": { "size": [0.1, 0.1, 0.1], "cells": [2, 2, 2] }, "material": "rubber",
                     "translate": [0.01, 1.2, 0.005] })";
  return R"({ "gravity": [0, -9.81, 0],
    "time": { "dt": 0.01, "steps": 200, "integrator": "implicit_euler" },
    "solver": { "tolerance": 0.001, "max_iterations": 200, "sleep": )" + sleep + R"( },
    "contact": { "dhat": 0.001, "friction": 0.3 },
    "materials": { "rubber": { "model": "neohookean", "youngs": 1e6, "poisson": 0.4, "density": 1000 } },
    "bodies": [ )" + bodies + R"( ],
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ] })";
}

void step_ok(Simulation& simulation) {
  const StepOutcome outcome = simulation.step();
  REQUIRE_MESSAGE(outcome.status == StepStatus::ok, outcome.message);
}

// Lowest y of body b's vertices, or highest with top.
double extreme_y(const Scene& scene, const State& state, int32_t b, bool top) {
  const BodyRange& r = scene.model.bodies[b];
  double y = top ? -INFINITY : INFINITY;
  for (int32_t v = r.vertex_begin; v < r.vertex_begin + r.vertex_count; ++v)
    y = top ? std::max(y, state.x[3 * v + 1]) : std::min(y, state.x[3 * v + 1]);
  return y;
}

std::string row_without_wall(const Simulation& simulation, bool with_sleep_column) {
  StepStats stats = simulation.last_stats();
  stats.wall_seconds = 0.0;
  if (!with_sleep_column) stats.sleeping_bodies = 0;
  return stats_row(stats);
}

}  // namespace

TEST_CASE("a cube resting on the floor falls asleep and is held exactly still, above the floor") {
  const Scene scene = test::scene_from_json(two_cubes(false, "true"), "sleep_one");
  Simulation simulation(scene);
  int asleep_at = -1;
  for (int k = 1; k <= 100 && asleep_at < 0; ++k) {
    step_ok(simulation);
    if (simulation.last_stats().sleeping_bodies == 1) asleep_at = k;
  }
  REQUIRE(asleep_at > 10);  // at least the rest window after landing
  const std::vector<double> x_asleep = simulation.state().x;
  for (int k = 0; k < 20; ++k) {
    step_ok(simulation);
    CHECK(simulation.last_stats().sleeping_bodies == 1);
    CHECK(simulation.last_stats().kinetic_energy == 0.0);
    CHECK(simulation.last_stats().newton_iterations == 0);  // nothing awake: no solve at all
    CHECK(simulation.last_stats().min_distance > 0.0);
  }
  CHECK(simulation.state().x == x_asleep);
  CHECK(std::all_of(simulation.state().v.begin(), simulation.state().v.end(), [](double v) { return v == 0.0; }));
}

TEST_CASE("a cube falling onto a sleeping one wakes it before they touch, and lands as with sleeping off") {
  const Scene on = test::scene_from_json(two_cubes(true, "true"), "sleep_two_on");
  const Scene off = test::scene_from_json(two_cubes(true, "false"), "sleep_two_off");
  Simulation sleeping(on), awake(off);
  bool a_slept = false, touched = false;
  int diverged_at = -1;
  for (int k = 1; k <= 120; ++k) {
    CAPTURE(k);
    step_ok(sleeping);
    step_ok(awake);
    const bool a_asleep = sleeping.history().sleep_group[0] >= 0;
    a_slept = a_slept || a_asleep;
    const double gap = extreme_y(on, sleeping.state(), 1, false) - extreme_y(on, sleeping.state(), 0, true);
    if (gap < 2.0 * kDhat && !touched) {
      touched = true;
      CHECK(a_slept);
      CHECK_FALSE(a_asleep);  // woken by B's approach, never met asleep
    }
    CHECK(sleeping.last_stats().min_distance > 0.0);
    // Until A first sleeps the two runs are the same run.
    if (diverged_at < 0 && row_without_wall(sleeping, false) != row_without_wall(awake, false)) diverged_at = k;
  }
  CHECK(a_slept);
  CHECK(touched);
  REQUIRE(diverged_at > 0);
  // Frozen instead of resting at under 1 cm/s for a few steps: the landing ends where it ends
  // without sleeping, to well within dhat.
  double largest = 0.0;
  for (size_t i = 0; i < sleeping.state().x.size(); ++i)
    largest = std::max(largest, std::abs(sleeping.state().x[i] - awake.state().x[i]));
  CAPTURE(largest);
  CHECK(largest < 0.2 * kDhat);
}

TEST_CASE("sleeping changes nothing before the first body sleeps") {
  const Scene on = test::scene_from_json(two_cubes(true, "true"), "sleep_same_on");
  const Scene off = test::scene_from_json(two_cubes(true, "false"), "sleep_same_off");
  Simulation sleeping(on), awake(off);
  int compared = 0;
  for (int k = 1; k <= 60; ++k) {
    step_ok(sleeping);
    step_ok(awake);
    if (sleeping.last_stats().sleeping_bodies > 0) break;
    CHECK(row_without_wall(sleeping, true) == row_without_wall(awake, true));
    CHECK(sleeping.state().x == awake.state().x);
    ++compared;
  }
  CHECK(compared >= 10);  // A rests from its first step and sleeps after the window
}

TEST_CASE("a restored simulation with sleeping bodies continues bit for bit") {
  const Scene scene = test::scene_from_json(two_cubes(true, "{ \"steps\": 5 }"), "sleep_restore");
  Simulation original(scene);
  for (int k = 0; k < 30; ++k) step_ok(original);
  REQUIRE(original.last_stats().sleeping_bodies == 1);  // A sleeps, B still falls
  CheckpointWriter saved;
  save_simulation(saved, original);
  std::vector<std::string> expected;
  for (int k = 0; k < 40; ++k) {
    step_ok(original);
    expected.push_back(row_without_wall(original, true));
  }
  Simulation restored(scene);
  CheckpointReader in(saved.bytes(), "test");
  restore_simulation(in, restored);
  CHECK_NOTHROW(in.expect_end());
  for (int k = 0; k < 40; ++k) {
    step_ok(restored);
    CHECK(row_without_wall(restored, true) == expected[k]);
  }
  CHECK(restored.state().x == original.state().x);
  CHECK(restored.history().sleep_group == original.history().sleep_group);
}

TEST_CASE("a step stopped after it woke a sleeping group leaves the group asleep") {
  // A sleeps from about step 10; B lands on it near step 47, and the step whose motion reaches A
  // wakes it before its attempts. Stopped there (at its first Newton iteration), the step must put
  // A back to sleep: the run resumed from that state wakes it itself, as the run never stopped did.
  const Scene scene = test::scene_from_json(two_cubes(true, "{ \"steps\": 5 }"), "sleep_stopped");
  CHECK(test::check_stopped_steps(scene, 60, 1) >= 40);
}

namespace {

// A tower of three affine cubes (0.14, 0.12 and 0.10 m) on the floor, 0.5 mm apart, and above the
// top one, 0.5 mm off it, a driven plate (a tet body on a moving boundary) that slides across it
// at 3 cm/s: the plate never rests and touches the top cube only.
std::string tower_under_a_sliding_plate(const std::string& sleep) {
  std::string bodies;
  const double sizes[3] = {0.14, 0.12, 0.10};
  double bottom = 0.0005;
  for (double size : sizes) {
    bodies += R"({ "box": { "size": [)" + std::to_string(size) + ", " + std::to_string(size) + ", " +
              std::to_string(size) + R"(], "cells": [1, 1, 1] }, "material": "stone", "translate": [0, )" +
              std::to_string(bottom + 0.5 * size) + R"(, 0] }, )";
    bottom += size + 0.0005;
  }
  bodies += R"({ "box": { "size": [0.06, 0.02, 0.06], "cells": [1, 1, 1] }, "material": "rubber", "translate": [0, )" +
            std::to_string(bottom + 0.01) + R"(, 0] })";
  const std::string low = std::to_string(bottom - 0.001), high = std::to_string(bottom + 0.021);
  return R"({ "gravity": [0, -9.81, 0],
    "time": { "dt": 0.01, "steps": 60, "integrator": "implicit_euler" },
    "solver": { "tolerance": 0.001, "max_iterations": 200, "sleep": )" + sleep + R"( },
    "contact": { "dhat": 0.001, "friction": 0.3 },
    "materials": { "stone": { "model": "affine", "density": 1000 },
                   "rubber": { "model": "neohookean", "youngs": 1e6, "poisson": 0.4, "density": 1000 } },
    "bodies": [ )" + bodies + R"( ],
    "boundary": [ { "box_min": [-0.1, )" + low + R"(, -0.1], "box_max": [0.1, )" + high + R"(, 0.1], "body": 3,
                    "velocity": [0.03, 0, 0] } ],
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ] })";
}

}  // namespace

TEST_CASE("a body that keeps moving keeps awake only the bodies it touches, not the whole stack") {
  // The plate touches only the top cube; the two below it rest on bodies at rest, so they sleep
  // though the four are one contact group (a group-wide rule would keep all four awake).
  const Scene on = test::scene_from_json(tower_under_a_sliding_plate("true"), "sleep_tower_on");
  const Scene off = test::scene_from_json(tower_under_a_sliding_plate("false"), "sleep_tower_off");
  Simulation sleeping(on), awake(off);
  int both_asleep_at = -1;
  for (int k = 1; k <= 60; ++k) {
    CAPTURE(k);
    step_ok(sleeping);
    step_ok(awake);
    CHECK(sleeping.last_stats().min_distance > 0.0);
    const std::vector<int32_t>& group = sleeping.history().sleep_group;
    CHECK(group[3] < 0);  // driven: never asleep
    CHECK(group[2] < 0);  // touches the driven one
    if (both_asleep_at < 0 && group[0] >= 0 && group[1] >= 0) both_asleep_at = k;
    if (both_asleep_at > 0) {
      CHECK(group[0] >= 0);  // once asleep, nothing that moves touches them
      CHECK(group[1] >= 0);
    }
  }
  REQUIRE(both_asleep_at > 10);  // the rest window after they settle
  CHECK(both_asleep_at < 40);
  // Every body ends where it ends with sleeping off: the sleepers were held where they rest.
  double largest = 0.0;
  for (size_t i = 0; i < sleeping.state().x.size(); ++i)
    if (!on.model.axis_node(static_cast<int32_t>(i / 3)))
      largest = std::max(largest, std::abs(sleeping.state().x[i] - awake.state().x[i]));
  CAPTURE(largest);
  CHECK(largest < 0.2 * kDhat);
}

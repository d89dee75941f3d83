// A Simulation restored from a checkpoint takes the same steps bit for bit as the one it was
// saved from: over contact, friction, moving obstacles and joints, whose solvers all carry state
// from step to step (barrier stiffness, contact pattern, multipliers, stiffenings).
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/run.hpp"
#include "engine/output/checkpoint_file.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <string>
#include <vector>

using namespace nexdyn;

namespace {

// stats.csv rows (without wall_seconds) of `steps` steps.
std::vector<std::string> take_steps(Simulation& simulation, int steps) {
  std::vector<std::string> rows;
  for (int k = 0; k < steps; ++k) {
    const StepOutcome outcome = simulation.step();
    REQUIRE_MESSAGE(outcome.status == StepStatus::ok, outcome.message);
    StepStats stats = simulation.last_stats();
    stats.wall_seconds = 0.0;
    rows.push_back(stats_row(stats));
  }
  return rows;
}

// Runs `before` steps, saves, runs `after` more; a second simulation restored from the save runs
// the same `after` steps. Both must agree in every stats value and every coordinate.
void check_restore(const std::string& scene_name, int before, int after) {
  CAPTURE(scene_name);
  const Scene scene = load_scene(test::scene_path(scene_name));
  Simulation original(scene);
  take_steps(original, before);
  CheckpointWriter saved;
  save_simulation(saved, original);
  const std::vector<std::string> expected = take_steps(original, after);

  Simulation restored(scene);
  CheckpointReader in(saved.bytes(), "test");
  restore_simulation(in, restored);
  CHECK_NOTHROW(in.expect_end());
  CHECK(restored.state().step == before);
  const std::vector<std::string> rows = take_steps(restored, after);
  for (int k = 0; k < after; ++k) CHECK(rows[k] == expected[k]);
  CHECK(restored.state().x == original.state().x);
  CHECK(restored.state().v == original.state().v);
  CHECK(restored.state().a == original.state().a);
}

}  // namespace

TEST_CASE("a restored simulation continues bit for bit: contact stack") { check_restore("cube_stack.json", 40, 40); }

TEST_CASE("a restored simulation continues bit for bit: friction on a slope") { check_restore("slope_slide.json", 30, 30); }

TEST_CASE("a restored simulation continues bit for bit: a wall pushing a block with friction") {
  check_restore("block_push.json", 30, 20);
}

TEST_CASE("a restored simulation continues bit for bit: joints") { check_restore("double_pendulum.json", 100, 60); }

TEST_CASE("restoring refuses a checkpoint of another scene") {
  const Scene stack = load_scene(test::scene_path("cube_stack.json"));
  const Scene cantilever = load_scene(test::scene_path("cantilever.json"));
  Simulation a(stack);
  CheckpointWriter saved;
  save_simulation(saved, a);
  Simulation b(cantilever);
  CheckpointReader in(saved.bytes(), "stack.ckpt");
  CHECK_THROWS_AS(restore_simulation(in, b), CheckpointError);
}

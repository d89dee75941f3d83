// Recovery from failed steps: a step whose dt is too large is retried as two of half the dt,
// counted in the statistics; a recovered step is exactly two half steps; a step that fails at
// every level leaves the state before it and says what failed and where.
#include "engine/run.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <string>

using namespace nexdyn;

namespace {

// scenes/twist_big_dt.json: the end of a bar turned 1.6 rad per 0.1 s step. The held end face
// jumps 92 degrees at the start of a step and inverts the tets next to it, so the full step
// cannot even start; at 0.05 s it can.
Scene twist_scene(double dt, int halvings, double angular_velocity = 16.0) {
  Scene scene = load_scene(test::scene_path("twist_big_dt.json"));
  scene.time.dt = dt;
  scene.solver.substep_halvings = halvings;
  for (DirichletMotion& m : scene.model.dirichlet_motions)
    if (m.angular_velocity != 0.0) m.angular_velocity = angular_velocity;
  return scene;
}

}  // namespace

TEST_CASE("a step too large for its prescribed twist completes through sub-stepping, with the retries counted") {
  const Scene without = twist_scene(0.1, 0);
  Simulation failing(without);
  const StepOutcome failed = failing.step();
  CHECK(failed.status == StepStatus::non_finite);
  CHECK(failed.message.find("tet ") != std::string::npos);
  CHECK(failed.message.find("is inverted") != std::string::npos);
  CHECK(failing.state().step == 0);

  const Scene with = twist_scene(0.1, 4);
  Simulation recovering(with);
  for (int k = 1; k <= 4; ++k) {
    const StepOutcome outcome = recovering.step();
    REQUIRE_MESSAGE(outcome.status == StepStatus::ok, outcome.message);
    CHECK(recovering.last_stats().retries >= 1);
    CHECK(recovering.state().step == k);
    CHECK(recovering.state().time == test::relative(0.1 * k, 1e-15));
  }
}

TEST_CASE("a recovered step is exactly two steps of half the dt") {
  const Scene big = twist_scene(0.1, 4), half = twist_scene(0.05, 0);
  Simulation recovered(big), halves(half);
  REQUIRE(recovered.step().status == StepStatus::ok);
  REQUIRE(recovered.last_stats().retries == 1);
  int iterations = 0;
  for (int k = 0; k < 2; ++k) {
    REQUIRE(halves.step().status == StepStatus::ok);
    iterations += halves.last_stats().newton_iterations;
  }
  CHECK(recovered.state().time == halves.state().time);
  CHECK(recovered.state().x == halves.state().x);
  CHECK(recovered.state().v == halves.state().v);
  CHECK(recovered.state().a == halves.state().a);
  CHECK(recovered.last_stats().kinetic_energy == halves.last_stats().kinetic_energy);
  // The failed attempt stopped before its first Newton iteration: all iterations are the halves'.
  CHECK(recovered.last_stats().newton_iterations == iterations);
}

TEST_CASE("a step that fails at every level leaves the state before it and says where") {
  // 40 rad/s with one halving allowed: the full step turns the end face 229 degrees and its
  // first half 115; both invert the tets next to it.
  const Scene scene = twist_scene(0.1, 1, 40.0);
  Simulation simulation(scene);
  const State before = simulation.state();
  const StepOutcome outcome = simulation.step();
  CHECK(outcome.status == StepStatus::non_finite);
  CHECK(outcome.message.find("is inverted") != std::string::npos);
  CHECK(outcome.message.find("after 1 halving of dt, the last try a step of 0.05 s from t = 0 s") != std::string::npos);
  CHECK(simulation.state().step == 0);
  CHECK(simulation.state().time == 0.0);
  CHECK(simulation.state().x == before.x);
  CHECK(simulation.state().v == before.v);
  CHECK(simulation.last_stats().retries == 1);
}

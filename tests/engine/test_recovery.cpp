// Recovery from failed steps: a step whose dt is too large is retried as two of half the dt,
// counted in the statistics; a recovered step is exactly two half steps (also with joints and a
// pushing wall, from a warmed-up history); a step that fails at every level leaves the state
// before it and says what failed and where.
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/run.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/stop_support.hpp"
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
    // Why: the first failed attempt's status and message, and the step it tried (the first step
    // cannot start, its first tets inverted; later ones also fail to converge in the full dt).
    const std::string& why = recovering.last_stats().retried_because;
    INFO(why);
    const char* starts[] = {"0", "0.1", "0.2", "0.3"};
    CHECK(why.find(std::string("(a step of 0.1 s from t = ") + starts[k - 1] + " s)") != std::string::npos);
    if (k == 1) {
      CHECK(why.find("[non_finite] ") == 0);
      CHECK(why.find("is inverted") != std::string::npos);
    } else {
      CHECK((why.find("[non_finite] ") == 0 || why.find("[max_iterations] ") == 0));
    }
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

namespace {

// Scene `name` with dt = 2^-k s: every time of the run (multiples of dt and dt / 2) is then exact,
// so a step's halves and the steps of a scene of half the dt see the same times bit for bit.
Scene scene_with_dt(const std::string& name, double dt) {
  Scene scene = load_scene(test::scene_path(name));
  scene.time.dt = dt;
  scene.solver.substep_halvings = 1;
  return scene;
}

}  // namespace

// Nothing keeps a copy of dt: the joints' stiffness, the kinematic multipliers (forces times the
// potential scale), the contact memory and the barrier stiffness are all recomputed or rescaled
// from the attempt's StepContext. So after `warmup` steps, a step whose full-dt attempt fails
// and is rolled back equals two steps of a simulation of half the dt restored from the same
// checkpoint, with a non-trivial history: joint multipliers, or a wall pushing a block with
// friction.
TEST_CASE("a rolled-back step with history is exactly two steps of half the dt: joints and a pushing wall") {
  struct Case {
    const char* scene;
    double dt;  // [s] a power of two
    int warmup;
  };
  for (const Case& c : {Case{"double_pendulum.json", 0x1p-9, 10}, Case{"block_push.json", 0x1p-8, 20}}) {
    CAPTURE(c.scene);
    const Scene full = scene_with_dt(c.scene, c.dt), half = scene_with_dt(c.scene, 0.5 * c.dt);
    Simulation recovered(full), halves(half);
    for (int k = 0; k < c.warmup; ++k) REQUIRE(recovered.step().status == StepStatus::ok);
    CheckpointWriter saved;
    save_simulation(saved, recovered);
    CheckpointReader in(saved.bytes(), "the warm-up");
    restore_simulation(in, halves);
    // The history is not trivial: the joints hold, or the wall pushes.
    const StepHistory& h = recovered.history();
    const bool joints = !h.joint_multipliers.empty();
    const double held = joints ? Eigen::Map<const Eigen::VectorXd>(h.joint_multipliers.data(), h.joint_multipliers.size()).norm()
                               : recovered.kinematic().total_force().norm();
    CHECK(held > 0.1);  // [N]
    recovered.fail_attempts_at_level(0);
    REQUIRE(recovered.step().status == StepStatus::ok);
    CHECK(recovered.last_stats().retries == 1);
    int iterations = 0;
    for (int k = 0; k < 2; ++k) {
      REQUIRE(halves.step().status == StepStatus::ok);
      iterations += halves.last_stats().newton_iterations;
    }
    CHECK(recovered.state().time == halves.state().time);
    CHECK(recovered.state().x == halves.state().x);
    CHECK(recovered.state().v == halves.state().v);
    CHECK(recovered.state().a == halves.state().a);
    CHECK(recovered.state().a_bar == halves.state().a_bar);
    CHECK(recovered.history().joint_multipliers == halves.history().joint_multipliers);
    CHECK(recovered.history().kinematic_multipliers == halves.history().kinematic_multipliers);
    CHECK(recovered.history().contact_memory == halves.history().contact_memory);
    CHECK(recovered.history().kappa == halves.history().kappa);
    CHECK(recovered.last_stats().newton_iterations == iterations);
  }
}

// A stop request (SIGINT, SIGTERM) abandons the step under way at its next safe point
// (engine/stop_request.hpp): the step's attempts are put back, halves that had finished
// included, and the step taken again is the step never stopped. Stops at the first, the fifth
// and the twentieth Newton iteration of every step: in the twist's retried halves (a stop in a
// later half must undo the earlier ones), with joint rounds, with a pushing wall's solves.
TEST_CASE("a step stopped at a safe point leaves the simulation as it was, and the run goes on as if never stopped") {
  struct Case {
    Scene scene;
    int steps;
  };
  const Case cases[] = {{twist_scene(0.1, 4), 3},
                        {scene_with_dt("double_pendulum.json", 0x1p-9), 12},
                        {scene_with_dt("block_push.json", 0x1p-8), 24}};
  for (const Case& c : cases) {
    int stopped = 0;
    for (const int64_t at : {1, 5, 20}) {
      CAPTURE(at);
      stopped += test::check_stopped_steps(c.scene, c.steps, at);
    }
    CHECK(stopped >= c.steps);  // most steps reach the fifth iteration, the twist's the twentieth
  }
}

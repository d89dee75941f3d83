// MPM steps under the retry by halving that both kinds of simulation share (engine/step_retry.hpp,
// issue 39): a step taken as halves ends at its own time bit for bit and is exactly two steps of
// half the dt, reports the most plane nodes either half held, says after how many halvings it
// gave up, and a checkpoint of particles with a non-finite value is refused.
#include "engine/mpm/mpm_simulation.hpp"
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

// A rubber block thrown down onto a plane: it lands within a few steps and bounces off.
std::string bouncing_block(double dt, const std::string& solver = "") {
  return R"({"gravity": [0, -9.81, 0], "time": {"dt": )" + std::to_string(dt) + R"(, "integrator": "newmark"},
    "solver": {"substep_halvings": 2)" + solver + R"(},
    "mpm": {"grid_spacing": 0.025, "domain_min": [-0.3, -0.1, -0.3], "domain_max": [0.3, 0.5, 0.3]},
    "materials": {"m": {"model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000}},
    "bodies": [{"particles": {"box": {"size": [0.1, 0.1, 0.1], "per_cell": 2}}, "material": "m",
                "translate": [0, 0.09, 0], "velocity": [0, -1.5, 0]}],
    "contact": {}, "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}}]})";
}

}  // namespace

TEST_CASE("mpm retry: a step taken as halves ends at its own time and is two steps of half the dt") {
  // Every step fails at the scene's dt (the test seam) and is taken as two halves. Its time must
  // be t_n + dt, as an unsplit step's, not t_n + dt/2 + dt/2, which differs in the last bit from
  // the third step of 0.01 s on; and its particles those of two steps of dt/2.
  const Scene split_scene = test::scene_from_json(bouncing_block(0.01), "mpm_split");
  const Scene half_scene = test::scene_from_json(bouncing_block(0.005), "mpm_half");
  MpmSimulation split(split_scene), half(half_scene);
  split.fail_attempts_at_level(0);
  double expected_time = 0.0;
  int64_t first_half_larger = 0;
  for (int k = 0; k < 16; ++k) {
    CAPTURE(k);
    const StepOutcome outcome = split.step();
    REQUIRE_MESSAGE(outcome.ok(), outcome.message);
    CHECK(split.last_stats().retries == 1);
    expected_time += 0.01;
    CHECK(split.state().time == expected_time);
    int64_t contacts[2];
    for (int64_t& c : contacts) {
      REQUIRE(half.step().ok());
      c = half.last_stats().contacts;
    }
    CHECK(split.state().particles.x == half.state().particles.x);
    CHECK(split.state().particles.v == half.state().particles.v);
    // contacts: the most plane nodes either half held (it used to be the second half's).
    CHECK(split.last_stats().contacts == std::max(contacts[0], contacts[1]));
    first_half_larger += contacts[0] > contacts[1];
  }
  MESSAGE(first_half_larger << " of 16 steps held more nodes in their first half than in their second");
  CHECK(first_half_larger > 0);  // the bounce: otherwise the contacts check above could not fail
}

TEST_CASE("mpm retry: a step that fails at every level says after how many halvings") {
  // One Newton iteration at a tolerance no step meets: every attempt fails, down to dt / 4.
  const Scene scene =
      test::scene_from_json(bouncing_block(0.01, R"(, "max_iterations": 1, "tolerance": 1e-14)"), "mpm_fail");
  MpmSimulation simulation(scene);
  const std::vector<double> x0 = simulation.state().particles.x;
  const StepOutcome outcome = simulation.step();
  REQUIRE_FALSE(outcome.ok());
  CHECK(outcome.status == StepStatus::max_iterations);
  CHECK(outcome.message.find("(after 2 halvings of dt, the last try a step of 0.0025 s from t = 0 s)") !=
        std::string::npos);
  CHECK(simulation.state().particles.x == x0);
  CHECK(simulation.state().time == 0.0);
}

TEST_CASE("mpm checkpoints: a non-finite particle value is refused, and a good state is taken bit for bit") {
  const Scene scene = test::scene_from_json(bouncing_block(0.01), "mpm_restore");
  MpmSimulation original(scene);
  for (int k = 0; k < 3; ++k) REQUIRE(original.step().ok());
  CheckpointWriter good;
  save_simulation(good, original);
  MpmSimulation restored(scene);
  CheckpointReader good_in(good.bytes(), "good");
  restore_simulation(good_in, restored);
  CHECK(restored.state().time == original.state().time);
  CHECK(restored.state().particles.x == original.state().particles.x);
  for (int k = 0; k < 3; ++k) {
    REQUIRE(original.step().ok());
    REQUIRE(restored.step().ok());
  }
  CHECK(restored.state().particles.x == original.state().particles.x);

  for (const char* field : {"x", "F", "a_bar"}) {
    CAPTURE(field);
    MpmState bad = original.state();
    std::vector<double>& values = std::string(field) == "x"   ? bad.particles.x
                                  : std::string(field) == "F" ? bad.particles.F
                                                              : bad.history.a_bar;
    values[values.size() / 2] = std::nan("");
    MpmSimulation holder(scene);
    holder.adopt(bad, original.previous_total());
    CheckpointWriter out;
    save_simulation(out, holder);
    MpmSimulation target(scene);
    CheckpointReader in(out.bytes(), "bad");
    CHECK_THROWS_WITH_AS(restore_simulation(in, target), doctest::Contains("non-finite"), CheckpointError);
    CHECK(target.state().particles.x == scene.mpm->initial.x);  // untouched
  }
}

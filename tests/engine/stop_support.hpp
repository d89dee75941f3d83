// Stopped steps (engine/stop_request.hpp) for the tests: a step abandoned at a safe point must
// leave its simulation bit for bit as it found it, and the run must go on as if never stopped.
#pragma once

#include "engine/output/checkpoint_file.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/run.hpp"
#include "engine/simulation.hpp"
#include "engine/stop_request.hpp"

#include <doctest/doctest.h>

#include <csignal>
#include <string>

namespace nexdyn::test {

// Everything a checkpoint keeps of a simulation: its state and history, as bytes.
inline std::string simulation_bytes(const Simulation& simulation) {
  CheckpointWriter out;
  save_simulation(out, simulation);
  return out.bytes();
}

// Takes `steps` steps of `scene` twice: `reference` straight, `stopped` with every step first
// stopped as its `at`-th Newton iteration begins (the process sends itself SIGTERM there, which
// StopSignals turns into a stop request, as in `nexdyn run`) and then taken again. Each stopped
// step must leave the simulation as it was, and each row must be the reference's. Returns the
// number of steps stopped (a step with fewer Newton iterations than `at` is not).
inline int check_stopped_steps(const Scene& scene, int steps, int64_t at) {
  Simulation reference(scene), stopped(scene);
  int count = 0;
  for (int k = 1; k <= steps; ++k) {
    CAPTURE(k);
    const std::string before = simulation_bytes(stopped);
    StepOutcome outcome;
    {
      StopSignals signals;
      raise_at_safe_point(SafePoint::newton_iteration, at, SIGTERM);
      outcome = stopped.step();
      raise_at_safe_point(SafePoint::newton_iteration, 0, 0);
    }
    if (outcome.status == StepStatus::stopped) {
      ++count;
      CHECK(simulation_bytes(stopped) == before);
      clear_stop_request();
      outcome = stopped.step();
    }
    REQUIRE_MESSAGE(outcome.ok(), outcome.message);
    REQUIRE(reference.step().ok());
    StepStats a = reference.last_stats(), b = stopped.last_stats();
    a.wall_seconds = b.wall_seconds = 0.0;
    CHECK(stats_row(a) == stats_row(b));
  }
  CHECK(simulation_bytes(stopped) == simulation_bytes(reference));
  return count;
}

}  // namespace nexdyn::test

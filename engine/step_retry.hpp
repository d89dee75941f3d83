// The retry by halving that every kind of simulation takes (tet bodies: Simulation; particle
// bodies: MpmSimulation), written once.
//
// advance_or_split(stepper, t_start, t_end, dt, level, max_halvings, log) attempts the
// interval [t_start, t_end] as one step of dt (the scene's dt at level 0). A failed attempt is put back exactly as it found the simulation, and the
// interval is attempted as two halves, [t_start, t_mid] and [t_mid, t_end] with
// t_mid = t_start + (t_end - t_start) / 2, each of which may split again, max_halvings deep at
// most. If either half fails for good, the simulation goes back to where the interval started.
//
// - Times are exact: after a successful attempt of [t0, t1] the simulation's time is set to t1,
//   never to a sum of halves, so a halved step ends at the same time bit for bit as the step it
//   replaces.
// - Step sizes are exact too: a half is a step of dt / 2, not of t_mid - t_start (which can differ
//   in the last bit), so a retried half is exactly a step of a scene with half the dt.
// - `log.retries` counts the failed attempts that were split, and `log.first_failure` says why
//   the first of them failed (a retried step is otherwise silent about what went wrong).
// - When even the smallest attempt fails, its message ends with where the halving stopped:
//   " (after N halvings of dt, the last try a step of H s from t = T s)".
// - An outcome with retry_may_help false (particles left the MPM grid) is not split.
// - A stop request (StepStopped, engine/stop_request.hpp) thrown by an attempt puts every level
//   back as it found the simulation and goes on up: the caller catches it at the step's start.
//
// A Stepper provides:
//   Snapshot snapshot() const;             everything a failed attempt must put back: the state,
//                                          the history, and the step's running sums (stats)
//   void go_back(const Snapshot&);         puts it back, and drops caches built from the failure
//   StepOutcome attempt(double t_start, double t_end, double dt, int level, const Snapshot& before);
//                                          one step of dt over the interval from the state at t_start
//                                          (`before` is that state, for attempts that retake
//                                          themselves, as the energy guard does)
//   void set_time(double t);               the state's time after a successful attempt
#pragma once

#include "engine/step_result.hpp"
#include "engine/stop_request.hpp"

#include <cstdio>
#include <string>

namespace nexdyn {

// What a step stopped by a request (StepStopped) returns, once advance_or_split has put the
// simulation back to the step's start: never retried.
inline StepOutcome stopped_outcome(const StepStopped& stop) {
  return {StepStatus::stopped, "stopped by signal " + std::to_string(stop.signal) + " before the step finished", false};
}

template <typename Stepper>
StepOutcome advance_or_split(Stepper& stepper, double t_start, double t_end, double dt, int level,
                             int max_halvings, RetryLog& log) {
  const auto before = stepper.snapshot();
  StepOutcome outcome;
  try {
    outcome = stepper.attempt(t_start, t_end, dt, level, before);
  } catch (const StepStopped&) {
    stepper.go_back(before);
    throw;
  }
  if (outcome.ok()) {
    stepper.set_time(t_end);
    return outcome;
  }
  stepper.go_back(before);
  if (!outcome.retry_may_help) return outcome;
  if (level >= max_halvings) {
    if (max_halvings == 0) return outcome;
    char where[160];
    std::snprintf(where, sizeof where, " (after %d halving%s of dt, the last try a step of %.3g s from t = %.6g s)",
                  max_halvings, max_halvings == 1 ? "" : "s", dt, t_start);
    outcome.message += where;
    return outcome;
  }
  ++log.retries;
  if (log.first_failure.empty()) {
    char attempt[96];
    std::snprintf(attempt, sizeof attempt, " (a step of %.3g s from t = %.6g s)", dt, t_start);
    log.first_failure = "[" + std::string(step_status_name(outcome.status)) + "] " + outcome.message + attempt;
  }
  const double t_mid = t_start + 0.5 * (t_end - t_start);
  const double half = 0.5 * dt;
  try {
    outcome = advance_or_split(stepper, t_start, t_mid, half, level + 1, max_halvings, log);
    if (outcome.ok()) outcome = advance_or_split(stepper, t_mid, t_end, half, level + 1, max_halvings, log);
  } catch (const StepStopped&) {
    stepper.go_back(before);  // the first half may have finished
    throw;
  }
  if (!outcome.ok()) stepper.go_back(before);
  return outcome;
}

}  // namespace nexdyn

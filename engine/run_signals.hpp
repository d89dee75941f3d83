// Signals of `nexdyn run` (engine/run.cpp) and of Python's Simulation.step (engine/python): SIGINT
// and SIGTERM abandon the step under way at its next safe point (engine/stop_request.hpp), and the
// test hook NEXDYN_TEST_SIGNAL (run.hpp, kTestSignalVariable) makes a run send itself a signal at a
// chosen place of a chosen step.
#pragma once

#include <csignal>
#include <cstdint>
#include <utility>

namespace nexdyn {

// While alive, SIGINT (and SIGTERM, unless `interrupt_only`) request a stop (request_stop) instead
// of ending the process; the handler puts the default action back, so a second signal ends the
// process at once. A request left from before is forgotten when one is made.
class StopSignals {
 public:
  explicit StopSignals(bool interrupt_only = false);
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  int received() const;  // the signal received, 0 if none

 private:
  bool interrupt_only_;
  void (*previous_int_)(int) = SIG_DFL;
  void (*previous_term_)(int) = SIG_DFL;
};

// The test hook behind kill-and-resume and signal tests: the process sends itself a signal at a
// chosen place of a chosen step, so that a test knows exactly what the run had written when it
// was stopped, however fast or slow the machine is.
struct SignalHook {
  // As the step begins, after its stats row, after its checkpoint, or inside it: as its
  // `newton_iteration`-th Newton iteration begins (counted over the step's solves and retries).
  enum class Place { begin, row, checkpoint, newton };
  int signal = 0;  // 0: no hook
  int64_t step = 0;
  Place place = Place::begin;
  int64_t newton_iteration = 1;

  // Once: a process that goes on after the signal (Python, after KeyboardInterrupt) does not
  // stop at the same place again when it takes the step anew.
  void at(int64_t now, Place here) {
    if (signal != 0 && now == step && here == place) std::raise(std::exchange(signal, 0));
  }
  // Arms the safe point of place `newton` as step `now` begins, and disarms it (for good) when
  // that step is over.
  void arm(int64_t now) const;
  void disarm(int64_t now);
};

// The hook of the environment's NEXDYN_TEST_SIGNAL (none when unset). Throws std::runtime_error
// naming the variable when its value is malformed; says on stderr when one is set.
SignalHook signal_hook_from_environment();

}  // namespace nexdyn

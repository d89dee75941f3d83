// Signals of `nexdyn run` (engine/run.cpp): SIGINT and SIGTERM stop a run after the step under way,
// and the test hook NEXDYN_TEST_SIGNAL (run.hpp, kTestSignalVariable) makes a run send itself a
// signal at a chosen place of a chosen step.
#pragma once

#include <csignal>
#include <cstdint>

namespace nexdyn {

// While alive, SIGINT and SIGTERM set a flag instead of ending the process; the handler puts the
// default action back, so a second signal ends the process at once.
class StopSignals {
 public:
  StopSignals();
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
  int received() const;  // the signal received, 0 if none

 private:
  void (*previous_int_)(int) = SIG_DFL;
  void (*previous_term_)(int) = SIG_DFL;
};

// The test hook behind kill-and-resume and signal tests: the process sends itself a signal at a
// chosen place of a chosen step, so that a test knows exactly what the run had written when it
// was stopped, however fast or slow the machine is.
struct SignalHook {
  enum class Place { begin, row, checkpoint };
  int signal = 0;  // 0: no hook
  int64_t step = 0;
  Place place = Place::begin;

  void at(int64_t now, Place here) const {
    if (signal != 0 && now == step && here == place) std::raise(signal);
  }
};

// The hook of the environment's NEXDYN_TEST_SIGNAL (none when unset). Throws std::runtime_error
// naming the variable when its value is malformed; says on stderr when one is set.
SignalHook signal_hook_from_environment();

}  // namespace nexdyn

// A request to abandon the step under way, made by SIGINT or SIGTERM (engine/run_signals.hpp) or by
// Ctrl-C in Python (engine/python), and the safe points inside a step that honour it.
//
// A step can take minutes on a dense pile, and a batch system that sends SIGTERM kills the process
// some 30 s later. So the loops of a step that can run for more than a fraction of a second call
// stop_point() as they go: Newton's iterations, the line search's trials, the CCD's batches of
// pairs, the islands' factorisations, and the iterations of the other solvers. Once a stop is
// requested, the next stop_point() throws StepStopped. Nothing between a safe point and the step's
// driver holds a resource that the unwinding would not give back; the retry by halving
// (engine/step_retry.hpp) puts the simulation back exactly where the step began, and the step
// returns StepStatus::stopped. The state is then that of the last finished step, ready for a
// checkpoint, and the run continued from it takes the same steps as one never stopped.
#pragma once

#include <cstdint>

namespace nexdyn {

// What a safe point throws once a stop is requested. Not a std::exception on purpose: no handler
// of errors takes it for one.
struct StepStopped {
  int signal = 0;  // the signal that asked for the stop
};

// Asks the step under way to stop at its next safe point. Safe inside a signal handler.
void request_stop(int signal) noexcept;
// The signal of the pending request, 0 when there is none.
int stop_requested() noexcept;
// Forgets the request (before a run starts, or before Python's next step).
void clear_stop_request() noexcept;

// The places whose passes the test hook counts (run_signals.hpp, NEXDYN_TEST_SIGNAL's PLACE).
enum class SafePoint { any, newton_iteration };

// A safe point: throws StepStopped when a stop is requested. A `place` other than `any` also
// counts toward the test hook armed for that place.
void stop_point(SafePoint place = SafePoint::any);

// The test hook: the `count`-th pass through `place` from now on raises `signal` (then the pass
// goes on, and, for SIGINT and SIGTERM, throws as the handler asked). count 0 disarms it.
void raise_at_safe_point(SafePoint place, int64_t count, int signal);

}  // namespace nexdyn

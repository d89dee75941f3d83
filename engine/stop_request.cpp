// The request to abandon a step and its safe points (see stop_request.hpp).
#include "engine/stop_request.hpp"

#include <atomic>
#include <csignal>

namespace nexdyn {

namespace {

// Written by a signal handler: a lock-free atomic is the one kind a handler may touch.
std::atomic<int> g_request{0};
static_assert(std::atomic<int>::is_always_lock_free);

// The test hook: which place, how many passes to go, which signal. Armed and passed on the
// thread that drives the step (safe points inside parallel loops are SafePoint::any).
struct Armed {
  SafePoint place = SafePoint::any;
  int64_t remaining = 0;
  int signal = 0;
};
Armed g_armed;

}  // namespace

void request_stop(int signal) noexcept { g_request.store(signal, std::memory_order_relaxed); }

int stop_requested() noexcept { return g_request.load(std::memory_order_relaxed); }

void clear_stop_request() noexcept { g_request.store(0, std::memory_order_relaxed); }

void stop_point(SafePoint place) {
  if (place != SafePoint::any && g_armed.remaining > 0 && place == g_armed.place && --g_armed.remaining == 0)
    std::raise(g_armed.signal);
  if (const int signal = stop_requested(); signal != 0) throw StepStopped{signal};
}

void raise_at_safe_point(SafePoint place, int64_t count, int signal) { g_armed = {place, count, signal}; }

}  // namespace nexdyn

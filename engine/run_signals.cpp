// SIGINT / SIGTERM handling and the signal test hook of `nexdyn run` (see run_signals.hpp).
#include "engine/run_signals.hpp"

#include "engine/run.hpp"
#include "engine/stop_request.hpp"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace {

// SIGINT / SIGTERM: the step under way stops at its next safe point, and the run with a checkpoint.
extern "C" void on_stop_signal(int signal) {
  request_stop(signal);
  std::signal(signal, SIG_DFL);
}

}  // namespace

StopSignals::StopSignals(bool interrupt_only) : interrupt_only_(interrupt_only) {
  clear_stop_request();
  previous_int_ = std::signal(SIGINT, on_stop_signal);
  if (!interrupt_only_) previous_term_ = std::signal(SIGTERM, on_stop_signal);
}

StopSignals::~StopSignals() {
  std::signal(SIGINT, previous_int_);
  if (!interrupt_only_) std::signal(SIGTERM, previous_term_);
}

int StopSignals::received() const { return stop_requested(); }

void SignalHook::arm(int64_t now) const {
  if (signal != 0 && now == step && place == Place::newton)
    raise_at_safe_point(SafePoint::newton_iteration, newton_iteration, signal);
}

void SignalHook::disarm(int64_t now) {
  if (signal == 0 || place != Place::newton || now != step) return;
  raise_at_safe_point(SafePoint::newton_iteration, 0, 0);
  signal = 0;
}

SignalHook signal_hook_from_environment() {
  SignalHook hook;
  const char* text = std::getenv(kTestSignalVariable);
  if (!text || !*text) return hook;
  const std::string value = text;
  auto fail = [&] {
    throw std::runtime_error(std::string(kTestSignalVariable) + ": expected SIGNAL@STEP[:PLACE] with SIGNAL one of "
                             "KILL, TERM, INT, STOP, STEP >= 1 and PLACE one of begin, row, checkpoint, newton, newtonN "
                             "(N >= 1); got \"" + value + "\"");
  };
  const size_t at = value.find('@');
  if (at == std::string::npos) fail();
  const std::string name = value.substr(0, at);
  if (name == "KILL") hook.signal = SIGKILL;
  else if (name == "TERM") hook.signal = SIGTERM;
  else if (name == "INT") hook.signal = SIGINT;
  else if (name == "STOP") hook.signal = SIGSTOP;  // suspended there, holding what it holds
  else fail();
  const size_t colon = value.find(':', at);
  const std::string step = value.substr(at + 1, colon == std::string::npos ? std::string::npos : colon - at - 1);
  if (step.empty() || step.find_first_not_of("0123456789") != std::string::npos || step.size() > 15) fail();
  hook.step = std::stoll(step);
  if (hook.step < 1) fail();
  const std::string place = colon == std::string::npos ? "begin" : value.substr(colon + 1);
  if (place == "begin") hook.place = SignalHook::Place::begin;
  else if (place == "row") hook.place = SignalHook::Place::row;
  else if (place == "checkpoint") hook.place = SignalHook::Place::checkpoint;
  else if (place.rfind("newton", 0) == 0) {
    hook.place = SignalHook::Place::newton;
    const std::string n = place.substr(6);
    if (!n.empty()) {
      if (n.find_first_not_of("0123456789") != std::string::npos || n.size() > 9 || std::stoll(n) < 1) fail();
      hook.newton_iteration = std::stoll(n);
    }
  } else {
    fail();
  }
  std::fprintf(stderr, "nexdyn: %s=%s: this run will send itself SIG%s at step %lld (%s)\n", kTestSignalVariable,
               value.c_str(), name.c_str(), static_cast<long long>(hook.step), place.c_str());
  return hook;
}

}  // namespace nexdyn

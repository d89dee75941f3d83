// SIGINT / SIGTERM handling and the signal test hook of `nexdyn run` (see run_signals.hpp).
#include "engine/run_signals.hpp"

#include "engine/run.hpp"

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace {

// SIGINT / SIGTERM: the run stops after the step under way, with a checkpoint.
volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void on_stop_signal(int signal) {
  g_stop_signal = signal;
  std::signal(signal, SIG_DFL);
}

}  // namespace

StopSignals::StopSignals() {
  g_stop_signal = 0;
  previous_int_ = std::signal(SIGINT, on_stop_signal);
  previous_term_ = std::signal(SIGTERM, on_stop_signal);
}

StopSignals::~StopSignals() {
  std::signal(SIGINT, previous_int_);
  std::signal(SIGTERM, previous_term_);
}

int StopSignals::received() const { return g_stop_signal; }

SignalHook signal_hook_from_environment() {
  SignalHook hook;
  const char* text = std::getenv(kTestSignalVariable);
  if (!text || !*text) return hook;
  const std::string value = text;
  auto fail = [&] {
    throw std::runtime_error(std::string(kTestSignalVariable) + ": expected SIGNAL@STEP[:PLACE] with SIGNAL one of "
                             "KILL, TERM, INT, STEP >= 1 and PLACE one of begin, row, checkpoint; got \"" + value + "\"");
  };
  const size_t at = value.find('@');
  if (at == std::string::npos) fail();
  const std::string name = value.substr(0, at);
  if (name == "KILL") hook.signal = SIGKILL;
  else if (name == "TERM") hook.signal = SIGTERM;
  else if (name == "INT") hook.signal = SIGINT;
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
  else fail();
  std::fprintf(stderr, "nexdyn: %s=%s: this run will send itself SIG%s at step %lld (%s)\n", kTestSignalVariable,
               value.c_str(), name.c_str(), static_cast<long long>(hook.step), place.c_str());
  return hook;
}

}  // namespace nexdyn

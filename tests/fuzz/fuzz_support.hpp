// What the fuzz targets count as a finding, shared by tests/fuzz/fuzz_*.cpp.
//
// A reader may reject any input, but only in one way: an exception derived from std::exception
// whose message is one clear line that starts with the name of the file at fault. Everything
// else aborts the process, which libFuzzer reports as a crash and saves as a reproducer:
// std::bad_alloc (an allocation the input did not justify), an exception of another type, an
// empty, multi-line, control-character or runaway message, or a message that does not say which
// file it is about. Sanitizer reports, hangs (-timeout) and memory blow-ups (-rss_limit_mb,
// -malloc_limit_mb) are findings of libFuzzer itself.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <new>
#include <string>
#include <string_view>

namespace nexdyn::fuzz {

// Longest accepted message: the scene loader cuts its messages at 1000 characters.
inline constexpr std::size_t kMaxMessageChars = 1024;

[[noreturn]] inline void finding(const char* what, std::string_view message) {
  std::fprintf(stderr, "FUZZ FINDING: %s\nmessage (%zu bytes): %.*s\n", what, message.size(),
               static_cast<int>(message.size() < 4096 ? message.size() : 4096), message.data());
  std::abort();
}

// Aborts unless `message` is an accepted rejection of a file named `source`.
inline void check_message(std::string_view message, std::string_view source) {
  if (message.empty()) finding("empty error message", message);
  if (message.size() > kMaxMessageChars) finding("error message longer than 1024 characters", message);
  for (char c : message)
    if (static_cast<unsigned char>(c) < 32 || c == 127) finding("control character or line break in the error message", message);
  if (message.substr(0, source.size()) != source || message.substr(source.size(), 2) != ": ")
    finding("error message does not start with the file name", message);
}

// NEXDYN_FUZZ_VERBOSE=1 prints what happened to each input: for replaying a corpus by hand.
inline bool verbose() {
  static const bool on = std::getenv("NEXDYN_FUZZ_VERBOSE") != nullptr;
  return on;
}

// Runs `body`; an exception is fine only as check_message allows.
template <typename Body>
void expect_clean(std::string_view source, Body&& body) {
  try {
    body();
    if (verbose()) std::fprintf(stderr, "accepted\n");
  } catch (const std::bad_alloc& e) {
    finding("std::bad_alloc escaped", e.what());
  } catch (const std::exception& e) {
    if (verbose()) std::fprintf(stderr, "rejected: %s\n", e.what());
    check_message(e.what(), source);
  } catch (...) {
    finding("an exception not derived from std::exception escaped", "");
  }
}

}  // namespace nexdyn::fuzz

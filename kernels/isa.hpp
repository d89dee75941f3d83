// Which instruction-set path the hand-vectorised kernels take: AVX-512, AVX2 or plain C++.
//
// The project is built for the building machine (-march=native), but the few kernels written
// with intrinsics (today the box scans of bvh/blocked_boxes.hpp) are compiled for every path in
// files of their own and chosen when they run, by what the CPU reports. So one binary runs on any
// x86-64 machine, and a benchmark or test can force a narrower path on a wider CPU to measure or
// check it. Every path computes exactly the same results (the box scans only compare doubles),
// so forcing one changes speed, never output.
//
// The environment variable NEXDYN_ISA = scalar | avx2 | avx512 caps the path (read once, at the
// first call of active_isa()): the widest path both it and the CPU allow is taken. A value that
// names no path is an error, and so is asking for a path this CPU cannot run.
#pragma once

#include <atomic>
#include <optional>
#include <string_view>

namespace nexdyn {

// Ordered from narrowest to widest.
enum class Isa : int {
  scalar = 0,  // plain C++ (whatever the compiler makes of it)
  avx2 = 1,    // AVX2 + FMA: 4 doubles per vector (x86-64-v3)
  avx512 = 2,  // AVX-512 F + VL: 8 doubles per vector, masked compress
};

inline constexpr Isa kAllIsas[] = {Isa::scalar, Isa::avx2, Isa::avx512};

// The widest path this CPU (and operating system) can run.
Isa detected_isa();

namespace isa_detail {
extern std::atomic<int> g_active;  // the active path; -1 until the environment has been read
Isa read_active_isa();             // reads NEXDYN_ISA once, sets g_active
}  // namespace isa_detail

// The path the kernels take now: detected_isa(), capped by NEXDYN_ISA. Throws
// std::invalid_argument on a bad NEXDYN_ISA (the variable and its value named). Inline: the box
// scans ask once per query.
inline Isa active_isa() {
  const int active = isa_detail::g_active.load(std::memory_order_relaxed);
  return active >= 0 ? static_cast<Isa>(active) : isa_detail::read_active_isa();
}

// Forces a path (benchmarks and tests); throws std::invalid_argument if the CPU cannot run it.
void set_active_isa(Isa isa);

// "scalar", "avx2", "avx512"; and back (nullopt for any other text).
const char* isa_name(Isa isa);
std::optional<Isa> parse_isa(std::string_view name);

}  // namespace nexdyn

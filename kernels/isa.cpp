// Instruction-set path selection (see isa.hpp).
#include "kernels/isa.hpp"

#include <atomic>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <string>

namespace nexdyn {

namespace isa_detail {
std::atomic<int> g_active{-1};
}  // namespace isa_detail

namespace {

std::once_flag g_env_once;

void read_environment() {
  const Isa detected = detected_isa();
  Isa chosen = detected;
  if (const char* value = std::getenv("NEXDYN_ISA"); value != nullptr && *value != '\0') {
    const std::optional<Isa> wanted = parse_isa(value);
    if (!wanted) {
      throw std::invalid_argument(std::string("NEXDYN_ISA=") + value +
                                  ": expected one of scalar, avx2, avx512");
    }
    if (static_cast<int>(*wanted) > static_cast<int>(detected)) {
      throw std::invalid_argument(std::string("NEXDYN_ISA=") + value + ": this CPU runs at most " +
                                  isa_name(detected));
    }
    chosen = *wanted;
  }
  isa_detail::g_active.store(static_cast<int>(chosen), std::memory_order_relaxed);
}

}  // namespace

Isa detected_isa() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  // __builtin_cpu_supports also checks that the operating system saves the wide registers.
  static const Isa detected = [] {
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl")) return Isa::avx512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return Isa::avx2;
    return Isa::scalar;
  }();
  return detected;
#else
  return Isa::scalar;
#endif
}

Isa isa_detail::read_active_isa() {
  std::call_once(g_env_once, read_environment);
  return static_cast<Isa>(g_active.load(std::memory_order_relaxed));
}

void set_active_isa(Isa isa) {
  if (static_cast<int>(isa) > static_cast<int>(detected_isa())) {
    throw std::invalid_argument(std::string("instruction set ") + isa_name(isa) +
                                ": this CPU runs at most " + isa_name(detected_isa()));
  }
  std::call_once(g_env_once, [] {});  // a forced path wins over the environment from now on
  isa_detail::g_active.store(static_cast<int>(isa), std::memory_order_relaxed);
}

const char* isa_name(Isa isa) {
  switch (isa) {
    case Isa::scalar: return "scalar";
    case Isa::avx2: return "avx2";
    case Isa::avx512: return "avx512";
  }
  return "unknown";
}

std::optional<Isa> parse_isa(std::string_view name) {
  for (Isa isa : kAllIsas)
    if (name == isa_name(isa)) return isa;
  return std::nullopt;
}

}  // namespace nexdyn

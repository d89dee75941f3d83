// libFuzzer target: parse_stl (ASCII and binary STL surfaces) on arbitrary bytes, then the
// closed-surface check on whatever it accepts.
//
// A rejection must be one clear MeshError line naming the file (fuzz_support.hpp). An accepted
// surface must be one the checks can index (finite, ids in range, a triangle at least) and be
// welded (fuzz_surface.hpp). Run it with scripts/fuzz.sh.
#include "engine/mesh/surface_reader.hpp"
#include "tests/fuzz/fuzz_support.hpp"
#include "tests/fuzz/fuzz_surface.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

using namespace nexdyn;

namespace {

constexpr std::string_view kSource = "fuzz.stl";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  std::optional<TriangleSurface> surface;
  fuzz::expect_clean(kSource, [&] {
    surface = parse_stl(bytes, kSource);
    fuzz::check_surface_buffers(*surface);
    fuzz::check_welded(*surface);
  });
  if (surface) fuzz::check_closed_surface(std::move(*surface), kSource);
  return 0;
}

// libFuzzer target: the scene loader on arbitrary bytes as the scene file, then a Simulation
// built from whatever loads, as `nexdyn check` does (no step is taken).
//
// The input is written to a scene file in a folder of this process that also holds small valid
// and broken meshes (copied at start-up from scenes/meshes and tests/data), so the fuzzer can
// reach the mesh readers, the box mesher, arrays, obstacles, boundaries, joints and
// the start-state checks. The seed corpus (tests/data/fuzz/fuzz_scene) holds shipped scenes,
// whose "meshes/..." paths resolve here. A rejection must be one clear line starting with the
// scene file (fuzz_support.hpp); a scene that loads must have finite rest positions and tets of
// positive volume. The loader runs with small SceneLimits, so that legitimately large scenes
// (a box of 10^6 cells) are refused by the limit check instead of exhausting -rss_limit_mb;
// the default limits are the same code with larger numbers. Run it with scripts/fuzz.sh.
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"
#include "tests/fuzz/fuzz_support.hpp"

#include <oneapi/tbb/global_control.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

const fs::path kSourceDir = NEXDYN_SOURCE_DIR;
fs::path g_dir;    // this process's folder
fs::path g_scene;  // the scene file the input is written to
std::unique_ptr<tbb::global_control> g_one_thread;

constexpr SceneLimits kFuzzLimits = {20'000, 50'000, 64};

void remove_folder() {
  std::error_code error;
  fs::remove_all(g_dir, error);
}

void check_scene(const Scene& scene) {
  const Model& m = scene.model;
  if (m.rest_positions.size() != 3 * static_cast<std::size_t>(m.num_vertices))
    fuzz::finding("loaded scene with rest_positions of the wrong size", "");
  for (double x : m.rest_positions)
    if (!std::isfinite(x)) fuzz::finding("loaded scene with a non-finite rest position", "");
  for (double v : m.rest_volume)
    if (!(v > 0.0) || !std::isfinite(v)) fuzz::finding("loaded scene with a tet of volume <= 0", "");
  for (int32_t v : m.tets)
    if (v < 0 || v >= m.num_vertices) fuzz::finding("loaded scene with a tet vertex out of range", "");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // The folder mirrors tests/data so that every seed finds its meshes: the scene sits in
  // data/nasty/ beside the nasty corpus's meshes, the shipped meshes are in data/nasty/meshes/
  // (the shipped scenes' "meshes/cube.msh"), the reader tests' broken meshes in data/meshes/
  // (the nasty scenes' "../meshes/bad_nan.msh").
  g_dir = fs::temp_directory_path() / ("nexdyn_fuzz_scene_" + std::to_string(getpid()));
  const fs::path data = g_dir / "data";
  fs::remove_all(g_dir);
  fs::create_directories(data / "nasty" / "meshes");
  fs::create_directories(data / "meshes");
  for (const char* name : {"tet.msh", "cube.msh", "pyramid.msh", "torus.msh", "bar-186.msh", "wall.obj",
                           "roller.obj", "bowl.obj"})
    fs::copy_file(kSourceDir / "scenes" / "meshes" / name, data / "nasty" / "meshes" / name);
  for (const char* folder : {"meshes", "nasty"})
    for (const auto& entry : fs::directory_iterator(kSourceDir / "tests" / "data" / folder)) {
      const fs::path& file = entry.path();
      if (entry.is_regular_file() && (file.extension() == ".msh" || file.extension() == ".obj"))
        fs::copy_file(file, data / folder / file.filename());
    }
  g_scene = data / "nasty" / "scene.json";
  std::atexit(remove_folder);
  // One worker: reproducible, and the machine's other core stays free.
  g_one_thread = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, 1);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  {
    std::FILE* out = std::fopen(g_scene.c_str(), "wb");
    if (out == nullptr || std::fwrite(data, 1, size, out) != size || std::fclose(out) != 0) {
      std::perror("fuzz_scene: cannot write the scene file");
      std::abort();
    }
  }
  const std::string source = g_scene.string();
  fuzz::expect_clean(source, [&] {
    const Scene scene = load_scene(g_scene, kFuzzLimits);
    check_scene(scene);
    Simulation check(scene);  // builds the assembly and checks the initial forces
  });
  return 0;
}

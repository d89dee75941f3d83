// The layers of the source tree (docs/architecture.md, "Layers"): every #include of a file in
// kernels/, bvh/ or engine/ points to a header of its own layer or of one below it, never above,
// and the two simulations do not include each other. A new file must be given a layer here.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct Layer {
  const char* prefix;  // a path from the repository's root, or its start
  int layer;
};

// First match wins: the longer prefixes of a folder come before the folder.
const std::vector<Layer> kLayers = {
    // 0: pure math and the broad phase, no engine types
    {"kernels/", 0},
    {"bvh/", 0},
    // 1: the engine's plain data and its parallel loops; meshes and their files
    {"engine/parallel.hpp", 1},
    {"engine/active_subset.hpp", 1},
    {"engine/atomic_file.", 1},
    {"engine/coordinate_map.", 1},
    {"engine/integrator.", 1},
    {"engine/model.hpp", 1},
    {"engine/state.hpp", 1},
    {"engine/step_context.hpp", 1},
    {"engine/step_history.hpp", 1},
    {"engine/step_profile.hpp", 1},
    {"engine/step_result.hpp", 1},
    {"engine/stop_request.", 1},
    {"engine/mesh/", 1},
    // 2: sparse matrices: patterns, islands, CHOLMOD, the island systems, slab operators
    {"engine/sparse/", 2},
    // 3: contact geometry and potentials; the MPM grid, particles and step
    {"engine/contact/", 3},
    {"engine/mpm/mpm_simulation.", 7},
    {"engine/mpm/", 3},
    // 4: the incremental potential and its terms
    {"engine/potential/", 4},
    {"engine/terms/", 4},
    // 5: the solvers of a step: Newton, the linearised step, Projective Dynamics
    {"engine/solver/", 5},
    // 6: scenes: what a scene file says, read and built
    {"engine/scene/", 6},
    // 7: the simulations, built from a Scene, and what only they use
    {"engine/simulation", 7},
    {"engine/step_retry.hpp", 7},
    {"engine/sleeping.", 7},
    {"engine/energy_balance.", 7},
    // 8: files written from a simulation: frames, checkpoints
    {"engine/output/", 8},
    // 9: the programs around them: the run loop, pictures, charts, CCD queries, the CLI, Python,
    // the allocator policy a program sets
    {"engine/run", 9},
    {"engine/allocation.", 9},
    {"engine/ccd_queries.", 9},
    {"engine/render/", 9},
    {"engine/plot/", 9},
    {"engine/cli/", 9},
    {"engine/python/", 9},
};

int layer_of(const std::string& path) {
  for (const Layer& l : kLayers)
    if (path.rfind(l.prefix, 0) == 0) return l.layer;
  return -1;
}

// Includes that the layer numbers allow but the design does not: the two simulations are
// siblings and share only what lies below them (step_result.hpp, step_retry.hpp).
bool forbidden(const std::string& file, const std::string& included) {
  const bool mpm = file.rfind("engine/mpm/", 0) == 0;
  const bool tets = file.rfind("engine/simulation", 0) == 0;
  return (mpm && included.rfind("engine/simulation", 0) == 0) ||
         (tets && included.rfind("engine/mpm/mpm_simulation", 0) == 0);
}

std::vector<std::string> sources() {
  const fs::path root = NEXDYN_SOURCE_DIR;
  std::vector<std::string> files;
  for (const char* folder : {"kernels", "bvh", "engine"})
    for (const auto& entry : fs::recursive_directory_iterator(root / folder)) {
      const std::string ext = entry.path().extension().string();
      if (entry.is_regular_file() && (ext == ".hpp" || ext == ".cpp"))
        files.push_back(fs::relative(entry.path(), root).generic_string());
    }
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

TEST_CASE("layers: every #include points to the same layer or one below (docs/architecture.md)") {
  const std::regex include_line(R"re(^\s*#\s*include\s+"((kernels|bvh|engine)/[^"]+)")re");
  const std::vector<std::string> files = sources();
  REQUIRE(files.size() > 100);
  std::string unplaced, upward;
  int64_t includes = 0;
  for (const std::string& file : files) {
    const int layer = layer_of(file);
    if (layer < 0) {
      unplaced += "\n  " + file;
      continue;
    }
    std::ifstream in(fs::path(NEXDYN_SOURCE_DIR) / file);
    int line_number = 0;
    for (std::string line; std::getline(in, line);) {
      ++line_number;
      std::smatch m;
      if (!std::regex_search(line, m, include_line)) continue;
      ++includes;
      const std::string included = m[1];
      const int target = layer_of(included);
      if (target > layer || forbidden(file, included))
        upward += "\n  " + file + ":" + std::to_string(line_number) + " (layer " + std::to_string(layer) +
                  ") includes " + included + " (layer " + std::to_string(target) + ")";
    }
  }
  MESSAGE(files.size() << " files, " << includes << " includes checked");
  INFO("files with no layer in tests/engine/test_layers.cpp:" << unplaced);
  CHECK(unplaced.empty());
  INFO("includes against the layers:" << upward);
  CHECK(upward.empty());
}

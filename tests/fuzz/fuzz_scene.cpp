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
// the default limits are the same code with larger numbers.
//
// Byte mutations mostly break the JSON syntax, so half of the mutations are structural
// (LLVMFuzzerCustomMutator): the input is parsed, one value in it is replaced by an awkward one
// (a huge, tiny, negative or non-integer number, a wrong type, a key or mesh name from the
// dictionary, a copy of another value), a key or element is added or removed, and the document
// is written back. Run it with scripts/fuzz.sh.
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"
#include "tests/fuzz/fuzz_support.hpp"

#include <oneapi/tbb/global_control.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

const fs::path kSourceDir = NEXDYN_SOURCE_DIR;
fs::path g_dir;    // this process's folder
fs::path g_scene;  // the scene file the input is written to
std::unique_ptr<tbb::global_control> g_one_thread;

constexpr SceneLimits kFuzzLimits = {20'000, 50'000, 64};

using nlohmann::json;

// Keys and names for the structural mutations: the quoted words of the dictionary.
std::vector<std::string> g_words;

void read_words() {
  std::ifstream in(kSourceDir / "tests" / "data" / "fuzz" / "fuzz_scene.dict");
  for (std::string line; std::getline(in, line);)
    if (line.size() > 6 && line.rfind("\"\\\"", 0) == 0 && line.compare(line.size() - 3, 3, "\\\"\"") == 0)
      g_words.push_back(line.substr(3, line.size() - 6));  // "\"name\"" -> name
  if (g_words.empty()) g_words.push_back("name");
}

// Every value of the document, depth first (depth-limited: the input is a few kB).
void collect(json& value, std::vector<json*>& out, int depth) {
  out.push_back(&value);
  if (depth > 32) return;
  if (value.is_array())
    for (json& item : value) collect(item, out, depth + 1);
  else if (value.is_object())
    for (auto& item : value.items()) collect(item.value(), out, depth + 1);
}

json awkward_value(std::mt19937& rng, const std::vector<json*>& nodes) {
  static const json kNumbers[] = {0, -1, 1, 2, 3, 1000, 1001, 1000000, 2147483647, 4294967297LL, -9223372036854775807LL,
                                  9223372036854775807LL, 18446744073709551615ULL, 0.5, -0.5, 1e-9, 1e-320, 1e308,
                                  -1e308, 0.49999999999, 1e-3, 100.0};
  auto pick = [&](std::size_t n) { return static_cast<std::size_t>(rng() % n); };
  switch (pick(7)) {
    case 0: return kNumbers[pick(std::size(kNumbers))];
    case 1: return json::array({kNumbers[pick(std::size(kNumbers))], kNumbers[pick(std::size(kNumbers))],
                                kNumbers[pick(std::size(kNumbers))]});
    case 2: return g_words[pick(g_words.size())];
    case 3: return *nodes[pick(nodes.size())];  // a copy of another value
    case 4: return pick(2) ? json(true) : json(nullptr);
    case 5: return json::object();
    default: return json::array();
  }
}

// One structural change to `doc`.
void mutate_document(json& doc, std::mt19937& rng) {
  std::vector<json*> nodes;
  collect(doc, nodes, 0);
  json& target = *nodes[rng() % nodes.size()];
  const unsigned action = rng() % 4;
  if (action == 0 && target.is_object() && !target.empty()) {  // remove a key
    auto it = target.begin();
    std::advance(it, rng() % target.size());
    target.erase(it);
  } else if (action == 1 && target.is_object()) {  // add (or overwrite) a key
    target[g_words[rng() % g_words.size()]] = awkward_value(rng, nodes);
  } else if (action == 2 && target.is_array() && !target.empty()) {  // duplicate or drop an element
    const std::size_t k = rng() % target.size();
    if (rng() % 2) target.push_back(json(target[k]));
    else target.erase(target.begin() + static_cast<std::ptrdiff_t>(k));
  } else if (target.is_number_float() || target.is_number_integer()) {  // scale a number
    static const double kFactors[] = {-1.0, 0.0, 1e-12, 0.999999, 1.000001, 2.0, 1e6, 1e300};
    target = target.get<double>() * kFactors[rng() % std::size(kFactors)];
  } else {
    target = awkward_value(rng, nodes);
  }
}

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
  read_words();
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

extern "C" size_t LLVMFuzzerMutate(uint8_t* data, size_t size, size_t max_size);

extern "C" size_t LLVMFuzzerCustomMutator(uint8_t* data, size_t size, size_t max_size, unsigned int seed) {
  std::mt19937 rng(seed);
  if (rng() % 2 == 0) {
    json doc = json::parse(data, data + size, nullptr, false);  // no exceptions: discarded when bad
    if (!doc.is_discarded()) {
      mutate_document(doc, rng);
      const std::string text = doc.dump(1);
      if (text.size() <= max_size) {
        std::memcpy(data, text.data(), text.size());
        return text.size();
      }
    }
  }
  return LLVMFuzzerMutate(data, size, max_size);
}

// libFuzzer target: parse_obj (the .obj reader of obstacle meshes) on arbitrary bytes.
//
// A rejection must be one clear MeshError line naming the file (fuzz_support.hpp). An accepted
// mesh must hold what the scene loader relies on: finite positions, at least one triangle,
// triangle ids in range, and no degenerate triangle. Run it with scripts/fuzz.sh.
#include "engine/mesh/obj_reader.hpp"
#include "tests/fuzz/fuzz_support.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

using namespace nexdyn;

namespace {

constexpr std::string_view kSource = "fuzz.obj";

void check_mesh(const ObjMesh& mesh) {
  if (mesh.positions.size() % 3 != 0 || mesh.triangles.size() % 3 != 0 || mesh.triangles.empty())
    fuzz::finding("accepted obj with ragged or empty buffers", "");
  for (double x : mesh.positions)
    if (!std::isfinite(x)) fuzz::finding("accepted obj with a non-finite position", "");
  const std::size_t n = mesh.positions.size() / 3;
  for (int32_t v : mesh.triangles)
    if (v < 0 || static_cast<std::size_t>(v) >= n) fuzz::finding("accepted obj with a vertex id out of range", "");
  auto p = [&](int32_t v) { return Eigen::Vector3d::Map(&mesh.positions[3 * static_cast<std::size_t>(v)]); };
  for (std::size_t t = 0; t < mesh.triangles.size(); t += 3)
    if (is_degenerate_triangle(p(mesh.triangles[t]), p(mesh.triangles[t + 1]), p(mesh.triangles[t + 2])))
      fuzz::finding("accepted obj with a degenerate triangle", "");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  fuzz::expect_clean(kSource, [&] { check_mesh(parse_obj(text, kSource)); });
  return 0;
}

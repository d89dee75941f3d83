// libFuzzer target: parse_msh (Gmsh 2.2 / 4.1 ASCII) on arbitrary bytes, then extract_surface on
// whatever it accepts, as loading a scene body does.
//
// A rejection must be one clear MeshError line naming the file (fuzz_support.hpp). An accepted
// mesh must hold the TetMesh invariants every later stage relies on: finite positions, ids in
// range, no repeated vertex in a tet, no degenerate tet, every tet positively oriented, and a
// surface that only uses the mesh's vertices. Run it with scripts/fuzz.sh.
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "tests/fuzz/fuzz_support.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

using namespace nexdyn;

namespace {

constexpr std::string_view kSource = "fuzz.msh";

void check_mesh(const TetMesh& mesh) {
  if (mesh.positions.size() % 3 != 0 || mesh.tets.size() % 4 != 0 || mesh.tets.empty())
    fuzz::finding("accepted mesh with ragged or empty buffers", "");
  for (double x : mesh.positions)
    if (!std::isfinite(x)) fuzz::finding("accepted mesh with a non-finite position", "");
  const int32_t n = mesh.num_vertices();
  for (int32_t t = 0; t < mesh.num_tets(); ++t) {
    const int32_t* c = &mesh.tets[4 * static_cast<std::size_t>(t)];
    for (int i = 0; i < 4; ++i) {
      if (c[i] < 0 || c[i] >= n) fuzz::finding("accepted mesh with a vertex id out of range", "");
      for (int j = i + 1; j < 4; ++j)
        if (c[i] == c[j]) fuzz::finding("accepted mesh with a repeated vertex in a tet", "");
    }
    if (!(signed_tet_volume(mesh, t) > 0.0)) fuzz::finding("accepted mesh with a tet of volume <= 0", "");
  }
  if (find_degenerate_tet(mesh) >= 0) fuzz::finding("accepted mesh with a degenerate tet", "");
  const SurfaceMesh surface = extract_surface(mesh);
  for (int32_t v : surface.triangles)
    if (v < 0 || v >= n) fuzz::finding("surface triangle with a vertex id out of range", "");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  fuzz::expect_clean(kSource, [&] {
    MshReadStats stats;
    check_mesh(parse_msh(text, kSource, &stats));
  });
  return 0;
}

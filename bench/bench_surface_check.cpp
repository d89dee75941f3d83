// checked_closed_surface on surfaces of 2.5k to 100k triangles (issue 21): the check that stands
// between a surface file and tetrahedralisation must not cost more than reading the file.
//   sphere1K        the largest of the IPC triMeshes (2,474 triangles)
//   armadillo13K    the boundary of the IPC Armadillo tet mesh (17,296 triangles, a scan)
//   icosphere/6     a subdivided icosahedron, 81,920 triangles
//   box/91          a box with 91 x 91 grids for faces, 99,372 triangles, every neighbour coplanar
//   rotated_box/91  the same turned about a skew axis: neighbours coplanar up to rounding, the
//                   orientation signs decided by the exact fallback (the slow path)
// and, for each, the self-intersection search alone (the part that is not linear in the size).
// Items are triangles.
//
//   build/bench/bench_surface_check --benchmark_min_time=0.5
#include <benchmark/benchmark.h>

#include <Eigen/Geometry>

#include <filesystem>
#include <string>

#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/self_intersection.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/surface_check.hpp"
#include "engine/mesh/surface_reader.hpp"
#include "tests/engine/mesh/closed_surfaces.hpp"
#include "tests/test_data.hpp"

using namespace nexdyn;

namespace {

TriangleSurface armadillo() {
  const TetMesh mesh = read_msh(test::ipc_tet_mesh("Armadillo13K.msh"));
  return {mesh.positions, extract_surface(mesh).triangles};
}

Eigen::Matrix3d skew_rotation() {
  return Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
}

void register_surface(const std::string& name, const TriangleSurface& surface) {
  benchmark::RegisterBenchmark(("checked_closed_surface/" + name).c_str(), [surface](
                                                                               benchmark::State& state) {
    for (auto _ : state) benchmark::DoNotOptimize(checked_closed_surface(surface, "bench"));
    state.SetItemsProcessed(state.iterations() * surface.num_triangles());
  })->Unit(benchmark::kMillisecond);
  benchmark::RegisterBenchmark(("first_self_intersection/" + name).c_str(), [surface](
                                                                                benchmark::State& state) {
    for (auto _ : state)
      benchmark::DoNotOptimize(first_self_intersection(surface.positions, surface.triangles));
    state.SetItemsProcessed(state.iterations() * surface.num_triangles());
  })->Unit(benchmark::kMillisecond);
}

}  // namespace

int main(int argc, char** argv) {
  register_surface("sphere1K", read_triangle_surface(test::ipc_tri_mesh("sphere1K.obj")));
  register_surface("armadillo13K", armadillo());
  register_surface("icosphere/6", test::icosphere(6));
  register_surface("box/91", test::grid_box(91));
  register_surface("rotated_box/91", test::grid_box(91, skew_rotation()));
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

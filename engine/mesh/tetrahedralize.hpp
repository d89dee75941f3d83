// Tetrahedralising a closed triangle surface with TetGen (Debian's libtet, TetGen 1.5), so that a
// body can be given as the surface users hold (.obj, .stl, .ply) instead of a tet mesh.
//
// Why TetGen: it is one small library package, it is deterministic and single-threaded, and its
// "-Y" switch keeps the input surface exactly (no Steiner point on the boundary): the tet mesh's
// boundary is the input's triangles on the input's vertices, so contact sees the surface the user
// drew. Gmsh's library would do too, but pulls 21 packages (OpenCASCADE among them) for the same
// result. TetGen then adds points only inside the volume. A coarse surface (a cube of 12
// triangles) leaves it little room: tets along a big surface triangle stay big whatever
// max_volume says. With refine_surface TetGen may also split the surface triangles, with new
// points on them, so the shape is the same and max_volume holds everywhere.
//
// The surface must already be closed, manifold, consistently oriented and free of
// self-intersections (surface_check.hpp); TetGen's own failures still become one MeshError line.
#pragma once

#include "engine/mesh/mesh_error.hpp"
#include "engine/mesh/tet_mesh.hpp"

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace nexdyn {

// The radius-edge ratio (circumradius / shortest edge) of a regular tet, sqrt(6)/4: the best any
// tet can have. Quality below is this divided by a tet's ratio, so 1 is a regular tet.
inline constexpr double kRegularTetRadiusEdgeRatio = 0.61237243569579452;

// The "tetrahedralize" keys of a surface body (docs/scenes.md) and the options of `nexdyn mesh`.
struct TetrahedralizeSettings {
  // Largest tet volume [m^3, in the surface file's units]; 0: no bound (TetGen's quality alone
  // decides how many interior points to add).
  double max_volume = 0.0;
  // Smallest allowed quality (sqrt(6)/4) / (circumradius / shortest edge), in (0, 1]; 0 turns
  // quality refinement off. The default 0.306 is TetGen's own default ratio bound of 2.0.
  double min_quality = kRegularTetRadiusEdgeRatio / 2.0;
  // Let TetGen add points on the surface (in its triangles' planes, up to round-off) so that
  // max_volume and min_quality hold next to a coarse surface too; false keeps the surface's
  // triangles as given.
  bool refine_surface = false;
};

// TetGen refines reliably down to a radius-edge ratio of about 1.1 (its manual); a higher
// min_quality may not terminate, so it is refused.
inline constexpr double kMaxMinQuality = kRegularTetRadiusEdgeRatio / 1.1;

// Refuses settings out of range: a negative or non-finite max_volume, a min_quality outside
// [0, kMaxMinQuality]. Returns "" when fine, otherwise the sentence saying what is wrong.
std::string tetrahedralize_settings_problem(const TetrahedralizeSettings& settings);

// The TetGen switches for these settings ("pQ", "Y" unless refine_surface, quality, volume),
// also a part of the mesh cache's key.
std::string tetgen_switches(const TetrahedralizeSettings& settings);

// Fills the surface (positions: num_vertices x 3, triangles: num_triangles x 3, outward winding,
// every vertex used) with tets. The result's first num_vertices vertices are the input's, in
// order; its boundary triangles are the input's (without refine_surface) or cover them with
// points on them (with it); every tet is positively oriented. Throws
// MeshError naming `name` when TetGen fails or produces a degenerate tet.
TetMesh tetrahedralize_surface(std::span<const double> positions, std::span<const int32_t> triangles,
                               const TetrahedralizeSettings& settings, std::string_view name);

}  // namespace nexdyn

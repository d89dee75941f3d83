// TetGen behind one function (see tetrahedralize.hpp).
#include "engine/mesh/tetrahedralize.hpp"

// Debian's libtet is built as a library: the char* entry point and the throwing error path
// (terminatetetgen throws an int instead of calling exit) exist only with this symbol.
#define TETLIBRARY
#include <tetgen.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace nexdyn {

namespace {

// TetGen's exit codes (terminatetetgen in tetgen.h), as a user can act on them.
std::string tetgen_failure(int code) {
  switch (code) {
    case 1: return "TetGen ran out of memory (try a larger max_volume)";
    case 3: return "TetGen found a self-intersection of the surface";
    case 4: return "TetGen found an input feature too small for its tolerance (nearly coincident vertices?)";
    case 5: return "TetGen found two facets too close to each other";
    case 10: return "TetGen refused the input";
    default: return "TetGen failed with internal error " + std::to_string(code);
  }
}

// TetGen's `facetlist` for a triangle surface: one facet of one 3-corner polygon per triangle,
// allocated with new[] because tetgenio's destructor frees them with delete[].
void fill_facets(tetgenio& in, std::span<const int32_t> triangles) {
  const int count = static_cast<int>(triangles.size() / 3);
  in.numberoffacets = count;
  in.facetlist = new tetgenio::facet[count];
  for (int t = 0; t < count; ++t) {
    tetgenio::facet& facet = in.facetlist[t];
    tetgenio::init(&facet);
    facet.numberofpolygons = 1;
    facet.polygonlist = new tetgenio::polygon[1];
    tetgenio::polygon& polygon = facet.polygonlist[0];
    tetgenio::init(&polygon);
    polygon.numberofvertices = 3;
    polygon.vertexlist = new int[3];
    for (int c = 0; c < 3; ++c) polygon.vertexlist[c] = triangles[3 * t + c];
  }
}

}  // namespace

std::string tetrahedralize_settings_problem(const TetrahedralizeSettings& s) {
  char buf[160];
  if (!std::isfinite(s.max_volume) || s.max_volume < 0.0) {
    std::snprintf(buf, sizeof buf, "max_volume must be a positive volume or 0 (no bound), not %g", s.max_volume);
    return buf;
  }
  if (!std::isfinite(s.min_quality) || s.min_quality < 0.0 || s.min_quality > kMaxMinQuality) {
    std::snprintf(buf, sizeof buf,
                  "min_quality must be in [0, %.3f] (0: no refinement; TetGen may not finish above %.3f), "
                  "not %g", kMaxMinQuality, kMaxMinQuality, s.min_quality);
    return buf;
  }
  return "";
}

std::string tetgen_switches(const TetrahedralizeSettings& s) {
  // p: the input is a piecewise linear complex (our triangles); Q: quiet; Y: no Steiner point
  // on the surface, so its triangles stay exactly as given. Refining the surface, M: no merging
  // of nearly coplanar triangles, whose shared edge TetGen would otherwise flip, moving the
  // surface (6e-6 of the size on the IPC sphere).
  std::string switches = s.refine_surface ? "pQM" : "pYQ";
  char buf[64];
  if (s.min_quality > 0.0) {
    std::snprintf(buf, sizeof buf, "q%.17g", kRegularTetRadiusEdgeRatio / s.min_quality);
    switches += buf;
  }
  if (s.max_volume > 0.0) {
    std::snprintf(buf, sizeof buf, "a%.17g", s.max_volume);
    switches += buf;
  }
  return switches;
}

TetMesh tetrahedralize_surface(std::span<const double> positions, std::span<const int32_t> triangles,
                               const TetrahedralizeSettings& settings, std::string_view name) {
  const std::string prefix = std::string(name) + ": ";
  if (const std::string problem = tetrahedralize_settings_problem(settings); !problem.empty())
    throw MeshError(prefix + problem);
  const int num_vertices = static_cast<int>(positions.size() / 3);
  tetgenio in, out;
  in.firstnumber = 0;
  in.numberofpoints = num_vertices;
  in.pointlist = new REAL[positions.size()];
  std::copy(positions.begin(), positions.end(), in.pointlist);
  fill_facets(in, triangles);

  std::string switches = tetgen_switches(settings);
  try {
    tetrahedralize(switches.data(), &in, &out);
  } catch (int code) {
    throw MeshError(prefix + tetgen_failure(code));
  }
  if (out.numberoftetrahedra <= 0 || out.numberofcorners != 4)
    throw MeshError(prefix + "TetGen produced no tets (is the surface closed?)");
  // TetGen keeps every input point, first and in order; check it rather than trust it, since
  // the caller relies on the boundary holding the input's vertices.
  if (out.numberofpoints < num_vertices ||
      !std::equal(positions.begin(), positions.end(), out.pointlist))
    throw MeshError(prefix + "TetGen moved or dropped an input vertex (duplicate vertices?)");

  TetMesh mesh;
  mesh.positions.assign(out.pointlist, out.pointlist + 3 * static_cast<size_t>(out.numberofpoints));
  mesh.tets.assign(out.tetrahedronlist, out.tetrahedronlist + 4 * static_cast<size_t>(out.numberoftetrahedra));
  orient_tets_positively(mesh);
  if (const int32_t bad = find_degenerate_tet(mesh); bad >= 0)
    throw MeshError(prefix + "TetGen produced a flat tet (" + std::to_string(bad) +
                    "); try a lower min_quality or a larger max_volume");
  return mesh;
}

}  // namespace nexdyn

// What fuzz_stl and fuzz_ply check on a surface a reader accepted, and on what the closed-surface
// check then makes of it (the path of a surface file to tetrahedralisation).
//
// The readers must hand over a surface the checks can index blindly: finite positions, at least
// one triangle, ids in range. STL welds equal corners, so its vertices must also be distinct and
// all used. checked_closed_surface may refuse anything, but only with a clean MeshError line
// (fuzz_support.hpp); what it accepts must have only used vertices and a positive volume.
#pragma once

#include "engine/mesh/surface_check.hpp"
#include "engine/mesh/surface_reader.hpp"
#include "tests/fuzz/fuzz_support.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <string_view>
#include <utility>
#include <vector>

namespace nexdyn::fuzz {

inline void check_surface_buffers(const TriangleSurface& surface) {
  if (surface.positions.size() % 3 != 0 || surface.triangles.size() % 3 != 0 || surface.triangles.empty())
    finding("accepted surface with ragged or empty buffers", "");
  for (double x : surface.positions)
    if (!std::isfinite(x)) finding("accepted surface with a non-finite position", "");
  const std::size_t n = surface.positions.size() / 3;
  for (int32_t v : surface.triangles)
    if (v < 0 || static_cast<std::size_t>(v) >= n)
      finding("accepted surface with a vertex id out of range", "");
}

// Welded: every vertex used, no two at the same position.
inline void check_welded(const TriangleSurface& surface) {
  const std::size_t n = surface.positions.size() / 3;
  std::vector<char> used(n, 0);
  for (int32_t v : surface.triangles) used[static_cast<std::size_t>(v)] = 1;
  if (std::find(used.begin(), used.end(), 0) != used.end())
    finding("welded surface with an unused vertex", "");
  std::vector<std::array<double, 3>> points(n);
  for (std::size_t v = 0; v < n; ++v)
    points[v] = {surface.positions[3 * v], surface.positions[3 * v + 1], surface.positions[3 * v + 2]};
  std::sort(points.begin(), points.end());
  if (std::adjacent_find(points.begin(), points.end()) != points.end())
    finding("welded surface with two vertices at one position", "");
}

// The closed-surface check on an accepted surface, as tetrahedralisation would run it.
inline void check_closed_surface(TriangleSurface surface, std::string_view source) {
  expect_clean(source, [&] {
    const TriangleSurface checked = checked_closed_surface(std::move(surface), source);
    check_surface_buffers(checked);
    std::vector<char> used(checked.positions.size() / 3, 0);
    for (int32_t v : checked.triangles) used[static_cast<std::size_t>(v)] = 1;
    if (std::find(used.begin(), used.end(), 0) != used.end())
      finding("checked surface with an unused vertex", "");
    if (!(enclosed_volume(checked) > 0.0)) finding("checked surface without a positive volume", "");
  });
}

}  // namespace nexdyn::fuzz

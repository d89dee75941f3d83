// Kuhn-split box mesh (see box_mesher.hpp for why this split).
#include "engine/mesh/box_mesher.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace nexdyn {
namespace {

// The 6 orders in which a monotone path from corner 0 to corner 7 of the unit cell can step
// along the axes (0 = x, 1 = y, 2 = z). The tet of an order is the 4 corners the path visits.
// Odd permutations give negatively oriented tets; their last two corners are swapped below.
constexpr int kAxisOrders[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1},   // even
                                   {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};  // odd

}  // namespace

TetMesh make_box_mesh(const Eigen::Vector3d& size, const std::array<int, 3>& cells) {
  const char* const axis_name = "xyz";
  for (int d = 0; d < 3; ++d) {
    if (!(std::isfinite(size[d]) && size[d] > 0.0))
      throw std::invalid_argument(std::string("box mesh: size.") + axis_name[d] +
                                  " must be positive and finite, got " + std::to_string(size[d]));
    if (cells[d] < 1)
      throw std::invalid_argument(std::string("box mesh: cells.") + axis_name[d] +
                                  " must be >= 1, got " + std::to_string(cells[d]));
  }
  const int64_t nx = cells[0], ny = cells[1], nz = cells[2];
  const int64_t num_vertices = (nx + 1) * (ny + 1) * (nz + 1);
  const int64_t num_tets = kTetsPerBoxCell * nx * ny * nz;
  // The tets array holds 4 ids per tet and num_tets() returns int32: keep 4 * num_tets in range.
  if (4 * num_tets > std::numeric_limits<int32_t>::max())
    throw std::invalid_argument("box mesh: " + std::to_string(nx) + " x " + std::to_string(ny) +
                                " x " + std::to_string(nz) + " cells is too many for 32-bit ids");

  TetMesh mesh;
  mesh.positions.resize(3 * static_cast<std::size_t>(num_vertices));
  auto vertex_id = [&](int64_t i, int64_t j, int64_t k) {
    return static_cast<int32_t>(i + (nx + 1) * (j + (ny + 1) * k));
  };
  for (int64_t k = 0; k <= nz; ++k)
    for (int64_t j = 0; j <= ny; ++j)
      for (int64_t i = 0; i <= nx; ++i) {
        // (i/n - 1/2) * size hits -size/2 and +size/2 exactly at the ends, so the box is
        // centred on the origin to the last bit.
        double* x = &mesh.positions[3 * static_cast<std::size_t>(vertex_id(i, j, k))];
        x[0] = (static_cast<double>(i) / static_cast<double>(nx) - 0.5) * size[0];
        x[1] = (static_cast<double>(j) / static_cast<double>(ny) - 0.5) * size[1];
        x[2] = (static_cast<double>(k) / static_cast<double>(nz) - 0.5) * size[2];
      }

  mesh.tets.reserve(4 * static_cast<std::size_t>(num_tets));
  for (int64_t k = 0; k < nz; ++k)
    for (int64_t j = 0; j < ny; ++j)
      for (int64_t i = 0; i < nx; ++i)
        for (int order = 0; order < kTetsPerBoxCell; ++order) {
          int64_t corner[3] = {i, j, k};
          int32_t tet[4];
          tet[0] = vertex_id(corner[0], corner[1], corner[2]);
          for (int step = 0; step < 3; ++step) {
            ++corner[kAxisOrders[order][step]];
            tet[step + 1] = vertex_id(corner[0], corner[1], corner[2]);
          }
          if (order >= 3) std::swap(tet[2], tet[3]);
          mesh.tets.insert(mesh.tets.end(), tet, tet + 4);
        }
  return mesh;
}

}  // namespace nexdyn

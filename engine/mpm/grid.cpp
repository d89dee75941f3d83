// The dense MPM grid (see grid.hpp).
#include "engine/mpm/grid.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

Eigen::Vector3d Grid::node_position(int64_t node) const {
  const int64_t i = node % nodes[0];
  const int64_t j = (node / nodes[0]) % nodes[1];
  const int64_t k = node / (int64_t{nodes[0]} * nodes[1]);
  return node_position(static_cast<int32_t>(i), static_cast<int32_t>(j), static_cast<int32_t>(k));
}

Grid grid_geometry(double grid_spacing, const Eigen::Vector3d& domain_min, const Eigen::Vector3d& domain_max) {
  Grid grid;
  grid.h = grid_spacing;
  grid.inv_h = 1.0 / grid_spacing;
  grid.origin = domain_min;
  for (int a = 0; a < 3; ++a) {
    // The relative slack keeps a domain that is a whole number of cells from gaining a node to
    // rounding of (max - min) / h.
    const double cells = std::ceil((domain_max[a] - domain_min[a]) / grid_spacing - 1e-9);
    grid.nodes[a] = static_cast<int32_t>(std::max(0.0, cells)) + 1;
  }
  return grid;
}

Grid make_grid(double grid_spacing, const Eigen::Vector3d& domain_min,
               const Eigen::Vector3d& domain_max) {
  Grid grid = grid_geometry(grid_spacing, domain_min, domain_max);
  const size_t n = static_cast<size_t>(grid.num_nodes());
  grid.mass.assign(n, 0.0);
  grid.momentum.assign(3 * n, 0.0);
  grid.velocity.assign(3 * n, 0.0);
  return grid;
}

}  // namespace nexdyn

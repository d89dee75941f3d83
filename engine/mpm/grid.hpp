// The background grid of MPM (issue 23; seed 002): nodes at domain_min + (i, j, k) h, quadratic
// B-spline weights w_ip and gradients grad w_ip of a particle over its 3x3x3 stencil, and the node
// storage the particle-to-grid transfer fills (engine/mpm/transfer.hpp).
//
// Quadratic B-spline (Steffen et al. 2008; Jiang et al. 2016, SIGGRAPH course "The material point
// method for simulating continuum materials", eq. 123), per axis with d = |x - x_i| / h:
//   N(d) = 3/4 - d^2 (d < 1/2),  1/2 (3/2 - d)^2 (1/2 <= d < 3/2),  0 otherwise;
// the weight of node i is the product over the axes. A particle's stencil starts at the node
// base = floor((x - domain_min) / h - 1/2); with f = (x - domain_min) / h - base in [1/2, 3/2) the
// three weights per axis are 1/2 (3/2 - f)^2, 3/4 - (f - 1)^2, 1/2 (f - 1/2)^2. They sum to 1,
// reproduce linear functions (sum_i w_ip x_i = x_p), and sum_i w_ip (x_i - x_p)(x_i - x_p)^T =
// h^2/4 I, the D_p of APIC (Jiang et al. 2015), whose inverse 4/h^2 the G2P transfer uses.
//
// Storage is dense: every node of the box [domain_min, domain_max] has a slot in each array,
// 32 bytes per node (mass 8, momentum 24) plus 24 for the velocity: 56 bytes per node. A 1 m^3
// domain at h = 1 cm is 1.03 M nodes, 58 MB. Dense arrays keep the node index arithmetic and make
// the coloured scatter trivially race-free; a sparse (block-hashed) grid is the way to larger
// domains and is left for when scenes need it.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace nexdyn {

struct Grid {
  double h = 0.0;                                        // grid spacing [m]
  double inv_h = 0.0;                                    // 1/h [1/m]
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();      // domain_min, the position of node 0 [m]
  std::array<int32_t, 3> nodes{0, 0, 0};                 // nodes per axis

  // ---- node arrays (num_nodes), written by particles_to_grid ------------------------------------
  std::vector<double> mass;      // (num_nodes) m_i = sum_p w_ip m_p [kg]
  std::vector<double> momentum;  // (num_nodes x 3) sum_p w_ip m_p (v_p + C_p (x_i - x_p)) [kg m/s]
  std::vector<double> velocity;  // (num_nodes x 3) momentum / mass where mass > 0, else 0 [m/s]

  int64_t num_nodes() const { return int64_t{nodes[0]} * nodes[1] * nodes[2]; }
  int64_t num_dofs() const { return 3 * num_nodes(); }
  // x-fastest node numbering.
  int64_t node_index(int32_t i, int32_t j, int32_t k) const {
    return i + int64_t{nodes[0]} * (j + int64_t{nodes[1]} * k);
  }
  Eigen::Vector3d node_position(int32_t i, int32_t j, int32_t k) const {
    return origin + h * Eigen::Vector3d(i, j, k);
  }
  Eigen::Vector3d node_position(int64_t node) const;
};

// A grid with spacing h whose nodes cover [domain_min, domain_max] (the last node per axis may lie
// up to h beyond domain_max), node arrays allocated and zero.
Grid make_grid(double grid_spacing, const Eigen::Vector3d& domain_min,
               const Eigen::Vector3d& domain_max);
// The same grid's geometry (spacing, origin, node counts) without its node arrays: for checks
// that need only the stencils.
Grid grid_geometry(double grid_spacing, const Eigen::Vector3d& domain_min, const Eigen::Vector3d& domain_max);

// The quadratic B-spline stencil of one particle: node base[a] + o (o = 0, 1, 2) on axis a has the
// 1D weight w[a][o] and derivative dw[a][o] (already divided by h, so in 1/m).
struct BSplineStencil {
  int32_t base[3];
  double w[3][3];
  double dw[3][3];

  // Weight and gradient of node (base + (a, b, c)).
  double weight(int a, int b, int c) const { return w[0][a] * w[1][b] * w[2][c]; }
  Eigen::Vector3d gradient(int a, int b, int c) const {
    return Eigen::Vector3d(dw[0][a] * w[1][b] * w[2][c], w[0][a] * dw[1][b] * w[2][c],
                           w[0][a] * w[1][b] * dw[2][c]);
  }
};

// The stencil of the particle at x (3 doubles). No bounds check: see stencil_inside.
inline BSplineStencil bspline_stencil(const Grid& grid, const double* x) {
  BSplineStencil s;
  for (int a = 0; a < 3; ++a) {
    const double u = (x[a] - grid.origin[a]) * grid.inv_h;
    const double b = std::floor(u - 0.5);
    const double f = u - b;  // in [1/2, 3/2)
    s.base[a] = static_cast<int32_t>(b);
    s.w[a][0] = 0.5 * (1.5 - f) * (1.5 - f);
    s.w[a][1] = 0.75 - (f - 1.0) * (f - 1.0);
    s.w[a][2] = 0.5 * (f - 0.5) * (f - 0.5);
    s.dw[a][0] = (f - 1.5) * grid.inv_h;
    s.dw[a][1] = -2.0 * (f - 1.0) * grid.inv_h;
    s.dw[a][2] = (f - 0.5) * grid.inv_h;
  }
  return s;
}

// True when all 27 nodes of the stencil are grid nodes (false for NaN positions too).
inline bool stencil_inside(const Grid& grid, const BSplineStencil& s) {
  for (int a = 0; a < 3; ++a)
    if (!(s.base[a] >= 0 && s.base[a] + 2 < grid.nodes[a])) return false;
  return true;
}

// Calls fn(node, o, weight, gradient) for the 27 nodes of a stencil in a fixed order (z slowest,
// x fastest), o = a + 3 b + 9 c the node's slot in the stencil.
template <typename Fn>
inline void for_each_stencil_node(const Grid& grid, const BSplineStencil& s, Fn&& fn) {
  for (int c = 0; c < 3; ++c)
    for (int b = 0; b < 3; ++b) {
      const int64_t row = grid.node_index(s.base[0], s.base[1] + b, s.base[2] + c);
      for (int a = 0; a < 3; ++a) fn(row + a, a + 3 * b + 9 * c, s.weight(a, b, c), s.gradient(a, b, c));
    }
}

}  // namespace nexdyn

// P2G and G2P transfers (see transfer.hpp).
#include "engine/mpm/transfer.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>  // cross

#include <algorithm>

namespace nexdyn {

int64_t bin_particles(const Grid& grid, const Particles& particles, ParticleBins& bins) {
  const int64_t n = particles.size();
  for (int a = 0; a < 3; ++a) bins.blocks[a] = (grid.nodes[a] + kMpmBlockCells - 1) / kMpmBlockCells;
  const int64_t num_blocks = bins.num_blocks();
  bins.block_of.resize(static_cast<size_t>(n));
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      const BSplineStencil s = bspline_stencil(grid, &particles.x[3 * p]);
      if (!stencil_inside(grid, s)) {
        bins.block_of[p] = -1;
        continue;
      }
      const int32_t bx = s.base[0] / kMpmBlockCells, by = s.base[1] / kMpmBlockCells,
                    bz = s.base[2] / kMpmBlockCells;
      bins.block_of[p] = bx + bins.blocks[0] * (by + bins.blocks[1] * bz);
    }
  }, 4096);

  // Counting sort, stable in particle id. Serial: a few ms at 1M particles, and it keeps the
  // order trivially independent of the thread count.
  bins.block_begin.assign(static_cast<size_t>(num_blocks + 1), 0);
  int64_t outside = 0;
  for (int64_t p = 0; p < n; ++p) {
    const int32_t b = bins.block_of[p];
    if (b < 0) ++outside;
    else ++bins.block_begin[b + 1];
  }
  for (int64_t b = 0; b < num_blocks; ++b) bins.block_begin[b + 1] += bins.block_begin[b];
  bins.order.resize(static_cast<size_t>(n - outside));
  {
    std::vector<int32_t> next(bins.block_begin.begin(), bins.block_begin.end() - 1);
    for (int64_t p = 0; p < n; ++p) {
      const int32_t b = bins.block_of[p];
      if (b >= 0) bins.order[next[b]++] = static_cast<int32_t>(p);
    }
  }
  for (auto& list : bins.colour_blocks) list.clear();
  for (int32_t bz = 0; bz < bins.blocks[2]; ++bz)
    for (int32_t by = 0; by < bins.blocks[1]; ++by)
      for (int32_t bx = 0; bx < bins.blocks[0]; ++bx) {
        const int32_t b = bx + bins.blocks[0] * (by + bins.blocks[1] * bz);
        if (bins.block_begin[b + 1] == bins.block_begin[b]) continue;
        bins.colour_blocks[(bx & 1) | ((by & 1) << 1) | ((bz & 1) << 2)].push_back(b);
      }
  return outside;
}

void particles_to_grid(const Particles& particles, const ParticleBins& bins, Grid& grid) {
  const int64_t num_nodes = grid.num_nodes();
  grid.mass.resize(static_cast<size_t>(num_nodes));
  grid.momentum.resize(static_cast<size_t>(3 * num_nodes));
  grid.velocity.resize(static_cast<size_t>(3 * num_nodes));
  parallel_for(num_nodes, [&](int64_t begin, int64_t end) {
    std::fill(grid.mass.begin() + begin, grid.mass.begin() + end, 0.0);
    std::fill(grid.momentum.begin() + 3 * begin, grid.momentum.begin() + 3 * end, 0.0);
  }, 16384);

  double* mass = grid.mass.data();
  double* momentum = grid.momentum.data();
  for_each_particle_coloured(bins, [&](int32_t p) {
    const double* xp = &particles.x[3 * p];
    const BSplineStencil s = bspline_stencil(grid, xp);
    const double m = particles.mass[p];
    const Eigen::Map<const Eigen::Matrix3d> C(&particles.C[9 * p]);
    const Eigen::Vector3d mv = m * Eigen::Map<const Eigen::Vector3d>(&particles.v[3 * p]);
    const Eigen::Matrix3d mC = m * C;
    // x_i - x_p = d0 + h (a, b, c) for node base + (a, b, c), so the APIC momentum
    // m (v + C (x_i - x_p)) is q0 + a hC_0 + b hC_1 + c hC_2: adds per node, no matrix products.
    const Eigen::Vector3d d0 = grid.node_position(s.base[0], s.base[1], s.base[2]) -
                               Eigen::Map<const Eigen::Vector3d>(xp);
    const Eigen::Vector3d q0 = mv + mC * d0;
    const Eigen::Matrix3d hC = grid.h * mC;
    for (int c = 0; c < 3; ++c)
      for (int b = 0; b < 3; ++b) {
        const int64_t row = grid.node_index(s.base[0], s.base[1] + b, s.base[2] + c);
        const double wbc = s.w[1][b] * s.w[2][c];
        const Eigen::Vector3d qbc = q0 + double(b) * hC.col(1) + double(c) * hC.col(2);
        for (int a = 0; a < 3; ++a) {
          const double w = s.w[0][a] * wbc;
          const Eigen::Vector3d q = w * (qbc + double(a) * hC.col(0));
          const int64_t node = row + a;
          mass[node] += w * m;
          momentum[3 * node + 0] += q[0];
          momentum[3 * node + 1] += q[1];
          momentum[3 * node + 2] += q[2];
        }
      }
  });

  parallel_for(num_nodes, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const double m = grid.mass[i];
      const double inv = m > 0.0 ? 1.0 / m : 0.0;
      for (int a = 0; a < 3; ++a) grid.velocity[3 * i + a] = grid.momentum[3 * i + a] * inv;
    }
  }, 16384);
}

void grid_to_particles(const Grid& grid, const double* grid_velocity, const double* grid_displacement,
                       Particles& particles) {
  const double d_inv = 4.0 * grid.inv_h * grid.inv_h;  // D_p^-1 of quadratic B-splines
  parallel_for(particles.size(), [&](int64_t begin, int64_t end) {
    for (int64_t p = begin; p < end; ++p) {
      double* xp = &particles.x[3 * p];
      const BSplineStencil s = bspline_stencil(grid, xp);
      const Eigen::Vector3d d0 = grid.node_position(s.base[0], s.base[1], s.base[2]) -
                                 Eigen::Map<const Eigen::Vector3d>(xp);
      // B = sum w v_i (x_i - x_p)^T = v d0^T + h [S_0 S_1 S_2] with S_k = sum w v_i o_k, o the
      // node's offset (a, b, c) in the stencil: no outer product per node.
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
      Eigen::Vector3d dx = Eigen::Vector3d::Zero();  // sum w u_i
      Eigen::Matrix3d G = Eigen::Matrix3d::Zero();   // sum u_i (grad w)^T
      for (int c = 0; c < 3; ++c)
        for (int b = 0; b < 3; ++b) {
          const int64_t row = grid.node_index(s.base[0], s.base[1] + b, s.base[2] + c);
          const double wbc = s.w[1][b] * s.w[2][c];
          const double dwb = s.dw[1][b] * s.w[2][c], dwc = s.w[1][b] * s.dw[2][c];
          Eigen::Vector3d v_row = Eigen::Vector3d::Zero(), s_row = Eigen::Vector3d::Zero();
          for (int a = 0; a < 3; ++a) {
            const int64_t node = row + a;
            const double w = s.w[0][a] * wbc;
            const Eigen::Vector3d wv = w * Eigen::Map<const Eigen::Vector3d>(&grid_velocity[3 * node]);
            v_row += wv;
            s_row += double(a) * wv;
            if (grid_displacement) {
              const Eigen::Vector3d ui = Eigen::Map<const Eigen::Vector3d>(&grid_displacement[3 * node]);
              dx += w * ui;
              G.col(0) += (s.dw[0][a] * wbc) * ui;
              G.col(1) += (s.w[0][a] * dwb) * ui;
              G.col(2) += (s.w[0][a] * dwc) * ui;
            }
          }
          v += v_row;
          S.col(0) += s_row;
          S.col(1) += double(b) * v_row;
          S.col(2) += double(c) * v_row;
        }
      const Eigen::Matrix3d B = v * d0.transpose() + grid.h * S;
      Eigen::Map<Eigen::Vector3d>(&particles.v[3 * p]) = v;
      Eigen::Map<Eigen::Matrix3d>(&particles.C[9 * p]) = d_inv * B;
      if (grid_displacement) {
        Eigen::Map<Eigen::Vector3d>(xp) += dx;
        Eigen::Map<Eigen::Matrix3d> F(&particles.F[9 * p]);
        F = (Eigen::Matrix3d::Identity() + G) * F.eval();
      }
    }
  });
}

double grid_total_mass(const Grid& grid) {
  double m = 0.0;
  for (double mi : grid.mass) m += mi;
  return m;
}

Eigen::Vector3d grid_total_momentum(const Grid& grid) {
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
  for (int64_t i = 0; i < grid.num_nodes(); ++i) q += Eigen::Map<const Eigen::Vector3d>(&grid.momentum[3 * i]);
  return q;
}

Eigen::Vector3d grid_total_angular_momentum(const Grid& grid) {
  Eigen::Vector3d L = Eigen::Vector3d::Zero();
  for (int64_t i = 0; i < grid.num_nodes(); ++i)
    if (grid.mass[i] > 0.0)
      L += grid.node_position(i).cross(Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(&grid.momentum[3 * i])));
  return L;
}

}  // namespace nexdyn

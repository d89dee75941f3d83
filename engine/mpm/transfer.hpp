// Particle-to-grid and grid-to-particle transfers of MLS/APIC MPM with quadratic B-splines
// (Jiang et al. 2015, "The affine particle-in-cell method"; Hu et al. 2018, "A moving least
// squares material point method"), deterministic on any number of threads.
//
//   P2G   m_i = sum_p w_ip m_p,   (m v)_i = sum_p w_ip m_p (v_p + C_p (x_i - x_p))
//   G2P   v_p = sum_i w_ip v_i,   C_p = 4/h^2 sum_i w_ip v_i (x_i - x_p)^T   (D_p^-1 = 4/h^2 I)
//         with the grid's step displacement u_i = x_i^{n+1} - x_i^n (seed 002):
//         x_p += sum_i w_ip u_i,  F_p <- (I + sum_i u_i (grad w_ip)^T) F_p
// (the weights at x_p^n). Moving the particle by the interpolated displacement is the same as
// x_p^{n+1} = sum_i w_ip x_i^{n+1}, by linear reproduction of the B-splines.
//
// Determinism without atomics on doubles: a particle writes only the 27 nodes of its stencil,
// which start at its base node. Particles are binned by the block of kMpmBlockCells^3 base nodes
// that holds their base node; a block's particles then touch nodes in a box of
// (kMpmBlockCells + 2)^3, which overlaps only the boxes of adjacent blocks. Blocks are coloured by
// the parity of their block coordinates (8 colours): two blocks of one colour are at least two
// blocks apart on some axis, so (with kMpmBlockCells >= 2) they never share a node. Colours run
// one after another, blocks of a colour in parallel, each block's particles in ascending id. So
// every node receives its contributions in the same order (colour, then particle id) whatever
// the thread count, and every sum is the same double.
#pragma once

#include "engine/mpm/grid.hpp"
#include "engine/mpm/particles.hpp"
#include "engine/parallel.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace nexdyn {

inline constexpr int32_t kMpmBlockCells = 4;  // base nodes per block per axis (>= 2, see above)
inline constexpr int kMpmColours = 8;

// Particles sorted into blocks; rebuilt whenever particles have moved (every step).
struct ParticleBins {
  std::array<int32_t, 3> blocks{0, 0, 0};             // blocks per axis
  std::vector<int32_t> block_of;                      // (num_particles) block id of each particle
  std::vector<int32_t> order;                         // (num_particles) particle ids, by block, ascending within
  std::vector<int32_t> block_begin;                   // (num_blocks + 1) offsets into order
  std::array<std::vector<int32_t>, kMpmColours> colour_blocks;  // non-empty blocks per colour, ascending

  int64_t num_blocks() const { return int64_t{blocks[0]} * blocks[1] * blocks[2]; }
};

// Bins the particles of `particles` on `grid`. Returns the number of particles whose stencil leaves
// the grid (or whose position is NaN); those are left out of the bins, and the caller must not run
// a transfer before dealing with them (0: all binned).
int64_t bin_particles(const Grid& grid, const Particles& particles, ParticleBins& bins);

// Calls fn(p) for every binned particle such that calls running at the same time never share a
// stencil node, and each node sees its particles in a fixed order (see the top of this file).
template <typename Fn>
void for_each_particle_coloured(const ParticleBins& bins, Fn&& fn) {
  for (int colour = 0; colour < kMpmColours; ++colour) {
    const std::vector<int32_t>& list = bins.colour_blocks[colour];
    parallel_for(
        static_cast<int64_t>(list.size()),
        [&](int64_t begin, int64_t end) {
          for (int64_t k = begin; k < end; ++k) {
            const int32_t block = list[k];
            for (int32_t q = bins.block_begin[block]; q < bins.block_begin[block + 1]; ++q) fn(bins.order[q]);
          }
        },
        1);
  }
}

// P2G: writes grid.mass, grid.momentum (every node: zero where no particle reaches) and
// grid.velocity = momentum / mass (0 where mass is 0).
void particles_to_grid(const Particles& particles, const ParticleBins& bins, Grid& grid);

// G2P: v_p and C_p from the node velocities grid_velocity (num_nodes x 3); when grid_displacement
// (num_nodes x 3, x_i^{n+1} - x_i^n) is given, also x_p and F_p as above. Runs over all particles,
// which must lie inside the grid (bin_particles returned 0).
void grid_to_particles(const Grid& grid, const double* grid_velocity, const double* grid_displacement,
                       Particles& particles);

// Totals on the grid: sum_i m_i, sum_i (m v)_i, and sum_i x_i x (m v)_i (about the origin).
double grid_total_mass(const Grid& grid);
Eigen::Vector3d grid_total_momentum(const Grid& grid);
Eigen::Vector3d grid_total_angular_momentum(const Grid& grid);

}  // namespace nexdyn

// Range drivers of tetrahedral elasticity: plain loops over tets [begin, end) of flat arrays, the
// hot path of every Newton iteration. The engine cuts the tets into fixed-size chunks, runs them on
// TBB workers and gathers the per-tet slabs in a fixed order (engine/potential/elastic_assembly.cpp), so the
// results do not depend on the thread count.
//
// Inside the loops: no allocation, no virtual call, no exception, one material (template
// argument, chosen by the caller or by the runtime-dispatch overloads below, outside the loop).
// Outputs are indexed by global tet id: energy[t], gradient + 12 t, hessian + 144 t.
//
// The loops run the element kernels (tet_kernels.hpp) on four tets per AVX2 instruction. Results
// equal the element functions of elasticity.hpp to rounding, and are bitwise independent of how
// [0, num_tets) is cut into ranges. The Hessian slab is written with streaming (non-temporal)
// stores when `hessian` is 16-byte aligned (std::vector<double> is); a 64-byte aligned buffer is
// slightly faster still. hessian_range ends with a store fence, so the slab is visible to
// whichever thread gathers it once the call has returned.
//
// Inverted neo-Hookean tets (J <= 0): energy_range returns +inf; gradient_range writes
// energy[t] = +inf and a NaN gradient; hessian_range writes a NaN gradient and Hessian. Both
// return the number of such tets in the range (0 for the other models), so a caller can check
// without scanning the slabs. The Newton solver should never see them: it evaluates derivatives
// only at states whose energy the line search found finite.
#pragma once

#include "kernels/elasticity/material.hpp"

#include <cstdint>

namespace nexdyn {

struct TetRange {
  const double* x;        // (num_vertices x 3) current positions [m]
  const int32_t* tets;    // (num_tets x 4) corner vertex ids, positively oriented at rest
  const double* Dm_inv;   // (num_tets x 9) inverse rest edge matrix, column-major [1/m]
  const double* volume;   // (num_tets) rest volume [m^3]
};

// The templates are defined and explicitly instantiated for every MaterialModel in
// elasticity_range.cpp, so including this header does not compile the kernels again.

// Sum of the tet energies in [begin, end), summed in tet order; +inf if a neo-Hookean tet is
// inverted.
template <MaterialModel M>
double energy_range(const TetRange& range, int64_t begin, int64_t end,
                    const LameParameters& lame);

// energy: (num_tets) per-tet energies; gradient: (num_tets x 12) per-tet gradients.
template <MaterialModel M>
int64_t gradient_range(const TetRange& range, int64_t begin, int64_t end,
                       const LameParameters& lame, double* energy, double* gradient);

// gradient: (num_tets x 12); hessian: (num_tets x 144) column-major 12x12, PSD-projected and
// exactly symmetric. The gradients equal gradient_range's up to rounding (last bits).
template <MaterialModel M>
int64_t hessian_range(const TetRange& range, int64_t begin, int64_t end,
                      const LameParameters& lame, double* gradient, double* hessian);

// Runtime dispatch: one switch per call, then the specialised loop.
double energy_range(MaterialModel model, const TetRange& range, int64_t begin, int64_t end,
                    const LameParameters& lame);
int64_t gradient_range(MaterialModel model, const TetRange& range, int64_t begin, int64_t end,
                       const LameParameters& lame, double* energy, double* gradient);
int64_t hessian_range(MaterialModel model, const TetRange& range, int64_t begin, int64_t end,
                      const LameParameters& lame, double* gradient, double* hessian);

}  // namespace nexdyn

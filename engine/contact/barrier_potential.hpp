// The IPC barrier potential of the whole scene: B(x) = sum over contact pairs k of b(d_k(x)),
// edge-edge terms multiplied by the parallel-edge mollifier (DESIGN.md section 5; seed 001).
//
// Distances are SQUARED, as in kernels/distance and kernels/barrier: dhat2 = dhat^2 and a pair is
// active when d_k < dhat2. The barrier stiffness kappa is applied by the caller.
//
// The pairs come from a candidate list (candidates.hpp) that the caller keeps valid for the
// positions it evaluates: after find_candidates(x0, x1) every x on the segment x0 -> x1 may be
// evaluated, because the list holds every pair that comes closer than dhat anywhere on it.
//
// Per Newton iteration, assemble() computes the active pairs at x with their local gradients and
// PSD-projected Hessians (parallel over pairs, one slab per pair, no sharing); the caller gathers
// them into the global system in pair order, so results do not depend on the number of threads.
// A pair's stencil is its 4 vertex ids (vertex-triangle: p, t0, t1, t2; edge-edge: ea0, ea1, eb0,
// eb1; vertex-plane: v, -1, -1, -1); Dirichlet-held vertices are written as -1 too, because
// their rows and columns are eliminated from the Newton system anyway.
#pragma once

#include "engine/contact/candidates.hpp"
#include "engine/model.hpp"

#include <cstdint>
#include <vector>

namespace nexdyn {

// Diagonal of the bounding box of the tet bodies' start positions (obstacles excluded): the
// length scale of dhat's default (1e-3 of it) and of the barrier stiffness heuristics.
double bodies_bbox_diagonal(const Model& model);

class BarrierPotential {
 public:
  // dhat: activation distance [m] (> 0).
  BarrierPotential(const Model& model, double dhat);

  double dhat() const { return dhat_; }

  // Candidates for the motion x0 -> x1 (x1 = nullptr: for x0 alone).
  void find_candidates(const double* x0, const double* x1);
  const ContactCandidates& candidates() const { return candidates_; }

  // sum_k b(d_k(x)) over the candidates; +inf when a pair touches or crosses (d <= 0) or a vertex
  // is on or behind an obstacle plane.
  double energy(const double* x) const;
  // Smallest squared distance over the candidates (squared signed distance for planes, 0 behind
  // one); +inf without candidates.
  double min_squared_distance(const double* x) const;

  // The contact columns of stats.csv at x, from a fresh candidate search (the candidate list the
  // solver uses is left alone): the barrier sum, the number of pairs closer than dhat, and the
  // exact smallest distance over all pairs and planes [m] (+inf when there are none). Pairs
  // farther than dhat are found by widening the search until the closest one is certain.
  struct Summary {
    double barrier = 0.0;
    int64_t active = 0;
    double min_distance = 0.0;
  };
  Summary summarize(const double* x) const;

  // Active pairs at x with the derivatives of weight * b: gradient (12 per pair) and, when
  // with_hessian, the PSD-projected Hessian (144 per pair, column-major 12x12, rows and columns
  // in stencil order).
  void assemble(const double* x, double weight, bool with_hessian);
  int64_t num_active() const { return static_cast<int64_t>(stencils_.size() / 4); }
  const std::vector<int32_t>& stencils() const { return stencils_; }  // (num_active x 4)
  const std::vector<double>& local_hessians() const { return hessians_; }
  // grad += the assembled gradient, in pair order.
  void add_gradient(double* grad) const;

  // Largest alpha in (0, 1] such that x + t alpha p keeps every pair apart for t in [0, 1]
  // (conservative CCD: it never overshoots a contact and stops short of touching). Recomputes
  // the candidates for the sweep x -> x + p, so afterwards any point on it may be evaluated.
  double max_step(const double* x, const double* p);

 private:
  const Model& model_;
  double dhat_ = 0.0, dhat2_ = 0.0;
  ContactCandidates candidates_;
  std::vector<double> x1_;  // (3n) end of the swept motion
  std::vector<uint8_t> candidate_active_;  // (candidates) workspace of assemble()
  // Active set of the last assemble().
  std::vector<uint8_t> active_kind_;     // 0 vertex-triangle, 1 edge-edge, 2 vertex-plane
  std::vector<int32_t> active_index_;    // index into the candidate list of that kind
  std::vector<int32_t> stencils_;        // (num_active x 4)
  std::vector<double> gradients_;        // (num_active x 12)
  std::vector<double> hessians_;         // (num_active x 144)
};

}  // namespace nexdyn

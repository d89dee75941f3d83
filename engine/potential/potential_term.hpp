// One term of the incremental potential (incremental_potential.hpp): inertia and gravity,
// elasticity, joints, the contact barrier, friction, kinematic targets, Rayleigh damping. The
// potential is the ordered list of its terms,
//   E(x) = sum over terms t of w_t e_t(x),
// where w_t is the weight of the term's class (TermScale): 1, the integrator's potential scale s,
// or its contact scale s_c (engine/step_context.hpp). The solver loops over the list; each term is
// called once per stage, never per element.
//
// Protocol of one step (solver/newton.cpp drives the per-solve part):
//   begin_step(x_tilde, ctx)      the attempt's predictor and weights
//   begin_solve(x)                once per Newton solve, at its start point
//   per iteration: prepare(x)     what the derivatives need at x (the contact active set)
//                  add_derivatives / add_diagonal
//                  sweep, group_max_steps, linked_max_steps (terms that bound the step: contact CCD)
//                  energy / add_group_energy at trial points
//                  end_iteration(x')        at the accepted point (adaptive stiffness)
//
// Hessians come in three kinds (TermHessian), merged by the potential in this order:
//   pattern_values  the term writes the values of the elastic pattern: elasticity first (which
//                   also carries the joints' constant coupling slabs), then Rayleigh damping,
//                   which adds its k D into the same values (engine/terms/damping_term.hpp);
//   stencil_slabs   the term keeps one dense slab per stencil (slabs()), merged into the contact
//                   pattern (sparse/contact_pattern.hpp);
//   diagonal        the term adds to the diagonal of the merged matrix (add_diagonal()).
#pragma once

#include "engine/active_subset.hpp"
#include "engine/sparse/hessian_pattern.hpp"
#include "engine/step_context.hpp"

#include <cstdint>
#include <functional>
#include <vector>

namespace nexdyn {

class ContactCandidates;

// What a term's energy is multiplied by in E.
enum class TermScale : uint8_t {
  one,        // 1: inertia and gravity, kinematic targets
  potential,  // s: elasticity, joints
  contact,    // s_c: the barrier and friction (impulsive: incremental_potential.hpp)
};

enum class TermHessian : uint8_t { pattern_values, stencil_slabs, diagonal };

// A stencil_slabs term's Hessian of the last add_derivatives: (num x 4) vertex ids (-1 = none),
// (num + 1) slab starts, and the column-major 3n x 3n slabs.
struct StencilSlabs {
  const std::vector<int32_t>* stencils = nullptr;
  const std::vector<int64_t>* slab_begin = nullptr;
  const double* slabs = nullptr;
};

// Where add_derivatives writes, for one Newton iteration.
struct DerivativeOutput {
  double* grad = nullptr;            // (3n) every term adds weight x its gradient
  double* pattern_values = nullptr;  // (elastic nnz) written by the pattern_values term
  const ActiveSubset* subset = nullptr;  // null: all vertices; else only these must be right
};

class PotentialTerm {
 public:
  virtual ~PotentialTerm() = default;
  virtual const char* name() const = 0;
  virtual TermScale scale() const = 0;
  virtual TermHessian hessian() const = 0;

  virtual void begin_step(const std::vector<double>& /*x_tilde*/, const StepContext& /*ctx*/) {}
  // preceding_gradient(g) adds to g the weighted gradient at x of the terms listed before this
  // one (the barrier balances its stiffness against them).
  virtual void begin_solve(const double* /*x*/, const std::function<void(double*)>& /*preceding_gradient*/) {}
  virtual void prepare(const double* /*x*/) {}

  // The term's energy e_t(x), unweighted; +inf where x is forbidden (an inverted tet, a touching
  // contact pair).
  virtual double energy(const double* x) const = 0;
  // out[g] (num_groups values) += e_t summed over the parts whose moving vertices are in group g
  // (group_of_vertex[v], -1 = does not move; parts with no moving vertex are left out).
  virtual void add_group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* out) = 0;
  // grad += weight x the gradient at x (all vertices).
  virtual void add_gradient(const double* x, double weight, double* grad) = 0;
  // grad += weight x the gradient, and weight x the Hessian into the term's kind of storage
  // (pattern values, or its own slabs), at least on out.subset.
  virtual void add_derivatives(const double* x, double weight, const DerivativeOutput& out) = 0;
  // diagonal terms: values[pattern.diagonal[i]] += weight x the Hessian's diagonal entry i.
  virtual void add_diagonal(const double* /*x*/, double /*weight*/, const CscPattern& /*pattern*/,
                            double* /*values*/, const ActiveSubset* /*subset*/) {}
  virtual StencilSlabs slabs() const { return {}; }
  // Stencils (num x 4) that couple vertices in the Hessian beyond the elastic pattern (null: none).
  virtual const std::vector<int32_t>* coupling_stencils() const { return nullptr; }

  // ---- terms that bound the step (contact): see BarrierPotential::sweep
  virtual void sweep(const double* /*x*/, const double* /*p*/, const uint8_t* /*moving*/, const double* /*pad*/) {}
  virtual void move_sweep_end(const double* /*x*/, const double* /*p*/) {}
  // The pairs of the last sweep (null: none).
  virtual const ContactCandidates* swept_pairs() const { return nullptr; }
  virtual void group_max_steps(const double* /*x*/, const int32_t* /*group_of_vertex*/, double* /*alpha*/) {}
  virtual void linked_max_steps(const double* /*x*/, const int32_t* /*group_of_vertex*/, int32_t /*num_groups*/,
                                   double* /*alpha*/) {}
  // Largest fraction of the step p from x that the term allows (1: any).
  virtual double max_step(const double* /*x*/, const double* /*p*/) { return 1.0; }

  // Stencils (num x 4) whose part of E changed outside Newton since the last solve began (a new
  // friction lag: its old and new contacts), or null; the next solve thaws their islands. The
  // call clears the report; the list stays valid until the term changes again.
  virtual const std::vector<int32_t>* take_changed_stencils() { return nullptr; }

  // At Newton's accepted point: returns the stencils whose energy changed (an adaptive stiffness
  // raised), or null when nothing changed.
  virtual const std::vector<int32_t>* end_iteration(const double* /*x*/) { return nullptr; }
};

}  // namespace nexdyn

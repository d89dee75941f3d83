// The incremental potential of one time step (DESIGN.md sections 4 and 5):
//   E(x) = w/2 (x - x_tilde)^T M (x - x_tilde)
//          + s (Psi_elastic(x) + Phi_joints(x) - sum_i m_i g . (x_i - x_tilde_i))
//          + s_c (kappa B(x) + D(x)) + Phi_kinematic(x) + s Phi_damping(x)
// with w = 1 for dynamic schemes and 0 for "static", s the integrator's potential scale,
// Phi_joints the augmented Lagrangian of the joints (engine/potential/joints.hpp, with its weight
// 1 / (gamma c_a) inside), kappa B the IPC barrier of contact (when the scene has contact) and D
// its lagged friction (engine/contact/friction_potential.hpp), both weighted by the contact
// scale s_c = r h^2 (IntegratorParams::contact_scale), and Phi_kinematic the augmented
// Lagrangian that moves the vertices of moving boundaries and obstacles in contact scenes
// (engine/potential/kinematic_targets.hpp), and Phi_damping = 1/(2k) v(x)^T D v(x) the Rayleigh
// damping of materials that damp (engine/terms/damping_term.hpp).
//
// Why a weight of their own: contact forces are impulsive. The trapezoidal rule (Newmark) would
// apply the barrier force found at the end of a step half in this step and half again in the
// next, through a_n; a barrier force is huge only in the last sliver of a step, so that second
// half pushes bodies that are already separating and injects energy (measured: +130% in a
// head-on collision; +58% to +90% for a torus thrown at a plate under generalized-alpha). Instead
// the contact force f_c = -kappa grad B acts as one impulse h f_c at the end of the step, which
// moves the position by s_c M^-1 f_c and never enters the acceleration carried to the next step
// (Simulation::update_with_contact; the weight r and the start-of-step "contact memory" that
// keeps resting contacts at rest are explained at IntegratorParams::contact_weight). Friction
// rides on the contact force and is treated alike. Joint forces are end-of-step impulses too
// (weight s / (gamma c_a), the one that makes v += h gamma abar_{n+1} give exactly h f):
// carried over by the trapezoidal rule, the force of a stiff constraint alternates from step to
// step and the alternation grows (measured on the double pendulum: the total energy went from
// 0.01% to 1e3% off in 70 steps). Gravity is measured from
// x_tilde (engine/terms/inertia_term.hpp).
//
// The potential is the ordered list of its terms (engine/potential/potential_term.hpp, one file each in
// engine/terms/): inertia and gravity, elasticity, joints, the barrier, friction, the kinematic
// targets and Rayleigh damping (added by Simulation when a material damps), each weighted by its
// class's weight (1, s or s_c). E, its gradient and its Hessian are
// sums over the list in list order; the Hessian is merged by kind (the elastic pattern's values,
// then the stencil slabs, then the diagonals).
//
// Newton (solver/newton.cpp) drives it through a fixed protocol per solve:
//   begin_solve(x0)                    contact candidates at x0, barrier stiffness of the step
//   per iteration: prepare(x)          active contact set and Newton pattern at x
//                  gradient_hessian(x) values in pattern() order
//                  max_step(x, p)      CCD bound on the step; candidates now cover x -> x + p
//                  energy(x + a p)     for any a in [0, max_step]
//                  end_iteration(x')   adaptive stiffness at the accepted point
#pragma once

#include "engine/contact/barrier_potential.hpp"
#include "engine/coordinate_map.hpp"
#include "engine/contact/friction_potential.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/joints.hpp"
#include "engine/potential/kinematic_targets.hpp"
#include "engine/model.hpp"
#include "engine/potential/potential_term.hpp"
#include "engine/sparse/contact_pattern.hpp"
#include "engine/step_context.hpp"
#include "engine/step_history.hpp"
#include "engine/step_profile.hpp"
#include "engine/terms/barrier_term.hpp"
#include "engine/terms/friction_term.hpp"

#include <memory>
#include <vector>

namespace nexdyn {

class IncrementalPotential {
 public:
  // The standard list: inertia and gravity, elasticity, then the joints and the barrier when
  // given (null: none in the scene). The joints' constant Hessian is in the elastic assembly's
  // coupling slabs (engine/potential/joints.hpp). The barrier stiffness and the contact pattern's pairs
  // live in `history`, which must outlive the potential.
  IncrementalPotential(const Model& model, ElasticAssembly& elastic, StepHistory& history,
                       BarrierPotential* contact = nullptr, const JointSet* joints = nullptr);
  // Appends lagged friction over the contacts (needs the barrier; null: frictionless).
  void set_friction(FrictionPotential* friction);
  // Appends the kinematic targets (engine/potential/kinematic_targets.hpp; null: none).
  void set_kinematic(const KinematicTargets* kinematic);
  // Appends any other term (after those above).
  void add_term(std::unique_ptr<PotentialTerm> term);
  const std::vector<std::unique_ptr<PotentialTerm>>& terms() const { return terms_; }

  // Fixes x_tilde and the attempt's weights (s, s_c, whether inertia is present) for the coming
  // solves, and brings the contact pattern to the history's pairs.
  void begin_step(const std::vector<double>& x_tilde, const StepContext& ctx);

  // Times elastic, barrier and friction assembly into `profile` (null: no timing).
  void set_profile(StepProfile* profile);

  void begin_solve(const double* x);
  // E split over groups of moving vertices: out[g] (num_groups values, overwritten) sums the terms
  // that touch group g's vertices (group_of_vertex[v], -1 = does not move); +inf when one of them
  // is. Terms that touch no moving vertex are left out: while only the groups move, they are
  // constant. Every term's moving vertices must share one group. The island solver's line search
  // tests each group on its own with it (solver/newton.cpp).
  void group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* out);
  // E(x); +inf when x inverts a tet whose material forbids it or touches in a contact pair.
  double energy(const double* x) const;
  void prepare(const double* x, bool first_iteration);
  // Gradient (3n) and Hessian values (pattern() order, mass on the diagonal) at x. With a subset
  // (the islands still being solved), only its vertices' entries and columns are right; the
  // others hold leftovers that the caller must not use.
  void gradient_hessian(const double* x, double* grad, double* hessian_values,
                        const ActiveSubset* subset = nullptr);
  // Gradient alone (3n, written), every vertex.
  void gradient(const double* x, double* grad);
  // Largest fraction of the step p from x that every term allows (1 without contact).
  double max_step(const double* x, const double* p);
  // max_step for groups of vertices (barrier_potential.hpp): sweep(x, p) finds the candidates of
  // x -> x + p, then group_max_steps lowers alpha[g] to each group's collision-free fraction
  // (the caller joins its groups over sweep_candidates() first), or linked_max_steps does so for
  // groups that pairs may link, each taking its own fraction where the links allow. With `pad`, the
  // pairs cover paths within pad[v] of the segment too, and move_sweep_end(x, p) has the next
  // group_max_steps check such a path x -> x + p over them, without searching again.
  void sweep(const double* x, const double* p, const uint8_t* moving = nullptr, const double* pad = nullptr);
  void move_sweep_end(const double* x, const double* p);
  const ContactCandidates* sweep_candidates() const;
  void group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha);
  void linked_max_steps(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* alpha);
  // The stencil lists (num x 4 vertex ids, -1 = none) that couple vertices in the Hessian beyond
  // the elastic pattern: the barrier's active set and the lagged friction contacts.
  // With affine bodies these are over nodes (engine/coordinate_map.hpp), valid until the next call.
  std::vector<const std::vector<int32_t>*> coupling_stencils();
  // Between the nodes Newton solves for and the vertices the terms see (identity without affine
  // bodies). The potential's gradients and Hessians are over nodes: the followers' parts are
  // folded onto their bodies' nodes, and the followers' entries are zero.
  const CoordinateMap& map() const { return map_; }

  // The stencil lists whose part of E changed outside Newton since the last call (a new friction
  // lag): the coming solve thaws their islands. Clears the terms' reports.
  const std::vector<const std::vector<int32_t>*>& take_changed_stencils();

  // At Newton's accepted point x: the stencil lists whose energy changed there (an adaptive
  // stiffness raised; empty: E did not change).
  const std::vector<const std::vector<int32_t>*>& end_iteration(const double* x);

  const CscPattern& pattern() const {
    return contact_pattern_ ? contact_pattern_->pattern() : static_cast<const CscPattern&>(elastic_.pattern());
  }
  int64_t pattern_version() const { return contact_pattern_ ? contact_pattern_->version() : 0; }
  // The tets' and joints' part of the pattern alone (constant for a run).
  const CscPattern& elastic_pattern() const { return elastic_.pattern(); }

  double barrier_stiffness() const { return history_.kappa; }
  BarrierTerm* barrier() const { return barrier_; }     // null without contact
  FrictionTerm* friction() const { return friction_; }  // null without friction
  // At the solution x of a step: the acceleration that the impulsive forces (contact
  // f_c = -kappa grad B, friction f_f = -grad D and the joint forces) put into a_{n+1} through
  // update_implicit, delta = (s_c / s) M^-1 f on free vertices (0 on held ones), which the step
  // takes out again (see the top of this file); and f_c and f_f themselves, held vertices
  // included, for the energy balance (contact_force(), friction_force(); empty without contact).
  void impulsive_forces(const double* x, std::vector<double>& delta);
  const std::vector<double>& contact_force() const { return contact_force_; }    // (3n) [N]
  const std::vector<double>& friction_force() const { return friction_force_; }  // (3n) [N], or empty
  const std::vector<double>& joint_force() const { return joint_force_; }        // (3n) [N], or empty

 private:
  double weight(const PotentialTerm& term) const;

  const Model& model_;
  CoordinateMap map_;
  ElasticAssembly& elastic_;
  StepHistory& history_;  // kappa
  std::vector<std::unique_ptr<PotentialTerm>> terms_;
  // The terms the step's impulse and friction lag need by name (owned by terms_).
  BarrierTerm* barrier_ = nullptr;
  FrictionTerm* friction_ = nullptr;
  BarrierPotential* contact_ = nullptr;
  FrictionPotential* friction_potential_ = nullptr;
  const JointSet* joints_ = nullptr;
  std::unique_ptr<ContactPattern> contact_pattern_;  // with a stencil_slabs term
  // The stencil_slabs terms' stencils as one list for the pattern, in list order (a copy per
  // iteration when more than one has stencils), and their slab arrays as pieces.
  std::vector<int32_t> stencils_;
  std::vector<int64_t> slab_begin_;
  std::vector<const double*> slab_pieces_;
  std::vector<int64_t> piece_begin_;
  // With affine bodies, per term: its stencils over nodes, its slabs mapped to them (J^T H J) and
  // its coupling stencils over nodes.
  std::vector<MappedStencils> mapped_;
  std::vector<std::vector<double>> mapped_slabs_;
  std::vector<std::vector<int32_t>> mapped_coupling_;
  std::vector<double> elastic_values_;  // elastic Hessian values before merging with contact
  std::vector<double> group_term_;      // (num_groups) workspace of group_energy
  // The answer of end_iteration or take_changed_stencils (each read at once by Newton).
  std::vector<const std::vector<int32_t>*> changed_;
  // (3n) outputs and workspaces of impulsive_forces
  std::vector<double> contact_force_, friction_force_, joint_force_, contact_gradient_, friction_gradient_,
      joint_gradient_;
  StepProfile* profile_ = nullptr;
  double scale_ = 1.0;          // s
  double contact_scale_ = 1.0;  // s_c
};

}  // namespace nexdyn

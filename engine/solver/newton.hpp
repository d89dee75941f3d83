// Projected Newton on the incremental potential with a CCD-capped backtracking (Armijo) line
// search (DESIGN.md section 5), solved island by island.
//
// Per iteration: gradient and PSD-projected Hessian (parallel, deterministic), Dirichlet DOFs
// eliminated (their rows and columns become identity, their gradient zero). The system then
// splits into islands (islands.hpp): groups of vertices that no tet, joint or contact couples to
// each other. Each island gets its own factorisation (island_system.hpp: dense, simplicial or
// supernodal CHOLMOD, its symbolic analysis kept while its pattern holds), its own direction
// p = -H^-1 g and its own convergence test: converged when max|p| / dt is below the tolerance.
// A converged island stops moving and is not factorised again while it stays the same island
// and the barrier stiffness does not change; the solve is over when every island has converged.
// Because the potential is a sum over islands, this is exactly Newton on the whole system with
// the converged parts frozen, and a body falling alone converges in one or two iterations even
// while a pile next to it needs thirty.
//
// The step length is capped per island: each takes the largest collision-free fraction of its
// own motion (one global cap would let the closest impact of the scene slow every body), and
// where a pair of the CCD sweep links two islands that take different fractions, the pair is
// checked again along the motion the two give together (a collision there gives both the
// smaller one). The sweep's pairs also join islands into groups, which might meet along the
// step: each group backtracks on its own along its islands' capped directions until its own
// part of the energy decreases enough (Armijo); where a full step fell by more than the
// quadratic model said (its curvature clamped by the projection), the step is tried longer
// (extend_step). Every trial point is intersection-free and its
// barrier is evaluated over the pairs close to the whole segment. A failure is returned as a
// StepStatus with a sentence saying why, never thrown (a matrix that is not positive definite, a
// CHOLMOD failure, a system too large for the solver's tables: island_system.hpp,
// cholmod_solver.hpp); the solver never accepts a step it could not finish.
#pragma once

#include "engine/potential/incremental_potential.hpp"
#include "engine/model.hpp"
#include "engine/sparse/island_system.hpp"
#include "engine/sparse/islands.hpp"
#include "engine/step_result.hpp"
#include "engine/step_profile.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace nexdyn {

struct NewtonSettings {
  double tolerance = 1e-5;  // [m/s] on max|p| / dt
  int max_iterations = 100;
  double dt = 0.01;         // [s] turns the increment into a velocity
  // Lagged quantities brought up to date inside the solve (the friction lag of converged
  // lagging): after an iteration whose increment is below relag_below [m/s], at most max_relags
  // times a solve, relag(x) re-lags at the accepted point and says whether the potential changed
  // (the islands of its changed stencils are then thawed). Without it, a caller that lags at each
  // solution re-solves from there, and each re-solve restarts Newton's convergence. A re-lag is
  // taken only while the solve has as many iterations left as the last lag took to converge
  // (the first: the iterations since the start): each re-lag restarts convergence, so lags
  // taken near the limit turned a solve that had converged under every lag into a failed one.
  std::function<bool(const double*)> relag;
  double relag_below = 0.0;
  int max_relags = 0;
  // [m] With affine bodies, how far off its chord a vertex's turned trial point may go and still
  // be covered by the iteration's one CCD sweep (its boxes are padded by up to this much,
  // build_groups); turns that go further are searched again (turned_point_valid). Ten dhat
  // from the simulation (engine/simulation_solve.cpp, kTurnReach); 0 without contact.
  double turn_reach = 0.0;
  // Full steps that the energy falls along faster than the quadratic model says are tried longer
  // (NewtonSolver::extend_step); the simulation turns it off where static friction is above
  // kinetic (engine/simulation_solve.cpp).
  bool extend_steps = true;
};

struct NewtonResult {
  StepStatus status = StepStatus::ok;
  int iterations = 0;        // linear solves
  int analyses = 0;          // symbolic factorisations of islands (pattern changes)
  double increment = 0.0;    // largest max|p| / dt of the last iteration's islands [m/s]
  std::string message;       // why it failed; empty when ok
};

// One Newton iteration as the solver saw it (NewtonSolver::set_history): what was solved, and per
// group of moving islands (numbered as the line search numbers them) the CCD cap on the step
// length (the smallest of its islands' caps), the slope g.p along the capped direction, the
// group's energy at the start and at the accepted point, and the accepted fraction of the capped
// step. The last iteration of a converged solve has no groups: every island was below the
// tolerance.
struct NewtonIterate {
  int32_t solved_islands = 0;  // factorised and solved this iteration
  int32_t moving_islands = 0;  // of those, not converged: they moved
  double increment = 0.0;      // largest max|p| / dt of the solved islands [m/s]
  std::vector<double> ccd_cap, slope, start_energy, accepted_energy, step_length;  // (groups)
  bool extended = false;       // the groups are those of a lengthened direction (extend_step),
  double full_step_decrease = 0.0;  // which then beat this decrease of the full steps' groups
  std::vector<double> x;       // the accepted point (3n), when asked for
};

class NewtonSolver {
 public:
  NewtonSolver(const Model& model, IncrementalPotential& potential);

  // Minimises the potential starting from x (Dirichlet DOFs already at their targets).
  // On success x is the minimiser; on failure x is the last accepted iterate.
  NewtonResult solve(std::vector<double>& x, const NewtonSettings& settings);

  // Times the linear solves and line searches into `profile` (may be null: no timing).
  void set_profile(StepProfile* profile) { profile_ = profile; }

  // Holds these vertices where they are in the coming solves (held = true), or releases them
  // again; for kinematic vertices once they are on their targets (engine/potential/kinematic_targets.hpp),
  // and for sleeping bodies. Vertices held `in_islands` stay in the islands they were solved in,
  // as rows of the identity: a kinematic boundary is pulled in one solve and held in the next,
  // and so both solve the same islands with the same factors (without it, each solve of the
  // 100x100 mat gave the other's 88 MB factor back and faulted a fresh one in).
  void hold(const std::vector<int32_t>& vertices, bool held, bool in_islands = false);

  // Re-solving after a change that touches only some vertices (a new friction lag): the next
  // solve keeps every island that converged in the last one frozen, except those thawed here
  // (the islands holding a vertex of these stencils, num x 4 vertex ids, -1 = none) and those
  // the potential's terms report changed (IncrementalPotential::take_changed_stencils).
  void thaw(const std::vector<int32_t>& stencils);
  void keep_converged_next_solve() { keep_converged_ = true; }

  // Appends every iteration of the coming solves to `history` (null: stop), with the accepted
  // points when `with_points`; for tests and for diagnosing a step that fails.
  void set_history(std::vector<NewtonIterate>* history, bool with_points = false) {
    history_ = history;
    history_points_ = with_points;
  }

  // The largest total memory of the cached islands' factors seen so far [bytes].
  double peak_factor_bytes() const { return peak_factor_bytes_; }

 private:
  void eliminate_dirichlet(double* grad, double* values) const;
  // The value indices of constrained rows and columns, from constrained_dof_.
  void collect_constrained_values();
  // potential_.prepare at x, for iteration `iteration`. The contact pattern refuses a system too
  // large for its 32-bit value tables by throwing std::length_error (contact_pattern.cpp); that
  // becomes a failed solve here (result filled in, false returned), since the solver never throws.
  bool prepare_potential(const double* x, int iteration, NewtonResult& result);
  // The cached system of island i (created on first sight; its pattern brought up to date).
  IslandSystem& island_system(int32_t i);
  // Factorises and solves the active islands: direction_ = H^-1 grad_ on their DOFs. Returns
  // the index in active_ of the first island that failed (active_status_ says how), or -1.
  int64_t solve_islands(int& analyses);
  // Forgets the systems of this solve whose islands are gone (solve_islands, each iteration).
  void forget_vanished_islands();
  // The stages of solve(), in order (each false/failing fills result's status and message):
  void forget_unused_systems();
  // Assembles the active islands at x and solves them into direction_ (= H^-1 g).
  bool solve_direction(const double* x, int it, NewtonResult& result);
  // direction_ = -H^-1 g; islands below the tolerance converge (p = 0); true when any moves.
  bool mark_moving_islands(const NewtonSettings& settings, NewtonResult& result);
  // Groups of moving islands linked by pairs of the CCD sweep of x -> x + p (padded by the affine
  // bodies' turns); returns their count.
  int32_t build_groups(const double* x);
  // Scales each moving island's direction to its collision-free fraction (settled over the pairs
  // that link islands of a group); the groups' slopes.
  bool cap_steps(const double* x, int32_t num_groups, NewtonResult& result);
  // Backtracking per group from x; the accepted point is left in trial_. With affine bodies the
  // trial points first turn them (CoordinateMap::turn), then, if that fails, go straight; a
  // group whose turned step was cut keeps the straight point where that is lower.
  bool line_search(const double* x, int32_t num_groups, NewtonResult& result);
  bool line_search_pass(const double* x, int32_t num_groups, bool turn, NewtonResult& result);
  // After the line search: the groups whose full, uncapped step decreased the energy by more than
  // the quadratic model predicted try a longer one (see the definition); trial_ and the groups'
  // numbers are then those of the longer steps if they decreased the energy more (extended_).
  void extend_step(const double* x, int32_t num_groups);
  // Whether group k's trial energy decreased enough (Armijo, with a round-off allowance).
  bool sufficient_decrease(int32_t k) const;
  // That allowance: the error of summing group k's energy at its start point.
  double energy_noise(int32_t k) const;
  // The turned trial point is collision-free from the straight one and, if its pairs had to be
  // searched again, every group still decreases with them (they then cover the accepted point).
  bool turned_point_valid(const double* x, int32_t num_groups);
  // Convergence bookkeeping: a converged island's vertices share a token (islands.hpp numbers
  // change from iteration to iteration; tokens say "this exact island converged").
  bool frozen(int32_t island) const;
  void mark_converged(int32_t island);
  // subset_ = the vertices of the active islands and the tets that touch them.
  void update_subset();

  const Model& model_;
  IncrementalPotential& potential_;
  StepProfile* profile_ = nullptr;
  std::vector<NewtonIterate>* history_ = nullptr;
  bool history_points_ = false;
  int64_t analyzed_version_ = -1;
  std::vector<uint8_t> constrained_dof_;      // (3n) 1 where a Dirichlet condition holds
  std::vector<uint8_t> held_in_islands_;      // (n) 1: held, yet kept in its island (hold())
  std::vector<int64_t> constrained_values_;   // value indices in a constrained row or column
  std::vector<double> grad_, direction_, values_, trial_;

  Islands islands_;
  // Island systems by a hash of their vertex list (collisions keep a short list), evicted when
  // unused for some solves (forget_unused_systems) or, if used in this solve, as soon as their
  // island is gone (forget_vanished_islands).
  std::unordered_map<uint64_t, std::vector<std::unique_ptr<IslandSystem>>> systems_;
  int64_t solve_count_ = 0;
  int64_t iteration_count_ = 0;  // Newton iterations over all solves
  bool keep_converged_ = false;
  double peak_factor_bytes_ = 0.0;
  std::vector<int32_t> active_;               // islands solved this iteration
  ActiveSubset subset_;                       // what gradient_hessian assembles
  std::vector<IslandSystem*> active_system_;  // (active_) their systems
  std::vector<StepStatus> active_status_;     // (active_) of the factorisation, then the solve
  std::vector<uint8_t> active_analyzed_;      // (active_) symbolic analysis redone
  std::vector<int64_t> run_alone_, run_parallel_;  // indices into active_, by how they may run
  std::vector<int32_t> vertex_token_;         // (num_vertices) 0 = not converged
  std::vector<int32_t> token_size_;           // (tokens) vertices of the island that converged
  DisjointSets groups_;                       // islands joined by the sweep's candidate pairs
  std::vector<uint8_t> island_moves_;         // (islands) has a direction this iteration
  std::vector<uint8_t> vertex_moves_;         // (num_vertices) in such an island
  std::vector<int32_t> group_of_island_;      // (islands) -1 = does not move
  std::vector<int32_t> group_of_vertex_;      // (num_vertices) -1 = does not move
  std::vector<int32_t> island_of_moving_vertex_;  // (num_vertices) its island if that moves, else -1
  std::vector<int32_t> unit_of_body_;         // (bodies) the CCD cap's unit: the body, or a jointed set's smallest
  std::vector<int32_t> unit_of_moving_vertex_;  // (num_vertices) its unit (or island) if it moves, else -1
  std::vector<double> unit_alpha_;            // (units) CCD cap of each unit
  std::vector<double> island_slope_;          // (islands) g . D p of the scaled direction
  // (groups) step length, slope g.p, energies at x and at the trial point, accepted
  std::vector<double> group_alpha_, group_slope_, group_start_, group_trial_;
  std::vector<uint8_t> group_done_;
  std::vector<int32_t> pending_group_of_vertex_;  // (num_vertices) line_search_pass: -1 once its group is done
  std::vector<double> pending_energy_;          // (groups) line_search_pass: the evaluated groups' energies
  std::vector<double> group_cap_;               // (groups) CCD cap, before the line search's halvings
  std::vector<double> group_extension_;         // (groups) extend_step's factor on the direction
  std::vector<double> group_reach_;             // (groups) the largest factor of its vertices so far
  std::vector<double> vertex_extension_;        // (num_vertices) extend_step's factors so far
  // extend_step's copy of the full steps' point and groups, restored when the longer steps lose
  std::vector<double> kept_direction_, kept_trial_, kept_cap_, kept_alpha_, kept_slope_, kept_start_,
      kept_accepted_;
  std::vector<int32_t> kept_group_of_vertex_;
  bool extended_ = false;                       // the last extend_step kept the longer steps,
  double full_step_decrease_ = 0.0;             // which beat this decrease of the full steps
  std::vector<double> straight_, turn_motion_;  // (3n) turned trial: the straight point, the turn
  std::vector<double> turn_pads_;               // (num_vertices) CoordinateMap::turn_pads, at most turn_reach_
  std::vector<uint8_t> turn_moves_;             // (num_vertices) turned beyond their pads
  std::vector<int32_t> turn_group_;             // (num_vertices) 0 where the turn moves, else -1
  bool turn_swept_ = false;                     // turned_point_valid searched the turn's pairs
  // line_search: the turned point and its groups' numbers, while the straight search is tried
  std::vector<double> turned_trial_, turned_alpha_, turned_energy_;
  std::vector<uint8_t> straight_kept_;          // (groups) the straight point was lower
  double turn_reach_ = 0.0;                     // NewtonSettings::turn_reach of the solve
  bool extend_steps_ = true;                    // NewtonSettings::extend_steps of the solve
};

}  // namespace nexdyn

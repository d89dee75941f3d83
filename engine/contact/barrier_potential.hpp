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
// Per Newton iteration the active set is built at x (build_active_set) and the derivatives are
// computed over it (compute_derivatives). The active set (active_set.hpp) is a list of stencils,
// one per closest feature rather than one per candidate pair: point-point and point-edge features
// shared by several pairs are merged into one stencil with an integer multiplicity, and the
// stencil's energy and derivatives are multiplicity x one evaluation. The derivatives of one
// stencil are kernels (kernels/barrier/barrier_stencils.hpp).
//
// A stencil's derivatives are stored at its real size n (1 vertex-plane, 2 point-point,
// 3 point-edge, 4 otherwise): a 3n gradient and a 3n x 3n PSD-projected Hessian slab. Both are
// computed in parallel, one slab per stencil, and the caller gathers them in stencil order, so
// results do not depend on the number of threads. stencils() lists each stencil's vertex ids
// padded to 4 (vertex-triangle: p, t0, t1, t2; edge-edge: ea0, ea1, eb0, eb1; point-edge: p,
// e0 < e1; point-point: a < b; vertex-plane: v); absent and eliminated held vertices are -1, the
// latter because their rows and columns are eliminated from the Newton system anyway.
//
// Files: barrier_potential.cpp (energies, summary, derivatives), contact_ccd.cpp (the swept
// search and the collision-free step), active_set.cpp (the pair cache and the stencils).
#pragma once

#include "engine/active_subset.hpp"
#include "engine/contact/active_set.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/model.hpp"
#include "engine/step_profile.hpp"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {

// Diagonal of the bounding box of the tet bodies' start positions (obstacles excluded): the
// length scale of dhat's default (1e-3 of it) and of the barrier stiffness heuristics.
double bodies_bbox_diagonal(const Model& model);

// grad += the per-stencil gradients (num x 12, padded to 4 vertices) at their stencils' vertices
// (num x 4, ids below num_vertices; -1 = absent or eliminated, skipped). Each vertex's entries
// are summed in stencil order on any number of threads (threads own ranges of vertices), so the
// sums do not depend on it. Shared by the barrier and friction potentials.
void add_stencil_gradients(const std::vector<int32_t>& stencils, const std::vector<double>& gradients,
                           int64_t num_vertices, double* grad);

class BarrierPotential {
 public:
  // Closest feature of a stencil; decides its size and derivative kernel.
  using StencilKind = ContactStencilKind;
  // Vertices n of a stencil: the slab is 3n x 3n.
  static int stencil_size(StencilKind kind) { return contact_stencil_size(kind); }

  // dhat: activation distance [m] (> 0).
  BarrierPotential(const Model& model, double dhat);

  double dhat() const { return dhat_; }
  // Times the solver's candidate searches (broad phase) and CCD into `profile` (null: no timing).
  void set_profile(StepProfile* profile) { profile_ = profile; }

  // Candidates for the motion x0 -> x1 (x1 = nullptr: for x0 alone), without the pairs of
  // sleeping bodies (set_asleep).
  void find_candidates(const double* x0, const double* x1);
  const ContactCandidates& candidates() const { return candidates_; }

  // The vertices of the sleeping bodies (ids; empty: none sleep). A pair none of whose vertices
  // is solved (free and awake, or driven by a moving boundary) has a constant energy and no
  // gradient on the solve's unknowns while they sleep: the searches leave it out, energy() adds
  // the energy it had, and so the pairs inside a sleeping pile cost the solve nothing (issue 40).
  // summarize() still measures every pair, and leaves them all in candidates().
  void set_asleep(const std::vector<int32_t>& vertices);

  // sum_k b(d_k(x)) over the candidates; +inf when a pair touches or crosses (d <= 0) or a vertex
  // is on or behind an obstacle plane.
  double energy(const double* x) const;
  // total[g] += the barrier sum over the candidates whose moving vertices are in group g
  // (group_of_vertex[v], -1 = does not move; pairs with no moving vertex are left out). A group
  // with a touching pair gets +inf.
  void group_energy(const double* x, const int32_t* group_of_vertex, double* total);
  // Smallest squared distance over the candidates (squared signed distance for planes, 0 behind
  // one); +inf without candidates. Exact below dhat^2; above it, a lower bound that is at least
  // dhat^2 (active_set.hpp), which is all the stiffness update and the contact test ask.
  double min_squared_distance(const double* x);

  // The contact columns of stats.csv at x: the barrier sum, the number of pairs closer than dhat,
  // and the exact smallest distance over all pairs and planes [m] (+inf when there are none).
  // The near pairs come from find_candidates(x, nullptr), which the list is left at: the solver's
  // next static search at the same x (the next step's first) is then free. Pairs farther than
  // dhat are found by widening the search until the closest one is certain.
  struct Summary {
    double barrier = 0.0;
    int64_t active = 0;
    double min_distance = 0.0;
  };
  Summary summarize(const double* x);

  // The active set at x: candidates closer than dhat, merged into stencils (see the top).
  void build_active_set(const double* x);
  // Derivatives of weight * b over the active set, at the x it was built at: gradient and, when
  // with_hessian, the PSD-projected Hessian slabs (column-major 3n x 3n, rows and columns in
  // stencil order, at slab_begin()[s]). With `active` (num_vertices flags), only the stencils
  // with an active vertex are computed; the others get a zero gradient and no Hessian slab.
  void compute_derivatives(const double* x, double weight, bool with_hessian,
                           const uint8_t* active = nullptr);
  void assemble(const double* x, double weight, bool with_hessian) {
    build_active_set(x);
    compute_derivatives(x, weight, with_hessian);
  }
  // sum over the active set of multiplicity x b: energy(x) again at the x of build_active_set,
  // computed per merged feature (a check of the merging).
  double active_set_energy(const double* x) const;
  // Candidate pairs closer than dhat (the sum of the multiplicities).
  int64_t num_active_pairs() const { return active_.num_active_pairs(); }
  int64_t num_stencils() const { return active_.num_stencils(); }
  const std::vector<int32_t>& stencils() const { return active_.stencils(); }            // (num_stencils x 4)
  const std::vector<StencilKind>& kinds() const { return active_.kinds(); }               // (num_stencils)
  // (num_stencils x 4) real vertex ids, held ones included; vertex-plane: v, plane index.
  const std::vector<int32_t>& stencil_vertices() const { return active_.vertices(); }
  const std::vector<int32_t>& multiplicities() const { return active_.multiplicities(); }  // (num_stencils)
  const std::vector<int64_t>& slab_begin() const { return active_.slab_begin(); }        // (num_stencils + 1)
  const std::vector<double>& local_hessians() const { return hessians_; }       // (slab_begin.back())
  // grad += the gradient of the last compute_derivatives(), in stencil order.
  void add_gradient(double* grad) const;
  // The same with the held vertices' entries too (the force on a moving boundary).
  void add_gradient_with_held(double* grad) const;

  // Largest alpha in (0, 1] such that x + t alpha p keeps every pair apart for t in [0, 1]
  // (conservative CCD: it never overshoots a contact and stops short of touching). Recomputes
  // the candidates for the sweep x -> x + p, so afterwards any point on it may be evaluated.
  double max_step(const double* x, const double* p);

  // max_step in two parts, for motions made of independent groups (the islands of the Newton
  // system, sparse/islands.hpp). sweep() recomputes the candidates for x -> x + p; then
  // group_max_steps() lowers alpha[g] to the largest collision-free fraction of group g's own
  // motion. group_of_vertex[v] is v's group (-1: v does not move), and every candidate pair's
  // moving vertices must share a group (join the groups over candidates() first). With a null
  // group_of_vertex all vertices form group 0.
  // With `moving` (num_vertices flags; p = 0 wherever it is 0), sweep() searches again only the
  // pairs with a moving vertex and keeps the other pairs of the last search, valid because their
  // vertices have not moved since. That makes it cost what the moving bodies cost. With `pad`
  // too (num_vertices, as find_contact_candidates'), the pairs also cover every path within
  // pad[v] of the segment. Such a search widens the affine bodies' moving vertices by a skin
  // (kSweepSkin dhat): a later masked sweep whose moving vertices all moved in it, and whose
  // paths (with their pads) stay within the skin of those segments, needs no search at all
  // (a Newton iteration of a few converging bodies; see covered_by_last_sweep).
  void sweep(const double* x, const double* p, const uint8_t* moving = nullptr, const double* pad = nullptr);
  void group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha);
  // group_max_steps() for groups that pairs may link (the islands of a Newton step): each group
  // is capped by its own pairs and by the pairs linking it to others (checked along the whole
  // motion); the groups then move by different fractions of their motions, and the linking pairs
  // are checked again along the motion those fractions give together. A pair that would come too
  // close lowers its groups to the smallest fraction among them, until no pair does (at worst,
  // every group of a linked set takes the set's smallest cap, as if they were one group).
  void linked_max_steps(const double* x, const int32_t* group_of_vertex, int32_t num_groups, double* alpha);
  // The next group_max_steps() checks the motion x -> x + p over the pairs of the last sweep,
  // without searching again: the caller promises that this path lies within that sweep's pads.
  void move_sweep_end(const double* x, const double* p);

 private:
  const Model& model_;
  double dhat_ = 0.0, dhat2_ = 0.0;
  StepProfile* profile_ = nullptr;
  ContactCandidates candidates_;
  bool static_search_ = false;     // candidates_ come from find_candidates(static_x_, nullptr)
  std::vector<double> static_x_;   // (3n)
  // set_asleep(): (num_vertices) 1 where a vertex is solved, empty when no body sleeps; whether
  // candidates_ went without the unsolved pairs, and the energy those pairs had there.
  std::vector<uint8_t> solved_;
  bool dropped_ = false;
  double dropped_energy_ = 0.0;
  // While bodies sleep, the searches of a step start from the last one: candidates_ hold every
  // pair within reach at cover_x_ (and maybe more, which costs nothing: a pair beyond dhat adds
  // 0), so a search at x needs to look again only at the vertices that moved from there.
  bool covers_ = false;
  std::vector<double> cover_x_;      // (3n)
  std::vector<uint8_t> moved_;       // (num_vertices) incremental_search's mask
  std::vector<double> no_motion_;    // (3n) zeros
  // The search for x -> x + p (p = nullptr: x alone) from the covered point; false when there is
  // none to start from (nothing searched, or a sleeper woke since).
  bool incremental_search(const double* x, const double* p);
  // The full search (every pair with a free vertex) into candidates_.
  void search_all(const double* x0, const double* x1);
  // Takes the pairs without a solved vertex out of candidates_ (they stand at x), their energy
  // into dropped_energy_.
  void drop_unsolved_pairs(const double* x);
  // Each candidate's distance and closest feature (cached while its vertices stay put), and the
  // stencils of the last build_active_set().
  ContactActiveSet active_;
  // Derivatives of the last compute_derivatives().
  std::vector<double> gradients_;  // (num_stencils x 12), the first 3n used
  std::vector<double> hessians_;   // (slab_begin().back())

  // sweep() and group_max_steps() (contact_ccd.cpp).
  std::vector<double> x1_;           // (3n) end of the swept motion
  ContactCandidates fresh_;          // pairs with a moving vertex, searched again
  std::vector<IndexPair> kept_;      // pairs of one list kept from the last search
  std::vector<int64_t> kept_index_;  // (kept_) their index in the old concatenated lists
  std::vector<IndexPair> redone_;     // pairs of one list with a moving vertex, searched again
  std::vector<int64_t> redone_index_; // (redone_) their index in the old concatenated lists
  std::vector<int64_t> origin_;      // (candidates) index in the old lists, -1 = fresh
  // (chunks of pairs) per chunk: the earliest impact of each run of one group (group_max_steps)
  std::vector<std::vector<std::pair<int32_t, double>>> run_minima_;
  // linked_max_steps(): the pairs linking groups (indices into the concatenated lists), per chunk
  // and all, each one's time of impact along the whole motion, whether the box or distance test
  // cleared it for any smaller fractions, the others and their groups, whether each of those
  // collides along the scaled motion, which groups the last round lowered, the fractions after a
  // round, the scaled ends (3n).
  std::vector<int64_t> links_;
  std::vector<std::vector<int64_t>> link_chunks_;
  std::vector<double> link_toi_;
  std::vector<uint8_t> link_cleared_;
  std::vector<int64_t> open_links_;
  std::vector<std::array<int32_t, 4>> open_groups_;
  std::vector<uint8_t> link_hits_, lowered_;
  std::vector<double> settled_, scaled_end_;
  // The last masked search's capsules, for sweeps that need none (sweep()): each vertex's swept
  // segment and radius (its pad plus the skin; -1: it did not move in that search, or is a tet
  // body's or held vertex, never covered; +inf: in no pair). Valid while skin_valid_: any other
  // search clears it.
  bool skin_valid_ = false;
  std::vector<double> skin_from_, skin_to_;         // (3n)
  std::vector<double> skin_radius_;                 // (num_vertices) [m]
  std::vector<double> skinned_pad_;                 // (num_vertices) workspace: pad + skin
  // Whether every moving vertex of the motion x -> x + p (within pad[v] of it) moved in the last
  // masked search and stays inside its capsule: the list then covers the motion already. (An
  // affine body's nodes are points of no pair: their radius is +inf and they never count.)
  bool covered_by_last_sweep(const double* x, const double* p, const uint8_t* moving, const double* pad) const;
  // group_max_steps' pass over the pairs of x -> x1_, lowering alpha; with set_links_aside, the
  // pairs linking groups are listed in links_ instead (linked_max_steps).
  void earliest_impacts(const double* x, const int32_t* group_of_vertex, double* alpha, bool set_links_aside);
  // The conservative CCD of candidate i (index into the concatenated lists) from x to y. With
  // `cleared`, whether the answer "no impact" came from the box or the distance test alone,
  // which then holds for every motion of each vertex along a part of its own (linked_max_steps).
  // cache_motion_ must be the active set's motion_since_cache(x).
  bool pair_ccd(int64_t i, const double* x, const double* y, double tmax, double& toi, bool* cleared = nullptr) const;
  std::vector<double> cache_motion_;  // (num_vertices) workspace: motion_since_cache at a CCD's or group energy's x
  // Per body, the largest motion since the cache (ContactActiveSet::body_motion_since_cache) and
  // the largest motion from x to x1_ of the vertices pairs are made of: set by earliest_impacts.
  std::vector<double> body_cache_motion_, body_reach_;  // (bodies) [m]
  // group_energy(): per body, the group its point vertices share, or kMixedGroups.
  static constexpr int32_t kMixedGroups = -2;
  std::vector<int32_t> body_group_;  // (bodies)
  // Whether candidate i certainly stays apart on the whole motion x -> x1_, from its bodies'
  // largest motions alone (earliest_impacts' first test, before the pair's vertices are read).
  bool bodies_stay_apart(int64_t i) const;
};

}  // namespace nexdyn

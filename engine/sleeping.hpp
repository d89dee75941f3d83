// Sleeping bodies: a body that has stayed still for a while stops being solved, as in Box2D,
// so that a pile at rest costs what its moving bodies cost (issue 19).
//
// The unit of sleep is a body, judged by the bodies it touches: those linked to it by contact
// candidates (pairs of surface primitives within dhat of each other) or joints. Static bodies
// (obstacle meshes, bodies whose every vertex is fixed) and planes link nothing, as the ground
// links nothing in Box2D.
//
//   at rest       after every step, an awake body whose every vertex moves slower than
//                 `velocity` and has drifted less than half the window's worth of it
//                 (0.5 * velocity * steps * dt) from where it was at the start of its current
//                 window of `steps` rest steps counts one more step at rest; any other body
//                 starts its count again from its current position.
//   ready         a body at rest for `steps` steps, or asleep.
//   falls asleep  a ready body every body it touches is ready too: velocities zero, positions,
//                 accelerations and contact memory frozen.
//   wakes         a sleeping body wakes when (a) after a step a body it touches moved (awake and
//                 not at rest this step, or driven), or (b) before a step, the motion at its
//                 velocity (x to x + dt v) of an awake body moving at least `velocity` brings one
//                 of its surface primitives within dhat of one of the sleeper's (the contact
//                 broad phase over those vertices). A body with a moving prescribed vertex never
//                 sleeps, and the bodies it touches stay awake.
//
// So a body still creeping in a pile at rest keeps awake the bodies it touches, not the pile
// (Box2D sleeps whole islands: one creeping body would keep a thousand awake). A woken body that
// does not move wakes no one; one that is pushed wakes its sleeping neighbours after the step, so
// a disturbance wakes a pile ring by ring as it spreads.
//
// A sleeping body's vertices are held where they are (NewtonSolver::hold), so they enter the
// step as fixed obstacles: CCD and the barrier still see them, and no step can end intersecting
// one. A body that hits a sleeping one where (b) did not foresee it (pushed off its path, or
// starting to fall from rest) meets it as a fixed obstacle for that one step, and wakes it for
// the next.
//
// The state (per body: steps at rest, sleeping group; per vertex: where the rest began) lives in
// StepHistory, so rollbacks and checkpoints carry it.
#pragma once

#include "engine/contact/candidates.hpp"
#include "engine/model.hpp"
#include "engine/state.hpp"
#include "engine/step_history.hpp"

#include <cstdint>
#include <utility>
#include <vector>

namespace nexdyn {

class SleepingBodies {
 public:
  // velocity > 0 [m/s]; dhat [m], the contact distance. Sizes the history's sleep fields when
  // they are empty (a fresh run).
  SleepingBodies(const Model& model, StepHistory& history, double velocity, int steps, double dhat);

  // After a restore: a history without sleep fields (written with sleeping off) starts with
  // every body awake and its rest beginning at state.x.
  void adopt(const State& state);

  // After a scripted change of velocities: wakes every sleeper that now has a vertex moving
  // (with the rest of its sleeping group, in an older build's checkpoint).
  void wake_moving(const State& state);
  // Before a step of length dt: wakes the sleepers a fast awake body's motion may reach.
  void wake_near_motion(const State& state, double dt);
  // After a step (with candidates: the contact candidates at state.x, within dhat): counts the
  // steps at rest, then puts ready bodies to sleep (their v = 0) and wakes the pushed ones.
  void update(State& state, const ContactCandidates& candidates, double dt);

  // Vertices of the sleeping bodies, ascending.
  std::vector<int32_t> sleeping_vertices() const;
  // (num_vertices) 1 where the vertex's body sleeps.
  bool vertex_asleep(int32_t v) const { return history_.sleep_group[model_.vertex_body[v]] >= 0; }
  int32_t num_sleeping() const;
  // Every body that could move sleeps (no awake free body, no driven one).
  bool all_asleep() const;

 private:
  enum class Kind : uint8_t { free, driven, fixed };  // may sleep; never sleeps; links nothing
  void wake(int32_t body, const State& state);
  // Wakes every body of the sleeping groups in `groups` (sorted here; repeats allowed).
  void wake_groups(std::vector<int32_t>& groups, const State& state);
  // The body's drift is measured from its positions in `state` from now on.
  void set_anchor(int32_t body, const State& state);
  void restart_rest(int32_t body, const State& state);

  const Model& model_;
  StepHistory& history_;
  double velocity_ = 0.0, dhat_ = 0.0;
  int steps_ = 0;
  std::vector<Kind> kind_;  // (bodies)
  // wake_near_motion's workspaces: the end of the awake bodies' motion (3n), the pairs it reaches.
  std::vector<double> end_;
  ContactCandidates reached_;
  std::vector<std::pair<int32_t, int32_t>> links_;  // update()'s workspace: (body, body it touches)
};

}  // namespace nexdyn

// The Newton solver's line search (see newton.hpp): per group of islands, backtracking from the
// CCD-capped step; with affine bodies, the turned trial point first, and the straight one if the
// turn fails or where it cut a group's step. The rest of the solve is in newton.cpp.
#include "engine/solver/newton.hpp"

#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace nexdyn {

namespace {
// Armijo sufficient-decrease constant and the smallest step length tried before giving up.
constexpr double kArmijo = 1e-4;
constexpr double kMinStepLength = 1e-10;
// extend_step: the longest multiple of a full step tried, and the rounds of lengthening.
constexpr double kMaxExtension = 8.0;
constexpr int kExtensionRounds = 3;
}  // namespace

bool NewtonSolver::line_search(const double* x, int32_t num_groups, NewtonResult& result) {
  if (model_.affine_bodies.empty()) return line_search_pass(x, num_groups, false, result);
  // Affine bodies turn along their step (CoordinateMap::turn): along the chord C + alpha D a body
  // turned by theta is stretched by theta^2 / 2, which the orthogonality potential charges
  // kappa V theta^4 and the quadratic model cannot see (its Hessian is flat along rotations), so
  // the search halved the steps of turning bodies over tens of iterations. If the turned point
  // fails (a turn into a contact, or no decrease once its pairs are known), the straight search.
  NewtonResult turned = result;
  turn_swept_ = false;
  if (!(line_search_pass(x, num_groups, true, turned) && turned_point_valid(x, num_groups))) {
    // The vertices whose turns were searched get the straight step's pairs again.
    if (turn_swept_) potential_.sweep(x, direction_.data(), turn_moves_.data(), turn_pads_.data());
    return line_search_pass(x, num_groups, false, result);
  }
  // A turn is second order off the chord, and can be worse than it: a tumbling box whose corner
  // is within dhat of the floor, its turn bringing the corner down where the chord does not, had
  // its turned steps cut to 2^-16 for 90 iterations running, while straight steps alone needed at
  // most 37 iterations in any step of that run. So where the turned search cut a group's step,
  // the straight search is tried too, and each such group keeps the lower of its two points (the
  // groups' energies are independent). Only when the turn stayed within the iteration's sweep
  // (!turn_swept_): both points are then covered by its pairs.
  bool cut = false;
  for (int32_t k = 0; k < num_groups; ++k) cut = cut || group_alpha_[k] < 1.0;
  if (!cut || turn_swept_) return true;
  turned_trial_ = trial_;
  turned_alpha_ = group_alpha_;
  turned_energy_ = group_trial_;
  NewtonResult straight = result;
  const bool straight_ok = line_search_pass(x, num_groups, false, straight);
  straight_kept_.assign(num_groups, 0);
  for (int32_t k = 0; k < num_groups; ++k) {
    straight_kept_[k] = straight_ok && turned_alpha_[k] < 1.0 && group_trial_[k] < turned_energy_[k];
    if (!straight_kept_[k]) group_alpha_[k] = turned_alpha_[k], group_trial_[k] = turned_energy_[k];
  }
  const int64_t n = model_.num_dofs();
  parallel_for(n, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const int32_t g = group_of_vertex_[i / 3];
      if (g >= 0 && !straight_kept_[g]) trial_[i] = turned_trial_[i];
    }
  }, 8192);
  return true;
}

bool NewtonSolver::turned_point_valid(const double* x, int32_t num_groups) {
  // The turned trial is off the swept segment x -> x + alpha p by the turn's motion (second order
  // in alpha theta). Where that motion is within a vertex's pad, build_groups' sweep covers it;
  // the vertices it takes further (a turn beyond the reach) have their pairs searched again along
  // the turn from the straight point, and then the line search's energies, which missed those
  // pairs, are taken again. Either way a CCD over the turn tells whether the trial is reached
  // without crossing a contact.
  if (!potential_.sweep_candidates()) return true;  // no contact
  const int64_t n = model_.num_dofs();
  straight_.resize(n);
  turn_motion_.resize(n);
  for (int64_t i = 0; i < n; ++i) {
    const int32_t g = group_of_vertex_[i / 3];
    straight_[i] = g < 0 ? x[i] : x[i] + group_alpha_[g] * direction_[i];
    turn_motion_[i] = trial_[i] - straight_[i];
  }
  // The vertices the turn moves (group 0 of the CCD below: the pairs without one stay where they
  // are, apart, and need no CCD), and those it takes beyond their pads.
  turn_moves_.assign(model_.num_vertices, 0);
  turn_group_.assign(model_.num_vertices, -1);
  bool any = false;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const Eigen::Vector3d off = Eigen::Vector3d::Map(&turn_motion_[3 * int64_t{v}]);
    if (off.isZero(0.0)) continue;
    any = true;
    turn_group_[v] = 0;
    if (model_.axis_node(v)) continue;  // a column of A: no point, in no contact pair
    if (off.norm() > turn_pads_[v]) turn_moves_[v] = 1, turn_swept_ = true;
  }
  if (!any) return true;
  if (turn_swept_)  // (the others move too, within their pads: their kept pairs cover them)
    potential_.sweep(straight_.data(), turn_motion_.data(), turn_moves_.data());
  else
    potential_.move_sweep_end(straight_.data(), turn_motion_.data());
  double alpha = 1.0;
  potential_.group_max_steps(straight_.data(), turn_group_.data(), &alpha);
  if (alpha < 1.0) return false;
  if (!turn_swept_) return true;
  potential_.group_energy(trial_.data(), group_of_vertex_.data(), num_groups, group_trial_.data());
  for (int32_t k = 0; k < num_groups; ++k)
    if (!sufficient_decrease(k)) return false;
  return true;
}

double NewtonSolver::energy_noise(int32_t k) const { return 1e-13 * std::max(1.0, std::abs(group_start_[k])); }

bool NewtonSolver::sufficient_decrease(int32_t k) const {
  return group_trial_[k] <= group_start_[k] + kArmijo * group_alpha_[k] * group_slope_[k] + energy_noise(k);
}

bool NewtonSolver::line_search_pass(const double* x, int32_t num_groups, bool turn, NewtonResult& result) {
  // Backtracking, group by group: the energy is a sum over groups plus terms that do not move, so
  // each group halves its own step until its own part of E decreases enough. Energies are
  // compared with a round-off allowance: near the minimum the decrease s*alpha*g.p can be smaller
  // than the error of summing E itself. The accepted point is left in trial_; with `turn` the
  // affine bodies' trial points are turned (line_search).
  ProfileScope scope(profile_, StepPhase::line_search);
  const int64_t n = model_.num_dofs();
  group_start_.resize(num_groups);
  group_trial_.resize(num_groups);
  pending_energy_.resize(num_groups);
  potential_.group_energy(x, group_of_vertex_.data(), num_groups, group_start_.data());
  std::fill(group_alpha_.begin(), group_alpha_.end(), 1.0);
  group_done_.assign(num_groups, 0);
  int32_t pending = num_groups;
  // After the first trial, only the groups still searching are evaluated: the others' vertices
  // are taken out of the groups (-1) in pending_group_of_vertex_. Every term sums a group's part
  // in runs of consecutive items of that group, which stay the same runs, so a group's energy
  // comes out bit for bit as when all are evaluated.
  const int32_t* evaluated = group_of_vertex_.data();
  while (pending > 0) {
    stop_point();
    parallel_for(n, [&](int64_t begin, int64_t end) {
      for (int64_t i = begin; i < end; ++i) {
        const int32_t g = group_of_vertex_[i / 3];
        trial_[i] = g < 0 ? x[i] : x[i] + group_alpha_[g] * direction_[i];
      }
    }, 8192);
    if (turn) potential_.map().turn(x, direction_.data(), group_of_vertex_.data(), group_alpha_.data(), trial_.data());
    potential_.group_energy(trial_.data(), evaluated, num_groups, pending_energy_.data());
    const int32_t pending_before = pending;
    for (int32_t k = 0; k < num_groups; ++k) {
      if (group_done_[k]) continue;
      group_trial_[k] = pending_energy_[k];
      if (sufficient_decrease(k)) {
        group_done_[k] = 1;
        --pending;
        continue;
      }
      group_alpha_[k] *= 0.5;
      if (group_alpha_[k] < kMinStepLength) {
        result.status = StepStatus::line_search_failed;
        char message[160];
        std::snprintf(message, sizeof(message),
                      "line search found no decrease along the Newton direction (increment %.3g m/s, energy %.6g)",
                      result.increment, group_start_[k]);
        result.message = message;
        return false;
      }
    }
    if (pending == pending_before || pending == 0) continue;
    pending_group_of_vertex_.resize(group_of_vertex_.size());
    for (size_t v = 0; v < group_of_vertex_.size(); ++v) {
      const int32_t g = group_of_vertex_[v];
      pending_group_of_vertex_[v] = g >= 0 && !group_done_[g] ? g : -1;
    }
    evaluated = pending_group_of_vertex_.data();
  }
  return true;
}

void NewtonSolver::extend_step(const double* x, int32_t num_groups) {
  // Where the PSD projection of a Hessian clamped negative curvature (a contact's, a compressed
  // tet's), the model is stiffer along p than the energy: the full step p = -H^-1 g falls short,
  // and the energy drops by more than the model's -g.p / 2, up to -g.p where it is linear along
  // p. Left alone, such iterations creep on at a linear rate: the last moving bodies of a landing
  // pile took 10-20 of them a step (docs/performance.md). Along a group's direction d, with slope
  // s = g.d < 0 and decrease D = E(x) - E(x + d), the parabola through E(x), s and E(x + d) is
  // least at s / (2 (D + s)) times d when D < -s (1 / (2 - rho) for a Newton direction whose
  // decrease is rho times the model's), and falls without end when D >= -s (8x is then taken).
  // Each group whose full, uncapped step (its slope above the energy's round-off) puts that
  // least point at 2 or beyond has its direction lengthened to there, at most 8x in all, and the
  // direction is swept, capped and searched from x like any other; kept if the moving groups'
  // energy fell by more in all than before, and then tried again (at most three rounds).
  extended_ = false;
  if (!extend_steps_) return;
  for (int round = 0; round < kExtensionRounds; ++round) {
    group_extension_.assign(num_groups, 1.0);
    group_reach_.assign(num_groups, 1.0);
    if (round > 0)  // (vertex_extension_ is filled by the first round that lengthens)
      for (int32_t v = 0; v < model_.num_vertices; ++v)
        if (group_of_vertex_[v] >= 0)
          group_reach_[group_of_vertex_[v]] = std::max(group_reach_[group_of_vertex_[v]], vertex_extension_[v]);
    bool any = false;
    double decrease_before = 0.0;
    for (int32_t k = 0; k < num_groups; ++k) {
      const double decrease = group_start_[k] - group_trial_[k];
      decrease_before += decrease;
      if (group_cap_[k] < 1.0 || group_alpha_[k] < 1.0) continue;
      const double slope = group_slope_[k];
      if (-slope <= energy_noise(k)) continue;  // the decrease is round-off: no curvature to read
      const double limit = kMaxExtension / group_reach_[k];
      const double least = decrease + slope < 0.0 ? slope / (2.0 * (decrease + slope)) : limit;
      if (!(least >= 2.0) || limit < 2.0) continue;
      group_extension_[k] = std::min(least, limit);
      any = true;
    }
    if (!any) return;
    kept_direction_ = direction_;
    kept_trial_.resize(trial_.size());
    kept_trial_.swap(trial_);
    kept_cap_ = group_cap_;
    kept_alpha_ = group_alpha_;
    kept_slope_ = group_slope_;
    kept_start_ = group_start_;
    kept_accepted_ = group_trial_;
    kept_group_of_vertex_ = group_of_vertex_;
    const int64_t n = model_.num_dofs();
    for (int64_t i = 0; i < n; ++i) {
      const int32_t g = group_of_vertex_[i / 3];
      if (g >= 0) direction_[i] *= group_extension_[g];
    }
    if (round == 0) vertex_extension_.assign(model_.num_vertices, 1.0);
    for (int32_t v = 0; v < model_.num_vertices; ++v)
      if (group_of_vertex_[v] >= 0) vertex_extension_[v] *= group_extension_[group_of_vertex_[v]];
    NewtonResult scratch;  // a cap or search that fails here leaves the steps before, not a failure
    const int32_t groups = build_groups(x);
    bool longer = cap_steps(x, groups, scratch);
    if (longer) {
      group_cap_.assign(group_alpha_.begin(), group_alpha_.end());
      longer = line_search(x, groups, scratch);
    }
    double decrease = 0.0;
    if (longer) {
      for (int32_t k = 0; k < groups; ++k) decrease += group_start_[k] - group_trial_[k];
      longer = decrease > decrease_before;
    }
    if (longer) {
      if (!extended_) full_step_decrease_ = decrease_before;
      extended_ = true;
      num_groups = groups;
      continue;
    }
    // The steps before, searched again: the contact candidates and turn searches are then those
    // of the accepted point (the longer direction's need not cover its turned trial point). The
    // searches succeeded once; should one fail now, their numbers are put back as they were.
    direction_.swap(kept_direction_);
    const int32_t regrouped = build_groups(x);
    if (cap_steps(x, regrouped, scratch)) {
      group_cap_.assign(group_alpha_.begin(), group_alpha_.end());
      if (line_search(x, regrouped, scratch)) return;
    }
    trial_.swap(kept_trial_);
    group_cap_.swap(kept_cap_);
    group_alpha_.swap(kept_alpha_);
    group_slope_.swap(kept_slope_);
    group_start_.swap(kept_start_);
    group_trial_.swap(kept_accepted_);
    group_of_vertex_.swap(kept_group_of_vertex_);
    return;
  }
}

}  // namespace nexdyn

// Sleeping bodies (see sleeping.hpp).
#include "engine/sleeping.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <utility>

namespace nexdyn {

SleepingBodies::SleepingBodies(const Model& model, StepHistory& history, double velocity, int steps,
                               double dhat)
    : model_(model), history_(history), velocity_(velocity), dhat_(dhat), steps_(steps) {
  const int32_t num_bodies = static_cast<int32_t>(model.bodies.size());
  kind_.assign(num_bodies, Kind::fixed);
  for (int32_t b = 0; b < num_bodies; ++b) {
    const BodyRange& body = model.bodies[b];
    bool all_held = true, driven = false;
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
      const int32_t id = model.dirichlet[v];
      all_held = all_held && id >= 0;
      driven = driven || (id >= 0 && model.dirichlet_motions[id].moves());
    }
    kind_[b] = driven ? Kind::driven : all_held ? Kind::fixed : Kind::free;
  }
  if (history_.sleep_group.empty()) {
    history_.rest_steps.assign(num_bodies, 0);
    history_.sleep_group.assign(num_bodies, -1);
    history_.rest_anchor = model.rest_positions;
  }
}

void SleepingBodies::adopt(const State& state) {
  if (!history_.sleep_group.empty()) return;
  history_.rest_steps.assign(kind_.size(), 0);
  history_.sleep_group.assign(kind_.size(), -1);
  history_.rest_anchor = state.x;
}

void SleepingBodies::set_anchor(int32_t body, const State& state) {
  const BodyRange& r = model_.bodies[body];
  std::copy_n(state.x.begin() + 3 * int64_t{r.vertex_begin}, 3 * int64_t{r.vertex_count},
              history_.rest_anchor.begin() + 3 * int64_t{r.vertex_begin});
}

void SleepingBodies::restart_rest(int32_t body, const State& state) {
  history_.rest_steps[body] = 0;
  set_anchor(body, state);
}

void SleepingBodies::wake(int32_t body, const State& state) {
  history_.sleep_group[body] = -1;
  restart_rest(body, state);
}

void SleepingBodies::wake_moving(const State& state) {
  const std::vector<int32_t>& group = history_.sleep_group;
  std::vector<int32_t> woken;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t g = group[model_.vertex_body[v]];
    const double* velocity = &state.v[3 * int64_t{v}];
    if (g >= 0 && (velocity[0] != 0.0 || velocity[1] != 0.0 || velocity[2] != 0.0)) woken.push_back(g);
  }
  wake_groups(woken, state);
}

void SleepingBodies::wake_groups(std::vector<int32_t>& groups, const State& state) {
  if (groups.empty()) return;
  std::sort(groups.begin(), groups.end());
  const std::vector<int32_t>& group = history_.sleep_group;
  for (int32_t b = 0; b < static_cast<int32_t>(kind_.size()); ++b)
    if (group[b] >= 0 && std::binary_search(groups.begin(), groups.end(), group[b])) wake(b, state);
}

void SleepingBodies::wake_near_motion(const State& state, double dt) {
  std::vector<int32_t>& group = history_.sleep_group;
  if (std::none_of(group.begin(), group.end(), [](int32_t g) { return g >= 0; })) return;
  // The pairs that the awake bodies' motion x -> x + dt v brings within dhat: the broad phase
  // of the moving vertices only, so this costs what the awake bodies cost.
  // Bodies slower than the rest speed are left out: they rest against their sleeping neighbours
  // (within dhat of them), and what they move in a step the barrier holds off; should they speed
  // up, update() wakes their neighbours after the step.
  const double speed2 = velocity_ * velocity_;
  std::vector<uint8_t> fast(kind_.size(), 0);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t b = model_.vertex_body[v];
    if (kind_[b] == Kind::fixed || group[b] >= 0 || fast[b] || model_.axis_node(v)) continue;
    fast[b] = kind_[b] == Kind::driven || Eigen::Vector3d::Map(&state.v[3 * int64_t{v}]).squaredNorm() >= speed2;
  }
  std::vector<uint8_t> awake(model_.num_vertices, 0);
  std::vector<double>& end = end_;
  end = state.x;
  bool any_awake = false;
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t b = model_.vertex_body[v];
    if (!fast[b] || model_.eliminated(v)) continue;
    awake[v] = 1;
    any_awake = true;
    for (int d = 0; d < 3; ++d) end[3 * int64_t{v} + d] += dt * state.v[3 * int64_t{v} + d];
  }
  if (!any_awake) return;
  find_contact_candidates(model_, state.x.data(), end.data(), 0.5 * dhat_, reached_, awake.data());
  std::vector<int32_t> woken;  // sleeping groups a moving vertex comes near
  auto reach = [&](const PairVertices& vertices) {
    bool moving = false;
    for (int32_t v : vertices) moving = moving || awake[v];
    if (!moving) return;
    for (int32_t v : vertices)
      if (const int32_t g = group[model_.vertex_body[v]]; g >= 0) woken.push_back(g);
  };
  // A vertex-plane pair reaches no body.
  for (const IndexPair& pr : reached_.vertex_triangle) reach(vertex_triangle_vertices(model_, pr));
  for (const IndexPair& pr : reached_.edge_edge) reach(edge_edge_vertices(model_, pr));
  // A woken body does not move yet (v = 0), so it wakes no one else this step.
  wake_groups(woken, state);
}

void SleepingBodies::update(State& state, const ContactCandidates& candidates, double dt) {
  const int32_t num_bodies = static_cast<int32_t>(kind_.size());
  std::vector<int32_t>& rest = history_.rest_steps;
  std::vector<int32_t>& group = history_.sleep_group;
  // Steps at rest of the awake free bodies: every vertex slow, and not drifting away.
  const double speed2 = velocity_ * velocity_;
  const double drift = 0.5 * velocity_ * steps_ * dt;
  std::vector<uint8_t> still(num_bodies, 1);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t b = model_.vertex_body[v];
    if (kind_[b] != Kind::free || group[b] >= 0 || !still[b]) continue;
    if (model_.axis_node(v)) continue;  // an affine body's rotation shows in its followers' speeds
    const Eigen::Vector3d x = Eigen::Vector3d::Map(&state.x[3 * int64_t{v}]);
    const Eigen::Vector3d anchor = Eigen::Vector3d::Map(&history_.rest_anchor[3 * int64_t{v}]);
    still[b] = Eigen::Vector3d::Map(&state.v[3 * int64_t{v}]).squaredNorm() < speed2 &&
               (x - anchor).cwiseAbs().maxCoeff() < drift;
  }
  for (int32_t b = 0; b < num_bodies; ++b) {
    if (kind_[b] != Kind::free || group[b] >= 0) continue;
    if (!still[b]) {
      restart_rest(b, state);
      continue;
    }
    // The drift is measured over windows of `steps` steps: a body resting for long while its
    // group waits for another one is not failed by the sum of its windows' jitter.
    if (++rest[b] % steps_ == 0) set_anchor(b, state);
  }
  // The bodies each body touches (contact candidates, joints), over the free and driven bodies.
  std::vector<std::pair<int32_t, int32_t>>& links = links_;
  links.clear();
  auto link = [&](int32_t u, int32_t w) {
    const int32_t a = model_.vertex_body[u], b = model_.vertex_body[w];
    if (a == b || kind_[a] == Kind::fixed || kind_[b] == Kind::fixed) return;
    links.emplace_back(a, b);
    links.emplace_back(b, a);
  };
  for (const IndexPair& pr : candidates.vertex_triangle) {
    const PairVertices v = vertex_triangle_vertices(model_, pr);
    link(v[0], v[1]);  // the vertex's body and the triangle's
  }
  for (const IndexPair& pr : candidates.edge_edge) {
    const PairVertices v = edge_edge_vertices(model_, pr);
    link(v[0], v[2]);  // the two edges' bodies
  }
  for (const Joint& joint : model_.joints)
    for (int k = 1; k < joint.count; ++k) link(joint.vertex[0], joint.vertex[k]);
  // Ready: at rest for the whole window, or asleep. Moving: awake and not still this step, or
  // driven. Both are read before anything changes, so the decisions do not depend on body order.
  std::vector<uint8_t> ready(num_bodies, 0), moving(num_bodies, 0);
  for (int32_t b = 0; b < num_bodies; ++b) {
    ready[b] = kind_[b] == Kind::free && (group[b] >= 0 || rest[b] >= steps_);
    moving[b] = kind_[b] == Kind::driven || (kind_[b] == Kind::free && group[b] < 0 && !still[b]);
  }
  // An awake ready body sleeps when every body it touches is ready too; a sleeping body wakes when
  // a body it touches moves. So a body still creeping keeps awake only the bodies it touches.
  std::vector<uint8_t> neighbours_ready(num_bodies, 1), neighbour_moves(num_bodies, 0);
  for (const auto& [a, b] : links) {
    if (!ready[b]) neighbours_ready[a] = 0;
    if (moving[b]) neighbour_moves[a] = 1;
  }
  for (int32_t b = 0; b < num_bodies; ++b) {
    if (kind_[b] != Kind::free) continue;
    if (group[b] >= 0) {
      if (neighbour_moves[b]) wake(b, state);
      continue;
    }
    if (!ready[b] || !neighbours_ready[b]) continue;
    const BodyRange& r = model_.bodies[b];
    std::fill_n(state.v.begin() + 3 * int64_t{r.vertex_begin}, 3 * int64_t{r.vertex_count}, 0.0);
    group[b] = b;
  }
}

std::vector<int32_t> SleepingBodies::sleeping_vertices() const {
  std::vector<int32_t> vertices;
  for (int32_t b = 0; b < static_cast<int32_t>(kind_.size()); ++b) {
    if (history_.sleep_group[b] < 0) continue;
    const BodyRange& r = model_.bodies[b];
    for (int32_t v = r.vertex_begin; v < r.vertex_begin + r.vertex_count; ++v)
      if (!model_.eliminated(v)) vertices.push_back(v);
  }
  return vertices;
}

bool SleepingBodies::all_asleep() const {
  for (size_t b = 0; b < kind_.size(); ++b)
    if (kind_[b] == Kind::driven || (kind_[b] == Kind::free && history_.sleep_group[b] < 0)) return false;
  return true;
}

int32_t SleepingBodies::num_sleeping() const {
  return static_cast<int32_t>(
      std::count_if(history_.sleep_group.begin(), history_.sleep_group.end(), [](int32_t g) { return g >= 0; }));
}

}  // namespace nexdyn

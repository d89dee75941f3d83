// Newton driver (see newton.hpp).
#include "engine/solver/newton.hpp"

#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"

#include <Eigen/Core>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <stdexcept>

namespace nexdyn {

namespace {
// Solves a small island's cached system outlives its last use by, and a big (supernodal) one's
// analysis: two, so that the two systems of a step with kinematic vertices (free, then held)
// keep theirs while they alternate.
constexpr int64_t kKeepIslandSolves = 64;
constexpr int64_t kKeepBigIslandSolves = 2;

std::string format(const char* fmt, double a, double b = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), fmt, a, b);
  return buf;
}

// "body B (scene entry E)" of vertex v, for messages that say where something went wrong.
std::string body_of_vertex(const Model& model, int32_t v) {
  const int32_t b = model.vertex_body[v];
  return "body " + std::to_string(b) + " (\"" + (model.bodies[b].obstacle ? "obstacles" : "bodies") + "\" entry " +
         std::to_string(model.bodies[b].scene_entry) + ")";
}

// Where x inverts a tet: "tet T of body B ... is inverted (volume <= 0)", or "" when none is.
std::string inverted_tet(const Model& model, const double* x) {
  for (int32_t t = 0; t < model.num_tets; ++t) {
    const int32_t* v = &model.tets[4 * int64_t{t}];
    const Eigen::Vector3d x0 = Eigen::Vector3d::Map(x + 3 * int64_t{v[0]});
    Eigen::Matrix3d ds;
    for (int k = 0; k < 3; ++k) ds.col(k) = Eigen::Vector3d::Map(x + 3 * int64_t{v[k + 1]}) - x0;
    if (!(ds.determinant() > 0.0))
      return "tet " + std::to_string(t) + " of " + body_of_vertex(model, v[0]) + " is inverted (volume <= 0)";
  }
  return "";
}
}  // namespace

NewtonSolver::NewtonSolver(const Model& model, IncrementalPotential& potential)
    : model_(model), potential_(potential), islands_(potential.elastic_pattern(), model.num_vertices) {
  const int64_t n = model.num_dofs();
  constrained_dof_.assign(n, 0);
  held_in_islands_.assign(model.num_vertices, 0);
  // Followers of affine bodies are no unknowns either: they move with their bodies' nodes.
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.eliminated(v) || model.follows_body(v))
      for (int d = 0; d < 3; ++d) constrained_dof_[3 * v + d] = 1;
  grad_.resize(n);
  direction_.resize(n);
  trial_.resize(n);
  vertex_token_.assign(model.num_vertices, 0);
  // The CCD's units (cap_steps): bodies, those joined by a ball joint as one.
  DisjointSets units;
  units.reset(static_cast<int32_t>(model.bodies.size()));
  for (const Joint& joint : model.joints)
    if (joint.type == JointType::ball)
      units.join(model.vertex_body[joint.vertex[0]], model.vertex_body[joint.vertex[4]]);
  unit_of_body_.resize(model.bodies.size());
  for (int32_t b = 0; b < units.size(); ++b) unit_of_body_[b] = units.find(b);
  hold({}, false);
}

void NewtonSolver::hold(const std::vector<int32_t>& vertices, bool held, bool in_islands) {
  for (int32_t v : vertices) {
    const bool constrained = held || model_.follows_body(v);  // a follower is never an unknown
    for (int d = 0; d < 3; ++d) constrained_dof_[3 * int64_t{v} + d] = constrained;
    held_in_islands_[v] = held && in_islands;
  }
  collect_constrained_values();
  std::vector<uint8_t> moving(model_.num_vertices);
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    moving[v] = !constrained_dof_[3 * int64_t{v}] || held_in_islands_[v];
  islands_.set_moving(moving);
}

void NewtonSolver::collect_constrained_values() {
  const CscPattern& pattern = potential_.pattern();
  constrained_values_.clear();
  for (int64_t c = 0; c < pattern.num_dofs; ++c)
    for (int64_t k = pattern.col_ptr[c]; k < pattern.col_ptr[c + 1]; ++k)
      if (constrained_dof_[c] || constrained_dof_[pattern.row_idx[k]])
        constrained_values_.push_back(k);
  values_.resize(pattern.nnz());
  analyzed_version_ = potential_.pattern_version();
}

void NewtonSolver::eliminate_dirichlet(double* grad, double* values) const {
  const CscPattern& pattern = potential_.pattern();
  for (int64_t k : constrained_values_) values[k] = 0.0;
  for (int64_t i = 0; i < pattern.num_dofs; ++i)
    if (constrained_dof_[i]) {
      grad[i] = 0.0;
      values[pattern.diagonal[i]] = 1.0;
    }
}

bool NewtonSolver::frozen(int32_t island) const {
  const int32_t* v = islands_.vertices().data() + islands_.vertex_ptr()[island];
  const int32_t size = islands_.island_size(island);
  const int32_t token = vertex_token_[v[0]];
  if (token == 0 || token_size_[token] != size) return false;
  for (int32_t k = 1; k < size; ++k)
    if (vertex_token_[v[k]] != token) return false;
  return true;
}

void NewtonSolver::mark_converged(int32_t island) {
  const int32_t token = static_cast<int32_t>(token_size_.size());
  token_size_.push_back(islands_.island_size(island));
  for (int32_t k = islands_.vertex_ptr()[island]; k < islands_.vertex_ptr()[island + 1]; ++k)
    vertex_token_[islands_.vertices()[k]] = token;
}

void NewtonSolver::update_subset() {
  std::vector<uint8_t>& active = subset_.vertex_mask;
  active.assign(model_.num_vertices, 0);
  for (int32_t i : active_)
    for (int32_t k = islands_.vertex_ptr()[i]; k < islands_.vertex_ptr()[i + 1]; ++k)
      active[islands_.vertices()[k]] = 1;
  // An affine body's followers are assembled with its nodes (their terms fold onto the nodes).
  for (const AffineBody& body : model_.affine_bodies)
    if (active[body.node]) std::fill_n(active.begin() + body.follower_begin, body.follower_count, uint8_t{1});
  subset_.vertices.clear();
  subset_.tets.clear();
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    if (active[v]) append_index(subset_.vertices, v);
  const int32_t* tets = model_.tets.data();
  for (int32_t t = 0; t < model_.num_tets; ++t)
    if (active[tets[4 * t]] | active[tets[4 * t + 1]] | active[tets[4 * t + 2]] |
        active[tets[4 * t + 3]])
      append_index(subset_.tets, t);
}

void NewtonSolver::thaw(const std::vector<int32_t>& stencils) {
  for (int32_t v : stencils) {
    if (v < 0) continue;
    if (model_.follows_body(v)) {  // no island of its own: its body's nodes'
      const int32_t node = model_.affine_bodies[model_.follows[v]].node;
      std::fill_n(vertex_token_.begin() + node, 4, 0);
      continue;
    }
    vertex_token_[v] = 0;
  }
}

bool NewtonSolver::prepare_potential(const double* x, int iteration, NewtonResult& result) {
  try {
    potential_.prepare(x, iteration == 0);
    return true;
  } catch (const std::length_error& e) {
    result.status = StepStatus::linear_solver_failed;
    result.message =
        "the Newton system is too large at Newton iteration " + std::to_string(iteration) + ": " + e.what();
    return false;
  }
}

IslandSystem& NewtonSolver::island_system(int32_t i) {
  const int32_t* v = islands_.vertices().data() + islands_.vertex_ptr()[i];
  const int32_t size = islands_.island_size(i);
  uint64_t hash = 1469598103934665603ull;  // FNV-1a over the vertex ids
  for (int32_t k = 0; k < size; ++k) hash = (hash ^ static_cast<uint32_t>(v[k])) * 1099511628211ull;
  std::vector<std::unique_ptr<IslandSystem>>& bucket = systems_[hash];
  IslandSystem* system = nullptr;
  for (auto& candidate : bucket)
    if (candidate->vertices().size() == static_cast<size_t>(size) &&
        std::equal(v, v + size, candidate->vertices().begin()))
      system = candidate.get();
  if (!system) {
    bucket.push_back(std::make_unique<IslandSystem>(std::vector<int32_t>(v, v + size)));
    system = bucket.back().get();
  }
  system->last_used = solve_count_;
  system->last_iteration = iteration_count_;
  return *system;
}

int64_t NewtonSolver::solve_islands(int& analyses) {
  const int64_t count = static_cast<int64_t>(active_.size());
  active_system_.resize(count);
  active_status_.assign(count, StepStatus::ok);
  for (int64_t a = 0; a < count; ++a) active_system_[a] = &island_system(active_[a]);
  forget_vanished_islands();
  // The big islands not solved now (frozen, or from an earlier solve) give their factors back.
  for (auto& [hash, bucket] : systems_)
    for (auto& system : bucket)
      if (system->last_iteration != iteration_count_ && system->num_dofs() > IslandSystem::kSimplicialDofs)
        system->release_numeric();
  {
    // Symbolic analyses of islands whose block of the pattern changed (no BLAS: all parallel).
    ProfileScope scope(profile_, StepPhase::analysis);
    std::vector<uint8_t>& analyzed = active_analyzed_;
    analyzed.assign(count, 0);
    parallel_for(count, [&](int64_t begin, int64_t end) {
      for (int64_t a = begin; a < end; ++a)
        analyzed[a] = active_system_[a]->update_pattern(potential_.pattern(), potential_.pattern_version(),
                                                        islands_.island_of_vertex().data(),
                                                        islands_.local_indices().data(), active_[a]);
    }, 1);
    for (uint8_t changed : analyzed) analyses += changed;
  }
  // Islands that must not share the BLAS run one after the other on one thread while the rest
  // share the others (island_system.hpp); each island's numbers are the same on any thread count.
  std::vector<int64_t>& alone = run_alone_;
  std::vector<int64_t>& parallel = run_parallel_;
  alone.clear();
  parallel.clear();
  for (int64_t a = 0; a < count; ++a) (active_system_[a]->must_run_alone() ? alone : parallel).push_back(a);
  auto run = [&](auto&& work) {
    run_both([&] { for (int64_t a : alone) work(a); },
             [&] {
               parallel_for(static_cast<int64_t>(parallel.size()), [&](int64_t begin, int64_t end) {
                 for (int64_t k = begin; k < end; ++k) work(parallel[k]);
               }, 1);
             });
  };
  {
    ProfileScope scope(profile_, StepPhase::factorization);
    run([&](int64_t a) {
      stop_point();  // a big island's factorisation can take seconds: a safe point before each
      active_status_[a] = active_system_[a]->factorize(values_.data());
    });
  }
  for (int64_t a = 0; a < count; ++a)
    if (active_status_[a] != StepStatus::ok) return a;
  {
    ProfileScope scope(profile_, StepPhase::solve);
    run([&](int64_t a) { active_status_[a] = active_system_[a]->solve(grad_.data(), direction_.data()); });
  }
  for (int64_t a = 0; a < count; ++a)
    if (active_status_[a] != StepStatus::ok) return a;
  return -1;
}

void NewtonSolver::forget_unused_systems() {
  // Forget the islands that went unused for kKeepIslandSolves solves (a frozen island is not looked
  // up, so a shorter memory would throw away the analyses of bodies that merely rest; big systems
  // rarely recur, and their analyses are big, so they go after kKeepBigIslandSolves), and every
  // convergence mark (unless told to keep them).
  ++solve_count_;
  for (auto it = systems_.begin(); it != systems_.end();) {
    auto& bucket = it->second;
    bucket.erase(std::remove_if(bucket.begin(), bucket.end(),
                                [&](const auto& s) {
                                  const int64_t keep =
                                      s->num_dofs() <= IslandSystem::kSimplicialDofs ? kKeepIslandSolves
                                                                                     : kKeepBigIslandSolves;
                                  return s->last_used < solve_count_ - keep;
                                }),
                 bucket.end());
    it = bucket.empty() ? systems_.erase(it) : std::next(it);
  }
  if (!keep_converged_) {
    std::fill(vertex_token_.begin(), vertex_token_.end(), 0);
    token_size_.assign(1, 0);
  }
  keep_converged_ = false;
}

void NewtonSolver::forget_vanished_islands() {
  // Systems used in this solve whose islands no longer exist (merged or split since) are
  // forgotten now, not at the next solve: in a landing pile the islands change at every
  // iteration, and such systems' tables and analyses held 0.9 GB at the peak of a 10,000-body
  // landing (heaptrack). Systems of earlier solves keep forget_unused_systems' rule (the free and
  // the held solves of a kinematic boundary alternate and keep each other's islands).
  auto vanished = [&](const IslandSystem& system) {
    if (system.last_used != solve_count_ || system.last_iteration == iteration_count_) return false;
    const std::vector<int32_t>& v = system.vertices();
    const int32_t i = islands_.island_of(v.front());
    if (i < 0 || islands_.island_size(i) != static_cast<int32_t>(v.size())) return true;
    return !std::equal(v.begin(), v.end(), islands_.vertices().begin() + islands_.vertex_ptr()[i]);
  };
  for (auto it = systems_.begin(); it != systems_.end();) {
    auto& bucket = it->second;
    bucket.erase(std::remove_if(bucket.begin(), bucket.end(), [&](const auto& s) { return vanished(*s); }),
                 bucket.end());
    it = bucket.empty() ? systems_.erase(it) : std::next(it);
  }
}

bool NewtonSolver::solve_direction(const double* x, int it, NewtonResult& result) {
  if (!prepare_potential(x, it, result)) return false;
  if (potential_.pattern_version() != analyzed_version_) collect_constrained_values();

  // Islands at x; the ones that have not converged are assembled, factorised and solved.
  islands_.build(potential_.coupling_stencils());
  active_.clear();
  for (int32_t i = 0; i < islands_.num_islands(); ++i)
    if (!frozen(i)) active_.push_back(i);
  update_subset();
  potential_.gradient_hessian(x, grad_.data(), values_.data(), &subset_);
  eliminate_dirichlet(grad_.data(), values_.data());
  for (const auto& [begin, end] : subset_.vertices)
    for (int64_t i = 3 * int64_t{begin}; i < 3 * int64_t{end}; ++i)
      if (!std::isfinite(grad_[i])) {
        const int32_t v = static_cast<int32_t>(i / 3);
        result.status = StepStatus::non_finite;
        result.message = "NaN or infinity in the gradient at Newton iteration " + std::to_string(it) +
                         ", at vertex " + std::to_string(v) + " of " + body_of_vertex(model_, v);
        return false;
      }
  std::fill(direction_.begin(), direction_.end(), 0.0);
  ++iteration_count_;
  const int64_t failed = solve_islands(result.analyses);
  double factor_bytes = 0.0;
  for (const auto& [hash, bucket] : systems_)
    for (const auto& system : bucket) factor_bytes += system->factor_bytes();
  peak_factor_bytes_ = std::max(peak_factor_bytes_, factor_bytes);
  if (failed < 0) return true;
  result.status = active_status_[failed];
  result.message = (result.status == StepStatus::factorization_failed ? "factorisation failed"
                                                                      : "the linear solver failed") +
                   std::string(" at Newton iteration ") + std::to_string(it) + ": " +
                   active_system_[failed]->error();
  return false;
}

bool NewtonSolver::mark_moving_islands(const NewtonSettings& settings, NewtonResult& result) {
  // p = -H^-1 g on the active islands. An island below the tolerance has converged: it stays
  // where it is (p = 0 there) until it changes or kappa does.
  result.increment = 0.0;
  island_moves_.assign(islands_.num_islands(), 0);
  for (int32_t i : active_)
    for (int32_t k = islands_.vertex_ptr()[i]; k < islands_.vertex_ptr()[i + 1]; ++k)
      for (int d = 0; d < 3; ++d) direction_[3 * int64_t{islands_.vertices()[k]} + d] *= -1.0;
  // Followers move with their bodies (p = J p_nodes). An affine body's increment is its
  // followers' largest motion, in metres like a tet vertex's: its axis nodes' entries are
  // dimensionless (columns of A R), so they do not count themselves.
  const CoordinateMap& map = potential_.map();
  map.follow(direction_.data());
  auto largest = [&](int32_t v) {
    double step = 0.0;
    for (int d = 0; d < 3; ++d) step = std::max(step, std::abs(direction_[3 * int64_t{v} + d]));
    return step;
  };
  auto for_followers = [&](int32_t node, auto&& f) {  // node: an affine body's p, else nothing
    if (model_.follows.empty() || model_.follows[node] != Model::kCentreNode) return;
    const BodyRange& body = model_.bodies[model_.vertex_body[node]];
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count - 4; ++v) f(v);
  };
  bool any_moving = false;
  for (int32_t i : active_) {
    double max_step = 0.0;
    for (int32_t k = islands_.vertex_ptr()[i]; k < islands_.vertex_ptr()[i + 1]; ++k) {
      const int32_t v = islands_.vertices()[k];
      if (!model_.axis_node(v)) max_step = std::max(max_step, largest(v));
      for_followers(v, [&](int32_t f) { max_step = std::max(max_step, largest(f)); });
    }
    const double increment = max_step / settings.dt;
    result.increment = std::max(result.increment, increment);
    if (increment >= settings.tolerance) {
      island_moves_[i] = 1;
      any_moving = true;
      continue;
    }
    mark_converged(i);
    for (int32_t k = islands_.vertex_ptr()[i]; k < islands_.vertex_ptr()[i + 1]; ++k) {
      const int32_t v = islands_.vertices()[k];
      for (int d = 0; d < 3; ++d) direction_[3 * int64_t{v} + d] = 0.0;
      for_followers(v, [&](int32_t f) {
        for (int d = 0; d < 3; ++d) direction_[3 * int64_t{f} + d] = 0.0;
      });
    }
  }
  return any_moving;
}

int32_t NewtonSolver::build_groups(const double* x) {
  // Groups: the moving islands, joined where a pair of the CCD sweep links two of them (they
  // may meet along the step, so they share a step length and an energy test).
  const int32_t num_islands = islands_.num_islands();
  vertex_moves_.resize(model_.num_vertices);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t i = islands_.island_of(v);
    vertex_moves_[v] = i >= 0 && island_moves_[i];
  }
  for (const AffineBody& body : model_.affine_bodies)
    std::fill_n(vertex_moves_.begin() + body.follower_begin, body.follower_count, vertex_moves_[body.node]);
  // Padded by how far the line search's turns can leave the chord (up to the reach), the sweep's
  // pairs cover the turned trial points too: mostly one search per iteration (turned_point_valid).
  const double* pads = nullptr;
  if (!model_.affine_bodies.empty()) {
    turn_pads_.assign(model_.num_vertices, 0.0);
    if (turn_reach_ > 0.0) {
      potential_.map().turn_pads(x, direction_.data(), vertex_moves_.data(), turn_pads_.data());
      // (plus a millionth of the reach for the rounding of the trial points: a turn by 1e-7 rad
      // leaves the chord by less than its coordinates' last bits)
      for (double& pad : turn_pads_) pad = std::min(pad + 1e-6 * turn_reach_, turn_reach_);
    }
    pads = turn_pads_.data();
  }
  potential_.sweep(x, direction_.data(), vertex_moves_.data(), pads);
  groups_.reset(num_islands);
  if (const ContactCandidates* c = potential_.sweep_candidates()) {
    const std::vector<int32_t>& island_of = islands_.island_of_vertex();
    auto join = [&](const PairVertices& vertices) {
      int32_t first = -1;
      for (int32_t v : vertices) {
        // A follower is in its body's island (that of its nodes).
        const int32_t node = model_.follows_body(v) ? model_.affine_bodies[model_.follows[v]].node : v;
        const int32_t i = island_of[node];
        if (i < 0 || !island_moves_[i]) continue;
        if (first < 0) first = i;
        else groups_.join(first, i);
      }
    };
    // A vertex-plane pair has one vertex: it joins nothing.
    for (const IndexPair& pr : c->vertex_triangle) join(vertex_triangle_vertices(model_, pr));
    for (const IndexPair& pr : c->edge_edge) join(edge_edge_vertices(model_, pr));
  }
  int32_t num_groups = 0;
  group_of_island_.assign(num_islands, -1);
  for (int32_t i = 0; i < num_islands; ++i) {
    if (!island_moves_[i]) continue;
    const int32_t root = groups_.find(i);  // the smallest island of the group: numbered first
    group_of_island_[i] = root == i ? num_groups++ : group_of_island_[root];
  }
  group_of_vertex_.resize(model_.num_vertices);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t i = islands_.island_of(v);
    group_of_vertex_[v] = i < 0 ? -1 : group_of_island_[i];
  }
  potential_.map().follow_groups(group_of_vertex_.data());
  return num_groups;
}

bool NewtonSolver::cap_steps(const double* x, int32_t num_groups, NewtonResult& result) {
  // Each moving body's largest collision-free fraction of its own motion, capped by its own pairs
  // and by those linking it to other bodies, which are then checked along the motion the bodies'
  // caps give together (BarrierPotential::linked_max_steps). One cap per island instead held a
  // landing pile, hundreds of bodies joined by their contacts into one island, to the fraction
  // that its worst pair allowed, iteration after iteration. The direction is scaled body by body
  // (bodies joined by a ball joint count as one). Scaled so, an island's direction is no longer
  // Newton's and need not descend: if it does not in some island (g . D p >= 0), every island
  // takes one cap, that of its own pairs and links. A group's cap (for the history) is its
  // smallest one; the group's line search then backtracks along the scaled direction.
  const int32_t num_islands = islands_.num_islands();
  island_of_moving_vertex_.resize(model_.num_vertices);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t i = islands_.island_of(v);
    island_of_moving_vertex_[v] = i >= 0 && island_moves_[i] ? i : -1;
  }
  potential_.map().follow_groups(island_of_moving_vertex_.data());
  const int64_t n = model_.num_dofs();
  unit_of_moving_vertex_.resize(model_.num_vertices);
  for (int32_t v = 0; v < model_.num_vertices; ++v)
    unit_of_moving_vertex_[v] = island_of_moving_vertex_[v] >= 0 ? unit_of_body_[model_.vertex_body[v]] : -1;
  unit_alpha_.assign(unit_of_body_.size(), 1.0);
  potential_.linked_max_steps(x, unit_of_moving_vertex_.data(), static_cast<int32_t>(unit_alpha_.size()),
                              unit_alpha_.data());
  island_slope_.assign(num_islands, 0.0);
  for (int64_t i = 0; i < n; ++i) {
    const int32_t u = unit_of_moving_vertex_[i / 3];
    if (u >= 0) island_slope_[island_of_moving_vertex_[i / 3]] += grad_[i] * direction_[i] * unit_alpha_[u];
  }
  bool descends = true;
  for (int32_t i = 0; i < num_islands; ++i) descends = descends && (!island_moves_[i] || island_slope_[i] < 0.0);
  if (!descends) {
    std::copy(island_of_moving_vertex_.begin(), island_of_moving_vertex_.end(), unit_of_moving_vertex_.begin());
    unit_alpha_.assign(num_islands, 1.0);
    potential_.linked_max_steps(x, unit_of_moving_vertex_.data(), num_islands, unit_alpha_.data());
  }
  group_alpha_.assign(num_groups, 1.0);
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    const int32_t u = unit_of_moving_vertex_[v];
    if (u < 0) continue;
    if (!(unit_alpha_[u] > 0.0)) {
      result.status = StepStatus::line_search_failed;
      result.message = "continuous collision detection allows no motion along the Newton direction";
      return false;
    }
    double& cap = group_alpha_[group_of_vertex_[v]];
    cap = std::min(cap, unit_alpha_[u]);
  }
  group_slope_.assign(num_groups, 0.0);
  for (int64_t i = 0; i < n; ++i) {
    const int32_t g = group_of_vertex_[i / 3];
    if (g < 0) continue;
    direction_[i] *= unit_alpha_[unit_of_moving_vertex_[i / 3]];
    group_slope_[g] += grad_[i] * direction_[i];
  }
  return true;
}

// The stages of one solve: per iteration, the direction on the islands not yet converged, the
// islands that still move, their groups and CCD caps, the line search, the lengthening of full
// steps that fell short (extend_step), the terms' adaptive updates.
NewtonResult NewtonSolver::solve(std::vector<double>& x, const NewtonSettings& settings) {
  NewtonResult result;
  turn_reach_ = settings.turn_reach;
  extend_steps_ = settings.extend_steps;
  forget_unused_systems();
  // Islands whose potential changed since the last solve (a new friction lag) start unfrozen.
  for (const std::vector<int32_t>* stencils : potential_.take_changed_stencils()) thaw(*stencils);
  potential_.begin_solve(x.data());
  if (!std::isfinite(potential_.energy(x.data()))) {
    result.status = StepStatus::non_finite;
    const std::string where = inverted_tet(model_, x.data());
    result.message = "the starting point of the step has infinite energy: " +
                     (where.empty() ? std::string("a contact pair touches (distance 0)") : where);
    return result;
  }
  int relags = 0;
  int lag_start = 0;  // the iteration the current lag's convergence began at
  for (int it = 0; it < settings.max_iterations; ++it) {
    stop_point(SafePoint::newton_iteration);
    if (!solve_direction(x.data(), it, result)) return result;
    result.iterations = it + 1;
    const bool any_moving = mark_moving_islands(settings, result);
    NewtonIterate* record = nullptr;
    if (history_) {
      record = &history_->emplace_back();
      record->solved_islands = static_cast<int32_t>(active_.size());
      record->increment = result.increment;
      for (int32_t i : active_) record->moving_islands += island_moves_[i];
      if (history_points_ && !any_moving) record->x = x;
    }
    if (!any_moving) return result;
    const int32_t num_groups = build_groups(x.data());
    if (!cap_steps(x.data(), num_groups, result)) return result;
    group_cap_.assign(group_alpha_.begin(), group_alpha_.end());
    if (!line_search(x.data(), num_groups, result)) return result;
    extend_step(x.data(), num_groups);
    x.swap(trial_);
    // Followers exactly at J q again (the line search moved them along J p, up to rounding).
    potential_.map().follow(x.data());
    if (record) {
      record->extended = extended_;
      record->full_step_decrease = extended_ ? full_step_decrease_ : 0.0;
      record->ccd_cap = group_cap_;
      record->slope = group_slope_;
      record->start_energy = group_start_;
      record->accepted_energy = group_trial_;
      record->step_length = group_alpha_;
      if (history_points_) record->x = x;
    }
    // A term whose energy changed there (kappa raised) thaws the islands of its stencils.
    for (const std::vector<int32_t>* stencils : potential_.end_iteration(x.data())) thaw(*stencils);
    // Near the solution, the caller may bring lagged quantities up to x (a friction lag): the
    // islands whose potential that changed are thawed, and the solve goes on with it.
    const int lag_cost = it + 1 - lag_start, left = settings.max_iterations - (it + 1);
    if (settings.relag && relags < settings.max_relags && result.increment < settings.relag_below &&
        left >= lag_cost) {
      ++relags;
      lag_start = it + 1;
      if (settings.relag(x.data()))
        for (const std::vector<int32_t>* stencils : potential_.take_changed_stencils()) thaw(*stencils);
    }
  }
  result.status = StepStatus::max_iterations;
  result.message = format("Newton did not converge in the iteration limit (last increment "
                          "%.3g m/s, tolerance %.3g m/s)", result.increment, settings.tolerance);
  return result;
}

}  // namespace nexdyn

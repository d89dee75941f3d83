// The incremental potential as a loop over its terms (see incremental_potential.hpp).
#include "engine/potential/incremental_potential.hpp"

#include "engine/parallel.hpp"
#include "engine/terms/elastic_term.hpp"
#include "engine/terms/inertia_term.hpp"
#include "engine/terms/joint_term.hpp"
#include "engine/terms/kinematic_term.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace nexdyn {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();
}  // namespace

IncrementalPotential::IncrementalPotential(const Model& model, ElasticAssembly& elastic, StepHistory& history,
                                           BarrierPotential* contact, const JointSet* joints)
    : model_(model), map_(model), elastic_(elastic), history_(history), contact_(contact), joints_(joints) {
  add_term(std::make_unique<InertiaTerm>(model));
  add_term(std::make_unique<ElasticTerm>(model, elastic));
  if (joints) add_term(std::make_unique<JointTerm>(*joints));
  if (contact) {
    auto barrier = std::make_unique<BarrierTerm>(model, *contact, history);
    barrier_ = barrier.get();
    add_term(std::move(barrier));
  }
}

void IncrementalPotential::set_friction(FrictionPotential* friction) {
  if (!friction || !barrier_) return;
  auto term = std::make_unique<FrictionTerm>(*friction, *barrier_);
  friction_ = term.get();
  friction_potential_ = friction;
  add_term(std::move(term));
}

void IncrementalPotential::set_kinematic(const KinematicTargets* kinematic) {
  if (kinematic) add_term(std::make_unique<KinematicTerm>(*kinematic));
}

void IncrementalPotential::add_term(std::unique_ptr<PotentialTerm> term) {
  if (term->hessian() == TermHessian::stencil_slabs && !contact_pattern_) {
    contact_pattern_ = std::make_unique<ContactPattern>(elastic_.pattern(), history_.contact_pattern_pairs,
                                                        history_.contact_pattern_stamp);
    elastic_values_.resize(elastic_.pattern().nnz());
  }
  terms_.push_back(std::move(term));
}

void IncrementalPotential::set_profile(StepProfile* profile) {
  profile_ = profile;
  if (barrier_) barrier_->set_profile(profile);
  if (friction_) friction_->set_profile(profile);
}

double IncrementalPotential::weight(const PotentialTerm& term) const {
  switch (term.scale()) {
    case TermScale::one: return 1.0;
    case TermScale::potential: return scale_;
    case TermScale::contact: return contact_scale_;
  }
  return 1.0;
}

void IncrementalPotential::begin_step(const std::vector<double>& x_tilde, const StepContext& ctx) {
  scale_ = ctx.potential_scale;
  contact_scale_ = ctx.contact_scale;
  for (const auto& term : terms_) term->begin_step(x_tilde, ctx);
  if (contact_pattern_) contact_pattern_->sync();
}

void IncrementalPotential::begin_solve(const double* x) {
  for (size_t k = 0; k < terms_.size(); ++k) {
    auto preceding_gradient = [&](double* grad) {
      for (size_t j = 0; j < k; ++j) terms_[j]->add_gradient(x, weight(*terms_[j]), grad);
    };
    terms_[k]->begin_solve(x, preceding_gradient);
  }
}

double IncrementalPotential::energy(const double* x) const {
  double sum = 0.0;
  for (const auto& term : terms_) {
    const double e = term->energy(x);
    if (!std::isfinite(e)) return kInf;  // an inverted tet or a touching pair
    sum += weight(*term) * e;
  }
  return sum;
}

void IncrementalPotential::group_energy(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                                        double* out) {
  std::fill(out, out + num_groups, 0.0);
  for (const auto& term : terms_) {
    group_term_.assign(num_groups, 0.0);
    term->add_group_energy(x, group_of_vertex, num_groups, group_term_.data());
    const double w = weight(*term);
    for (int32_t g = 0; g < num_groups; ++g)
      out[g] = std::isfinite(group_term_[g]) ? out[g] + w * group_term_[g] : kInf;
  }
}

void IncrementalPotential::prepare(const double* x, bool first_iteration) {
  for (const auto& term : terms_) term->prepare(x);
  if (!contact_pattern_) return;
  // One stencil list for the pattern, the stencil_slabs terms' in list order (copied only when
  // more than one has stencils: friction's are the barrier's of the lagged state, so the pattern
  // rarely grows). With affine bodies, the terms' stencils over nodes (coordinate_map.hpp).
  const std::vector<int32_t>* only_stencils = nullptr;
  const std::vector<int64_t>* only_slab_begin = nullptr;
  int with_stencils = 0;
  mapped_.resize(terms_.size());
  for (size_t t = 0; t < terms_.size(); ++t) {
    const StencilSlabs s = terms_[t]->slabs();
    if (terms_[t]->hessian() != TermHessian::stencil_slabs || !s.stencils) continue;
    if (!map_.identity()) {
      map_.map_stencils(*s.stencils, *s.slab_begin, mapped_[t]);
      only_stencils = &mapped_[t].stencils;
      only_slab_begin = &mapped_[t].slab_begin;
    } else {
      only_stencils = s.stencils;
      only_slab_begin = s.slab_begin;
    }
    ++with_stencils;
  }
  if (with_stencils <= 1) {
    static const std::vector<int32_t> kNoStencils;
    static const std::vector<int64_t> kNoSlabs{0};
    contact_pattern_->update(only_stencils ? *only_stencils : kNoStencils,
                             only_slab_begin ? *only_slab_begin : kNoSlabs, first_iteration);
    return;
  }
  stencils_.clear();
  slab_begin_.assign(1, 0);
  for (size_t t = 0; t < terms_.size(); ++t) {
    const StencilSlabs s = terms_[t]->slabs();
    if (terms_[t]->hessian() != TermHessian::stencil_slabs || !s.stencils) continue;
    const std::vector<int32_t>& stencils = map_.identity() ? *s.stencils : mapped_[t].stencils;
    const std::vector<int64_t>& slab_begin = map_.identity() ? *s.slab_begin : mapped_[t].slab_begin;
    stencils_.insert(stencils_.end(), stencils.begin(), stencils.end());
    const int64_t offset = slab_begin_.back();
    for (size_t k = 1; k < slab_begin.size(); ++k) slab_begin_.push_back(offset + slab_begin[k]);
  }
  contact_pattern_->update(stencils_, slab_begin_, first_iteration);
}

void IncrementalPotential::gradient_hessian(const double* x, double* grad, double* values,
                                            const ActiveSubset* subset) {
  const IndexRanges all_vertices{{0, model_.num_vertices}};
  const IndexRanges& vertices = subset ? subset->vertices : all_vertices;
  parallel_for_ranges(vertices, 4096, [&](int64_t begin, int64_t end) {
    std::fill(grad + 3 * begin, grad + 3 * end, 0.0);
  });
  // Gradients in list order; the pattern_values term writes the elastic pattern's values (into
  // `values` directly when nothing is merged with them) and the stencil_slabs terms their slabs.
  const DerivativeOutput out{grad, contact_pattern_ ? elastic_values_.data() : values, subset};
  for (const auto& term : terms_) {
    ProfileScope scope(term->hessian() == TermHessian::pattern_values ? profile_ : nullptr, StepPhase::elastic);
    term->add_derivatives(x, weight(*term), out);
  }
  if (contact_pattern_) {
    ProfileScope scope(profile_, StepPhase::barrier);
    slab_pieces_.clear();
    piece_begin_.clear();
    int64_t begin = 0;
    mapped_slabs_.resize(terms_.size());
    for (size_t t = 0; t < terms_.size(); ++t) {
      const StencilSlabs s = terms_[t]->slabs();
      if (terms_[t]->hessian() != TermHessian::stencil_slabs || !s.stencils) continue;
      if (map_.identity()) {
        slab_pieces_.push_back(s.slabs);
        piece_begin_.push_back(begin);
        begin += s.slab_begin->back();
        continue;
      }
      // J^T H J of the term's slabs, over the sub-stencils prepare() gave the pattern.
      mapped_slabs_[t].resize(mapped_[t].slab_begin.back());
      map_.map_slabs(*s.stencils, *s.slab_begin, s.slabs, mapped_[t], mapped_slabs_[t].data(),
                     subset ? subset->vertex_mask.data() : nullptr);
      slab_pieces_.push_back(mapped_slabs_[t].data());
      piece_begin_.push_back(begin);
      begin += mapped_[t].slab_begin.back();
    }
    if (slab_pieces_.empty()) {
      slab_pieces_.push_back(nullptr);
      piece_begin_.push_back(0);
    }
    contact_pattern_->assemble(elastic_values_.data(), slab_pieces_, piece_begin_, values, &vertices);
  }
  const CscPattern& merged = pattern();
  for (const auto& term : terms_)
    if (term->hessian() == TermHessian::diagonal) term->add_diagonal(x, weight(*term), merged, values, subset);
  map_.fold_gradient(grad);  // followers' gradients onto their bodies' nodes
}

void IncrementalPotential::gradient(const double* x, double* grad) {
  std::fill(grad, grad + model_.num_dofs(), 0.0);
  for (const auto& term : terms_) term->add_gradient(x, weight(*term), grad);
  map_.fold_gradient(grad);
}

double IncrementalPotential::max_step(const double* x, const double* p) {
  double alpha = 1.0;
  for (const auto& term : terms_) alpha = std::min(alpha, term->max_step(x, p));
  return alpha;
}

void IncrementalPotential::sweep(const double* x, const double* p, const uint8_t* moving, const double* pad) {
  for (const auto& term : terms_) term->sweep(x, p, moving, pad);
}

void IncrementalPotential::move_sweep_end(const double* x, const double* p) {
  for (const auto& term : terms_) term->move_sweep_end(x, p);
}

const ContactCandidates* IncrementalPotential::sweep_candidates() const {
  for (const auto& term : terms_)
    if (const ContactCandidates* pairs = term->swept_pairs()) return pairs;
  return nullptr;
}

void IncrementalPotential::group_max_steps(const double* x, const int32_t* group_of_vertex, double* alpha) {
  for (const auto& term : terms_) term->group_max_steps(x, group_of_vertex, alpha);
}

void IncrementalPotential::linked_max_steps(const double* x, const int32_t* group_of_vertex, int32_t num_groups,
                                               double* alpha) {
  for (const auto& term : terms_) term->linked_max_steps(x, group_of_vertex, num_groups, alpha);
}

std::vector<const std::vector<int32_t>*> IncrementalPotential::coupling_stencils() {
  std::vector<const std::vector<int32_t>*> lists;
  mapped_coupling_.resize(terms_.size());
  for (size_t t = 0; t < terms_.size(); ++t) {
    const std::vector<int32_t>* stencils = terms_[t]->coupling_stencils();
    if (!stencils) continue;
    if (map_.identity()) {
      lists.push_back(stencils);
      continue;
    }
    map_.map_coupling(*stencils, mapped_coupling_[t]);  // over nodes: islands are of nodes
    lists.push_back(&mapped_coupling_[t]);
  }
  return lists;
}

const std::vector<const std::vector<int32_t>*>& IncrementalPotential::take_changed_stencils() {
  changed_.clear();
  for (const auto& term : terms_)
    if (const std::vector<int32_t>* stencils = term->take_changed_stencils()) changed_.push_back(stencils);
  return changed_;
}

const std::vector<const std::vector<int32_t>*>& IncrementalPotential::end_iteration(const double* x) {
  changed_.clear();
  for (const auto& term : terms_)
    if (const std::vector<int32_t>* stencils = term->end_iteration(x)) changed_.push_back(stencils);
  return changed_;
}

void IncrementalPotential::impulsive_forces(const double* x, std::vector<double>& delta) {
  const int64_t n = model_.num_dofs();
  delta.assign(n, 0.0);
  if (!contact_ && !joints_) return;
  ProfileScope scope(profile_, StepPhase::barrier);
  // The gradient of s_c kappa B + s_c D + s w Phi_joints (s w = s_c), summed in this order;
  // divided by s (with a minus: a force) it is what update_implicit put into a_{n+1}. The
  // contact and friction parts are kept apart as well, for the energy balance.
  std::vector<double>& impulsive = contact_gradient_;
  impulsive.assign(n, 0.0);
  contact_force_.assign(contact_ ? n : 0, 0.0);
  friction_force_.assign(friction_potential_ ? n : 0, 0.0);
  const double to_force = -1.0 / contact_scale_;
  if (contact_) {
    contact_->assemble(x, contact_scale_ * history_.kappa, false);
    contact_->add_gradient_with_held(impulsive.data());
    for (int64_t i = 0; i < n; ++i) contact_force_[i] = impulsive[i] * to_force;
  }
  if (friction_potential_) {  // friction acts with the contact force that carries it
    friction_potential_->compute_derivatives(x, contact_scale_, false);
    friction_potential_->add_gradient_with_held(impulsive.data());
    std::vector<double>& friction = friction_gradient_;
    friction.assign(n, 0.0);
    friction_potential_->add_gradient_with_held(friction.data());
    for (int64_t i = 0; i < n; ++i) friction_force_[i] = friction[i] * to_force;
  }
  joint_force_.assign(joints_ ? n : 0, 0.0);
  if (joints_) {
    joint_gradient_.assign(n, 0.0);
    joints_->add_gradient(x, joint_gradient_.data());  // of w Phi
    const double to_joint_force = -1.0 / joints_->weight();
    for (int64_t i = 0; i < n; ++i) {
      impulsive[i] += scale_ * joint_gradient_[i];
      joint_force_[i] = joint_gradient_[i] * to_joint_force;
    }
  }
  // Affine bodies: the impulse on their nodes (J^T f), their nodes' delta, and their followers'
  // (J delta), so that the followers' velocities stay those of their bodies.
  map_.fold_gradient(impulsive.data());
  for (int32_t v = 0; v < model_.num_vertices; ++v) {
    if (model_.dirichlet[v] >= 0 || !(model_.mass[v] > 0.0)) continue;
    for (int d = 0; d < 3; ++d) {
      const int64_t i = 3 * int64_t{v} + d;
      delta[i] = -(impulsive[i] / (scale_ * model_.mass[v]));
    }
  }
  map_.follow(delta.data());
}

}  // namespace nexdyn

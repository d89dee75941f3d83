// Augmented Lagrangian of kinematic vertices (see kinematic_targets.hpp). Serial loops: the
// kinematic vertices are a small part of a scene, and every sum runs in vertex order, so the
// results do not depend on the number of threads.
#include "engine/potential/kinematic_targets.hpp"

#include <algorithm>
#include <cmath>

namespace nexdyn {

KinematicTargets::KinematicTargets(const Model& model, StepHistory& history)
    : num_dofs_(model.num_dofs()), history_(history) {
  double free_mass = 0.0;
  int64_t free = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (model.dirichlet[v] < 0) {
      free_mass += model.mass[v];
      ++free;
    } else if (model.dirichlet_motions[model.dirichlet[v]].kinematic) {
      vertices_.push_back(v);
    }
  }
  const double mean = free > 0 && free_mass > 0.0 ? free_mass / free : 1.0;
  for (int32_t v : vertices_) mass_.push_back(model.mass[v] > 0.0 ? model.mass[v] : mean);
  stiffness_.assign(vertices_.size(), 0.0);
  target_.assign(3 * vertices_.size(), 0.0);
  history_.kinematic_multipliers.assign(3 * vertices_.size(), 0.0);
}

void KinematicTargets::set_targets(const std::vector<double>& x_target) {
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d) target_[3 * i + d] = x_target[3 * size_t(vertices_[i]) + d];
}

void KinematicTargets::set_stiffness(double ratio) {
  // Stiffenings are powers of two: (ratio m) times their product is the number the successive
  // stiffenings gave.
  for (size_t i = 0; i < vertices_.size(); ++i) stiffness_[i] = ratio * mass_[i] * history_.kinematic_stiffening;
}

void KinematicTargets::begin_attempt(double ratio, double scale) {
  set_stiffness(ratio);
  if (scale != history_.kinematic_multiplier_scale) {
    const double factor = scale / history_.kinematic_multiplier_scale;
    for (double& lambda : history_.kinematic_multipliers) lambda *= factor;
    history_.kinematic_multiplier_scale = scale;
  }
}

double KinematicTargets::max_violation(const double* x) const {
  double worst = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i) {
    double squared = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double c = x[3 * size_t(vertices_[i]) + d] - target_[3 * i + d];
      squared += c * c;
    }
    worst = std::max(worst, std::sqrt(squared));
  }
  return worst;
}

double KinematicTargets::energy(const double* x) const {
  double sum = 0.0;
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d) {
      const double c = x[3 * size_t(vertices_[i]) + d] - target_[3 * i + d];
      sum += (0.5 * stiffness_[i] * c - history_.kinematic_multipliers[3 * i + d]) * c;
    }
  return sum;
}

void KinematicTargets::group_energy(const double* x, const int32_t* group_of_vertex, double* total) const {
  for (size_t i = 0; i < vertices_.size(); ++i) {
    const int32_t g = group_of_vertex[vertices_[i]];
    if (g < 0) continue;
    for (int d = 0; d < 3; ++d) {
      const double c = x[3 * size_t(vertices_[i]) + d] - target_[3 * i + d];
      total[g] += (0.5 * stiffness_[i] * c - history_.kinematic_multipliers[3 * i + d]) * c;
    }
  }
}

void KinematicTargets::add_gradient(const double* x, double* grad, double scale) const {
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d) {
      const size_t dof = 3 * size_t(vertices_[i]) + d;
      grad[dof] += scale * (stiffness_[i] * (x[dof] - target_[3 * i + d]) - history_.kinematic_multipliers[3 * i + d]);
    }
}

void KinematicTargets::add_hessian_diagonal(const CscPattern& pattern, double* values, double scale) const {
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d) values[pattern.diagonal[3 * size_t(vertices_[i]) + d]] += scale * stiffness_[i];
}

void KinematicTargets::update_multipliers(const double* x) {
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d)
      history_.kinematic_multipliers[3 * i + d] -= stiffness_[i] * (x[3 * size_t(vertices_[i]) + d] - target_[3 * i + d]);
}

Eigen::Vector3d KinematicTargets::total_force() const {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < vertices_.size(); ++i)
    sum += Eigen::Vector3d::Map(&history_.kinematic_multipliers[3 * i]);
  return sum / history_.kinematic_multiplier_scale;
}

void KinematicTargets::motion_to_targets(const double* x, double* p) const {
  std::fill(p, p + num_dofs_, 0.0);
  for (size_t i = 0; i < vertices_.size(); ++i)
    for (int d = 0; d < 3; ++d) {
      const size_t dof = 3 * size_t(vertices_[i]) + d;
      p[dof] = target_[3 * i + d] - x[dof];
    }
}

}  // namespace nexdyn

// Joints held by an augmented Lagrangian in the incremental potential (issue 4; DESIGN.md
// section 5, "joints").
//
// Every joint j has a linear constraint c_j(x) = sum_k a_k x_{v_k} + o = 0 (Model::Joint). The
// step's potential gets, per joint,
//   Phi_j(x) = k_j / 2 |c_j(x)|^2 - lambda_j . c_j(x)
// and Newton minimises it with everything else; between solves the multiplier is updated,
// lambda_j <- lambda_j - k_j c_j, until every |c_j| is below the tolerance (Nocedal & Wright,
// ch. 17). At a minimiser grad Psi = J^T (lambda - k c), so lambda - k c is the joint's force
// [N] on the body; the multiplier is kept from step to step (StepHistory::joint_multipliers), so a
// joint whose force changes slowly needs one solve per step. Why not a penalty alone: k large enough for 1e-6 accuracy
// would swamp the Newton matrix; why not hard constraints: they would need a saddle-point solve
// instead of the Cholesky factorisation the rest of the step uses.
//
// Because c is linear, Phi's Hessian k J^T J is constant: (k a a^T) (x) I3 over the joint's
// vertices. It is handed to ElasticAssembly as 12x12 slabs of "coupling groups" of 4 vertices
// (the joint's tet, and for a ball joint its other tet and 4 groups of 2 + 2 corners for the
// cross blocks), so it lands in the same pattern and gather as the elastic Hessian.
#pragma once

#include "engine/model.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace nexdyn {

class JointSet {
 public:
  // The multipliers live in `multipliers` (StepHistory::joint_multipliers, 3 per joint), which
  // is sized here and must outlive the set.
  JointSet(const Model& model, std::vector<double>& multipliers);

  bool empty() const { return joints_.empty(); }
  int64_t size() const { return static_cast<int64_t>(joints_.size()); }

  // (num_groups x 4) vertex ids of the coupling groups, for ElasticAssembly.
  const std::vector<int32_t>& coupling_groups() const { return groups_; }

  // Sets the weight w on Phi (energy, gradient and slabs): 1 / gamma under Newmark, where joint
  // forces act as end-of-step impulses like contact forces (incremental_potential.hpp); and
  // k_j = ratio * m_j / scale * stiffening, with m_j the mass of the joint's vertices and scale
  // the attempt's potential scale s (E = inertia + s Psi), so that s k_j = ratio m_j times the
  // stiffenings so far: the joint is `ratio` times stiffer than the inertia of its vertices.
  // Writes the slabs of w k J^T J (num_groups x 144, column-major 12x12) into `slabs`. Called
  // for every attempt at a step, from its StepContext.
  void set_stiffness(double weight, double scale, double ratio, double stiffening, double* slabs);
  double weight() const { return weight_; }

  // c_j(x) of joint j.
  Eigen::Vector3d violation(const double* x, int64_t j) const;
  // max_j |c_j(x)| [m]: the joint_violation column of stats.csv.
  double max_violation(const double* x) const;
  // w sum_j Phi_j(x).
  double energy(const double* x) const;
  // total[g] += the energy of the joints whose moving vertices are in group g
  // (group_of_vertex[v], -1 = does not move).
  void group_energy(const double* x, const int32_t* group_of_vertex, double* total) const;
  // grad += w sum_j J_j^T (k_j c_j - lambda_j).
  void add_gradient(const double* x, double* grad, double scale = 1.0) const;
  // lambda_j <- lambda_j - k_j c_j(x).
  void update_multipliers(const double* x);
  void set_multiplier(int64_t j, const Eigen::Vector3d& lambda) { multiplier(j) = lambda; }

  // Force of joint j on its vertices at a minimiser, lambda_j - k_j c_j(x) [N]; for tests.
  Eigen::Vector3d force(const double* x, int64_t j) const;

  // For the consistent initial acceleration: J (3 num_joints x 3 num_vertices) applied to a
  // per-vertex field, and J^T applied to per-joint vectors (added into out).
  void apply(const double* field, double* out) const;             // out = J field
  void apply_transpose(const double* per_joint, double* out) const;  // out += J^T per_joint

 private:
  void write_slabs(double* slabs) const;
  Eigen::Map<Eigen::Vector3d> multiplier(int64_t j) { return Eigen::Vector3d::Map(&multiplier_[3 * j]); }
  Eigen::Map<const Eigen::Vector3d> multiplier(int64_t j) const {
    return Eigen::Map<const Eigen::Vector3d>(&multiplier_[3 * j]);
  }

  const std::vector<Joint>& joints_;
  const std::vector<double>& mass_;
  std::vector<int32_t> groups_;
  std::vector<double> stiffness_;               // (num_joints) k_j [N/m] of the attempt under way
  std::vector<double>& multiplier_;             // (num_joints x 3) lambda_j [N], in the history
  double weight_ = 1.0;
};

}  // namespace nexdyn

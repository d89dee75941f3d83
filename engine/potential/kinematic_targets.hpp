// Moving boundaries and obstacles that push bodies (issue 4): the vertices of kinematic motions
// (DirichletMotion::kinematic) reach their prescribed positions through an augmented Lagrangian.
//
// Why not eliminate them like fixed vertices: an eliminated vertex jumps to its target before
// the solve, and if a body is in the way the step starts intersecting; no line search can undo
// that. As unknowns of the step they move with everything else, so CCD sweeps their motion and
// the barrier pushes what is in their way. The step's potential gets
//   Phi(x) = sum_i k_i / 2 |x_i - t_i|^2 - lambda_i . (x_i - t_i),   t_i: target at t_{n+1},
// and between Newton solves lambda_i <- lambda_i - k_i (x_i - t_i) until every |x_i - t_i| is
// below the tolerance (as for joints, engine/potential/joints.hpp: lambda - k (x - t) is the force that
// holds the vertex on its path, and it is kept from step to step in StepHistory, so steady pushing
// needs one solve per step). At the end of the step the vertices are set exactly to their targets, after
// a CCD check of that last, tiny move.
//
// k_i = ratio m_i, stiffer than the vertex's inertia by `ratio`; obstacle vertices have no mass
// and use the mean mass of the free vertices instead. The Hessian k_i I3 sits on the diagonal.
#pragma once

#include "engine/model.hpp"
#include "engine/step_history.hpp"
#include "engine/sparse/hessian_pattern.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace nexdyn {

class KinematicTargets {
 public:
  // The multipliers live in `history` (kinematic_multipliers, sized here; their scale and the
  // stiffening too), which must outlive the targets.
  KinematicTargets(const Model& model, StepHistory& history);
  bool empty() const { return vertices_.empty(); }
  const std::vector<int32_t>& vertices() const { return vertices_; }

  // The targets of the coming step: the kinematic vertices' entries of x_target (3 per vertex of
  // the model).
  void set_targets(const std::vector<double>& x_target);
  // For an attempt at a step whose potential scale is `scale` (E = inertia + s Psi): k_i =
  // ratio * m_i times the history's stiffening, and the multipliers, lambda = s f, brought to
  // this s if they were accumulated under another (a retried step's halves: by 1/4, exactly).
  void begin_attempt(double ratio, double scale);
  // k_i = ratio * m_i times the history's stiffening (after it changed).
  void set_stiffness(double ratio);

  // max_i |x_i - t_i| [m].
  double max_violation(const double* x) const;
  // total[g] += the energy of the targets of vertices in group g (group_of_vertex[v], -1 = none).
  void group_energy(const double* x, const int32_t* group_of_vertex, double* total) const;
  double energy(const double* x) const;
  void add_gradient(const double* x, double* grad, double scale = 1.0) const;
  // values[diagonal of each kinematic DOF] += k_i.
  void add_hessian_diagonal(const CscPattern& pattern, double* values, double scale = 1.0) const;
  // lambda_i <- lambda_i - k_i (x_i - t_i).
  void update_multipliers(const double* x);
  // The summed multipliers over their s [N]: after a step, the force that kept the kinematic
  // vertices on their paths (for a wall pushing a body: the push, e.g. the friction it overcomes).
  Eigen::Vector3d total_force() const;
  // p = t - x on the kinematic vertices, 0 elsewhere (p has 3 entries per model vertex).
  void motion_to_targets(const double* x, double* p) const;

 private:
  int64_t num_dofs_ = 0;           // of the model
  std::vector<int32_t> vertices_;  // (num) model vertex ids, increasing
  std::vector<double> mass_;       // (num) m_i behind k_i [kg]
  std::vector<double> stiffness_;  // (num) k_i [N/m] of the attempt under way
  std::vector<double> target_;     // (num x 3) t_i [m]
  StepHistory& history_;           // lambda_i: kinematic_multipliers, under kinematic_multiplier_scale
};

}  // namespace nexdyn

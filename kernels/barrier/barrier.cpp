// Adaptive barrier stiffness of IPC (Li et al. 2020, supplemental sec. 3); see barrier.hpp for
// the formulas and the squared-distance convention.
#include "kernels/barrier/barrier.hpp"

#include <algorithm>

namespace nexdyn {

double initial_barrier_stiffness(double bbox_diagonal, double dhat, double average_mass,
                                 const Eigen::VectorXd& grad_energy,
                                 const Eigen::VectorXd& grad_barrier,
                                 double& max_barrier_stiffness,
                                 double min_barrier_stiffness_scale) {
  // A tiny squared gap relative to the scene; it must lie inside (0, dhat) for b'' > 0.
  const double d0_length = 1e-8 * bbox_diagonal;
  double d0 = d0_length * d0_length;
  if (!(d0 > 0.0 && d0 < dhat)) d0 = 0.5 * dhat;
  const double curvature = 4.0 * d0 * barrier_second_derivative(d0, dhat);
  const double kappa_min = min_barrier_stiffness_scale * average_mass / curvature;
  max_barrier_stiffness = 100.0 * kappa_min;

  double kappa = kappa_min;
  const double gb2 = grad_barrier.squaredNorm();
  if (gb2 > 0.0) kappa = -grad_energy.dot(grad_barrier) / gb2;
  return std::clamp(kappa, kappa_min, max_barrier_stiffness);
}

double update_barrier_stiffness(double prev_min_distance, double min_distance,
                                double max_barrier_stiffness, double kappa, double bbox_diagonal,
                                double dhat_epsilon_scale) {
  const double eps_length = dhat_epsilon_scale * bbox_diagonal;
  const double dhat_epsilon = eps_length * eps_length;
  if (prev_min_distance < dhat_epsilon && min_distance < dhat_epsilon &&
      min_distance < prev_min_distance) {
    return std::min(max_barrier_stiffness, 2.0 * kappa);
  }
  return kappa;
}

}  // namespace nexdyn

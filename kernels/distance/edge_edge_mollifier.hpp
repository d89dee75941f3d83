// Mollifier for nearly parallel edge-edge pairs (IPC, Li et al. 2020, sec. 4.3 and supplemental
// sec. 1.2). As two edges become parallel the edge-edge distance stops being smooth (its closest
// points jump), so IPC multiplies the edge-edge barrier by
//   m(c) = -c^2 / eps_x^2 + 2 c / eps_x  for c < eps_x,  1 otherwise,
//   c = |(ea1 - ea0) x (eb1 - eb0)|^2,  eps_x = 1e-3 |ea0 - ea1|^2 |eb0 - eb1|^2 at REST,
// which is C1 at c = eps_x (m = 1, m' = 0) and vanishes with c at parallel edges. The engine
// forms the product rule for m(x) b(d(x)); this file provides m, dm/dx and d2m/dx2.
// DOFs [ea0, ea1, eb0, eb1]. eps_x depends on rest positions only: compute it once per pair.
#pragma once

#include "kernels/distance/distance_primitives.hpp"

namespace nexdyn {

// eps_x from the REST positions of the two edges (IPC supplemental: 1e-3 of the squared rest
// lengths' product, so the mollified band is a relative angle of about 1.8 degrees).
inline double edge_edge_mollifier_threshold(const Eigen::Vector3d& ea0_rest,
                                            const Eigen::Vector3d& ea1_rest,
                                            const Eigen::Vector3d& eb0_rest,
                                            const Eigen::Vector3d& eb1_rest) {
  return 1e-3 * (ea0_rest - ea1_rest).squaredNorm() * (eb0_rest - eb1_rest).squaredNorm();
}

// c = |ea x eb|^2 = |ea|^2 |eb|^2 - (ea . eb)^2.
inline double edge_edge_cross_squarednorm(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                          const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1) {
  return (ea1 - ea0).cross(eb1 - eb0).squaredNorm();
}

// dc/dx. With ea = ea1 - ea0 and eb = eb1 - eb0:
//   dc/dea = 2 |eb|^2 ea - 2 (ea . eb) eb,  dc/deb = 2 |ea|^2 eb - 2 (ea . eb) ea.
inline Vector12d edge_edge_cross_squarednorm_gradient(const Eigen::Vector3d& ea0,
                                                      const Eigen::Vector3d& ea1,
                                                      const Eigen::Vector3d& eb0,
                                                      const Eigen::Vector3d& eb1) {
  const Eigen::Vector3d ea = ea1 - ea0;
  const Eigen::Vector3d eb = eb1 - eb0;
  const double ab = ea.dot(eb);
  const Eigen::Vector3d ga = 2.0 * (eb.squaredNorm() * ea - ab * eb);
  const Eigen::Vector3d gb = 2.0 * (ea.squaredNorm() * eb - ab * ea);
  Vector12d g;
  g.segment<3>(0) = -ga;
  g.segment<3>(3) = ga;
  g.segment<3>(6) = -gb;
  g.segment<3>(9) = gb;
  return g;
}

// d2c/dx2 from the (ea, eb) blocks
//   d2c/dea2 = 2 |eb|^2 I - 2 eb eb^T,  d2c/deb2 = 2 |ea|^2 I - 2 ea ea^T,
//   d2c/dea deb = 4 ea eb^T - 2 eb ea^T - 2 (ea . eb) I,
// mapped through ea = ea1 - ea0, eb = eb1 - eb0 (signs -1, +1 per endpoint).
inline Matrix12d edge_edge_cross_squarednorm_hessian(const Eigen::Vector3d& ea0,
                                                     const Eigen::Vector3d& ea1,
                                                     const Eigen::Vector3d& eb0,
                                                     const Eigen::Vector3d& eb1) {
  const Eigen::Vector3d ea = ea1 - ea0;
  const Eigen::Vector3d eb = eb1 - eb0;
  const double ab = ea.dot(eb);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d blocks[2][2];
  blocks[0][0] = 2.0 * (eb.squaredNorm() * I - eb * eb.transpose());
  blocks[1][1] = 2.0 * (ea.squaredNorm() * I - ea * ea.transpose());
  blocks[0][1] = 4.0 * ea * eb.transpose() - 2.0 * eb * ea.transpose() - 2.0 * ab * I;
  blocks[1][0] = blocks[0][1].transpose();
  constexpr double kSign[4] = {-1.0, 1.0, -1.0, 1.0};
  Matrix12d H;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      H.block<3, 3>(3 * i, 3 * j) = kSign[i] * kSign[j] * blocks[i / 2][j / 2];
    }
  }
  return H;
}

inline double edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                  const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                  double eps_x) {
  const double c = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
  if (!(c < eps_x)) return 1.0;
  const double q = c / eps_x;
  return (2.0 - q) * q;
}

// dm/dx = m'(c) dc/dx with m'(c) = 2 (1 - c / eps_x) / eps_x; zero where c >= eps_x.
inline Vector12d edge_edge_mollifier_gradient(const Eigen::Vector3d& ea0,
                                              const Eigen::Vector3d& ea1,
                                              const Eigen::Vector3d& eb0,
                                              const Eigen::Vector3d& eb1, double eps_x) {
  const double c = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
  if (!(c < eps_x)) return Vector12d::Zero();
  const double dm = 2.0 * (1.0 - c / eps_x) / eps_x;
  return dm * edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1);
}

// d2m/dx2 = m''(c) dc dc^T + m'(c) d2c with m''(c) = -2 / eps_x^2 (m is C1 but not C2 at
// c = eps_x, as in the paper). Not PSD in general: the engine projects the full product.
inline Matrix12d edge_edge_mollifier_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                             const Eigen::Vector3d& eb0,
                                             const Eigen::Vector3d& eb1, double eps_x) {
  const double c = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
  if (!(c < eps_x)) return Matrix12d::Zero();
  const double dm = 2.0 * (1.0 - c / eps_x) / eps_x;
  const double d2m = -2.0 / (eps_x * eps_x);
  const Vector12d gc = edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1);
  return d2m * gc * gc.transpose() + dm * edge_edge_cross_squarednorm_hessian(ea0, ea1, eb0, eb1);
}

}  // namespace nexdyn

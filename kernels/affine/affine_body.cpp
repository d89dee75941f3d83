// Affine bodies: the orthogonality potential and exact mass properties (see affine_body.hpp).
#include "kernels/affine/affine_body.hpp"

#include "kernels/elasticity/analytic_eigensystem.hpp"
#include "kernels/elasticity/svd3.hpp"

namespace nexdyn {

namespace {

// The row-by-row index of A(r, c) in q, from the column-by-column one of vec(A) (r + 3c).
constexpr int kRowMajor[9] = {0, 3, 6, 1, 4, 7, 2, 5, 8};

}  // namespace

double orthogonality_energy(const Eigen::Matrix3d& A) {
  return (A * A.transpose() - Eigen::Matrix3d::Identity()).squaredNorm();
}

AffineVector9 orthogonality_gradient(const Eigen::Matrix3d& A) {
  const Eigen::Matrix3d G = 4.0 * (A * A.transpose() - Eigen::Matrix3d::Identity()) * A;
  AffineVector9 g;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) g[3 * r + c] = G(r, c);
  return g;
}

namespace {

enum class TwistCurvature { exact, turned };

AffineMatrix9 orthogonality_hessian_in_q(const Eigen::Matrix3d& A, bool project, TwistCurvature twist) {
  Svd3 svd;
  svd3(A, svd);
  const Eigen::Vector3d& s = svd.sigma;
  SingularValueDerivatives<double> d;
  for (int k = 0; k < 3; ++k) {
    d.dpsi[k] = 4.0 * s[k] * (s[k] * s[k] - 1.0);
    for (int l = 0; l < 3; ++l) d.d2psi(k, l) = k == l ? 4.0 * (3.0 * s[k] * s[k] - 1.0) : 0.0;
  }
  for (int p = 0; p < 3; ++p) {
    const double si = s[kSigmaPairs[p][0]], sj = s[kSigmaPairs[p][1]];
    d.flip[p] = 4.0 * (si * si + si * sj + sj * sj - 1.0);
    d.twist[p] = twist == TwistCurvature::exact ? 4.0 * (si * si - si * sj + sj * sj - 1.0) : 2.0 * (si - sj) * (si - sj);
  }
  const Matrix9d column_major = project ? isotropic_pk1_derivative<true>(svd, d) : isotropic_pk1_derivative<false>(svd, d);
  AffineMatrix9 H;
  for (int i = 0; i < 9; ++i)
    for (int j = 0; j < 9; ++j) H(kRowMajor[i], kRowMajor[j]) = column_major(i, j);
  return H;
}

}  // namespace

AffineMatrix9 orthogonality_hessian(const Eigen::Matrix3d& A, bool project) {
  return orthogonality_hessian_in_q(A, project, TwistCurvature::exact);
}

AffineMatrix9 orthogonality_hessian_for_turns(const Eigen::Matrix3d& A) {
  return orthogonality_hessian_in_q(A, true, TwistCurvature::turned);
}

AffineMassProperties affine_mass_properties(const std::vector<double>& positions, const std::vector<int32_t>& tets) {
  AffineMassProperties m;
  const auto corner = [&](size_t t, int k) { return Eigen::Vector3d::Map(&positions[3 * size_t(tets[4 * t + k])]); };
  const size_t num_tets = tets.size() / 4;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  for (size_t t = 0; t < num_tets; ++t) {
    const Eigen::Vector3d x0 = corner(t, 0);
    const double volume = (corner(t, 1) - x0).cross(corner(t, 2) - x0).dot(corner(t, 3) - x0) / 6.0;
    m.volume += volume;
    first += volume * 0.25 * (x0 + corner(t, 1) + corner(t, 2) + corner(t, 3));
  }
  if (m.volume == 0.0) return m;
  m.center = first / m.volume;
  for (size_t t = 0; t < num_tets; ++t) {
    Eigen::Vector3d y[4], sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < 4; ++k) sum += (y[k] = corner(t, k) - m.center);
    const double volume = (y[1] - y[0]).cross(y[2] - y[0]).dot(y[3] - y[0]) / 6.0;
    Eigen::Matrix3d outer = sum * sum.transpose();
    for (int k = 0; k < 4; ++k) outer += y[k] * y[k].transpose();
    m.second_moment += (volume / 20.0) * outer;
  }
  return m;
}

Eigen::Matrix3d inertia_tensor(const Eigen::Matrix3d& second_moment, double density) {
  return density * (second_moment.trace() * Eigen::Matrix3d::Identity() - second_moment);
}

}  // namespace nexdyn

// The spectral radius of Projective Dynamics' iteration matrix, for Chebyshev's acceleration
// (see ProjectiveDynamics in projective_dynamics.hpp): given, or estimated by Lanczos at the rest
// shape, once per potential scale s.
#include "engine/solver/projective_dynamics.hpp"

#include "engine/solver/projective_dynamics_internal.hpp"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace nexdyn {

using pd::Clock;
using pd::seconds_since;
using pd::tet_rows;

double ProjectiveDynamics::spectral_radius(double s) {
  return settings_.rho > 0.0 ? settings_.rho : estimated_spectral_radius(s);
}

double ProjectiveDynamics::estimated_spectral_radius(double s) {
  if (const auto it = rho_cache_.find(s); it != rho_cache_.end()) return it->second;
  if (num_free_ == 0) return rho_cache_[s] = 0.0;
  const auto start = Clock::now();
  // The plane-free A: the estimate must not depend on where the bodies happen to touch.
  const std::vector<uint8_t> planes = plane_count_;
  std::fill(plane_count_.begin(), plane_count_.end(), 0);
  const bool factored = factorize(s, nullptr);
  plane_count_ = planes;
  if (!factored) return 0.0;  // the solve will report the failure; no acceleration meanwhile

  const int64_t nf = num_free_;
  const int64_t size = 3 * nf;
  // C v = (A - H_rest) v = s sum_t 2 mu V G^T skew(G v), vectors in the 3-column layout.
  std::vector<double> full(model_.num_dofs(), 0.0);
  auto apply_c = [&](const std::vector<double>& v, std::vector<double>& out) {
    for (int64_t i = 0; i < nf; ++i)
      for (int d = 0; d < 3; ++d) full[3 * int64_t{free_vertex_[i]} + d] = v[d * nf + i];
    tet_to_vertices([&](int64_t t, double* slab) {
      Eigen::Vector3d d[4];
      tet_rows(model_, t, d);
      Eigen::Matrix3d Fv = Eigen::Matrix3d::Zero();
      for (int a = 0; a < 4; ++a)
        if (!(held_corners_[t] & (1u << a)))
          Fv += Eigen::Map<const Eigen::Vector3d>(full.data() + 3 * int64_t{model_.tets[4 * t + a]}) * d[a].transpose();
      const Eigen::Matrix3d skew = 0.5 * (Fv - Fv.transpose());
      const double w = s * weight_[t];
      for (int a = 0; a < 4; ++a) {
        const Eigen::Vector3d r = w * (skew * d[a]);
        for (int k = 0; k < 3; ++k) slab[3 * a + k] = r[k];
      }
    }, out);
  };
  auto solve_a = [&](std::vector<double>& b, std::vector<double>& x) {
    x.resize(size);
    for (int d = 0; d < 3; ++d)
      if (cholmod_.solve(b.data() + d * nf, x.data() + d * nf) != StepStatus::ok) return false;
    return true;
  };
  auto dot = [](const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0.0;
    for (size_t i = 0; i < a.size(); ++i) sum += a[i] * b[i];
    return sum;
  };

  // Lanczos on B = A^-1 C, self-adjoint in <u, v>_A = u^T A v, from a fixed pseudo-random start
  // (mt19937_64 is specified to the bit, and the conversion below is ours).
  std::mt19937_64 rng(20150801);
  std::vector<double> q(size), q_prev(size, 0.0), cq, w, aw;
  for (double& value : q) value = double(rng() >> 11) * 0x1.0p-53 - 0.5;
  multiply(values_, q, aw);
  double norm = std::sqrt(dot(q, aw));
  for (double& value : q) value /= norm;
  std::vector<double> alpha, beta;
  double rho = 0.0, previous = -1.0;
  for (int j = 0; j < std::min<int64_t>(kMaxLanczosSteps, size); ++j) {
    apply_c(q, cq);
    if (!solve_a(cq, w)) break;
    alpha.push_back(dot(q, cq));  // <B q, q>_A = q^T C q
    const double b_prev = beta.empty() ? 0.0 : beta.back();
    for (int64_t i = 0; i < size; ++i) w[i] -= alpha.back() * q[i] + b_prev * q_prev[i];
    multiply(values_, w, aw);
    const double b = std::sqrt(std::max(dot(w, aw), 0.0));

    const int k = static_cast<int>(alpha.size());
    Eigen::MatrixXd T = Eigen::MatrixXd::Zero(k, k);
    for (int i = 0; i < k; ++i) {
      T(i, i) = alpha[i];
      if (i + 1 < k) T(i, i + 1) = T(i + 1, i) = beta[i];
    }
    rho = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(T, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
    if (previous >= 0.0 && std::abs(rho - previous) < kRhoTolerance * (1.0 - rho)) break;
    previous = rho;
    if (!(b > 1e-14 * std::abs(alpha.back()))) break;  // an invariant subspace: rho is exact
    beta.push_back(b);
    q_prev.swap(q);
    for (int64_t i = 0; i < size; ++i) q[i] = w[i] / b;
  }
  // The estimate is a lower bound of rho in exact arithmetic; keep it inside (0, 1).
  rho = std::clamp(rho, 0.0, 1.0 - 1e-9);
  stats_.rho_seconds += seconds_since(start);
  return rho_cache_[s] = rho;
}

}  // namespace nexdyn

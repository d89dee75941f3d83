// The Newton system of the MPM step (see mpm_step.hpp): the incremental potential, its gradient
// and per-particle stiffness, the matrix-free product with M + s K, the preconditioned conjugate
// gradients on it, and the projections of the plane and box conditions.
#include "engine/mpm/mpm_step.hpp"

#include "engine/mpm/grid_elasticity.hpp"
#include "engine/parallel.hpp"
#include "kernels/elasticity/elasticity.hpp"

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace nexdyn {

namespace {

constexpr int64_t kMaxCgIterations = 5000;

// Chunked sum of f(i) over [0, n), the same bits on any thread count.
template <typename F>
double node_sum(int64_t n, F&& f) {
  return deterministic_sum(
      n,
      [&](int64_t begin, int64_t end) {
        double sum = 0.0;
        for (int64_t i = begin; i < end; ++i) sum += f(i);
        return sum;
      },
      kMpmNodeGrain);
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  return node_sum(static_cast<int64_t>(a.size()), [&](int64_t i) { return a[i] * b[i]; });
}

// The 27 stencil nodes of a particle with g_o = F^nT grad w_o (the rows of dF/du).
struct StencilRows {
  int64_t node[27];
  Eigen::Vector3d g[27];
};

StencilRows stencil_rows(const Grid& grid, const Particles& particles, int64_t p) {
  StencilRows rows;
  const BSplineStencil s = bspline_stencil(grid, &particles.x[3 * p]);
  const Eigen::Matrix3d Ft = particles.deformation(p).transpose();
  for_each_stencil_node(grid, s, [&](int64_t node, int o, double, const Eigen::Vector3d& grad) {
    rows.node[o] = node;
    rows.g[o] = Ft * grad;
  });
  return rows;
}

}  // namespace

// The largest move of a particle under the node displacements w: max_p |sum_i w_ip w_i|.
// Nodes at the fringe of the particles' stencils carry almost no mass, and their own increments
// say nothing about the motion; the particles' do.
double MpmStepper::particle_increment(const Particles& particles, const std::vector<double>& w) {
  const int64_t n = particles.size();
  std::vector<double>& largest = chunk_max_;
  largest.assign(static_cast<size_t>((n + 1023) / 1024), 0.0);
  for_each_chunk(n, 1024, [&](int64_t c, int64_t begin, int64_t end) {
    double m = 0.0;
    for (int64_t p = begin; p < end; ++p) {
      const BSplineStencil s = bspline_stencil(grid_, &particles.x[3 * p]);
      Eigen::Vector3d move = Eigen::Vector3d::Zero();
      for_each_stencil_node(grid_, s, [&](int64_t node, int, double weight, const Eigen::Vector3d&) {
        const int32_t k = active_index_[node];
        if (k >= 0) move += weight * Eigen::Map<const Eigen::Vector3d>(&w[3 * int64_t{k}]);
      });
      m = std::max(m, move.cwiseAbs().maxCoeff());
    }
    largest[c] = m;
  });
  double m = 0.0;
  for (double x : largest) m = std::max(m, x);
  return m;
}

void MpmStepper::invert_projected_blocks() {
  for (size_t k = 0; k < active_.size(); ++k) {
    Eigen::Map<Eigen::Matrix3d> D(&diag_[9 * k]);
    if (hold_[k] == kFull) {
      D.setIdentity();
      continue;
    }
    if (hold_[k] == kNormal) {
      const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
      const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - n * n.transpose();
      D = (P * D * P + n * n.transpose()).eval();
    }
    D = D.inverse().eval();
  }
}

void MpmStepper::project(std::vector<double>& w) const {
  for (size_t k = 0; k < active_.size(); ++k) {
    if (hold_[k] == kFree) continue;
    Eigen::Map<Eigen::Vector3d> wk(&w[3 * k]);
    if (hold_[k] == kFull) {
      wk.setZero();
    } else {
      const Eigen::Map<const Eigen::Vector3d> n(&normal_[3 * k]);
      wk -= n * n.dot(wk);
    }
  }
}

void MpmStepper::scatter_to_dense(const std::vector<double>& compact, std::vector<double>& dense) const {
  for (size_t k = 0; k < active_.size(); ++k)
    for (int d = 0; d < 3; ++d) dense[3 * int64_t{active_[k]} + d] = compact[3 * k + d];
}

double MpmStepper::energy(const Particles& particles, const std::vector<double>& u, double s) {
  scatter_to_dense(u, dense_u_);
  const double elastic = grid_elastic_energy(grid_, particles, model_.materials, dense_u_.data());
  if (!std::isfinite(elastic)) return std::numeric_limits<double>::infinity();
  const Eigen::Vector3d& g = model_.gravity;
  const double inertia = node_sum(static_cast<int64_t>(active_.size()), [&](int64_t k) {
    double e = 0.0;
    for (int d = 0; d < 3; ++d) {
      const double du = u[3 * k + d] - u_tilde_[3 * k + d];
      e += 0.5 * m_[k] * du * du - s * m_[k] * g[d] * u[3 * k + d];
    }
    return e;
  });
  return inertia + s * elastic;
}

// The gradient g of E at u (compact, unprojected), and, for the linear solves, each particle's
// V_p dP/dF (projected) and the diagonal blocks of M + s K. Returns E_el(u).
double MpmStepper::gradient_and_stiffness(const Particles& particles, const std::vector<double>& u, double s,
                                          std::vector<double>& g) {
  scatter_to_dense(u, dense_u_);
  std::fill(dense_work_.begin(), dense_work_.end(), 0.0);
  const int64_t np = particles.size();
  stiffness_.resize(static_cast<size_t>(81 * np));
  particle_energy_.resize(static_cast<size_t>(np));
  const size_t na = active_.size();
  diag_.assign(9 * na, 0.0);
  for_each_particle_coloured(bins_, [&](int32_t p) {
    const StencilRows rows = stencil_rows(grid_, particles, p);
    Eigen::Matrix3d F = particles.deformation(p);
    for (int o = 0; o < 27; ++o) F += Eigen::Map<const Eigen::Vector3d>(&dense_u_[3 * rows.node[o]]) * rows.g[o].transpose();
    const Material& material = model_.materials[particles.material[p]];
    const double V = particles.volume0[p];
    particle_energy_[p] = V * energy_density(material.model, F, material.lame);
    const Eigen::Matrix3d VP = V * pk1(material.model, F, material.lame);
    Eigen::Map<Matrix9d> A(&stiffness_[81 * int64_t{p}]);
    A = V * pk1_derivative_projected(material.model, F, material.lame);
    for (int o = 0; o < 27; ++o) {
      Eigen::Vector3d::Map(&dense_work_[3 * rows.node[o]]) += VP * rows.g[o];
      const int32_t k = active_index_[rows.node[o]];
      if (k < 0) continue;
      // Block (c, e) = sum_{b, d} g_b A(c + 3b, e + 3d) g_d.
      Eigen::Matrix3d block = Eigen::Matrix3d::Zero();
      for (int b = 0; b < 3; ++b)
        for (int d = 0; d < 3; ++d) block += (rows.g[o][b] * rows.g[o][d]) * A.block<3, 3>(3 * b, 3 * d);
      Eigen::Matrix3d::Map(&diag_[9 * k]) += block;
    }
  });
  const Eigen::Vector3d& grav = model_.gravity;
  g.resize(3 * na);
  for (size_t k = 0; k < na; ++k)
    for (int d = 0; d < 3; ++d)
      g[3 * k + d] = m_[k] * (u[3 * k + d] - u_tilde_[3 * k + d]) - s * m_[k] * grav[d] +
                     s * dense_work_[3 * int64_t{active_[k]} + d];
  return deterministic_sum(np, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t p = begin; p < end; ++p) sum += particle_energy_[p];
    return sum;
  });
}

// out = (M + s K) w, K in its factored per-particle form. With g_o = F_n^T grad w_o, a particle's
// dF = sum_o w_o g_o^T = (sum_o w_o grad w_o^T) F_n and its forces dP g_o = (dP F_n^T) grad w_o,
// so each node costs one outer product in and one 3x3 product out, and F_n is applied once.
void MpmStepper::apply_hessian(const Particles& particles, double s, const std::vector<double>& w,
                               std::vector<double>& out) {
  const size_t na = active_.size();
  out.resize(3 * na);
  for (size_t k = 0; k < na; ++k)
    for (int d = 0; d < 3; ++d) out[3 * k + d] = m_[k] * w[3 * k + d];
  for_each_particle_coloured(bins_, [&](int32_t p) {
    const BSplineStencil stencil = bspline_stencil(grid_, &particles.x[3 * p]);
    int32_t k[27];
    Eigen::Matrix3d G = Eigen::Matrix3d::Zero();
    for_each_stencil_node(grid_, stencil, [&](int64_t node, int o, double, const Eigen::Vector3d& grad) {
      k[o] = active_index_[node];
      if (k[o] >= 0) G += Eigen::Map<const Eigen::Vector3d>(&w[3 * int64_t{k[o]}]) * grad.transpose();
    });
    const Eigen::Matrix3d F_n = particles.deformation(p);
    const Eigen::Matrix3d dF = G * F_n;
    const Eigen::Map<const Matrix9d> A(&stiffness_[81 * int64_t{p}]);
    Eigen::Matrix<double, 9, 1> dP = A * Eigen::Map<const Eigen::Matrix<double, 9, 1>>(dF.data());
    const Eigen::Matrix3d Q = s * (Eigen::Map<const Eigen::Matrix3d>(dP.data()) * F_n.transpose());
    for_each_stencil_node(grid_, stencil, [&](int64_t, int o, double, const Eigen::Vector3d& grad) {
      if (k[o] >= 0) Eigen::Vector3d::Map(&out[3 * int64_t{k[o]}]) += Q * grad;
    });
  });
}

// Preconditioned conjugate gradients on the projected system P (M + s K) P x = P rhs, from x = 0,
// with the inverses of the projected diagonal blocks as preconditioner (in diag_).
int64_t MpmStepper::conjugate_gradients(const Particles& particles, double s, const std::vector<double>& rhs,
                                        double tolerance, std::vector<double>& x) {
  const size_t n = rhs.size();
  x.assign(n, 0.0);
  r_ = rhs;
  project(r_);
  auto precondition = [&](const std::vector<double>& r, std::vector<double>& z) {
    z.resize(n);
    for (size_t k = 0; k < active_.size(); ++k)
      Eigen::Vector3d::Map(&z[3 * k]) =
          Eigen::Map<const Eigen::Matrix3d>(&diag_[9 * k]) * Eigen::Map<const Eigen::Vector3d>(&r[3 * k]);
    project(z);
  };
  const double r0 = std::sqrt(dot(r_, r_));
  if (r0 == 0.0) return 0;
  precondition(r_, z_);
  p_ = z_;
  double rz = dot(r_, z_);
  int64_t it = 0;
  while (it < kMaxCgIterations) {
    ++it;
    apply_hessian(particles, s, p_, q_);
    project(q_);
    const double pq = dot(p_, q_);
    if (!(pq > 0.0)) break;
    const double alpha = rz / pq;
    for (size_t i = 0; i < n; ++i) {
      x[i] += alpha * p_[i];
      r_[i] -= alpha * q_[i];
    }
    if (std::sqrt(dot(r_, r_)) <= tolerance * r0) break;
    precondition(r_, z_);
    const double rz_new = dot(r_, z_);
    const double beta = rz_new / rz;
    rz = rz_new;
    for (size_t i = 0; i < n; ++i) p_[i] = z_[i] + beta * p_[i];
  }
  return it;
}

}  // namespace nexdyn

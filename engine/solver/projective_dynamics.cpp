// Projective Dynamics with Chebyshev acceleration (see projective_dynamics.hpp).
#include "engine/solver/projective_dynamics.hpp"

#include "engine/parallel.hpp"
#include "engine/stop_request.hpp"
#include "engine/solver/projective_dynamics_internal.hpp"
#include "kernels/elasticity/svd3.hpp"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <utility>

namespace nexdyn {

using pd::Clock;
using pd::seconds_since;
using pd::tet_rows;

namespace {

// F of tet t at positions x (3n), with the rows d.
inline Eigen::Matrix3d deformation(const Model& model, int64_t t, const double* x, const Eigen::Vector3d d[4]) {
  Eigen::Matrix3d F = Eigen::Matrix3d::Zero();
  for (int a = 0; a < 4; ++a) F += Eigen::Map<const Eigen::Vector3d>(x + 3 * int64_t{model.tets[4 * t + a]}) * d[a].transpose();
  return F;
}

inline Eigen::Matrix3d closest_rotation(const Eigen::Matrix3d& F) {
  Svd3 svd;
  svd3(F, svd);
  return svd.U * svd.V.transpose();
}

std::string format(const char* fmt, double a, double b) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, a, b);
  return buf;
}

}  // namespace

ProjectiveDynamics::ProjectiveDynamics(const Model& model, PdSettings settings)
    : model_(model), settings_(settings) {
  const int32_t n = model.num_vertices;
  const int64_t num_tets = model.num_tets;
  free_index_.assign(n, -1);
  for (int32_t v = 0; v < n; ++v)
    if (model.dirichlet[v] < 0 && model.mass[v] > 0.0) {
      free_index_[v] = num_free_++;
      free_vertex_.push_back(v);
    }

  weight_.resize(num_tets);
  held_corners_.assign(num_tets, 0);
  for (int64_t t = 0; t < num_tets; ++t) {
    weight_[t] = 2.0 * model.materials[model.tet_material[t]].lame.mu * model.rest_volume[t];
    for (int a = 0; a < 4; ++a)
      if (free_index_[model.tets[4 * t + a]] < 0) held_corners_[t] |= uint8_t(1u << a);
  }

  // Scalar upper pattern over free vertices: (column j, row i <= j) pairs, sorted.
  std::vector<std::pair<int32_t, int32_t>> pairs;
  pairs.reserve(static_cast<size_t>(num_tets) * 10 + num_free_);
  for (int32_t i = 0; i < num_free_; ++i) pairs.emplace_back(i, i);
  for (int64_t t = 0; t < num_tets; ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const int32_t fa = free_index_[model.tets[4 * t + a]], fb = free_index_[model.tets[4 * t + b]];
        if (fa >= 0 && fb >= 0) pairs.emplace_back(std::max(fa, fb), std::min(fa, fb));
      }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  col_ptr_.assign(num_free_ + 1, 0);
  row_idx_.resize(pairs.size());
  for (size_t k = 0; k < pairs.size(); ++k) {
    ++col_ptr_[pairs[k].first + 1];
    row_idx_[k] = pairs[k].second;
  }
  for (int32_t j = 0; j < num_free_; ++j) col_ptr_[j + 1] += col_ptr_[j];
  diagonal_.resize(num_free_);
  for (int32_t j = 0; j < num_free_; ++j) diagonal_[j] = col_ptr_[j + 1] - 1;  // rows sorted, i <= j

  tet_slot_.assign(static_cast<size_t>(num_tets) * 16, -1);
  for (int64_t t = 0; t < num_tets; ++t)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) {
        const int32_t fa = free_index_[model.tets[4 * t + a]], fb = free_index_[model.tets[4 * t + b]];
        if (fa < 0 || fb < 0 || fa > fb) continue;
        const auto first = pairs.begin() + col_ptr_[fb], last = pairs.begin() + col_ptr_[fb + 1];
        tet_slot_[16 * t + 4 * a + b] = std::lower_bound(first, last, std::make_pair(fb, fa)) - pairs.begin();
      }

  corner_ptr_.assign(num_free_ + 1, 0);
  for (int64_t c = 0; c < 4 * num_tets; ++c) {
    const int32_t f = free_index_[model.tets[c]];
    if (f >= 0) ++corner_ptr_[f + 1];
  }
  for (int32_t i = 0; i < num_free_; ++i) corner_ptr_[i + 1] += corner_ptr_[i];
  corners_.resize(corner_ptr_.back());
  std::vector<int64_t> fill(corner_ptr_.begin(), corner_ptr_.end() - 1);
  for (int64_t c = 0; c < 4 * num_tets; ++c) {  // increasing c: each vertex's corners in tet order
    const int32_t f = free_index_[model.tets[c]];
    if (f >= 0) corners_[fill[f]++] = c;
  }

  Eigen::Vector3d lo = Eigen::Vector3d::Constant(HUGE_VAL), hi = -lo;
  for (int32_t v = 0; v < n; ++v) {
    const Eigen::Vector3d p(model.rest_positions.data() + 3 * int64_t{v});
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  bbox_diagonal_ = n > 0 ? (hi - lo).norm() : 0.0;

  slab_.resize(static_cast<size_t>(num_tets) * 12);
  rhs_.resize(3 * static_cast<size_t>(num_free_));
  sol_.resize(3 * static_cast<size_t>(num_free_));
  plane_count_.assign(num_free_, 0);
  plane_target_.assign(3 * static_cast<size_t>(num_free_), 0.0);
}

void ProjectiveDynamics::assemble_base(double s) {
  if (base_s_ == s) return;
  base_values_.assign(row_idx_.size(), 0.0);
  for (int32_t i = 0; i < num_free_; ++i) base_values_[diagonal_[i]] = model_.mass[free_vertex_[i]];
  // Serial, tets in order: the matrix is assembled once per s, and a fixed order makes it the
  // same double on any number of threads.
  Eigen::Vector3d d[4];
  for (int64_t t = 0; t < model_.num_tets; ++t) {
    tet_rows(model_, t, d);
    const double w = s * weight_[t];
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) {
        const int64_t slot = tet_slot_[16 * t + 4 * a + b];
        if (slot >= 0) base_values_[slot] += w * d[a].dot(d[b]);
      }
  }
  base_s_ = s;
}

bool ProjectiveDynamics::factorize(double s, PdResult* result) {
  if (factor_s_ == s && factor_planes_ == plane_count_) return true;
  const auto start = Clock::now();
  StepStatus status = StepStatus::ok;
  if (!cholmod_.has_analysis()) status = cholmod_.analyze(num_free_, col_ptr_.data(), row_idx_.data());
  if (status == StepStatus::ok) {
    assemble_base(s);
    values_ = base_values_;
    for (int32_t i = 0; i < num_free_; ++i)
      if (plane_count_[i]) values_[diagonal_[i]] += plane_count_[i] * kPlaneWeight * base_values_[diagonal_[i]];
    status = cholmod_.factorize(values_.data());
  }
  stats_.factor_seconds += seconds_since(start);
  if (status != StepStatus::ok) {
    factor_s_ = -1.0;
    if (result) {
      result->status = status;
      result->message = "projective dynamics: " + cholmod_.error();
    }
    return false;
  }
  factor_s_ = s;
  factor_planes_ = plane_count_;
  ++stats_.factorizations;
  if (result) ++result->factorizations;
  return true;
}

void ProjectiveDynamics::local_step(double s, const double* x) {
  const auto start = Clock::now();
  double* slab = slab_.data();
  parallel_for(model_.num_tets, [&](int64_t begin, int64_t end) {
    Eigen::Vector3d d[4];
    for (int64_t t = begin; t < end; ++t) {
      tet_rows(model_, t, d);
      const Eigen::Matrix3d R = closest_rotation(deformation(model_, t, x, d));
      const double w = s * weight_[t];
      double* out = slab + 12 * t;
      for (int a = 0; a < 4; ++a) {
        Eigen::Vector3d r = R * d[a];
        // Held corners' columns of A go to the right-hand side.
        if (held_corners_[t])
          for (int b = 0; b < 4; ++b)
            if (held_corners_[t] & (1u << b))
              r -= d[a].dot(d[b]) * Eigen::Map<const Eigen::Vector3d>(x + 3 * int64_t{model_.tets[4 * t + b]});
        for (int k = 0; k < 3; ++k) out[3 * a + k] = w * r[k];
      }
    }
  }, kPdTetGrain);
  stats_.local_seconds += seconds_since(start);
  stats_.local_tets += model_.num_tets;
}

bool ProjectiveDynamics::global_step(double s, const double* x_tilde, double* xhat, PdResult& result) {
  const auto start = Clock::now();
  const int64_t nf = num_free_;
  const double* slab = slab_.data();
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  parallel_for(nf, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const int64_t v = free_vertex_[i];
      const double m = model_.mass[v];
      double sum[3] = {0.0, 0.0, 0.0};
      for (int64_t k = corner_ptr_[i]; k < corner_ptr_[i + 1]; ++k) {
        const double* c = slab + 3 * corners_[k];
        for (int d = 0; d < 3; ++d) sum[d] += c[d];
      }
      const double w = plane_count_[i] ? kPlaneWeight * base_values_[diagonal_[i]] : 0.0;
      for (int d = 0; d < 3; ++d)
        rhs_[d * nf + i] = m * (x_tilde[3 * v + d] + s * g[d]) + sum[d] + w * plane_target_[3 * i + d];
    }
  }, kPdVertexGrain);
  for (int d = 0; d < 3; ++d) {
    const StepStatus status = cholmod_.solve(rhs_.data() + d * nf, sol_.data() + d * nf);
    if (status != StepStatus::ok) {
      result.status = status;
      result.message = "projective dynamics: " + cholmod_.error();
      stats_.global_seconds += seconds_since(start);
      return false;
    }
  }
  parallel_for(nf, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i)
      for (int d = 0; d < 3; ++d) xhat[3 * int64_t{free_vertex_[i]} + d] = sol_[d * nf + i];
  }, kPdVertexGrain);
  stats_.global_seconds += seconds_since(start);
  return true;
}

void ProjectiveDynamics::update_planes(const double* x) {
  const auto& planes = model_.obstacle_planes;
  if (planes.empty()) return;
  const double margin = settings_.plane_margin >= 0.0 ? settings_.plane_margin : 1e-6 * bbox_diagonal_;
  parallel_for(num_free_, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p(x + 3 * int64_t{free_vertex_[i]});
      uint8_t count = 0;
      Eigen::Vector3d target = Eigen::Vector3d::Zero();
      for (const ObstaclePlane& plane : planes) {
        const double distance = (p - plane.point).dot(plane.normal);
        if (distance >= margin || count == 255) continue;
        ++count;
        target += p - std::min(distance, 0.0) * plane.normal;
      }
      plane_count_[i] = count;
      for (int d = 0; d < 3; ++d) plane_target_[3 * i + d] = target[d];
    }
  }, kPdVertexGrain);
}

void ProjectiveDynamics::project_onto_planes(double* x) const {
  for (const ObstaclePlane& plane : model_.obstacle_planes)
    for (int32_t v : free_vertex_) {
      Eigen::Map<Eigen::Vector3d> p(x + 3 * int64_t{v});
      const double distance = (p - plane.point).dot(plane.normal);
      if (distance < 0.0) p -= distance * plane.normal;
    }
}

void ProjectiveDynamics::multiply(const std::vector<double>& values, const std::vector<double>& v,
                                  std::vector<double>& y) const {
  const int64_t nf = num_free_;
  y.assign(3 * nf, 0.0);
  for (int d = 0; d < 3; ++d) {
    const double* vd = v.data() + d * nf;
    double* yd = y.data() + d * nf;
    for (int64_t j = 0; j < nf; ++j)
      for (int64_t k = col_ptr_[j]; k < col_ptr_[j + 1]; ++k) {
        const int64_t i = row_idx_[k];
        yd[i] += values[k] * vd[j];
        if (i != j) yd[j] += values[k] * vd[i];
      }
  }
}

PdResult ProjectiveDynamics::solve(double s, double dt, const std::vector<double>& x_tilde, std::vector<double>& x) {
  PdResult result;
  if (num_free_ == 0) return result;
  const bool chebyshev = settings_.chebyshev;
  const bool measure_rho = chebyshev && settings_.rho_from_iterations && !(settings_.rho > 0.0);
  double rho = chebyshev && !measure_rho ? spectral_radius(s) : 0.0;
  std::vector<double> residuals;  // max|p| of the plain iterations, for measure_rho
  bool measured = false;
  const double gamma = chebyshev ? settings_.under_relaxation : 1.0;
  const int64_t ndofs = model_.num_dofs();

  std::vector<double> x_prev = x, xhat = x, next(ndofs);
  double omega = 1.0;
  int accelerated = 0;  // iterations since the Chebyshev recurrence (re)started
  for (int k = 0; k < settings_.max_iterations; ++k) {
    if (k % 16 == 0) stop_point();
    if (!model_.obstacle_planes.empty()) {
      update_planes(x.data());
      if (factor_s_ == s && factor_planes_ != plane_count_ && accelerated >= kPlainIterations)
        accelerated = kPlainIterations - 1;  // A changed: the recurrence restarts at omega = 1
    }
    if (!factorize(s, &result)) return result;
    local_step(s, x.data());
    if (!global_step(s, x_tilde.data(), xhat.data(), result)) return result;
    ++result.iterations;
    ++stats_.iterations;
    if (history_) history_->push_back(xhat);

    double max_step = 0.0;
    bool finite = true;
    for (int32_t v : free_vertex_)
      for (int d = 0; d < 3; ++d) {
        const double p = xhat[3 * int64_t{v} + d] - x[3 * int64_t{v} + d];
        finite = finite && std::isfinite(p);
        max_step = std::max(max_step, std::abs(p));
      }
    result.residual = max_step / dt;
    if (!finite) {
      result.status = StepStatus::non_finite;
      result.message = "projective dynamics: the positions are not finite";
      return result;
    }
    if (result.residual < settings_.tolerance) {
      x.swap(xhat);
      project_onto_planes(x.data());
      for (int32_t i = 0; i < num_free_; ++i) result.plane_vertices += plane_count_[i] > 0;
      return result;
    }

    if (!chebyshev) {
      x.swap(xhat);
      continue;
    }
    if (accelerated < kPlainIterations) {
      omega = 1.0;
      residuals.push_back(max_step);
    } else if (accelerated == kPlainIterations) {
      if (measure_rho && !measured && residuals.size() > kRateIterations) {  // once per step
        measured = true;
        const size_t n = residuals.size();
        const double rate = std::pow(residuals[n - 1] / residuals[n - 1 - kRateIterations], 1.0 / kRateIterations);
        rho = std::isfinite(rate) ? std::clamp(1.0 - (1.0 - rate) / gamma, 0.0, 0.9999) : 0.0;
      }
      omega = 2.0 / (2.0 - rho * rho);
    }
    else omega = 4.0 / (4.0 - rho * rho * omega);
    ++accelerated;
    for (int32_t v : free_vertex_)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * int64_t{v} + d;
        next[i] = omega * (gamma * (xhat[i] - x[i]) + x[i] - x_prev[i]) + x_prev[i];
      }
    for (int32_t v : free_vertex_)
      for (int d = 0; d < 3; ++d) {
        const int64_t i = 3 * int64_t{v} + d;
        x_prev[i] = x[i];
        x[i] = next[i];
      }
  }
  x.swap(xhat);  // the last plain result: no worse than the last iterate
  project_onto_planes(x.data());
  for (int32_t i = 0; i < num_free_; ++i) result.plane_vertices += plane_count_[i] > 0;
  result.status = StepStatus::max_iterations;
  result.message = format("projective dynamics did not converge in the iteration limit (last residual "
                          "%.3g m/s, tolerance %.3g m/s)", result.residual, settings_.tolerance);
  return result;
}

double ProjectiveDynamics::energy(double s, const std::vector<double>& x_tilde, const std::vector<double>& x) {
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  const double inertia = deterministic_sum(model_.num_vertices, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    for (int64_t v = begin; v < end; ++v) {
      double kinetic = 0.0, work = 0.0;
      for (int d = 0; d < 3; ++d) {
        const double dx = x[3 * v + d] - x_tilde[3 * v + d];
        kinetic += dx * dx;
        work += g[d] * dx;
      }
      sum += model_.mass[v] * (0.5 * kinetic - s * work);
    }
    return sum;
  }, kPdVertexGrain);
  const double elastic = deterministic_sum(model_.num_tets, [&](int64_t begin, int64_t end) {
    double sum = 0.0;
    Eigen::Vector3d d[4];
    for (int64_t t = begin; t < end; ++t) {
      tet_rows(model_, t, d);
      const Eigen::Matrix3d F = deformation(model_, t, x.data(), d);
      sum += 0.5 * weight_[t] * (F - closest_rotation(F)).squaredNorm();  // mu V ||F - R||^2
    }
    return sum;
  }, kPdTetGrain);
  return inertia + s * elastic;
}

void ProjectiveDynamics::gradient(double s, const std::vector<double>& x_tilde, const std::vector<double>& x,
                                  std::vector<double>& grad) {
  std::vector<double> elastic;
  tet_to_vertices([&](int64_t t, double* slab) {
    Eigen::Vector3d d[4];
    tet_rows(model_, t, d);
    const Eigen::Matrix3d F = deformation(model_, t, x.data(), d);
    const Eigen::Matrix3d P = s * weight_[t] * (F - closest_rotation(F));  // s dPsi/dF V
    for (int a = 0; a < 4; ++a) {
      const Eigen::Vector3d r = P * d[a];
      for (int k = 0; k < 3; ++k) slab[3 * a + k] = r[k];
    }
  }, elastic);
  const double g[3] = {model_.gravity.x(), model_.gravity.y(), model_.gravity.z()};
  const int64_t nf = num_free_;
  grad.assign(model_.num_dofs(), 0.0);
  for (int64_t i = 0; i < nf; ++i) {
    const int64_t v = free_vertex_[i];
    for (int d = 0; d < 3; ++d)
      grad[3 * v + d] = model_.mass[v] * (x[3 * v + d] - x_tilde[3 * v + d] - s * g[d]) + elastic[d * nf + i];
  }
}

}  // namespace nexdyn

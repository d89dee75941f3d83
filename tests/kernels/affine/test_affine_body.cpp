// The affine-body kernels (kernels/affine/affine_body.hpp): the orthogonality potential's gradient
// and Hessian against finite differences, its closed-form PSD projection against a numerical
// eigendecomposition, rotations as its zero set, and mass properties integrated exactly over tets
// against a box's closed form.
#include "kernels/affine/affine_body.hpp"

#include <doctest/doctest.h>

#include "kernels/projection/psd_projection.hpp"
#include <Eigen/Geometry>

#include <cmath>
#include <random>
#include <vector>

using namespace nexdyn;

namespace {

Eigen::Matrix3d from_q(const AffineVector9& a) {
  Eigen::Matrix3d A;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A(r, c) = a[3 * r + c];
  return A;
}

AffineVector9 to_q(const Eigen::Matrix3d& A) {
  AffineVector9 a;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[3 * r + c] = A(r, c);
  return a;
}

// A rotation times (I + amount * a random matrix): near a rigid motion for small amounts, far
// from one (and possibly inverted) for large ones.
Eigen::Matrix3d random_affine(std::mt19937& rng, double amount) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).matrix();
  Eigen::Matrix3d P;
  for (int k = 0; k < 9; ++k) P(k / 3, k % 3) = u(rng);
  return R * (Eigen::Matrix3d::Identity() + amount * P);
}

// The PSD part of a symmetric matrix, by a numerical eigendecomposition.
AffineMatrix9 numerical_projection(const AffineMatrix9& H) {
  const SymmetricEigen eig = symmetric_eigen(0.5 * (H + H.transpose()));
  return eig.vectors * eig.values.cwiseMax(0.0).asDiagonal() * eig.vectors.transpose();
}

// Tets of an axis-aligned box [lo, hi], six per box (the Kuhn split of the cube), all positive.
void box_tets(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, std::vector<double>& x, std::vector<int32_t>& tets) {
  const int32_t base = static_cast<int32_t>(x.size() / 3);
  for (int k = 0; k < 8; ++k)
    for (int d = 0; d < 3; ++d) x.push_back((k >> d) & 1 ? hi[d] : lo[d]);
  // Paths from corner 0 to corner 7 along the axes in every order.
  const int orders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (const auto& o : orders) {
    int32_t v[4] = {0, 0, 0, 0};
    for (int s = 0; s < 3; ++s) v[s + 1] = v[s] | (1 << o[s]);
    const Eigen::Vector3d p0 = Eigen::Vector3d::Map(&x[3 * size_t(base + v[0])]);
    const double det = (Eigen::Vector3d::Map(&x[3 * size_t(base + v[1])]) - p0)
                           .cross(Eigen::Vector3d::Map(&x[3 * size_t(base + v[2])]) - p0)
                           .dot(Eigen::Vector3d::Map(&x[3 * size_t(base + v[3])]) - p0);
    if (det < 0) std::swap(v[2], v[3]);
    for (int32_t k : v) tets.push_back(base + k);
  }
}

}  // namespace

TEST_CASE("affine orthogonality: gradient and Hessian agree with central differences") {
  std::mt19937 rng(11);
  for (double amount : {0.01, 0.3, 1.5}) {
    for (int sample = 0; sample < 5; ++sample) {
      CAPTURE(amount);
      CAPTURE(sample);
      const Eigen::Matrix3d A = random_affine(rng, amount);
      const AffineVector9 a = to_q(A);
      const AffineVector9 g = orthogonality_gradient(A);
      const AffineMatrix9 H = orthogonality_hessian(A, false);
      const double h = 1e-5;
      AffineVector9 g_fd;
      AffineMatrix9 H_fd;
      for (int i = 0; i < 9; ++i) {
        AffineVector9 up = a, down = a;
        up[i] += h;
        down[i] -= h;
        g_fd[i] = (orthogonality_energy(from_q(up)) - orthogonality_energy(from_q(down))) / (2 * h);
        H_fd.col(i) = (orthogonality_gradient(from_q(up)) - orthogonality_gradient(from_q(down))) / (2 * h);
      }
      // The energy is a quartic: central differences are exact up to h^2 times its fourth
      // derivative (24 at most per unit) and rounding.
      CHECK((g - g_fd).norm() <= 1e-8 * (1.0 + g.norm()));
      CHECK((H - H_fd).norm() <= 1e-7 * (1.0 + H.norm()));
      CHECK((H - H.transpose()).norm() <= 1e-12 * H.norm());
    }
  }
}

TEST_CASE("affine orthogonality: the closed-form projection is the nearest PSD matrix") {
  std::mt19937 rng(12);
  int indefinite = 0;
  for (double amount : {0.0, 0.05, 0.4, 0.9, 2.0}) {
    for (int sample = 0; sample < 8; ++sample) {
      CAPTURE(amount);
      CAPTURE(sample);
      const Eigen::Matrix3d A = random_affine(rng, amount);
      const AffineMatrix9 H = orthogonality_hessian(A, false);
      const AffineMatrix9 projected = orthogonality_hessian(A, true);
      indefinite += symmetric_eigen(H, false).values.minCoeff() < -1e-9 * H.norm();
      CHECK((projected - numerical_projection(H)).norm() <= 1e-10 * (1.0 + H.norm()));
    }
  }
  MESSAGE(indefinite << " of 40 samples had an indefinite Hessian");
  CHECK(indefinite > 5);  // the projection was tested where it changes something
}

TEST_CASE("affine orthogonality: zero on rotations, whose directions are free") {
  std::mt19937 rng(13);
  for (int sample = 0; sample < 10; ++sample) {
    const Eigen::Matrix3d R = random_affine(rng, 0.0);
    CHECK(orthogonality_energy(R) < 1e-28);
    CHECK(orthogonality_gradient(R).norm() < 1e-13);
    // The rotations' tangents W R (W skew) cost nothing; stretches cost 8 (flip) and 8 (scaling).
    const Eigen::VectorXd lambda = symmetric_eigen(orthogonality_hessian(R, true), false).values;
    for (int k = 0; k < 3; ++k) CHECK(std::abs(lambda[k]) < 1e-12);
    for (int k = 3; k < 9; ++k) CHECK(lambda[k] == doctest::Approx(8.0).epsilon(1e-12));
  }
}

TEST_CASE("affine orthogonality: the Hessian for turns charges a loaded body nothing to turn, and is the projected one on stretches") {
  std::mt19937 rng(14);
  const Eigen::Vector3d axes[3] = {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ()};
  auto skew = [](const Eigen::Vector3d& w) {
    Eigen::Matrix3d W;
    W << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
    return W;
  };
  for (double stretch : {1e-5, 1e-3, 0.05}) {
    CAPTURE(stretch);
    // A body turned by R and stretched evenly by 1 + stretch, as a load leaves it: turning it
    // further (the tangents W A) leaves its energy unchanged, so a turn costs nothing...
    const Eigen::Matrix3d A = random_affine(rng, 0.0) * (1.0 + stretch);
    const AffineMatrix9 turned = orthogonality_hessian_for_turns(A);
    const AffineMatrix9 projected = orthogonality_hessian(A, true);
    for (const Eigen::Vector3d& w : axes) {
      const AffineVector9 t = to_q(skew(w) * A);
      const double reference = projected.norm() * t.squaredNorm();
      CHECK(std::abs(t.dot(turned * t)) <= 1e-13 * reference);
      // ... where the exact Hessian's chord charges 4 ((1 + s)^2 - 1) per unit of the twist.
      CHECK(t.dot(projected * t) / t.squaredNorm() ==
            doctest::Approx(4.0 * ((1.0 + stretch) * (1.0 + stretch) - 1.0)).epsilon(1e-6));
    }
    // Stretches (S A, S symmetric) are the projected Hessian's: only the twists changed.
    for (int k = 0; k < 6; ++k) {
      Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
      const int r = k < 3 ? k : (k == 3 ? 0 : (k == 4 ? 0 : 1)), c = k < 3 ? k : (k == 3 ? 1 : 2);
      S(r, c) = S(c, r) = 1.0;
      const AffineVector9 t = to_q(S * A);
      CHECK((turned * t - projected * t).norm() <= 1e-9 * projected.norm() * t.norm());
    }
  }
  // Positive semi-definite everywhere, as a Newton Hessian must be.
  for (double amount : {0.0, 0.05, 0.4, 0.9}) {
    for (int sample = 0; sample < 8; ++sample) {
      const AffineMatrix9 H = orthogonality_hessian_for_turns(random_affine(rng, amount));
      CHECK(symmetric_eigen(H, false).values.minCoeff() >= -1e-12 * (1.0 + H.norm()));
    }
  }
}

TEST_CASE("affine mass properties: a box's volume, centre and second moment, turned or not") {
  const Eigen::Vector3d lo(-0.3, 0.1, 2.0), hi(0.5, 0.3, 2.6);
  const Eigen::Vector3d size = hi - lo;
  std::vector<double> x;
  std::vector<int32_t> tets;
  box_tets(lo, hi, x, tets);
  const AffineMassProperties m = affine_mass_properties(x, tets);
  const double volume = size.prod();
  CHECK(m.volume == doctest::Approx(volume).epsilon(1e-14));
  CHECK((m.center - 0.5 * (lo + hi)).norm() < 1e-14);
  const Eigen::Matrix3d expected = (volume / 12.0) * size.cwiseAbs2().asDiagonal().toDenseMatrix();
  CHECK((m.second_moment - expected).norm() < 1e-14 * expected.norm());
  // The inertia tensor of a box: m / 12 (b^2 + c^2, a^2 + c^2, a^2 + b^2).
  const double density = 700.0;
  const Eigen::Matrix3d I = inertia_tensor(m.second_moment, density);
  const double mass = density * volume;
  CHECK(I(0, 0) == doctest::Approx(mass / 12.0 * (size[1] * size[1] + size[2] * size[2])).epsilon(1e-13));
  CHECK(I(1, 1) == doctest::Approx(mass / 12.0 * (size[0] * size[0] + size[2] * size[2])).epsilon(1e-13));
  CHECK(I(2, 2) == doctest::Approx(mass / 12.0 * (size[0] * size[0] + size[1] * size[1])).epsilon(1e-13));

  // Turned and moved: the centre moves with the body and S turns as R S R^T.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).matrix();
  const Eigen::Vector3d t(3.0, -1.0, 0.25);
  std::vector<double> y = x;
  for (size_t v = 0; v < y.size(); v += 3) Eigen::Vector3d::Map(&y[v]) = R * Eigen::Vector3d::Map(&x[v]) + t;
  const AffineMassProperties turned = affine_mass_properties(y, tets);
  CHECK(turned.volume == doctest::Approx(volume).epsilon(1e-13));
  CHECK((turned.center - (R * m.center + t)).norm() < 1e-13);
  CHECK((turned.second_moment - R * m.second_moment * R.transpose()).norm() < 1e-13 * expected.norm());
}

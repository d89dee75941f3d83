// Tests of kernels/projection: the symmetric 3x3 eigensolver against Eigen's QR iteration on
// random, clustered, repeated and badly scaled spectra; the PSD projection (exactness on PSD
// input, eigenvalue clamping, symmetry, the Cholesky/eigen factor of 3x3 blocks); the SIMD lane
// layer (log accuracy, transposes, four lanes equal to four scalar calls).
#include "kernels/projection/mat3.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "kernels/projection/simd4.hpp"
#include "kernels/projection/sym_eigen3.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace nexdyn {
namespace {

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

// Q diag(values) Q^T with a random rotation Q.
Eigen::Matrix3d symmetric_with_spectrum(std::mt19937_64& rng, const Eigen::Vector3d& values) {
  const Eigen::Matrix3d Q = random_rotation(rng);
  const Eigen::Matrix3d A = Q * values.asDiagonal() * Q.transpose();
  return 0.5 * (A + A.transpose());
}

template <int N>
Eigen::Matrix<double, N, N> random_symmetric(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix<double, N, N> A;
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < N; ++i) A(i, j) = u(rng);
  return 0.5 * (A + A.transpose());
}

// Checks sym_eigen3 on A: orthonormal right-handed vectors, ascending values equal to Eigen's,
// and A V = V diag(values), all relative to the spectral scale.
void check_sym_eigen3(const Eigen::Matrix3d& A) {
  Eigen::Vector3d values;
  Eigen::Matrix3d vectors;
  sym_eigen3(A, values, vectors);
  const SymmetricEigen reference = symmetric_eigen(A);
  const double scale = std::max(reference.values.cwiseAbs().maxCoeff(), 1e-300);
  CAPTURE(A);
  CAPTURE(values.transpose());
  CHECK(values[0] <= values[1]);
  CHECK(values[1] <= values[2]);
  // Errors are measured after dividing by the scale: norm() of a 1e200 matrix overflows.
  CHECK(((values - reference.values) / scale).norm() <= 1e-13);
  CHECK((vectors.transpose() * vectors - Eigen::Matrix3d::Identity()).norm() <= 1e-14);
  CHECK(vectors.determinant() == doctest::Approx(1.0).epsilon(1e-14));
  CHECK(((A / scale) * vectors - vectors * (values / scale).asDiagonal()).norm() <= 1e-13);
}

TEST_CASE("projection: sym_eigen3 matches Eigen on random symmetric matrices") {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 2000; ++trial) check_sym_eigen3(random_symmetric<3>(rng));
}

TEST_CASE("projection: sym_eigen3 on repeated, clustered and badly scaled spectra") {
  std::mt19937_64 rng(12);
  const std::vector<Eigen::Vector3d> spectra = {
      {1.0, 1.0, 2.0},          {-3.0, 5.0, 5.0},          {2.0, 2.0, 2.0},
      {1.0, 1.0 + 1e-9, 3.0},   {1.0, 1.0 + 1e-12, 1.0 + 2e-12},
      {0.0, 0.0, 1.0},          {-1.0, 0.0, 1.0},          {1e-8, 1.0, 1e8},
      {1e-300, 2e-300, 5e-300}, {-7e200, 1e200, 3e200},    {0.0, 0.0, 0.0}};
  for (const Eigen::Vector3d& s : spectra)
    for (int trial = 0; trial < 50; ++trial) check_sym_eigen3(symmetric_with_spectrum(rng, s));
  // Exactly diagonal input with repeated entries (no rotation rounding at all).
  check_sym_eigen3(Eigen::Vector3d(3.0, 1.0, 3.0).asDiagonal().toDenseMatrix());
  check_sym_eigen3(Eigen::Matrix3d::Identity());
}

TEST_CASE("projection: sym_eigen3 propagates NaN instead of looping or lying") {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A(0, 1) = A(1, 0) = std::nan("");
  Eigen::Vector3d values;
  Eigen::Matrix3d vectors;
  sym_eigen3(A, values, vectors);
  CHECK(values.hasNaN());
}

TEST_CASE("projection: project_psd leaves PSD matrices bit-for-bit unchanged") {
  std::mt19937_64 rng(13);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix<double, 9, 9> R = random_symmetric<9>(rng);
    Eigen::Matrix<double, 9, 9> A = R * R.transpose();  // PSD, generically PD
    A.diagonal().array() += 1e-6;
    const Eigen::Matrix<double, 9, 9> before = A;
    CHECK(project_psd<9>(A) == 0);
    CHECK(A == before);
  }
}

template <int N>
void check_projection(std::mt19937_64& rng) {
  using Matrix = Eigen::Matrix<double, N, N>;
  const Matrix A = random_symmetric<N>(rng);
  const SymmetricEigen eig = symmetric_eigen(A);
  const int negative = int((eig.values.array() < 0.0).count());
  const Matrix expected = eig.vectors * eig.values.cwiseMax(0.0).asDiagonal() * eig.vectors.transpose();
  Matrix P = A;
  CHECK(project_psd<N>(P) == negative);
  CHECK(P == P.transpose());  // exactly symmetric
  CHECK((P - expected).norm() <= 1e-13 * A.norm());
  CHECK(symmetric_eigen(P, false).values[0] >= -1e-14 * A.norm());
  // Nearest PSD matrix in Frobenius norm: the distance is exactly the negative part's norm.
  const double negative_part = eig.values.cwiseMin(0.0).norm();
  CHECK((P - A).norm() == doctest::Approx(negative_part).epsilon(1e-10));
  // Idempotent up to rounding (clamped eigenvalues come back as +-ulp zeros).
  Matrix again = P;
  project_psd<N>(again);
  CHECK((again - P).norm() <= 1e-13 * A.norm());
  // min_eigenvalue / is_psd agree with Eigen.
  CHECK(min_eigenvalue<N>(A) == doctest::Approx(eig.values[0]).epsilon(1e-12));
  CHECK(is_psd<N>(A) == (negative == 0));
  CHECK(is_psd<N>(P));
}

TEST_CASE("projection: project_psd clamps negative eigenvalues (3x3, 6x6, 9x9, 12x12)") {
  std::mt19937_64 rng(14);
  for (int trial = 0; trial < 200; ++trial) {
    check_projection<3>(rng);
    check_projection<6>(rng);
    check_projection<9>(rng);
    check_projection<12>(rng);
  }
}

// The cheap pre-test must accept singular PSD matrices (rank-3 J^T J, as exactly parallel edges
// give) and reject any matrix with an eigenvalue clearly below -rel_tol * max diagonal.
TEST_CASE("projection: cholesky_psd_test accepts singular PSD and rejects negative eigenvalues") {
  std::mt19937_64 rng(18);
  using Matrix9 = Eigen::Matrix<double, 9, 9>;
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix<double, 3, 9> J = random_symmetric<9>(rng).topRows<3>();
    const Matrix9 A = J.transpose() * J;  // rank 3: six zero eigenvalues, up to rounding
    CHECK(cholesky_psd_test<9>(A, 1e-12));
    // One eigenvector direction pushed below zero by 1e-8 of the scale: rejected.
    const Eigen::Matrix<double, 9, 1> v = symmetric_eigen(A).vectors.col(0);  // a null vector of A
    const Matrix9 B = A - 1e-8 * A.diagonal().maxCoeff() * v * v.transpose();
    CHECK_FALSE(cholesky_psd_test<9>(B, 1e-12));
    // Generic random symmetric matrices are indefinite: rejected exactly when Eigen finds a
    // negative eigenvalue of any size beyond the tolerance.
    const Matrix9 C = random_symmetric<9>(rng);
    const double lowest = symmetric_eigen(C, false).values[0];
    if (std::abs(lowest) > 1e-6) CHECK(cholesky_psd_test<9>(C, 1e-12) == (lowest > 0.0));
  }
}

TEST_CASE("projection: project_psd with a positive eigenvalue floor") {
  std::mt19937_64 rng(15);
  Eigen::Matrix3d A = symmetric_with_spectrum(rng, {-2.0, 0.5, 3.0});
  CHECK(project_psd<3>(A, 1.0) == 2);
  CHECK(min_eigenvalue<3>(A) == doctest::Approx(1.0).epsilon(1e-12));
}

TEST_CASE("projection: psd_factor3 gives L L^T equal to the projection") {
  std::mt19937_64 rng(16);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  int cholesky_cases = 0, eigen_cases = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Matrix3d A = symmetric_with_spectrum(rng, {u(rng), u(rng), u(rng)});
    Eigen::Matrix3d expected = A;
    (project_psd<3>(expected) == 0 ? cholesky_cases : eigen_cases)++;
    const Eigen::Matrix3d L = psd_factor3(A);
    CAPTURE(A);
    CHECK((L * L.transpose() - expected).norm() <= 1e-13 * (1.0 + A.norm()));
  }
  // Both branches were exercised.
  CHECK(cholesky_cases > 100);
  CHECK(eigen_cases > 100);
  // Singular PSD (a zero eigenvalue) goes through the eigen branch and stays exact.
  const Eigen::Matrix3d singular = symmetric_with_spectrum(rng, {0.0, 1.0, 2.0});
  const Eigen::Matrix3d L = psd_factor3(singular);
  CHECK((L * L.transpose() - singular).norm() <= 1e-14 * 4.0);
}

TEST_CASE("projection: simd log is within 2 ulp of libm, lane for lane") {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> exponent(-700.0, 700.0), near_one(-1e-3, 1e-3);
  double worst_ulp = 0.0;
  for (int trial = 0; trial < 200000; ++trial) {
    const double x = trial % 2 ? std::exp(exponent(rng)) : 1.0 + near_one(rng);
    const double expected = std::log(x);
    const double got = simd::log(x);
    const double ulp = std::nextafter(std::abs(expected), 1e300) - std::abs(expected);
    worst_ulp = std::max(worst_ulp, std::abs(got - expected) / ulp);
    const Double4 lanes = simd::log(Double4{x, 2.0 * x, 0.5 * x, x});
    CHECK(lanes[0] == got);
    CHECK(lanes[1] == simd::log(2.0 * x));
    CHECK(lanes[2] == simd::log(0.5 * x));
  }
  CHECK(worst_ulp <= 2.0);
  CHECK(simd::log(1.0) == 0.0);
  CHECK(simd::log(std::exp(1.0)) == doctest::Approx(1.0).epsilon(1e-16));
  // Smallest and largest normal numbers: within 2 ulp like everywhere else (|log| ~ 709, so the
  // relative 1e-15 is about 2 ulp).
  CHECK(simd::log(2.2250738585072014e-308) ==
        doctest::Approx(std::log(2.2250738585072014e-308)).epsilon(1e-15));
  CHECK(simd::log(1.7976931348623157e308) ==
        doctest::Approx(std::log(1.7976931348623157e308)).epsilon(1e-15));
}

TEST_CASE("projection: simd transpose4, select and masks") {
  Double4 a{0, 1, 2, 3}, b{4, 5, 6, 7}, c{8, 9, 10, 11}, d{12, 13, 14, 15};
  simd::transpose4(a, b, c, d);
  const Double4 rows[4] = {a, b, c, d};
  for (int r = 0; r < 4; ++r)
    for (int l = 0; l < 4; ++l) CHECK(rows[r][l] == 4.0 * l + r);
  const Mask4 m = Double4{1, -1, 2, -2} > 0.0;
  CHECK(simd::any(m));
  CHECK_FALSE(simd::all(m));
  CHECK(simd::all(Double4{1, 1, 1, 1} > 0.0));
  CHECK_FALSE(simd::any(Double4{1, 1, 1, 1} < 0.0));
  const Double4 s = simd::select(m, Double4{1, 1, 1, 1}, Double4{0, 0, 0, 0});
  CHECK((s[0] == 1.0 && s[1] == 0.0 && s[2] == 1.0 && s[3] == 0.0));
  const Mask4 finite = simd::is_finite(Double4{1.0, INFINITY, NAN, -2.0});
  CHECK((finite[0] != 0 && finite[1] == 0 && finite[2] == 0 && finite[3] != 0));
  // Streaming stores land where ordinary ones would, at 32- and 16-byte alignment.
  alignas(64) double buffer[12] = {};
  simd::stream4(buffer, Double4{1, 2, 3, 4});
  simd::stream4(buffer + 6, Double4{5, 6, 7, 8});
  simd::stream_fence();
  CHECK((buffer[0] == 1 && buffer[3] == 4 && buffer[4] == 0 && buffer[6] == 5 && buffer[9] == 8));
}

TEST_CASE("projection: four-lane sym_eigen3 and psd_factor3 equal four scalar calls") {
  std::mt19937_64 rng(18);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int trial = 0; trial < 500; ++trial) {
    // Mixed lanes: random, repeated eigenvalues, a multiple of the identity, indefinite.
    Eigen::Matrix3d A[4] = {random_symmetric<3>(rng), symmetric_with_spectrum(rng, {1, 1, 3}),
                            2.0 * Eigen::Matrix3d::Identity(),
                            symmetric_with_spectrum(rng, {u(rng), u(rng), u(rng)})};
    Mat3<Double4> packed;
    for (int c = 0; c < 3; ++c)
      for (int r = 0; r < 3; ++r)
        packed(r, c) = Double4{A[0](r, c), A[1](r, c), A[2](r, c), A[3](r, c)};
    Vec3<Double4> values;
    Mat3<Double4> vectors;
    sym_eigen3(packed, values, vectors);
    const Mat3<Double4> L = psd_factor3(packed);
    for (int l = 0; l < 4; ++l) {
      Vec3<double> v1;
      Mat3<double> e1;
      sym_eigen3(to_mat3(A[l]), v1, e1);
      const Mat3<double> L1 = psd_factor3(to_mat3(A[l]));
      for (int i = 0; i < 3; ++i) CHECK(values[i][l] == doctest::Approx(v1[i]).epsilon(1e-15));
      // Eigenvectors of a repeated eigenvalue are any basis of its eigenspace, and rounding
      // picks it: compare V diag(values) V^T rather than V.
      Eigen::Matrix3d V_lane, L_lane;
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) {
          V_lane(r, c) = vectors(r, c)[l];
          L_lane(r, c) = L(r, c)[l];
        }
      const Eigen::Vector3d lambda(values[0][l], values[1][l], values[2][l]);
      CHECK((V_lane * lambda.asDiagonal() * V_lane.transpose() - A[l]).norm() <= 1e-14 * 4.0);
      CHECK((V_lane.transpose() * V_lane - Eigen::Matrix3d::Identity()).norm() <= 1e-14);
      CHECK((L_lane * L_lane.transpose() - to_eigen(L1) * to_eigen(L1).transpose()).norm() <=
            1e-14 * 4.0);
    }
  }
}

}  // namespace
}  // namespace nexdyn

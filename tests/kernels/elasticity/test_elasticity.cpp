// Tests of kernels/elasticity: every derivative against central finite differences (energy ->
// PK1 -> dP/dF in F-space; tet energy -> gradient -> exact Hessian in x-space) for the four
// materials on random, strongly stretched, flattened (nearly inverted), inverted and sliver tets
// and at rest, and on degenerate ones (rest slivers and needles of 1e-6 of a regular tet's
// volume, tets squashed to J = 1e-4..1e-8, where neo-Hookean's ln J and F^-T dominate) and random
// tets including ill-conditioned ones, with the step and tolerance following each tet's
// conditioning (tests/kernels/finite_differences.hpp); the analytic PSD projection against a
// brute-force eigen-projection; invariances; the neo-Hookean inversion contract; the signed SVD;
// the range drivers (four-lane SIMD) against the element layer.
#include "kernels/elasticity/elasticity.hpp"
#include "kernels/elasticity/elasticity_range.hpp"
#include "kernels/elasticity/svd3.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "tests/kernels/finite_differences.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace nexdyn {
namespace {

// Nearly incompressible enough that lambda dominates (nu = 0.4), in consistent units.
const LameParameters kLame = lame_from_young_poisson(1.0e4, 0.4);

Eigen::Matrix3d random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3d random_matrix(std::mt19937_64& rng, double amplitude) {
  std::uniform_real_distribution<double> u(-amplitude, amplitude);
  Eigen::Matrix3d A;
  for (int i = 0; i < 9; ++i) A(i) = u(rng);
  return A;
}

double relative_error(double a, double b, double floor) {
  return std::abs(a - b) / std::max({std::abs(a), std::abs(b), floor});
}

template <typename A, typename B>
double relative_error(const A& a, const B& b, double floor) {
  return (a - b).norm() / std::max({a.norm(), b.norm(), floor});
}

// One element test case: rest corners X, current corners x.
struct TetCase {
  std::string name;
  Matrix34d X;
  Matrix34d x;
  Eigen::Matrix3d Dm_inv;
  double volume = 0.0;
  double J = 1.0;          // det F
  double sigma_min = 1.0;  // smallest |singular value| of F
};

TetCase make_case(std::string name, const Matrix34d& X, const Eigen::Matrix3d& F,
                  const Eigen::Vector3d& shift, double noise, std::mt19937_64& rng) {
  TetCase c;
  c.name = std::move(name);
  c.X = X;
  REQUIRE(tet_rest_shape(X, c.Dm_inv, c.volume));
  std::uniform_real_distribution<double> u(-noise, noise);
  for (int k = 0; k < 4; ++k)
    c.x.col(k) = F * X.col(k) + shift + Eigen::Vector3d(u(rng), u(rng), u(rng));
  const Eigen::Matrix3d Fx = deformation_gradient(c.x, c.Dm_inv);
  c.J = Fx.determinant();
  c.sigma_min = Eigen::JacobiSVD<Eigen::Matrix3d>(Fx).singularValues()[2];
  return c;
}

// Rest tet: a reference tet mapped by a random well-conditioned affine map, positively oriented.
// `height` flattens it into a sliver; `width` < 1 shrinks its x and y into a needle along z.
Matrix34d random_rest_tet(std::mt19937_64& rng, double height = 1.0, double width = 1.0) {
  Matrix34d ref;
  ref << 0.0, width, 0.2 * width, 0.3 * width,  //
      0.0, 0.1 * width, 0.9 * width, 0.25 * width,    //
      0.0, 0.0, 0.1 * height, height;
  std::uniform_real_distribution<double> stretch(0.6, 1.4);
  const Eigen::Matrix3d A = random_rotation(rng) *
                            Eigen::Vector3d(stretch(rng), stretch(rng), stretch(rng)).asDiagonal();
  const Eigen::Vector3d t = random_matrix(rng, 1.0).col(0);
  Matrix34d X;
  for (int k = 0; k < 4; ++k) X.col(k) = A * ref.col(k) + t;
  return X;
}

// All element cases. `include_inverted` adds det F < 0 cases (not for neo-Hookean derivatives).
std::vector<TetCase> element_cases(bool include_inverted) {
  std::mt19937_64 rng(2024);
  std::vector<TetCase> cases;
  const Eigen::Vector3d shift(0.3, -0.2, 0.5);
  for (int i = 0; i < 4; ++i) {
    const Matrix34d X = random_rest_tet(rng);
    cases.push_back(make_case("rest", X, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(),
                              0.0, rng));
    cases.push_back(make_case("rigid", X, random_rotation(rng), shift, 0.0, rng));
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + random_matrix(rng, 0.3);
    cases.push_back(make_case("random", X, random_rotation(rng) * F, shift, 0.01, rng));
    cases.push_back(make_case("small strain", X,
                              Eigen::Matrix3d::Identity() + random_matrix(rng, 1e-3), shift,
                              0.0, rng));
    cases.push_back(make_case(
        "stretched", X,
        random_rotation(rng) * Eigen::Vector3d(2.5, 0.6, 1.3).asDiagonal() * random_rotation(rng),
        shift, 0.0, rng));
    cases.push_back(make_case("compressed", X, 0.4 * random_rotation(rng), shift, 0.005, rng));
    // Flattened to 1e-3 of its size, nearly inverted (J ~ 1e-3 > 0).
    cases.push_back(make_case(
        "flattened", X,
        random_rotation(rng) * Eigen::Vector3d(1.1, 0.9, 1e-3).asDiagonal() * random_rotation(rng),
        shift, 0.0, rng));
    // Two equal singular values (uniaxial): the 0/0 quotients of the eigensystem.
    cases.push_back(make_case(
        "uniaxial", X,
        random_rotation(rng) * Eigen::Vector3d(1.3, 0.8, 0.8).asDiagonal() * random_rotation(rng),
        shift, 0.0, rng));
    // A sliver at rest (height 1e-3): Dm^-1 is large.
    const Matrix34d sliver = random_rest_tet(rng, 1e-3);
    cases.push_back(make_case("sliver rest, random", sliver,
                              Eigen::Matrix3d::Identity() + random_matrix(rng, 0.2), shift, 0.0,
                              rng));
    if (include_inverted) {
      cases.push_back(make_case("inverted", X,
                                random_rotation(rng) *
                                    Eigen::Vector3d(1.1, 0.9, -0.3).asDiagonal() *
                                    random_rotation(rng),
                                shift, 0.0, rng));
      cases.push_back(make_case("barely inverted", X,
                                random_rotation(rng) *
                                    Eigen::Vector3d(1.2, 0.7, -1e-3).asDiagonal() *
                                    random_rotation(rng),
                                shift, 0.0, rng));
    }
  }
  for (const TetCase& c : cases) {
    if (!include_inverted) REQUIRE(c.J > 0.0);
  }
  return cases;
}

bool is_rest_like(const TetCase& c) { return c.name == "rest" || c.name == "rigid"; }

// Two computations of the same quantity by differently inlined code (the compiler fuses
// multiply-adds per context): they agree to rounding, amplified by the cancellation of a small
// strain (energy ~ strain^2 from O(1) terms), hence 1e-10 relative to an O(1e-3)-strain floor.
constexpr double kSameValueTolerance = 1e-10;

// Gradient magnitude of an O(1) strain: a floor for relative errors where the gradient vanishes.
double gradient_scale(const TetCase& c) {
  return (kLame.mu + kLame.lambda) * c.volume * c.Dm_inv.norm();
}

// Degenerate tets: rest slivers and needles (volume ~1e-6 of the regular tet: Dm^-1 ~1e6 in the
// thin directions), a flat "cap" (four nearly coplanar, well spread corners), tets squashed to
// J = 1e-4, 1e-6 and 1e-8 (neo-Hookean's ln J and F^-T dominate) or into needles, and, with
// `include_inverted`, inverted ones where two signed singular values nearly cancel (the corotated
// twist singularity) or the smallest barely changed sign.
std::vector<TetCase> degenerate_cases(bool include_inverted) {
  std::mt19937_64 rng(77);
  std::vector<TetCase> cases;
  const Eigen::Vector3d shift(0.3, -0.2, 0.5);
  auto usv = [&](double a, double b, double c) {
    return Eigen::Matrix3d(random_rotation(rng) * Eigen::Vector3d(a, b, c).asDiagonal() *
                           random_rotation(rng));
  };
  auto mild = [&] {
    return Eigen::Matrix3d(Eigen::Matrix3d::Identity() + random_matrix(rng, 0.2));
  };
  const Matrix34d sliver = random_rest_tet(rng, 1e-6);
  const Matrix34d needle = random_rest_tet(rng, 1.0, 1e-3);
  Matrix34d cap;
  cap << 0.0, 1.0, 0.0, 1.0,  //
      0.0, 0.0, 1.0, 1.0,     //
      0.0, 0.0, 0.0, 1e-6;
  const Eigen::Matrix3d R = random_rotation(rng);
  for (int k = 0; k < 4; ++k) cap.col(k) = R * cap.col(k);
  const Matrix34d regular = random_rest_tet(rng);
  cases.push_back(make_case("sliver rest 1e-6, random", sliver, mild(), shift, 0.0, rng));
  cases.push_back(make_case("needle rest 1e-3 x 1e-3, random", needle, mild(), shift, 0.0, rng));
  cases.push_back(make_case("cap rest 1e-6, random", cap, mild(), shift, 0.0, rng));
  cases.push_back(make_case("sliver rest 1e-6, squashed J 1e-4", sliver, usv(1.2, 0.9, 1e-4),
                            shift, 0.0, rng));
  cases.push_back(make_case("J 1e-4", regular, usv(1.3, 0.8, 1e-4), shift, 0.0, rng));
  cases.push_back(make_case("J 1e-6", regular, usv(1.1, 0.9, 1e-6), shift, 0.0, rng));
  cases.push_back(make_case("J 1e-8", regular, usv(1.0, 1.0, 1e-8), shift, 0.0, rng));
  cases.push_back(make_case("squashed to a needle, J 1e-6", regular, usv(1.2, 1e-3, 1e-3), shift,
                            0.0, rng));
  if (include_inverted) {
    cases.push_back(make_case("inverted, sigma_1 + sigma_2 = 1e-4", regular,
                              usv(1.0, 0.5, -0.5 + 1e-4), shift, 0.0, rng));
    cases.push_back(make_case("barely inverted -1e-6", regular, usv(1.2, 0.7, -1e-6), shift,
                              0.0, rng));
  }
  for (const TetCase& c : cases) {
    if (!include_inverted) REQUIRE(c.J > 0.0);
  }
  return cases;
}

// ------------------------------------------------------------------------------------------------
// Finite-difference budgets (tests/kernels/finite_differences.hpp).
//
// F-space. Psi varies on the scale ell_F of F's nearest singularity: sigma_min for neo-Hookean
// (ln J and F^-T), the smallest sum of two signed singular values for corotated (where R turns:
// the twist modes), none for the polynomial linear and StVK energies (then |F|, at least 1);
// kappa = max(|F|, 1) / ell_F.
//   noise of Psi  4 eps (|P| |F| + (mu + lambda) (1 + |F|^2)^2): F's entries carry eps |F|,
//                 which moves Psi by |P| times that (J by eps kappa of itself), and Psi sums
//                 terms up to (mu + lambda) |F|^4 that cancel near rest;
//   error of P    8 eps (kappa |P| + (mu + lambda) |F| (1 + |F|^2)): F^-T = cof(F) / J and the
//                 SVD's vectors are good to eps kappa, and P sums terms of (mu + lambda) |F|^3;
//   error of dP/dF  8 eps kappa, relative.
// x-space. F = Ds Dm^-1, Ds the differences of corners of size X: rounding Ds moves F by
// dF = 4 eps X |Dm^-1| more, and a step h moves F by up to |Dm^-1| h, so ell_x = ell_F / |Dm^-1|.
//   noise of E = V (noise of Psi + |P| dF); the gradient V P D^T carries V |Dm^-1| (error of P +
//   |dP/dF| dF); the exact Hessian 8 eps kappa + dF / ell_F, relative.
// Floors as elsewhere in this file: the stress of a 1e-3 strain, mu for dP/dF, 1e-4 of the
// gradient and Hessian scales of an O(1) strain.

struct MaterialScales {
  double ell_F = 1.0;
  double kappa = 1.0;
  double norm_F = 1.0;
};

MaterialScales material_scales(MaterialModel m, const Eigen::Matrix3d& F) {
  // Signed singular values from Eigen's SVD (not the kernel's), sigma_2 with the sign of det F.
  Eigen::Vector3d sigma = Eigen::JacobiSVD<Eigen::Matrix3d>(F).singularValues();
  if (F.determinant() < 0.0) sigma[2] = -sigma[2];
  MaterialScales s;
  s.norm_F = std::max(sigma[0], 1.0);
  if (m == MaterialModel::neohookean) {
    s.ell_F = std::abs(sigma[2]);
  } else if (m == MaterialModel::corotated) {
    s.ell_F = std::min(sigma[1] + sigma[2], s.norm_F);  // the smallest pair sum
  } else {
    s.ell_F = s.norm_F;
  }
  s.ell_F = std::max(s.ell_F, 1e-300);
  s.kappa = s.norm_F / s.ell_F;
  return s;
}

double stress_floor() { return 1e-3 * (kLame.mu + kLame.lambda); }

double pk1_error(const MaterialScales& s, const Eigen::Matrix3d& P) {
  return 8.0 * fd::kEps *
         (s.kappa * P.norm() + (kLame.mu + kLame.lambda) * s.norm_F * (1.0 + s.norm_F * s.norm_F));
}

// dPsi/dF = P.
fd::Budget pk1_budget(MaterialModel m, const Eigen::Matrix3d& F) {
  const MaterialScales s = material_scales(m, F);
  const Eigen::Matrix3d P = pk1(m, F, kLame);
  const double lame = kLame.mu + kLame.lambda;
  fd::Budget b;
  b.ell = s.ell_F;
  b.floor = stress_floor();
  const double F2 = s.norm_F * s.norm_F;
  b.noise = 4.0 * fd::kEps * (P.norm() * s.norm_F + lame * (1.0 + F2) * (1.0 + F2));
  b.analytic = pk1_error(s, P) / std::max(P.norm(), b.floor);
  return b;
}

// d(vec P)/d(vec F) = dP/dF.
fd::Budget pk1_derivative_budget(MaterialModel m, const Eigen::Matrix3d& F) {
  const MaterialScales s = material_scales(m, F);
  fd::Budget b;
  b.ell = s.ell_F;
  b.floor = kLame.mu;
  b.noise = pk1_error(s, pk1(m, F, kLame));
  b.analytic = 8.0 * fd::kEps * s.kappa;
  return b;
}

struct TetBudgets {
  fd::Budget gradient, hessian;
};

TetBudgets tet_budgets(MaterialModel m, const TetCase& c) {
  const Eigen::Matrix3d F = deformation_gradient(c.x, c.Dm_inv);
  const MaterialScales s = material_scales(m, F);
  const fd::Budget bp = pk1_budget(m, F);
  const Eigen::Matrix3d P = pk1(m, F, kLame);
  const double H9 = pk1_derivative(m, F, kLame).norm();
  const double dm = Eigen::JacobiSVD<Eigen::Matrix3d>(c.Dm_inv).singularValues()[0];
  double X = c.x.cwiseAbs().maxCoeff();
  for (int k = 1; k < 4; ++k) X = std::max(X, (c.x.col(k) - c.x.col(0)).norm());
  const double dF = 4.0 * fd::kEps * X * dm;
  Vector12d g;
  tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g);
  const double g_noise = c.volume * dm * (pk1_error(s, P) + H9 * dF) + 8.0 * fd::kEps * g.norm();
  TetBudgets b;
  b.gradient.ell = s.ell_F / dm;
  b.gradient.floor = 1e-4 * gradient_scale(c);
  b.gradient.noise = c.volume * (bp.noise + P.norm() * dF);
  b.gradient.analytic = g_noise / std::max(g.norm(), b.gradient.floor);
  b.hessian.ell = b.gradient.ell;
  b.hessian.floor = 1e-4 * gradient_scale(c) * c.Dm_inv.norm();
  b.hessian.noise = g_noise;
  b.hessian.analytic = 8.0 * fd::kEps * s.kappa + dF / s.ell_F;
  return b;
}

// Budgets above kResolvable are beyond what double-precision differences can check.
constexpr double kResolvable = 1e-3;

Eigen::Matrix3d as_matrix3(const Vector9d& v) {
  return Eigen::Map<const Eigen::Matrix3d>(v.data());
}
Vector9d as_vector9(const Eigen::Matrix3d& F) { return Eigen::Map<const Vector9d>(F.data()); }
Vector12d as_vector12(const Matrix34d& x) { return Eigen::Map<const Vector12d>(x.data()); }
Matrix34d as_matrix34(const Vector12d& v) { return Eigen::Map<const Matrix34d>(v.data()); }

// The four finite-difference checks of one material and tet. Each returns false, checking
// nothing, when its budget allows more than kResolvable.
bool check_pk1(MaterialModel m, const Eigen::Matrix3d& F) {
  const fd::Result r = fd::check(
      as_vector9(pk1(m, F, kLame)),
      [&](double h) {
        return fd::gradient<9>(
            [&](const Vector9d& f) { return energy_density(m, as_matrix3(f), kLame); },
            as_vector9(F), h);
      },
      pk1_budget(m, F));
  if (r.tolerance > kResolvable) return false;
  CAPTURE(r);
  CHECK(r.ok());
  CHECK(r.second_order());
  return true;
}

bool check_pk1_derivative(MaterialModel m, const Eigen::Matrix3d& F) {
  const fd::Result r = fd::check(
      pk1_derivative(m, F, kLame),
      [&](double h) {
        return fd::jacobian<9>(
            [&](const Vector9d& f) { return as_vector9(pk1(m, as_matrix3(f), kLame)); },
            as_vector9(F), h);
      },
      pk1_derivative_budget(m, F));
  if (r.tolerance > kResolvable) return false;
  CAPTURE(r);
  CHECK(r.ok());
  CHECK(r.second_order());
  return true;
}

bool check_tet_gradient(MaterialModel m, const TetCase& c) {
  Vector12d g;
  tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g);
  const fd::Result r = fd::check(
      g,
      [&](double h) {
        return fd::gradient<12>([&](const Vector12d& x) {
          return tet_energy(m, as_matrix34(x), c.Dm_inv, c.volume, kLame);
        }, as_vector12(c.x), h);
      },
      tet_budgets(m, c).gradient);
  if (r.tolerance > kResolvable) return false;
  CAPTURE(r);
  CHECK(r.ok());
  CHECK(r.second_order());
  return true;
}

bool check_tet_hessian(MaterialModel m, const TetCase& c) {
  const fd::Result r = fd::check(
      tet_hessian_exact(m, c.x, c.Dm_inv, c.volume, kLame),
      [&](double h) {
        return fd::jacobian<12>([&](const Vector12d& x) {
          Vector12d g;
          tet_energy_gradient(m, as_matrix34(x), c.Dm_inv, c.volume, kLame, g);
          return g;
        }, as_vector12(c.x), h);
      },
      tet_budgets(m, c).hessian);
  if (r.tolerance > kResolvable) return false;
  CAPTURE(r);
  CHECK(r.ok());
  CHECK(r.second_order());
  return true;
}

// ------------------------------------------------------------------------------------------------
// Signed SVD

void check_svd(const Eigen::Matrix3d& F, bool* used_fast_path = nullptr) {
  Svd3 svd;
  const bool fast = svd3(F, svd);
  if (used_fast_path) *used_fast_path = fast;
  CAPTURE(F);
  CAPTURE(svd.sigma.transpose());
  const double scale = std::max(F.norm(), 1e-300);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  CHECK((svd.U.transpose() * svd.U - I).norm() <= 1e-13);
  CHECK((svd.V.transpose() * svd.V - I).norm() <= 1e-13);
  CHECK(svd.U.determinant() == doctest::Approx(1.0).epsilon(1e-13));
  CHECK(svd.V.determinant() == doctest::Approx(1.0).epsilon(1e-13));
  CHECK((svd.U * svd.sigma.asDiagonal() * svd.V.transpose() - F).norm() <= 1e-13 * scale);
  CHECK(svd.sigma[0] >= svd.sigma[1] - 1e-13 * scale);
  CHECK(svd.sigma[1] >= std::abs(svd.sigma[2]) - 1e-13 * scale);
  // Singular values agree with Eigen's, the sign of the last one with det F.
  const Eigen::Vector3d reference = Eigen::JacobiSVD<Eigen::Matrix3d>(F).singularValues();
  CHECK((svd.sigma.cwiseAbs() - reference).norm() <= 1e-13 * scale);
  const double det = F.determinant();
  if (std::abs(det) > 1e-10 * scale * scale * scale) CHECK((svd.sigma[2] < 0.0) == (det < 0.0));
}

TEST_CASE("elasticity: svd3 on random matrices, mostly through the fast path") {
  std::mt19937_64 rng(1);
  int fast = 0;
  const int trials = 20000;
  for (int trial = 0; trial < trials; ++trial) {
    bool used_fast = false;
    check_svd(random_matrix(rng, 2.0), &used_fast);
    fast += used_fast;
  }
  CHECK(fast >= trials * 99 / 100);
}

TEST_CASE("elasticity: svd3 near rotations, clustered, rank-deficient and inverted") {
  std::mt19937_64 rng(2);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  check_svd(I);
  check_svd(-I);
  check_svd(Eigen::Matrix3d::Zero());
  check_svd(Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal().toDenseMatrix());
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Matrix3d R1 = random_rotation(rng), R2 = random_rotation(rng);
    auto usv = [&](double a, double b, double c) {
      return Eigen::Matrix3d(R1 * Eigen::Vector3d(a, b, c).asDiagonal() * R2.transpose());
    };
    check_svd(R1);                                     // rotation
    check_svd(R1 + random_matrix(rng, 1e-9));          // near rotation
    check_svd(R1 * (I + random_matrix(rng, 1e-6)));    // small strain
    check_svd(usv(1.0, 1.0 + 1e-9, 1.0 - 1e-9));      // clustered
    check_svd(usv(2.0, 2.0, 0.5));                     // double, largest
    check_svd(usv(2.0, 0.5, 0.5));                     // double, smallest
    check_svd(usv(3.0, 3.0, 3.0));                     // triple (scaled rotation)
    check_svd(usv(1.0, 0.7, 0.0));                     // rank 2
    check_svd(usv(1.0, 0.0, 0.0));                     // rank 1
    check_svd(usv(1.0, 1e-7, 1e-8));                   // two tiny (fallback territory)
    check_svd(usv(1.0, 0.8, 1e-3));                    // flattened
    check_svd(usv(1.2, 0.8, -0.3));                    // inverted
    check_svd(usv(1.0, 1.0, -1.0));                    // reflection
    check_svd(usv(1.0, 0.6, -1e-6));                   // barely inverted
    check_svd(usv(1e-200, 5e-201, 1e-201));            // tiny scale
    check_svd(usv(1e150, 3e149, -2e149));              // huge scale
  }
}

TEST_CASE("elasticity: svd3 returns NaN for non-finite input") {
  Svd3 svd;
  Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
  F(1, 2) = std::nan("");
  svd3(F, svd);
  CHECK(svd.sigma.hasNaN());
}

// ------------------------------------------------------------------------------------------------
// F-space derivatives

// The F-space checks on the regular cases must all be resolvable; on the degenerate ones, those
// beyond double precision are counted (see the end of the test for which).
TEST_CASE("elasticity: pk1 matches finite differences of energy_density") {
  int beyond = 0;
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (const TetCase& c : element_cases(!nh)) {
      CAPTURE(material_model_name(m));
      CAPTURE(c.name);
      CHECK(check_pk1(m, deformation_gradient(c.x, c.Dm_inv)));
    }
    for (const TetCase& c : degenerate_cases(!nh)) {
      CAPTURE(material_model_name(m));
      CAPTURE(c.name);
      beyond += !check_pk1(m, deformation_gradient(c.x, c.Dm_inv));
    }
  }
  CHECK(beyond == 0);
}

TEST_CASE("elasticity: pk1_derivative matches finite differences of pk1") {
  int beyond = 0;
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (int list = 0; list < 2; ++list) {
      for (const TetCase& c : list == 0 ? element_cases(!nh) : degenerate_cases(!nh)) {
        CAPTURE(material_model_name(m));
        CAPTURE(c.name);
        const Eigen::Matrix3d F = deformation_gradient(c.x, c.Dm_inv);
        const Matrix9d H = pk1_derivative(m, F, kLame);
        if (list == 0) {
          CHECK(check_pk1_derivative(m, F));
        } else {
          beyond += !check_pk1_derivative(m, F);
        }
        CHECK(relative_error(H, Matrix9d(H.transpose()), kLame.mu) <= 1e-14);  // Hessian
      }
    }
  }
  CHECK(beyond == 0);
}

// On degenerate tets both sides carry the exact dP/dF's rounding, 8 eps kappa relative to its
// largest eigenvalue (material_scales), and the brute-force eigensolver its own eps; the
// tolerance grows accordingly.
TEST_CASE("elasticity: projected dP/dF is the brute-force PSD projection of the exact one") {
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    int indefinite = 0;
    for (int list = 0; list < 2; ++list) {
      for (const TetCase& c : list == 0 ? element_cases(!nh) : degenerate_cases(!nh)) {
        CAPTURE(material_model_name(m));
        CAPTURE(c.name);
        const Eigen::Matrix3d F = deformation_gradient(c.x, c.Dm_inv);
        const Matrix9d exact = pk1_derivative(m, F, kLame);
        Matrix9d brute = exact;
        project_psd<9>(brute);
        const double exact_scale = symmetric_eigen(exact, false).values.cwiseAbs().maxCoeff();
        indefinite += min_eigenvalue<9>(exact) < -1e-6 * exact_scale;
        const Matrix9d projected = pk1_derivative_projected(m, F, kLame);
        const double kappa = material_scales(m, F).kappa;
        CHECK(relative_error(projected, brute, kLame.mu) <= 1e-9 + 100.0 * fd::kEps * kappa);
        CHECK(relative_error(projected, Matrix9d(projected.transpose()), kLame.mu) <= 1e-14);
        const Eigen::VectorXd eig = symmetric_eigen(projected, false).values;
        const double largest = eig.cwiseAbs().maxCoeff();
        CHECK(eig[0] >= -1e-8 * largest);
      }
    }
    // The projection really had work to do for the nonlinear models, never for linear.
    if (m == MaterialModel::linear) {
      CHECK(indefinite == 0);
    } else {
      CHECK(indefinite > 0);
    }
  }
}

TEST_CASE("elasticity: projected equals exact where the exact dP/dF is PSD (small stretch)") {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> stretch(1e-4, 1e-3);
  for (MaterialModel m : kAllMaterialModels) {
    for (int trial = 0; trial < 50; ++trial) {
      CAPTURE(material_model_name(m));
      // F = R S with a small pure stretch S > I: every eigenvalue of dP/dF is positive (the
      // twist modes' (psi_i + psi_j)/(sigma_i + sigma_j) > 0 under stretch), so the projection
      // must return the exact matrix.
      const Eigen::Matrix3d Q = random_rotation(rng);
      const Eigen::Matrix3d S =
          Q * Eigen::Vector3d(1.0 + stretch(rng), 1.0 + stretch(rng), 1.0 + stretch(rng))
                  .asDiagonal() *
          Q.transpose();
      const Eigen::Matrix3d F = random_rotation(rng) * S;
      const Matrix9d exact = pk1_derivative(m, F, kLame);
      if (m == MaterialModel::linear) {
        // Constant dP/dF with exact zero eigenvalues on the skew (rotation) modes.
        REQUIRE(min_eigenvalue<9>(exact) >= -1e-12 * exact.norm());
      } else {
        REQUIRE(min_eigenvalue<9>(exact) > 0.0);
      }
      CHECK(relative_error(pk1_derivative_projected(m, F, kLame), exact, kLame.mu) <= 1e-10);
    }
    // At rest (F = I) the rotational modes are exactly zero: still PSD, still equal.
    const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
    CHECK(relative_error(pk1_derivative_projected(m, I, kLame), pk1_derivative(m, I, kLame),
                         kLame.mu) <= 1e-12);
  }
}

TEST_CASE("elasticity: rotation invariance holds for stvk/corotated/neohookean, not linear") {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::Matrix3d F = Eigen::Matrix3d::Identity() + random_matrix(rng, 0.3);
    const Eigen::Matrix3d Q = random_rotation(rng);
    for (MaterialModel m : kAllMaterialModels) {
      CAPTURE(material_model_name(m));
      const double psi = energy_density(m, F, kLame);
      const double rotated = energy_density(m, Q * F, kLame);
      if (m == MaterialModel::linear) {
        CHECK(relative_error(psi, rotated, 0.0) > 1e-3);
      } else {
        CHECK(relative_error(psi, rotated, 0.0) <= 1e-12);
        // Isotropy as well: Psi(F Q) = Psi(F).
        CHECK(relative_error(psi, energy_density(m, F * Q, kLame), 0.0) <= 1e-12);
        // P is rotated with F: P(Q F) = Q P(F).
        CHECK(relative_error(pk1(m, Q * F, kLame), Q * pk1(m, F, kLame), kLame.mu) <= 1e-12);
      }
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Tet energy, gradient, Hessian

TEST_CASE("elasticity: tet gradient matches finite differences of tet energy") {
  int beyond = 0;
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (int list = 0; list < 2; ++list) {
      for (const TetCase& c : list == 0 ? element_cases(!nh) : degenerate_cases(!nh)) {
        CAPTURE(material_model_name(m));
        CAPTURE(c.name);
        Vector12d g;
        const double e = tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g);
        // Same formulas in another inlined copy: equal to rounding, which on degenerate tets
        // includes F's, eps |x| |Dm^-1| (the budget's noise of E).
        const double e_ref = tet_energy(m, c.x, c.Dm_inv, c.volume, kLame);
        const double floor = 1e-6 * (kLame.mu + kLame.lambda) * c.volume;
        CHECK(std::abs(e - e_ref) <=
              kSameValueTolerance * std::max({std::abs(e), std::abs(e_ref), floor}) +
                  tet_budgets(m, c).gradient.noise);
        if (list == 0) {
          CHECK(check_tet_gradient(m, c));
        } else {
          beyond += !check_tet_gradient(m, c);
        }
      }
    }
  }
  // Beyond double precision: neo-Hookean on the 1e-6 sliver squashed to J = 1e-4, whose nearest
  // singularity in x is sigma_min / |Dm^-1| ~ 1e-10 away while rounding the corners' differences
  // moves F by ~eps |x| |Dm^-1| ~ 2e-10: the one configuration counted.
  CHECK(beyond <= 1);
}

TEST_CASE("elasticity: exact tet Hessian matches finite differences of the gradient") {
  int beyond = 0;
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (int list = 0; list < 2; ++list) {
      for (const TetCase& c : list == 0 ? element_cases(!nh) : degenerate_cases(!nh)) {
        CAPTURE(material_model_name(m));
        CAPTURE(c.name);
        if (list == 0) {
          CHECK(check_tet_hessian(m, c));
        } else {
          beyond += !check_tet_hessian(m, c);
        }
      }
    }
  }
  // Beyond double precision: neo-Hookean on the 1e-6 sliver squashed to J = 1e-4, whose nearest
  // singularity in x is sigma_min / |Dm^-1| ~ 1e-10 away while rounding the corners' differences
  // moves F by ~eps |x| |Dm^-1| ~ 2e-10: the one configuration counted.
  CHECK(beyond <= 1);
}

// Random tets, none skipped: corners uniform in a cube (some are slivers or needles by chance),
// every third flattened to 10^-1..10^-6 of its height, every third shrunk to a needle of width
// 10^-1..10^-3; oriented positively by swapping two corners. Deformed by F = R1 diag(sigma) R2
// with sigma_0 ~ 1, sigma_1 down to 1e-3 and sigma_2 down to 1e-6; for the materials that allow
// it, every fourth F is inverted. Every material's four derivative checks with budgets from the
// tet's conditioning. What double precision cannot resolve is counted and must be rare.
TEST_CASE("elasticity: random tets including ill-conditioned ones against finite differences") {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto decades = [&](double lo, double hi) {
    return std::pow(10.0, std::uniform_real_distribution<double>(lo, hi)(rng));
  };
  int checked = 0, beyond = 0, ill = 0;
  for (int trial = 0; trial < 120; ++trial) {
    Matrix34d X;
    for (int k = 0; k < 4; ++k) X.col(k) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Matrix3d R = random_rotation(rng);
    if (trial % 3 == 1) {
      X = R * Eigen::Vector3d(1.0, 1.0, decades(-6.0, -1.0)).asDiagonal() * R.transpose() * X;
    } else if (trial % 3 == 2) {
      const double w = decades(-3.0, -1.0);
      X = R * Eigen::Vector3d(w, w, 1.0).asDiagonal() * R.transpose() * X;
    }
    Eigen::Matrix3d Dm;
    Dm << X.col(1) - X.col(0), X.col(2) - X.col(0), X.col(3) - X.col(0);
    if (Dm.determinant() < 0.0) X.col(1).swap(X.col(2));
    const Eigen::Vector3d sigma(decades(-0.3, 0.3), decades(-3.0, 0.3), decades(-6.0, 0.3));
    const Eigen::Matrix3d F =
        random_rotation(rng) * sigma.asDiagonal() * random_rotation(rng);
    const Eigen::Matrix3d F_inverted =
        random_rotation(rng) * Eigen::Vector3d(sigma[0], sigma[1], -sigma[2]).asDiagonal() *
        random_rotation(rng);
    const Eigen::Vector3d shift(u(rng), u(rng), u(rng));
    const TetCase c = make_case("random", X, F, shift, 0.0, rng);
    const TetCase ci = make_case("random inverted", X, F_inverted, shift, 0.0, rng);
    const double rest_condition =
        c.Dm_inv.norm() * Eigen::Matrix3d(c.Dm_inv.inverse()).norm();
    ill += rest_condition > 1e3 || c.sigma_min < 1e-3 * sigma.maxCoeff();
    for (MaterialModel m : kAllMaterialModels) {
      const bool invert = m != MaterialModel::neohookean && trial % 4 == 0;
      const TetCase& t = invert ? ci : c;
      CAPTURE(material_model_name(m));
      CAPTURE(trial);
      CAPTURE(rest_condition);
      CAPTURE(t.sigma_min);
      const Eigen::Matrix3d Ft = deformation_gradient(t.x, t.Dm_inv);
      for (bool resolved : {check_pk1(m, Ft), check_pk1_derivative(m, Ft), check_tet_gradient(m, t),
                            check_tet_hessian(m, t)}) {
        (resolved ? checked : beyond) += 1;
      }
    }
  }
  MESSAGE("random tets: ", ill, " of 120 ill-conditioned; ", checked, " checks, ", beyond,
          " beyond double-precision differences");
  CHECK(ill >= 60);
  CHECK(beyond <= checked / 20);
}

TEST_CASE("elasticity: projected tet Hessian is V B^T (dP/dF)+ B, symmetric and PSD") {
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (const TetCase& c : element_cases(!nh)) {
      CAPTURE(material_model_name(m));
      CAPTURE(c.name);
      Vector12d g, g_ref;
      Matrix12d H;
      const double e = tet_energy_gradient_hessian(m, c.x, c.Dm_inv, c.volume, kLame, g, H);
      const double e_ref = tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g_ref);
      // Same formulas as the gradient-only path, possibly fused differently by the compiler.
      CHECK(relative_error(e, e_ref, 1e-6 * (kLame.mu + kLame.lambda) * c.volume) <=
            kSameValueTolerance);
      CHECK(relative_error(g, g_ref, 1e-3 * gradient_scale(c)) <= kSameValueTolerance);
      CHECK(H == H.transpose());  // exactly symmetric (H = G G^T)
      const Eigen::Matrix3d F = deformation_gradient(c.x, c.Dm_inv);
      const Matrix12d expected =
          tet_hessian_from_pk1_derivative(pk1_derivative_projected(m, F, kLame), c.Dm_inv,
                                          c.volume);
      const double scale = c.volume * kLame.mu * c.Dm_inv.squaredNorm();
      CHECK(relative_error(H, expected, scale) <= 1e-10);
      const Eigen::VectorXd eig = symmetric_eigen(H, false).values;
      CHECK(eig[0] >= -1e-8 * eig.cwiseAbs().maxCoeff());
      // Translations are in the kernel: H [t t t t] = 0.
      Vector12d translation;
      translation << 1.0, -2.0, 0.5, 1.0, -2.0, 0.5, 1.0, -2.0, 0.5, 1.0, -2.0, 0.5;
      CHECK((H * translation).norm() <= 1e-10 * H.norm() * translation.norm());
    }
  }
}

TEST_CASE("elasticity: zero energy and zero gradient at rest and under rigid motion") {
  for (MaterialModel m : kAllMaterialModels) {
    for (const TetCase& c : element_cases(false)) {
      if (!is_rest_like(c)) continue;
      CAPTURE(material_model_name(m));
      CAPTURE(c.name);
      Vector12d g;
      const double e = tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g);
      if (c.name == "rigid" && m == MaterialModel::linear) {
        // Linear elasticity is not rotation invariant: a rigid rotation costs energy.
        CHECK(e > 1e-3 * (kLame.mu + kLame.lambda) * c.volume);
        continue;
      }
      CHECK(std::abs(e) <= 1e-12 * (kLame.mu + kLame.lambda) * c.volume);
      CHECK(g.norm() <= 1e-12 * gradient_scale(c));
    }
  }
}

TEST_CASE("elasticity: corner forces sum to zero and energy is translation invariant") {
  for (MaterialModel m : kAllMaterialModels) {
    const bool nh = m == MaterialModel::neohookean;
    for (const TetCase& c : element_cases(!nh)) {
      CAPTURE(material_model_name(m));
      CAPTURE(c.name);
      Vector12d g;
      const double e = tet_energy_gradient(m, c.x, c.Dm_inv, c.volume, kLame, g);
      const Eigen::Vector3d sum = g.segment<3>(0) + g.segment<3>(3) + g.segment<3>(6) +
                                  g.segment<3>(9);
      CHECK(sum.norm() <= 1e-13 * (g.norm() + 1e-12 * gradient_scale(c)));
      Matrix34d moved = c.x;
      moved.colwise() += Eigen::Vector3d(10.0, -3.0, 7.0);
      CHECK(relative_error(tet_energy(m, moved, c.Dm_inv, c.volume, kLame), e,
                           1e-6 * (kLame.mu + kLame.lambda) * c.volume) <= 1e-9);
    }
  }
}

TEST_CASE("elasticity: neo-Hookean energy is +inf for J <= 0, derivatives NaN") {
  std::mt19937_64 rng(5);
  const Matrix34d X = random_rest_tet(rng);
  Eigen::Matrix3d Dm_inv;
  double volume = 0.0;
  REQUIRE(tet_rest_shape(X, Dm_inv, volume));
  constexpr MaterialModel kNH = MaterialModel::neohookean;
  // Inverted: mirror the tet; degenerate: squash it flat (J == 0 exactly).
  Matrix34d inverted = X, flat = X;
  inverted.row(2) *= -1.0;
  flat.row(2).setZero();
  for (const Matrix34d& x : {inverted, flat}) {
    CHECK(tet_energy<kNH>(x, Dm_inv, volume, kLame) == kInfinity);
    CHECK(energy_density<kNH>(deformation_gradient(x, Dm_inv), kLame) == kInfinity);
    Vector12d g = Vector12d::Zero();
    Matrix12d H = Matrix12d::Zero();
    CHECK(tet_energy_gradient<kNH>(x, Dm_inv, volume, kLame, g) == kInfinity);
    CHECK(g.hasNaN());
    CHECK(tet_energy_gradient_hessian<kNH>(x, Dm_inv, volume, kLame, g, H) == kInfinity);
    CHECK(g.hasNaN());
    CHECK(H.hasNaN());
    CHECK(pk1_derivative_projected<kNH>(deformation_gradient(x, Dm_inv), kLame).hasNaN());
  }
  // The other models stay finite through inversion.
  for (MaterialModel m : {MaterialModel::linear, MaterialModel::stvk, MaterialModel::corotated}) {
    Vector12d g;
    Matrix12d H;
    CHECK(std::isfinite(tet_energy_gradient_hessian(m, inverted, Dm_inv, volume, kLame, g, H)));
    CHECK(g.allFinite());
    CHECK(H.allFinite());
  }
  // Corotated where two signed singular values cancel (sigma = (1, 0.5, -0.5)): the twist
  // eigenvalue is singular; the floored formula keeps the projected Hessian finite.
  const Eigen::Matrix3d F = Eigen::Vector3d(1.0, 0.5, -0.5).asDiagonal();
  CHECK(pk1_derivative_projected<MaterialModel::corotated>(F, kLame).allFinite());
}

TEST_CASE("elasticity: tet_rest_shape rejects degenerate and negatively oriented tets") {
  std::mt19937_64 rng(6);
  Matrix34d X = random_rest_tet(rng);
  Eigen::Matrix3d Dm_inv;
  double volume = 0.0;
  REQUIRE(tet_rest_shape(X, Dm_inv, volume));
  CHECK(volume > 0.0);
  CHECK((deformation_gradient(X, Dm_inv) - Eigen::Matrix3d::Identity()).norm() <= 1e-14);
  Matrix34d swapped = X;
  swapped.col(1).swap(swapped.col(2));
  CHECK_FALSE(tet_rest_shape(swapped, Dm_inv, volume));
  Matrix34d flat = X;
  flat.col(3) = 0.5 * (X.col(1) + X.col(2));
  flat.col(0) = X.col(1) + X.col(2) - flat.col(3);  // all four corners coplanar
  CHECK_FALSE(tet_rest_shape(flat, Dm_inv, volume));
}

// ------------------------------------------------------------------------------------------------
// Range drivers

// A small mesh of tets sharing vertices (a perturbed 2x2x2 grid cut into 6 tets per cell).
struct SmallMesh {
  std::vector<double> x;
  std::vector<int32_t> tets;
  std::vector<double> Dm_inv;
  std::vector<double> volume;
  int64_t num_tets() const { return int64_t(volume.size()); }
  TetRange range() const { return {x.data(), tets.data(), Dm_inv.data(), volume.data()}; }
};

SmallMesh small_mesh(std::mt19937_64& rng, double perturbation) {
  SmallMesh mesh;
  const int n = 3;  // vertices per side
  std::vector<double> rest;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) rest.insert(rest.end(), {double(i), double(j), double(k)});
  auto id = [&](int i, int j, int k) { return int32_t(i + n * (j + n * k)); };
  // Freudenthal cut: the 6 tets of a cell share the diagonal 000-111.
  const int paths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k + 1 < n; ++k)
    for (int j = 0; j + 1 < n; ++j)
      for (int i = 0; i + 1 < n; ++i)
        for (const auto& path : paths) {
          int c[3] = {i, j, k};
          int32_t ids[4];
          ids[0] = id(c[0], c[1], c[2]);
          for (int s = 0; s < 3; ++s) {
            ++c[path[s]];
            ids[s + 1] = id(c[0], c[1], c[2]);
          }
          Matrix34d X;
          for (int v = 0; v < 4; ++v) X.col(v) = Eigen::Map<Eigen::Vector3d>(&rest[3 * ids[v]]);
          Eigen::Matrix3d Dm_inv;
          double volume = 0.0;
          if (!tet_rest_shape(X, Dm_inv, volume)) {
            std::swap(ids[1], ids[2]);
            X.col(1).swap(X.col(2));
            REQUIRE(tet_rest_shape(X, Dm_inv, volume));
          }
          mesh.tets.insert(mesh.tets.end(), ids, ids + 4);
          mesh.Dm_inv.insert(mesh.Dm_inv.end(), Dm_inv.data(), Dm_inv.data() + 9);
          mesh.volume.push_back(volume);
        }
  std::uniform_real_distribution<double> u(-perturbation, perturbation);
  mesh.x = rest;
  for (double& v : mesh.x) v = 1.1 * v + u(rng);
  return mesh;
}

Matrix34d corners(const SmallMesh& mesh, int64_t t) {
  Matrix34d x;
  for (int k = 0; k < 4; ++k)
    x.col(k) = Eigen::Map<const Eigen::Vector3d>(&mesh.x[3 * mesh.tets[4 * t + k]]);
  return x;
}

TEST_CASE("elasticity: range drivers equal the element functions, independent of chunking") {
  std::mt19937_64 rng(7);
  const SmallMesh mesh = small_mesh(rng, 0.08);
  const int64_t nt = mesh.num_tets();
  REQUIRE(nt == 48);
  const TetRange range = mesh.range();
  for (MaterialModel m : kAllMaterialModels) {
    CAPTURE(material_model_name(m));
    std::vector<double> energy(nt, -1.0), gradient(12 * nt, -1.0);
    std::vector<double> gradient2(12 * nt, -1.0), hessian(144 * nt, -1.0);
    // Two sub-ranges, as the engine's chunks would call them.
    CHECK(gradient_range(m, range, 0, 20, kLame, energy.data(), gradient.data()) == 0);
    CHECK(gradient_range(m, range, 20, nt, kLame, energy.data(), gradient.data()) == 0);
    CHECK(hessian_range(m, range, 0, 31, kLame, gradient2.data(), hessian.data()) == 0);
    CHECK(hessian_range(m, range, 31, nt, kLame, gradient2.data(), hessian.data()) == 0);
    // Chunking does not change a bit: one call over everything gives the same slabs, the
    // gradient that hessian_range writes (gradient2) included.
    std::vector<double> energy_all(nt), gradient_all(12 * nt), gradient2_all(12 * nt),
        hessian_all(144 * nt);
    gradient_range(m, range, 0, nt, kLame, energy_all.data(), gradient_all.data());
    CHECK(energy_all == energy);
    CHECK(gradient_all == gradient);
    hessian_range(m, range, 0, nt, kLame, gradient2_all.data(), hessian_all.data());
    CHECK(hessian_all == hessian);
    CHECK(gradient2_all == gradient2);
    // hessian_range's gradient is gradient_range's, computed by another inlined copy of the same
    // formulas: equal to rounding.
    CHECK(relative_error(Eigen::Map<const Eigen::VectorXd>(gradient2.data(), 12 * nt),
                         Eigen::Map<const Eigen::VectorXd>(gradient.data(), 12 * nt), 0.0) <=
          kSameValueTolerance);
    double total = 0.0;
    for (int64_t t = 0; t < nt; ++t) {
      const Eigen::Map<const Eigen::Matrix3d> Dm_inv(&mesh.Dm_inv[9 * t]);
      Vector12d g;
      Matrix12d H;
      const double e =
          tet_energy_gradient_hessian(m, corners(mesh, t), Dm_inv, mesh.volume[t], kLame, g, H);
      total += e;
      // The range drivers run the same kernels on four-lane packs; the compiler may fuse
      // multiply-adds differently there: equal to rounding (chunking is bitwise, checked above).
      CHECK(relative_error(energy[t], e, 0.0) <= kSameValueTolerance);
      CHECK(relative_error(Eigen::Map<const Vector12d>(&gradient[12 * t]), g, 0.0) <=
            kSameValueTolerance);
      CHECK(relative_error(Eigen::Map<const Vector12d>(&gradient2[12 * t]), g, 0.0) <=
            kSameValueTolerance);
      CHECK(relative_error(Eigen::Map<const Matrix12d>(&hessian[144 * t]), H, 0.0) <=
            kSameValueTolerance);
    }
    CHECK(relative_error(energy_range(m, range, 0, nt, kLame), total, 0.0) <= kSameValueTolerance);
    CHECK(total > 0.0);
  }
}

TEST_CASE("elasticity: templated and runtime-dispatched range drivers agree") {
  std::mt19937_64 rng(8);
  const SmallMesh mesh = small_mesh(rng, 0.1);
  const int64_t nt = mesh.num_tets();
  constexpr MaterialModel kM = MaterialModel::neohookean;
  std::vector<double> e1(nt), e2(nt), g1(12 * nt), g2(12 * nt);
  gradient_range<kM>(mesh.range(), 0, nt, kLame, e1.data(), g1.data());
  gradient_range(kM, mesh.range(), 0, nt, kLame, e2.data(), g2.data());
  CHECK(e1 == e2);
  CHECK(g1 == g2);
  CHECK(energy_range<kM>(mesh.range(), 0, nt, kLame) ==
        energy_range(kM, mesh.range(), 0, nt, kLame));
}

TEST_CASE("elasticity: range drivers report inverted neo-Hookean tets") {
  std::mt19937_64 rng(9);
  SmallMesh mesh = small_mesh(rng, 0.0);
  const int64_t nt = mesh.num_tets();
  // Push the centre vertex (1, 1, 1) far through a face: some incident tets invert.
  const int centre = 1 + 3 * (1 + 3 * 1);
  mesh.x[3 * centre + 0] += 3.0;
  int64_t expected = 0;
  for (int64_t t = 0; t < nt; ++t) {
    const Eigen::Map<const Eigen::Matrix3d> Dm_inv(&mesh.Dm_inv[9 * t]);
    expected += deformation_gradient(corners(mesh, t), Dm_inv).determinant() <= 0.0;
  }
  REQUIRE(expected > 0);
  std::vector<double> energy(nt), gradient(12 * nt), hessian(144 * nt);
  constexpr MaterialModel kNH = MaterialModel::neohookean;
  CHECK(energy_range(kNH, mesh.range(), 0, nt, kLame) == kInfinity);
  CHECK(gradient_range(kNH, mesh.range(), 0, nt, kLame, energy.data(), gradient.data()) ==
        expected);
  CHECK(hessian_range(kNH, mesh.range(), 0, nt, kLame, gradient.data(), hessian.data()) ==
        expected);
  int64_t infinite = 0;
  for (double e : energy) infinite += e == kInfinity;
  CHECK(infinite == expected);
  // Other models: finite energy, nothing reported.
  CHECK(std::isfinite(energy_range(MaterialModel::stvk, mesh.range(), 0, nt, kLame)));
  CHECK(gradient_range(MaterialModel::corotated, mesh.range(), 0, nt, kLame, energy.data(),
                       gradient.data()) == 0);
}

}  // namespace
}  // namespace nexdyn

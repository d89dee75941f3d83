// The mollified edge-edge stencil and the PSD projection of translation-invariant 4-point
// Hessians (see barrier_stencils.hpp).
//
// Compiled here, out of line, so that the roundings of the product rule do not depend on the code
// a caller inlines them into: with -ffp-contract=fast the compiler fuses a multiply and an add
// into one FMA where the surrounding code lets it, and which ones it fuses changes the last bit.
// For the same reason the few sums whose rounding the nearly parallel case is sensitive to are
// written out with explicit FMAs (the choices the engine made before these kernels moved here,
// so that results stayed bit for bit the same).
#include "kernels/barrier/barrier_stencils.hpp"

#include <cmath>

namespace nexdyn {

namespace {

// A Hessian whose eigenvalues are all above -kPsdTolerance times its largest diagonal entry
// counts as PSD and is kept unprojected (cholesky_psd_test).
constexpr double kPsdTolerance = 1e-12;

// U = [q1 q2 q3] (x) I3 with q1 = (1, -1, 0, 0) / sqrt 2, q2 = (1, 1, -2, 0) / sqrt 6,
// q3 = (1, 1, 1, -3) / sqrt 12: orthonormal, and each q sums to 0, so U's columns span the
// complement of the rigid translations (1, 1, 1, 1) (x) e_k.
Eigen::Matrix<double, 12, 9> translation_free_basis() {
  const double q[3][4] = {{1.0 / std::sqrt(2.0), -1.0 / std::sqrt(2.0), 0.0, 0.0},
                          {1.0 / std::sqrt(6.0), 1.0 / std::sqrt(6.0), -2.0 / std::sqrt(6.0), 0.0},
                          {1.0 / std::sqrt(12.0), 1.0 / std::sqrt(12.0), 1.0 / std::sqrt(12.0), -3.0 / std::sqrt(12.0)}};
  Eigen::Matrix<double, 12, 9> u = Eigen::Matrix<double, 12, 9>::Zero();
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 4; ++i) u.block<3, 3>(3 * i, 3 * k).diagonal().setConstant(q[k][i]);
  return u;
}

// Gradient and (when H is given) Hessian of the squared distance of an edge-edge pair whose
// closest feature is f, placed into the pair's 12 DOFs.
void edge_edge_feature_derivatives(const ClosestFeature& f, const Eigen::Vector3d (&X)[4], Vector12d& g,
                                   Matrix12d* H) {
  if (H) H->setZero();
  auto scatter = [&](const auto& gr, auto&& hessian, int n) {
    // The points the feature leaves out get zeros one by one: g.setZero() first is a 96-byte
    // memset, which gcc's tuning for AMD Zen emits as `rep stos`, slow to start for so few bytes.
    bool in_feature[4] = {false, false, false, false};
    for (int i = 0; i < n; ++i) {
      g.segment<3>(3 * f.idx[i]) = gr.template segment<3>(3 * i);
      in_feature[f.idx[i]] = true;
    }
    for (int p = 0; p < 4; ++p)
      if (!in_feature[p]) g.segment<3>(3 * p).setZero();
    if (!H) return;
    const auto hr = hessian();
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) H->block<3, 3>(3 * f.idx[i], 3 * f.idx[j]) = hr.template block<3, 3>(3 * i, 3 * j);
  };
  const Eigen::Vector3d& a = X[f.idx[0]];
  const Eigen::Vector3d& b = X[f.idx[1]];
  if (f.n == 2) {
    scatter(point_point_distance_gradient(a, b), [&] { return point_point_distance_hessian(a, b); }, 2);
  } else if (f.n == 3) {
    const Eigen::Vector3d& c = X[f.idx[2]];
    scatter(point_line_distance_gradient(a, b, c), [&] { return point_line_distance_hessian(a, b, c); }, 3);
  } else {
    g = line_line_distance_gradient(X[0], X[1], X[2], X[3]);
    if (H) *H = line_line_distance_hessian(X[0], X[1], X[2], X[3]);
  }
}

// c = |ea x eb|^2 with its roundings fixed: each component of the cross product as one FMA, the
// squares rounded on their own (fma(n, n, 0) cannot be fused into the sum) and summed in order.
double cross_squarednorm(const Eigen::Vector3d (&X)[4]) {
  const Eigen::Vector3d a = X[1] - X[0], b = X[3] - X[2];
  const double n0 = std::fma(a[1], b[2], -(a[2] * b[1]));
  const double n1 = std::fma(a[2], b[0], -(a[0] * b[2]));
  const double n2 = std::fma(a[0], b[1], -(a[1] * b[0]));
  return (std::fma(n0, n0, 0.0) + std::fma(n1, n1, 0.0)) + std::fma(n2, n2, 0.0);
}

// u . v as the kernel below rounds it: the x and y products rounded and summed, the z product
// fused in (fma(x, y, 0) is a product that cannot be fused into the sum).
double rounded_dot(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  return std::fma(u[2], v[2], std::fma(u[0], v[0], 0.0) + std::fma(u[1], v[1], 0.0));
}

// dc/dx (edge_edge_cross_squarednorm_gradient) with its roundings fixed, those the engine's
// compiled kernel had when it was called out of line: dc/dea1 = -dc/dea0 = ga and dc/deb1 =
// -dc/deb0 = gb with ga_k = 2 fma(-(ea . eb), eb_k, |eb|^2 ea_k), gb_k = 2 fma(-(ea . eb), ea_k,
// |ea|^2 eb_k). Inline, so that the caller gets it in registers (the out-of-line call returned
// it through memory in 16-byte stores, which the caller's 32-byte loads could not forward from:
// a fifth of the mollified gradient's time).
struct CrossGradient {
  double ga[3], gb[3];
};

CrossGradient cross_squarednorm_gradient_halves(const Eigen::Vector3d (&X)[4]) {
  const Eigen::Vector3d a = X[1] - X[0], b = X[3] - X[2];
  const double ab = rounded_dot(a, b), aa = rounded_dot(a, a), bb = rounded_dot(b, b);
  CrossGradient g;
  for (int k = 0; k < 3; ++k) {
    g.ga[k] = 2.0 * std::fma(-ab, b[k], bb * a[k]);
    g.gb[k] = 2.0 * std::fma(-ab, a[k], aa * b[k]);
  }
  return g;
}

Vector12d cross_squarednorm_gradient(const Eigen::Vector3d (&X)[4]) {
  const CrossGradient h = cross_squarednorm_gradient_halves(X);
  Vector12d g;
  for (int k = 0; k < 3; ++k) {
    g[k] = -h.ga[k];
    g[3 + k] = h.ga[k];
    g[6 + k] = -h.gb[k];
    g[9 + k] = h.gb[k];
  }
  return g;
}

// The Hessian of c, compiled on its own (never inlined), as the engine called it before these
// kernels moved here: inlined into the product rule below, the compiler fuses some of its
// multiply-adds differently.
[[gnu::noinline]] Matrix12d cross_squarednorm_hessian(const Eigen::Vector3d (&X)[4]) {
  return edge_edge_cross_squarednorm_hessian(X[0], X[1], X[2], X[3]);
}

// The mollifier m(c) = (2 - c / eps_x) c / eps_x below eps_x (edge_edge_mollifier.hpp), from
// one evaluation of c: its value, and its gradient m' grad c and Hessian m'' grad c grad c^T +
// m' hess c (m' = 2 (1 - c / eps_x) / eps_x, m'' = -2 / eps_x^2) when asked for.
struct Mollifier {
  double m = 1.0;
  Vector12d gradient = Vector12d::Zero();
};

Mollifier mollifier(const Eigen::Vector3d (&X)[4], double eps_x, Matrix12d* hessian) {
  Mollifier out;
  const double c = cross_squarednorm(X);
  if (!(c < eps_x)) {
    if (hessian) hessian->setZero();
    return out;
  }
  const double q = c / eps_x;
  const double dm = 2.0 * (1.0 - q) / eps_x;
  out.m = (2.0 - q) * q;
  const Vector12d gc = cross_squarednorm_gradient(X);
  out.gradient = dm * gc;
  if (hessian) {
    const Vector12d d2m_gc = (-2.0 / (eps_x * eps_x)) * gc;
    const Matrix12d Hc = cross_squarednorm_hessian(X);
    for (int j = 0; j < 12; ++j)
      for (int i = 0; i < 12; ++i) (*hessian)(i, j) = std::fma(dm, Hc(i, j), d2m_gc(i) * gc(j));
  }
  return out;
}

// w (m b' grad d + b grad m), the mollified stencil's gradient without its Hessian, from the
// barrier's b and b' and the distance's gradient gd: each entry w fma(b, m' dc/dx_i, m b' gd_i),
// the roundings of the product rule below, formed entry by entry so that nothing goes through
// memory in pieces of other widths (the caller's vector loads could not forward such stores).
// Outside the band (m = 1, m' = 0) the second term is a zero (whose only effect is to turn a -0
// into +0: kept, so that every bit stays as it was).
void mollified_gradient(const Eigen::Vector3d (&X)[4], double eps_x, double b, double b1, double w,
                        const Vector12d& gd, double* gradient) {
  const double c = cross_squarednorm(X);
  if (!(c < eps_x)) {
    for (int i = 0; i < 12; ++i) gradient[i] = w * (b1 * gd[i] + 0.0);
    return;
  }
  const double q = c / eps_x;
  const double dm = 2.0 * (1.0 - q) / eps_x;
  const double mb1 = ((2.0 - q) * q) * b1;
  const CrossGradient gc = cross_squarednorm_gradient_halves(X);
  for (int k = 0; k < 3; ++k) {
    gradient[k] = w * std::fma(b, dm * -gc.ga[k], mb1 * gd[k]);
    gradient[3 + k] = w * std::fma(b, dm * gc.ga[k], mb1 * gd[3 + k]);
    gradient[6 + k] = w * std::fma(b, dm * -gc.gb[k], mb1 * gd[6 + k]);
    gradient[9 + k] = w * std::fma(b, dm * gc.gb[k], mb1 * gd[9 + k]);
  }
}

// The mollified stencil's gradient (12 entries from `gradient`) and, with `hessian`, its
// projected Hessian. One function for both, so that the distance's roundings (which depend on
// the code the compiler inlines them into) are the same in both.
void mollified_derivatives(const Eigen::Vector3d (&X)[4], EdgeEdgeCase ec, double eps_x, double dhat2, double w,
                           double* gradient, Matrix12d* hessian) {
  const double d = edge_edge_distance(X[0], X[1], X[2], X[3], ec);
  Vector12d gd;
  Matrix12d Hd, Hm;
  edge_edge_feature_derivatives(closest_feature(ec), X, gd, hessian ? &Hd : nullptr);
  const auto [b, b1, b2] = barrier_values(d, dhat2);  // one log for the three
  if (!hessian) {
    mollified_gradient(X, eps_x, b, b1, w, gd, gradient);
    return;
  }
  const Mollifier m = mollifier(X, eps_x, &Hm);
  Eigen::Map<Vector12d>{gradient} = w * (m.m * b1 * gd + b * m.gradient);
  const Vector12d& gm = m.gradient;
  Matrix12d H = m.m * (b2 * gd * gd.transpose() + b1 * Hd) + b1 * (gd * gm.transpose() + gm * gd.transpose()) + b * Hm;
  H *= w;
  project_psd_translation_free(H);
  *hessian = H;
}

}  // namespace

void project_psd_translation_free(Matrix12d& H) {
  static const Eigen::Matrix<double, 12, 9> U = translation_free_basis();
  // lazyProduct: coefficient-wise small products, not the blocked GEMM path Eigen picks at 12x9.
  const Eigen::Matrix<double, 9, 12> UtH = U.transpose().lazyProduct(H);
  Matrix9d T = UtH.lazyProduct(U);
  T = 0.5 * (T + T.transpose()).eval();
  // Already PSD, as exactly parallel edges are (their Hessian is b m' J^T J there): H keeps its
  // values, without an eigendecomposition.
  if (cholesky_psd_test<9>(T, kPsdTolerance)) return;
  if (project_psd<9>(T) == 0) return;  // nothing clamped: H keeps its exact values
  const Eigen::Matrix<double, 12, 9> UT = U.lazyProduct(T);
  const Matrix12d projected = UT.lazyProduct(U.transpose());
  H = 0.5 * (projected + projected.transpose());
}

Vector12d mollified_edge_edge_barrier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                               const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x,
                                               double dhat2, double weight) {
  Vector12d gradient;
  mollified_edge_edge_barrier_gradient(ea0, ea1, eb0, eb1, edge_edge_case(ea0, ea1, eb0, eb1), eps_x, dhat2, weight,
                                       gradient);
  return gradient;
}

void mollified_edge_edge_barrier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                          const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeCase ec,
                                          double eps_x, double dhat2, double weight, Eigen::Ref<Vector12d> gradient) {
  const Eigen::Vector3d X[4] = {ea0, ea1, eb0, eb1};
  mollified_derivatives(X, ec, eps_x, dhat2, weight, gradient.data(), nullptr);
}

void mollified_edge_edge_barrier_gradient_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                  const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x,
                                                  double dhat2, double weight, Eigen::Ref<Vector12d> gradient,
                                                  Eigen::Ref<Matrix12d> projected_hessian) {
  mollified_edge_edge_barrier_gradient_hessian(ea0, ea1, eb0, eb1, edge_edge_case(ea0, ea1, eb0, eb1), eps_x, dhat2,
                                               weight, gradient, projected_hessian);
}

void mollified_edge_edge_barrier_gradient_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
                                                  const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1,
                                                  EdgeEdgeCase ec, double eps_x, double dhat2, double weight,
                                                  Eigen::Ref<Vector12d> gradient,
                                                  Eigen::Ref<Matrix12d> projected_hessian) {
  const Eigen::Vector3d X[4] = {ea0, ea1, eb0, eb1};
  Vector12d g;
  Matrix12d H;
  mollified_derivatives(X, ec, eps_x, dhat2, weight, g.data(), &H);
  gradient = g;
  projected_hessian = H;
}

}  // namespace nexdyn

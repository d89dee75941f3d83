// The coordinate map of one stencil (kernels/affine/affine_map.hpp): a stencil over vertices of
// tet and affine bodies mapped to their nodes, against an explicit Jacobian and against central
// differences of a function of the vertex positions composed with the map.
#include "kernels/affine/affine_map.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>

#include <cmath>
#include <random>
#include <vector>

using namespace nexdyn;

namespace {

// A vertex of an affine body whose nodes are first, first + 1, first + 2, first + 3 (p, c_0, c_1,
// c_2), at rest coordinates y.
VertexNodes affine_vertex(int32_t first, const Eigen::Vector3d& y) {
  VertexNodes v;
  v.count = 4;
  for (int t = 0; t < 4; ++t) {
    v.node[t] = first + t;
    v.weight[t] = t == 0 ? 1.0 : y[t - 1];
  }
  return v;
}

VertexNodes tet_vertex(int32_t node) {
  VertexNodes v;
  v.count = 1;
  v.node[0] = node;
  v.weight[0] = 1.0;
  return v;
}

// The stencil's Jacobian, 3k x 3K.
Eigen::MatrixXd jacobian(const std::vector<VertexNodes>& vertices, const std::vector<int32_t>& nodes) {
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3 * vertices.size(), 3 * nodes.size());
  for (size_t i = 0; i < vertices.size(); ++i)
    for (int t = 0; t < vertices[i].count; ++t)
      for (size_t a = 0; a < nodes.size(); ++a)
        if (nodes[a] == vertices[i].node[t]) J.block<3, 3>(3 * i, 3 * a) += vertices[i].weight[t] * Eigen::Matrix3d::Identity();
  return J;
}

// A smooth function of k vertex positions with off-diagonal blocks, and its derivatives:
// f = sum_i |x_i|^4 + (x_0 . x_1)^2.
double f_of(const Eigen::VectorXd& x) {
  double f = 0.0;
  for (int i = 0; i < x.size() / 3; ++i) f += std::pow(x.segment<3>(3 * i).squaredNorm(), 2);
  return f + std::pow(x.segment<3>(0).dot(x.segment<3>(3)), 2);
}
Eigen::VectorXd gradient_of(const Eigen::VectorXd& x) {
  Eigen::VectorXd g(x.size());
  for (int i = 0; i < x.size() / 3; ++i) g.segment<3>(3 * i) = 4.0 * x.segment<3>(3 * i).squaredNorm() * x.segment<3>(3 * i);
  const double c = x.segment<3>(0).dot(x.segment<3>(3));
  g.segment<3>(0) += 2.0 * c * x.segment<3>(3);
  g.segment<3>(3) += 2.0 * c * x.segment<3>(0);
  return g;
}
Eigen::MatrixXd hessian_of(const Eigen::VectorXd& x) {
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(x.size(), x.size());
  for (int i = 0; i < x.size() / 3; ++i) {
    const Eigen::Vector3d xi = x.segment<3>(3 * i);
    H.block<3, 3>(3 * i, 3 * i) = 4.0 * xi.squaredNorm() * Eigen::Matrix3d::Identity() + 8.0 * xi * xi.transpose();
  }
  const Eigen::Vector3d x0 = x.segment<3>(0), x1 = x.segment<3>(3);
  H.block<3, 3>(0, 0) += 2.0 * x1 * x1.transpose();
  H.block<3, 3>(3, 3) += 2.0 * x0 * x0.transpose();
  H.block<3, 3>(0, 3) += 2.0 * x1 * x0.transpose() + 2.0 * x0.dot(x1) * Eigen::Matrix3d::Identity();
  H.block<3, 3>(3, 0) = H.block<3, 3>(0, 3).transpose();
  return H;
}

}  // namespace

TEST_CASE("affine map: a stencil's nodes, J^T g and J^T H J against the explicit Jacobian and central differences") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random3 = [&] { return Eigen::Vector3d(u(rng), u(rng), u(rng)); };
  struct Case {
    const char* what;
    std::vector<VertexNodes> vertices;
    std::vector<int32_t> nodes;  // expected, in first-named order
  };
  const Case cases[] = {
      {"point of an affine body against a triangle of another",
       {affine_vertex(40, random3()), affine_vertex(20, random3()), affine_vertex(20, random3()), affine_vertex(20, random3())},
       {40, 41, 42, 43, 20, 21, 22, 23}},
      {"edge of a tet body against an edge of an affine body",
       {tet_vertex(5), tet_vertex(2), affine_vertex(30, random3()), affine_vertex(30, random3())},
       {5, 2, 30, 31, 32, 33}},
      {"tet vertices only: the identity", {tet_vertex(3), tet_vertex(1), tet_vertex(8)}, {3, 1, 8}},
  };
  for (const Case& c : cases) {
    INFO(c.what);
    const int k = static_cast<int>(c.vertices.size());
    int32_t nodes[kMaxStencilNodes];
    const int K = stencil_nodes(c.vertices.data(), k, nodes);
    REQUIRE(K == static_cast<int>(c.nodes.size()));
    CHECK(std::vector<int32_t>(nodes, nodes + K) == c.nodes);
    const Eigen::MatrixXd J = jacobian(c.vertices, c.nodes);

    // Node coordinates, the vertex positions they give, and the function's derivatives there.
    Eigen::VectorXd q(3 * K);
    for (int i = 0; i < 3 * K; ++i) q[i] = u(rng);
    const Eigen::VectorXd x = J * q;
    const Eigen::VectorXd g = gradient_of(x);
    const Eigen::MatrixXd H = hessian_of(x);
    Eigen::VectorXd mapped_g(3 * K);
    Eigen::MatrixXd mapped_H(3 * K, 3 * K);
    map_stencil_gradient(c.vertices.data(), k, g.data(), nodes, K, mapped_g.data());
    map_stencil_hessian(c.vertices.data(), k, H.data(), nodes, K, mapped_H.data());

    // Against J^T g and J^T H J, and exactly symmetric.
    CHECK((mapped_g - J.transpose() * g).norm() <= 1e-13 * g.norm() * J.norm());
    CHECK((mapped_H - J.transpose() * H * J).norm() <= 1e-13 * H.norm() * J.squaredNorm());
    CHECK(mapped_H == mapped_H.transpose());

    // Against central differences of f(J q) and of the mapped gradient.
    const double h = 1e-6;
    for (int i = 0; i < 3 * K; ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h;
      qm[i] -= h;
      const double dfdq = (f_of(J * qp) - f_of(J * qm)) / (2 * h);
      CHECK(std::abs(dfdq - mapped_g[i]) <= 1e-6 * (1.0 + mapped_g.norm()));
      Eigen::VectorXd gp(3 * K), gm(3 * K);
      const Eigen::VectorXd xp = J * qp, xm = J * qm;
      const Eigen::VectorXd vp = gradient_of(xp), vm = gradient_of(xm);
      map_stencil_gradient(c.vertices.data(), k, vp.data(), nodes, K, gp.data());
      map_stencil_gradient(c.vertices.data(), k, vm.data(), nodes, K, gm.data());
      CHECK(((gp - gm) / (2 * h) - mapped_H.col(i)).norm() <= 1e-6 * (1.0 + mapped_H.norm()));
    }
  }
}

TEST_CASE("affine map: a stencil over more than eight nodes is refused") {
  // Three affine bodies: 12 nodes.
  const VertexNodes vertices[3] = {affine_vertex(0, Eigen::Vector3d(1, 2, 3)), affine_vertex(4, Eigen::Vector3d(1, 0, 0)),
                                   affine_vertex(8, Eigen::Vector3d(0, 1, 0))};
  int32_t nodes[kMaxStencilNodes];
  CHECK(stencil_nodes(vertices, 2, nodes) == 8);
  CHECK(stencil_nodes(vertices, 3, nodes) == -1);
}

TEST_CASE("affine map: upper triangles summed and mirrored once equal the sum of whole maps, bit for bit") {
  // CoordinateMap::map_slabs sums the contacts of one pair of bodies this way.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto random3 = [&] { return Eigen::Vector3d(u(rng), u(rng), u(rng)); };
  const int K = 8;
  const int32_t nodes[K] = {20, 21, 22, 23, 40, 41, 42, 43};
  Eigen::MatrixXd whole = Eigen::MatrixXd::Zero(3 * K, 3 * K), summed(3 * K, 3 * K), one(3 * K, 3 * K);
  summed.setConstant(std::nan(""));  // the lower triangle is never read before the mirror writes it
  for (int s = 0; s < 5; ++s) {
    // A point of body 40 against a triangle of body 20, or an edge of each.
    std::vector<VertexNodes> vertices;
    if (s % 2)
      vertices = {affine_vertex(40, random3()), affine_vertex(20, random3()), affine_vertex(20, random3()),
                  affine_vertex(20, random3())};
    else
      vertices = {affine_vertex(20, random3()), affine_vertex(20, random3()), affine_vertex(40, random3()),
                  affine_vertex(40, random3())};
    Eigen::MatrixXd A = Eigen::MatrixXd::NullaryExpr(12, 12, [&] { return u(rng); });
    const Eigen::MatrixXd H = A + A.transpose();
    map_stencil_hessian(vertices.data(), 4, H.data(), nodes, K, one.data());
    whole += one;
    map_stencil_hessian_upper(vertices.data(), 4, H.data(), nodes, K, s == 0 ? summed.data() : one.data());
    if (s > 0)
      for (int c = 0; c < 3 * K; ++c)
        for (int r = 0; r <= c; ++r) summed(r, c) += one(r, c);
  }
  mirror_upper(summed.data(), K);
  CHECK(summed == whole);
  CHECK(summed.norm() > 0.0);
}

// The coordinate map between nodes and vertices (engine/coordinate_map.hpp) against a dense
// vertex Jacobian J: follower positions are J q, the folded gradient J^T g, and the mapped
// stencil slabs, scattered, J^T H J of the vertex slabs.
#include "engine/coordinate_map.hpp"

#include <doctest/doctest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

using namespace nexdyn;

namespace {

// Three tet vertices (0..2); affine body A: followers 3..5, nodes 6..9; body B: followers 10, 11,
// nodes 12..15.
Model two_affine_bodies(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> y(-1.0, 1.0);
  Model model;
  model.num_vertices = 16;
  model.follows.assign(16, -1);
  model.follower_rest.assign(3 * 16, 0.0);
  auto add_body = [&](int32_t followers, int32_t count, int32_t node) {
    AffineBody body;
    body.node = node;
    body.follower_begin = followers;
    body.follower_count = count;
    for (int32_t v = followers; v < followers + count; ++v) {
      model.follows[v] = static_cast<int32_t>(model.affine_bodies.size());
      for (int j = 0; j < 3; ++j) model.follower_rest[3 * v + j] = y(rng);
    }
    model.affine_bodies.push_back(body);
  };
  add_body(3, 3, 6);
  add_body(10, 2, 12);
  return model;
}

// J over all vertex slots: rows of a follower map to its body's nodes, every other row is the
// identity on its own slot (so a follower's column is zero: it is no unknown).
Eigen::MatrixXd dense_jacobian(const Model& model) {
  const int n = 3 * model.num_vertices;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(n, n);
  for (int v = 0; v < model.num_vertices; ++v) {
    if (model.follows[v] < 0) {
      J.block<3, 3>(3 * v, 3 * v).setIdentity();
      continue;
    }
    const AffineBody& body = model.affine_bodies[model.follows[v]];
    J.block<3, 3>(3 * v, 3 * body.node).setIdentity();
    for (int j = 0; j < 3; ++j)
      J.block<3, 3>(3 * v, 3 * (body.node + 1 + j)) = model.follower_rest[3 * v + j] * Eigen::Matrix3d::Identity();
  }
  return J;
}

// Adds the column-major slabs of `stencils` (-1 ids skipped) into the dense matrix H.
void scatter(const std::vector<int32_t>& stencils, const std::vector<int64_t>& slab_begin, const double* slabs,
             Eigen::MatrixXd& H) {
  for (size_t s = 0; s + 1 < slab_begin.size(); ++s) {
    const int64_t size = slab_begin[s + 1] - slab_begin[s];
    const int n = size == 9 ? 1 : size == 36 ? 2 : size == 81 ? 3 : 4;
    const Eigen::Map<const Eigen::MatrixXd> slab(slabs + slab_begin[s], 3 * n, 3 * n);
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b) {
        const int32_t i = stencils[4 * s + a], j = stencils[4 * s + b];
        if (i < 0 || j < 0) continue;
        H.block<3, 3>(3 * i, 3 * j) += slab.block<3, 3>(3 * a, 3 * b);
      }
  }
}

}  // namespace

TEST_CASE("coordinate map: follower positions and directions are J q") {
  std::mt19937_64 rng(1);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  REQUIRE_FALSE(map.identity());
  std::normal_distribution<double> normal;
  Eigen::VectorXd q(3 * model.num_vertices);
  for (int i = 0; i < q.size(); ++i) q[i] = normal(rng);
  for (int v = 0; v < model.num_vertices; ++v)
    if (model.follows[v] >= 0) q.segment<3>(3 * v).setZero();
  const Eigen::VectorXd expected = dense_jacobian(model) * q;
  Eigen::VectorXd x = q;
  map.follow(x.data());
  CHECK((x - expected).norm() <= 1e-14 * expected.norm());
  // A node or tet vertex is its own, with weight 1.
  const VertexNodes plain = map.nodes_of(1);
  CHECK(plain.count == 1);
  CHECK(plain.node[0] == 1);
  CHECK(map.nodes_of(-1).count == 0);
}

TEST_CASE("coordinate map: the folded gradient is J^T g, zero at the followers") {
  std::mt19937_64 rng(2);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  std::normal_distribution<double> normal;
  Eigen::VectorXd g(3 * model.num_vertices);
  for (int i = 0; i < g.size(); ++i) g[i] = normal(rng);
  const Eigen::VectorXd expected = dense_jacobian(model).transpose() * g;
  map.fold_gradient(g.data());
  CHECK((g - expected).norm() <= 1e-14 * expected.norm());
  for (int v : {3, 4, 5, 10, 11}) CHECK(g.segment<3>(3 * v).isZero(0.0));
}

TEST_CASE("coordinate map: stencils over one node set are summed, J^T H J in sub-stencils of at most 4 distinct nodes") {
  std::mt19937_64 rng(3);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  // Stencils over vertices and their widths n (slab 3n x 3n): two affine bodies (8 nodes); tet
  // vertices with a follower (7); a vertex-plane stencil of a follower (4); a held vertex (-1)
  // amid tet vertices; the same tet vertices alone; a follower with an absent second vertex;
  // another contact of the two bodies.
  const std::vector<int32_t> stencils = {3, 10, 11, 4, 0, 1, 2, 3, 5, -1, -1, -1, 0, 1, -1, 2,
                                         0, 1, 2, -1, 10, -1, -1, -1, 5, 10, -1, -1};
  const std::vector<int> widths = {4, 4, 1, 4, 3, 2, 2};
  std::vector<int64_t> slab_begin{0};
  for (int n : widths) slab_begin.push_back(slab_begin.back() + 9 * n * n);
  std::vector<double> slabs(slab_begin.back());
  std::normal_distribution<double> normal;
  for (size_t s = 0; s < widths.size(); ++s) {
    const int n = 3 * widths[s];
    Eigen::MatrixXd B(n, n);
    for (int i = 0; i < B.size(); ++i) B.data()[i] = normal(rng);
    Eigen::Map<Eigen::MatrixXd>(slabs.data() + slab_begin[s], n, n) = B * B.transpose();
  }

  MappedStencils mapped;
  map.map_stencils(stencils, slab_begin, mapped);
  // Groups in order of first source: the two bodies {0, 6}, {1}, {2}, the tet vertices {3, 4},
  // {5}. Sub-stencils: 8 nodes: 4 chunks of 2, 6; 7 nodes: 4 chunks, 6; 4 or fewer: 1.
  const std::vector<std::vector<int64_t>> groups = {{0, 6}, {1}, {2}, {3, 4}, {5}};
  const std::vector<int64_t> subs = {6, 6, 1, 1, 1};
  REQUIRE(mapped.num_groups() == static_cast<int64_t>(groups.size()));
  for (size_t g = 0; g < groups.size(); ++g) {
    CAPTURE(g);
    CHECK(std::vector<int64_t>(mapped.sources.begin() + mapped.source_begin[g],
                               mapped.sources.begin() + mapped.source_begin[g + 1]) == groups[g]);
    CHECK(mapped.first[g + 1] - mapped.first[g] == subs[g]);
  }
  std::vector<double> out(mapped.slab_begin.back());
  map.map_slabs(stencils, slab_begin, slabs.data(), mapped, out.data());

  const int num_dofs = 3 * model.num_vertices;
  const Eigen::MatrixXd J = dense_jacobian(model);
  for (size_t g = 0; g < groups.size(); ++g) {
    CAPTURE(g);
    // The group's vertex slabs, summed, against its sub-stencils' node slabs.
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(num_dofs, num_dofs), Hq = H;
    for (int64_t s : groups[g]) {
      const std::vector<int32_t> one(stencils.begin() + 4 * s, stencils.begin() + 4 * s + 4);
      const std::vector<int64_t> one_begin{0, slab_begin[s + 1] - slab_begin[s]};
      scatter(one, one_begin, slabs.data() + slab_begin[s], H);
    }
    const std::vector<int32_t> sub(mapped.stencils.begin() + 4 * mapped.first[g],
                                   mapped.stencils.begin() + 4 * mapped.first[g + 1]);
    std::vector<int64_t> sub_begin;
    for (int64_t k = mapped.first[g]; k <= mapped.first[g + 1]; ++k)
      sub_begin.push_back(mapped.slab_begin[k] - mapped.slab_begin[mapped.first[g]]);
    scatter(sub, sub_begin, out.data() + mapped.slab_begin[mapped.first[g]], Hq);
    const Eigen::MatrixXd expected = J.transpose() * H * J;
    CHECK((Hq - expected).norm() <= 1e-13 * expected.norm());
    // Each sub-stencil: distinct nodes, none a follower, an exactly symmetric slab.
    for (int64_t k = mapped.first[g]; k < mapped.first[g + 1]; ++k) {
      const int32_t* ids = &mapped.stencils[4 * k];
      for (int a = 0; a < 4; ++a) {
        if (ids[a] < 0) continue;
        CHECK(model.follows[ids[a]] < 0);
        for (int b = a + 1; b < 4; ++b) CHECK(ids[a] != ids[b]);
      }
      const int64_t size = mapped.slab_begin[k + 1] - mapped.slab_begin[k];
      const int n = static_cast<int>(std::lround(std::sqrt(double(size))));
      const Eigen::Map<const Eigen::MatrixXd> slab(out.data() + mapped.slab_begin[k], n, n);
      CHECK(slab == slab.transpose());
    }
  }
}

TEST_CASE("coordinate map: coupling stencils join every node of a stencil, and bodies of three are refused") {
  std::mt19937_64 rng(4);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  std::vector<int32_t> coupled;
  map.map_coupling({3, 10, 11, 4}, coupled);
  // Union-find over the nodes of the sub-stencils: one set holding all 8 nodes.
  std::vector<int> parent(model.num_vertices);
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (size_t k = 0; k < coupled.size(); k += 4)
    for (int a = 1; a < 4 && coupled[k + a] >= 0; ++a) parent[find(coupled[k + a])] = find(coupled[k]);
  for (int node : {7, 8, 9, 12, 13, 14, 15}) CHECK(find(node) == find(6));
  CHECK(find(0) != find(6));
  // A tet vertex and two affine bodies: 9 nodes, more than a contact stencil can touch.
  std::vector<int32_t> out;
  CHECK_THROWS_AS(map.map_coupling({0, 3, 10, -1}, out), std::logic_error);
}

TEST_CASE("coordinate map: followers take the line-search group of their body") {
  std::mt19937_64 rng(5);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  std::vector<int32_t> group(model.num_vertices, -1);
  group[6] = 2;
  map.follow_groups(group.data());
  for (int v : {3, 4, 5}) CHECK(group[v] == 2);
  for (int v : {10, 11}) CHECK(group[v] == -1);
}

namespace {
Eigen::Matrix3d rotation(const Eigen::Vector3d& w) { return Eigen::AngleAxisd(w.norm(), w.normalized()).matrix(); }
}  // namespace

TEST_CASE("coordinate map: a turned trial rotates a rigid body rigidly and agrees with the chord to first order") {
  // Body A (nodes 6..9) at a rotation C0, its direction the rotation's tangent W C0 (plus a
  // stretch E C0 in the second part). The chord C0 + alpha D stretches the body by
  // (alpha theta)^2 / 2; the turned trial is exp(alpha W) (I + alpha E) C0 exactly, and differs
  // from the chord by O(alpha^2).
  std::mt19937_64 rng(11);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  const int n = 3 * model.num_vertices;
  const Eigen::Matrix3d C0 = rotation({0.3, -0.5, 0.2});
  const Eigen::Vector3d w(0.2, 0.7, -0.4);  // |w| = 0.83 rad over a full step
  const Eigen::Matrix3d W = (Eigen::Matrix3d() << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0).finished();
  const Eigen::Vector3d p(0.1, 0.2, 0.3), dp(0.01, -0.02, 0.005);

  auto state = [&](const Eigen::Matrix3d& D, std::vector<double>& x, std::vector<double>& d) {
    x.assign(n, 0.0);
    d.assign(n, 0.0);
    Eigen::Vector3d::Map(&x[3 * 6]) = p;
    Eigen::Vector3d::Map(&d[3 * 6]) = dp;
    for (int j = 0; j < 3; ++j) {
      Eigen::Vector3d::Map(&x[3 * (7 + j)]) = C0.col(j);
      Eigen::Vector3d::Map(&d[3 * (7 + j)]) = D.col(j);
    }
    map.follow(x.data());
    map.follow(d.data());  // as Newton's direction: the followers' part is J d
  };
  std::vector<int32_t> group(model.num_vertices, -1);
  for (int v : {3, 4, 5, 6, 7, 8, 9}) group[v] = 0;  // body B does not move

  auto turned = [&](const std::vector<double>& x, const std::vector<double>& d, double alpha) {
    std::vector<double> trial(n);
    for (int i = 0; i < n; ++i) trial[i] = group[i / 3] < 0 ? x[i] : x[i] + alpha * d[i];
    CHECK(map.turn(x.data(), d.data(), group.data(), &alpha, trial.data()) == 1);
    return trial;
  };
  auto nodes_c = [&](const std::vector<double>& q) {
    Eigen::Matrix3d C;
    for (int j = 0; j < 3; ++j) C.col(j) = Eigen::Vector3d::Map(&q[3 * (7 + j)]);
    return C;
  };

  SUBCASE("a pure turn stays a rotation, its followers on it") {
    std::vector<double> x, d;
    state(W * C0, x, d);
    for (double alpha : {1.0, 0.5, 0.125}) {
      const std::vector<double> trial = turned(x, d, alpha);
      const Eigen::Matrix3d C = nodes_c(trial);
      CHECK((C - rotation(alpha * w) * C0).norm() < 1e-14);
      CHECK((C.transpose() * C - Eigen::Matrix3d::Identity()).norm() < 1e-14);
      CHECK((Eigen::Vector3d::Map(&trial[3 * 6]) - (p + alpha * dp)).norm() < 1e-15);  // p is not turned
      std::vector<double> refollowed = trial;
      map.follow(refollowed.data());
      for (int i = 0; i < n; ++i) CHECK(trial[i] == doctest::Approx(refollowed[i]).epsilon(1e-15));
      for (int i = 3 * 10; i < n; ++i) CHECK(trial[i] == x[i]);  // body B untouched
    }
  }
  SUBCASE("with a stretch, turn minus chord shrinks as alpha^2") {
    Eigen::Matrix3d E;
    E << 0.02, 0.01, 0.0, 0.01, -0.03, 0.005, 0.0, 0.005, 0.01;
    std::vector<double> x, d;
    state((W + E) * C0, x, d);
    double previous = 0.0;
    for (double alpha : {0.1, 0.05, 0.025}) {
      const std::vector<double> trial = turned(x, d, alpha);
      const Eigen::Matrix3d C = nodes_c(trial);
      CHECK((C - rotation(alpha * w) * (Eigen::Matrix3d::Identity() + alpha * E) * C0).norm() < 1e-14);
      double gap = 0.0;
      for (int i = 0; i < n; ++i) gap = std::max(gap, std::abs(trial[i] - (x[i] + (group[i / 3] < 0 ? 0.0 : alpha * d[i]))));
      if (previous > 0.0) CHECK(previous / gap == doctest::Approx(4.0).epsilon(0.05));
      previous = gap;
    }
  }
}

TEST_CASE("coordinate map: turn pads bound how far every turned trial leaves the chord") {
  // Body A (nodes 6..9) at a stretched rotation, its direction a turn by theta (up to past pi)
  // plus a stretch; the line search takes any alpha of a direction that the CCD may have scaled
  // down. Each follower's turned trial stays within its pad of the chord point, and for a pure
  // turn the pad is within a factor of 2 of the largest gap (a bound that cannot be loose by
  // more: |R - I - W| u reaches sqrt(a^2 + b^2) for u across the axis, the pad a + b).
  std::mt19937_64 rng(23);
  const Model model = two_affine_bodies(rng);
  const CoordinateMap map(model);
  const int n = 3 * model.num_vertices;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<int32_t> group(model.num_vertices, -1);
  for (int v : {3, 4, 5, 6, 7, 8, 9}) group[v] = 0;
  std::vector<uint8_t> moves(model.num_vertices, 0);
  moves[6] = 1;
  for (double theta : {0.05, 1.0, 2.5, 4.0}) {
    for (double stretch : {0.0, 0.05}) {
      CAPTURE(theta);
      CAPTURE(stretch);
      const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      const Eigen::Vector3d w = theta * axis;
      const Eigen::Matrix3d W = (Eigen::Matrix3d() << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0).finished();
      Eigen::Matrix3d E = Eigen::Matrix3d::NullaryExpr([&] { return stretch * u(rng); });
      E = 0.5 * (E + E.transpose()).eval();
      const Eigen::Matrix3d C0 = rotation({u(rng), u(rng), u(rng)}) * (Eigen::Matrix3d::Identity() + 0.1 * E);
      std::vector<double> x(n, 0.0), d(n, 0.0);
      for (int i = 0; i < n; ++i) x[i] = u(rng);
      Eigen::Vector3d::Map(&d[3 * 6]) = Eigen::Vector3d(u(rng), u(rng), u(rng));
      for (int j = 0; j < 3; ++j) {
        Eigen::Vector3d::Map(&x[3 * (7 + j)]) = C0.col(j);
        Eigen::Vector3d::Map(&d[3 * (7 + j)]) = ((W + E) * C0).col(j);
      }
      map.follow(x.data());
      map.follow(d.data());
      std::vector<double> pad(model.num_vertices, -1.0);
      map.turn_pads(x.data(), d.data(), moves.data(), pad.data());
      for (int v = 0; v < model.num_vertices; ++v)
        if (v < 3 || v > 5) CHECK(pad[v] == 0.0);  // tet vertices, nodes and the still body B
      double tightest = 0.0;
      for (double scale : {1.0, 0.5, 0.1}) {
        std::vector<double> scaled = d;
        for (double& di : scaled) di *= scale;
        for (int k = 1; k <= 20; ++k) {
          const double alpha = k / 20.0;
          std::vector<double> trial(n);
          for (int i = 0; i < n; ++i) trial[i] = group[i / 3] < 0 ? x[i] : x[i] + alpha * scaled[i];
          const std::vector<double> chord = trial;
          map.turn(x.data(), scaled.data(), group.data(), &alpha, trial.data());
          for (int v = 3; v <= 5; ++v) {
            const double gap = (Eigen::Vector3d::Map(&trial[3 * v]) - Eigen::Vector3d::Map(&chord[3 * v])).norm();
            CHECK(gap <= pad[v] * (1.0 + 1e-12));
            tightest = std::max(tightest, gap / pad[v]);
          }
        }
      }
      if (stretch == 0.0) CHECK(tightest > 0.5);
    }
  }
}

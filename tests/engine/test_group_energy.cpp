// Grouped energies (group_energy of ElasticAssembly, BarrierPotential, FrictionPotential and
// IncrementalPotential), which the island solver's line search tests group by group
// (engine/solver/newton.cpp): with every vertex in group 0 they add up to energy(); with groups
// along bodies, each group's total is the energy of the terms touching its vertices, summed
// element by element from the kernels (friction pair by pair from its definition, with no code of
// FrictionPotential); terms of vertices in group -1 contribute nothing.
#include "engine/contact/barrier_potential.hpp"
#include "engine/contact/friction_potential.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "kernels/barrier/barrier.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

using namespace nexdyn;

namespace {

constexpr double kDhat = 0.05;
constexpr double kDt = 0.01;
constexpr double kKappa = 1e3;

// Body 1 rests 0.01 m on body 0, which is 0.02 m over a ground plane; bodies 2 and 3 stand alone
// 0.02 m over the plane, far from the others. Two materials alternate, so the tets form four
// material batches. With dhat = 0.05 m there are vertex-triangle, edge-edge and vertex-plane
// contacts, with friction.
Scene four_bodies_on_ground() {
  return test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 },
    "contact": { "dhat": 0.05, "friction": 0.4 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 },
                   "b": { "model": "stvk", "youngs": 3e5, "poisson": 0.2, "density": 500 } },
    "bodies": [ { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.4, 0.4, 0.4], "cells": [2, 1, 2] }, "material": "b",
                  "translate": [0.03, 0.46, -0.02] },
                { "box": { "size": [0.3, 0.3, 0.3], "cells": [2, 2, 2] }, "material": "a",
                  "translate": [1.0, -0.1, 0.0] },
                { "box": { "size": [0.3, 0.3, 0.3], "cells": [1, 2, 1] }, "material": "b",
                  "translate": [-1.0, -0.1, 0.0] } ],
    "obstacles": [ { "plane": { "point": [0, -0.27, 0], "normal": [0, 1, 0] } } ]
  })", "group_energy_bodies");
}

Eigen::Vector3d point(const double* x, int32_t v) { return Eigen::Vector3d::Map(x + 3 * int64_t{v}); }

// Group of a term from its vertices: the one group its grouped vertices share (-1: none).
int32_t term_group(const std::vector<int32_t>& group, std::initializer_list<int32_t> vertices) {
  int32_t g = -1;
  for (int32_t v : vertices) {
    if (v < 0 || group[v] < 0) continue;
    REQUIRE((g < 0 || g == group[v]));  // the groups of the test never split a term
    g = group[v];
  }
  return g;
}

// Per-group sums, with slot num_groups for the terms of no group.
struct Reference {
  std::vector<double> total;
  explicit Reference(int32_t num_groups) : total(num_groups + 1, 0.0) {}
  void add(int32_t g, double e) { total[g < 0 ? total.size() - 1 : g] += e; }
  double all() const {
    double s = 0.0;
    for (double t : total) s += t;
    return s;
  }
};

Reference elastic_reference(const Model& m, const double* x, const std::vector<int32_t>& group, int32_t num_groups) {
  Reference ref(num_groups);
  for (int32_t t = 0; t < m.num_tets; ++t) {
    const int32_t* tet = &m.tets[4 * int64_t{t}];
    Eigen::Matrix<double, 3, 4> xt;
    for (int c = 0; c < 4; ++c) xt.col(c) = point(x, tet[c]);
    const Material& mat = m.materials[m.tet_material[t]];
    ref.add(term_group(group, {tet[0], tet[1], tet[2], tet[3]}),
            tet_energy(mat.model, xt, Eigen::Matrix3d::Map(&m.Dm_inv[9 * int64_t{t}]), m.rest_volume[t], mat.lame));
  }
  return ref;
}

// The barrier of every candidate pair on its own, from the distance kernels.
Reference barrier_reference(const Model& m, const ContactCandidates& c, const double* x,
                            const std::vector<int32_t>& group, int32_t num_groups) {
  const double dhat2 = kDhat * kDhat;
  const double* r = m.rest_positions.data();
  Reference ref(num_groups);
  for (const IndexPair& pair : c.vertex_triangle) {
    const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
    const double d = point_triangle_distance(point(x, pair.first), point(x, t[0]), point(x, t[1]), point(x, t[2]));
    ref.add(term_group(group, {pair.first, t[0], t[1], t[2]}), d < dhat2 ? barrier(d, dhat2) : 0.0);
  }
  for (const IndexPair& pair : c.edge_edge) {
    const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
    const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
    const Eigen::Vector3d a0 = point(x, ea[0]), a1 = point(x, ea[1]), b0 = point(x, eb[0]), b1 = point(x, eb[1]);
    const double d = edge_edge_distance(a0, a1, b0, b1);
    double e = 0.0;
    if (d < dhat2) {
      const double eps_x = edge_edge_mollifier_threshold(point(r, ea[0]), point(r, ea[1]), point(r, eb[0]), point(r, eb[1]));
      e = barrier(d, dhat2) * edge_edge_mollifier(a0, a1, b0, b1, eps_x);
    }
    ref.add(term_group(group, {ea[0], ea[1], eb[0], eb[1]}), e);
  }
  for (const IndexPair& pair : c.vertex_plane) {
    const ObstaclePlane& plane = m.obstacle_planes[pair.second];
    const double s = (point(x, pair.first) - plane.point).dot(plane.normal);
    const double d = s > 0.0 ? s * s : 0.0;
    ref.add(term_group(group, {pair.first}), d < dhat2 ? barrier(d, dhat2) : 0.0);
  }
  return ref;
}

// The closest point of triangle (a, b, c) to p as weights of its corners: the projection onto the
// plane when it falls inside, else the closest point of the nearest edge.
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c) {
  Eigen::Matrix<double, 3, 2> basis;
  basis << b - a, c - a;
  const Eigen::Vector2d uv = (basis.transpose() * basis).ldlt().solve(basis.transpose() * (p - a));
  if (uv.x() >= 0.0 && uv.y() >= 0.0 && uv.x() + uv.y() <= 1.0) return {1.0 - uv.x() - uv.y(), uv.x(), uv.y()};
  const Eigen::Vector3d corner[3] = {a, b, c};
  Eigen::Vector3d best;
  double best_d = std::numeric_limits<double>::infinity();
  for (int e = 0; e < 3; ++e) {
    const Eigen::Vector3d& e0 = corner[e];
    const Eigen::Vector3d& e1 = corner[(e + 1) % 3];
    const double t = std::clamp((p - e0).dot(e1 - e0) / (e1 - e0).squaredNorm(), 0.0, 1.0);
    const double d = (p - (e0 + t * (e1 - e0))).squaredNorm();
    if (d < best_d) {
      best_d = d;
      best.setZero();
      best[e] = 1.0 - t;
      best[(e + 1) % 3] = t;
    }
  }
  return best;
}

// The closest points of segments a0-a1 and b0-b1 as parameters (s on a, t on b): the lines'
// closest points, each clamped to its segment and the other re-projected (the edges here are
// never parallel to round-off: the boxes are perturbed).
Eigen::Vector2d closest_on_segments(const Eigen::Vector3d& a0, const Eigen::Vector3d& a1, const Eigen::Vector3d& b0,
                                    const Eigen::Vector3d& b1) {
  const Eigen::Vector3d u = a1 - a0, v = b1 - b0, w = a0 - b0;
  const double A = u.dot(u), B = u.dot(v), C = v.dot(v), D = u.dot(w), E = v.dot(w);
  double s = std::clamp((B * E - C * D) / (A * C - B * B), 0.0, 1.0);
  double t = std::clamp((B * s + E) / C, 0.0, 1.0);
  s = std::clamp((B * t - D) / A, 0.0, 1.0);
  return {s, t};
}

// IPC's smoothed Coulomb antiderivative f0 (Li et al. 2020, eq. 15), eps_u = epsv dt.
double f0(double y, double eps_u) {
  return y >= eps_u ? y : -y * y * y / (3.0 * eps_u * eps_u) + y * y / eps_u + eps_u / 3.0;
}

// The lagged friction of every candidate pair closer than dhat at x_lag, on its own: the normal
// force lambda = -kappa b'(d) 2 sqrt(d) (times the mollifier for an edge pair), the closest
// points' weights and normal frozen at x_lag, the tangential part of the relative displacement
// from x_start to x, and mu lambda f0(|u_T|). Shares no code with FrictionPotential.
Reference friction_reference(const Model& m, const ContactCandidates& c, const std::vector<double>& x_lag,
                             const std::vector<double>& x_start, const std::vector<double>& x, double kappa,
                             const std::vector<int32_t>& group, int32_t num_groups) {
  const double dhat2 = kDhat * kDhat, mu = 0.4, eps_u = 0.1 * kDt;
  const double* r = m.rest_positions.data();
  auto lag = [&](int32_t v) { return point(x_lag.data(), v); };
  auto moved = [&](int32_t v) { return Eigen::Vector3d(point(x.data(), v) - point(x_start.data(), v)); };
  auto term = [&](double lambda, const Eigen::Vector3d& normal, const Eigen::Vector3d& slip) {
    const Eigen::Vector3d tangential = slip - slip.dot(normal) * normal;
    return mu * lambda * f0(tangential.norm(), eps_u);
  };
  auto normal_force = [&](double d) { return -kappa * barrier_first_derivative(d, dhat2) * 2.0 * std::sqrt(d); };
  Reference ref(num_groups);
  for (const IndexPair& pair : c.vertex_triangle) {
    const int32_t p = pair.first;
    const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
    const Eigen::Vector3d w = closest_on_triangle(lag(p), lag(t[0]), lag(t[1]), lag(t[2]));
    const Eigen::Vector3d gap = lag(p) - (w[0] * lag(t[0]) + w[1] * lag(t[1]) + w[2] * lag(t[2]));
    if (gap.squaredNorm() >= dhat2) continue;
    const Eigen::Vector3d slip = moved(p) - (w[0] * moved(t[0]) + w[1] * moved(t[1]) + w[2] * moved(t[2]));
    ref.add(term_group(group, {p, t[0], t[1], t[2]}), term(normal_force(gap.squaredNorm()), gap.normalized(), slip));
  }
  for (const IndexPair& pair : c.edge_edge) {
    const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
    const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
    const Eigen::Vector2d st = closest_on_segments(lag(ea[0]), lag(ea[1]), lag(eb[0]), lag(eb[1]));
    auto on_a = [&](auto&& f) { return Eigen::Vector3d((1.0 - st[0]) * f(ea[0]) + st[0] * f(ea[1])); };
    auto on_b = [&](auto&& f) { return Eigen::Vector3d((1.0 - st[1]) * f(eb[0]) + st[1] * f(eb[1])); };
    const Eigen::Vector3d gap = on_a(lag) - on_b(lag);
    if (gap.squaredNorm() >= dhat2) continue;
    const double eps_x = edge_edge_mollifier_threshold(point(r, ea[0]), point(r, ea[1]), point(r, eb[0]), point(r, eb[1]));
    const double lambda = normal_force(gap.squaredNorm()) *
                          edge_edge_mollifier(lag(ea[0]), lag(ea[1]), lag(eb[0]), lag(eb[1]), eps_x);
    ref.add(term_group(group, {ea[0], ea[1], eb[0], eb[1]}), term(lambda, gap.normalized(), on_a(moved) - on_b(moved)));
  }
  for (const IndexPair& pair : c.vertex_plane) {
    const ObstaclePlane& plane = m.obstacle_planes[pair.second];
    const double s = (lag(pair.first) - plane.point).dot(plane.normal);
    if (s * s >= dhat2) continue;
    ref.add(term_group(group, {pair.first}), term(normal_force(s * s), plane.normal, moved(pair.first)));
  }
  return ref;
}

bool close(double a, double b, double tolerance = 1e-12) {
  return std::abs(a - b) <= tolerance * std::max(std::abs(a), std::abs(b));
}

// Vertex groups along bodies: body_group[b] for every vertex of body b.
std::vector<int32_t> groups_of_bodies(const Model& m, std::initializer_list<int32_t> body_group) {
  std::vector<int32_t> group(m.num_vertices);
  const std::vector<int32_t> per_body(body_group);
  for (int32_t v = 0; v < m.num_vertices; ++v) group[v] = per_body[m.vertex_body[v]];
  return group;
}

// The contact state of the tests: candidates and active set at x_lag, friction lagged there with
// kKappa and a step start x_start, and an evaluation point x; both x_start and x near x_lag.
struct ContactSetup {
  Scene scene = four_bodies_on_ground();
  const Model& model = scene.model;
  std::vector<double> x_lag = test::perturbed(model.rest_positions, 2e-3, 3);
  std::vector<double> x_start = test::perturbed(x_lag, 2e-3, 4);
  std::vector<double> x = test::perturbed(x_lag, 2e-3, 5);
  BarrierPotential contact{model, kDhat};
  FrictionPotential friction{model, FrictionTable(2, {0.4, 0.4}), 0.1};

  ContactSetup() {
    contact.find_candidates(x_lag.data(), nullptr);
    contact.build_active_set(x_lag.data());
    friction.lag(contact, x_lag.data(), kKappa, x_start.data(), kDt);
  }

  Reference friction_reference(const std::vector<int32_t>& group, int32_t num_groups) const {
    return ::friction_reference(model, contact.candidates(), x_lag, x_start, x, kKappa, group, num_groups);
  }
};

}  // namespace

TEST_CASE("group energies with every vertex in group 0 add up to energy()") {
  ContactSetup s;
  const Model& model = s.model;
  const ElasticAssembly elastic(model);
  REQUIRE(model.material_batches.size() == 4);
  REQUIRE(s.contact.candidates().vertex_triangle.size() > 0);
  REQUIRE(s.contact.candidates().edge_edge.size() > 0);
  REQUIRE(s.contact.candidates().vertex_plane.size() > 0);
  REQUIRE(s.friction.num_stencils() > 10);
  const std::vector<int32_t> zero(model.num_vertices, 0);
  double e = 0.0, b = 0.0, f = 0.0;
  elastic.group_energy(s.x.data(), zero.data(), &e);
  s.contact.group_energy(s.x.data(), zero.data(), &b);
  s.friction.group_energy(s.x.data(), zero.data(), &f);
  CHECK(elastic.energy(s.x.data()) > 0.0);
  CHECK(s.contact.energy(s.x.data()) > 0.0);
  CHECK(s.friction.energy(s.x.data()) > 0.0);
  CHECK(close(e, elastic.energy(s.x.data())));
  CHECK(close(b, s.contact.energy(s.x.data())));
  CHECK(close(f, s.friction.energy(s.x.data())));
  // And the element-by-element references agree with energy(), so they can judge the groups.
  CHECK(close(elastic_reference(model, s.x.data(), zero, 1).all(), elastic.energy(s.x.data())));
  CHECK(close(barrier_reference(model, s.contact.candidates(), s.x.data(), zero, 1).all(), s.contact.energy(s.x.data())));
  CHECK(close(s.friction_reference(zero, 1).all(), s.friction.energy(s.x.data())));
}

TEST_CASE("group energies along bodies: each group totals the terms touching it, group -1 adds nothing") {
  ContactSetup s;
  const Model& model = s.model;
  const ElasticAssembly elastic(model);
  // Bodies 0 and 1 (in contact) are group 1, body 2 group 0, body 3 moves in no group.
  const std::vector<int32_t> group = groups_of_bodies(model, {1, 1, 0, -1});
  const int32_t num_groups = 2;
  // Totals are added to: start from offsets.
  const double offset[2] = {0.25, -3.0};
  auto grouped = [&](auto&& term, const std::vector<double>& x) {
    std::vector<double> total(offset, offset + 2);
    term(x.data(), group.data(), total.data());
    return total;
  };
  auto elastic_terms = [&](const double* x, const int32_t* g, double* t) { elastic.group_energy(x, g, t); };
  auto barrier_terms = [&](const double* x, const int32_t* g, double* t) { s.contact.group_energy(x, g, t); };
  auto friction_terms = [&](const double* x, const int32_t* g, double* t) { s.friction.group_energy(x, g, t); };

  const std::vector<double> e = grouped(elastic_terms, s.x), b = grouped(barrier_terms, s.x),
                            f = grouped(friction_terms, s.x);
  const Reference e_ref = elastic_reference(model, s.x.data(), group, num_groups);
  const Reference b_ref = barrier_reference(model, s.contact.candidates(), s.x.data(), group, num_groups);
  const Reference f_ref = s.friction_reference(group, num_groups);
  for (int32_t g = 0; g < num_groups; ++g) {
    CAPTURE(g);
    CHECK(e_ref.total[g] > 0.0);
    CHECK(b_ref.total[g] > 0.0);
    CHECK(close(e[g] - offset[g], e_ref.total[g]));
    CHECK(close(b[g] - offset[g], b_ref.total[g]));
    CHECK(f_ref.total[g] > 0.0);
    CHECK(close(f[g] - offset[g], f_ref.total[g]));
  }
  // Body 3 has tets and plane contacts of its own: they are in no group.
  CHECK(e_ref.total[num_groups] > 0.0);
  CHECK(b_ref.total[num_groups] > 0.0);
  CHECK(f_ref.total[num_groups] > 0.0);

  // Moving the vertices of group -1 changes no group's total, not even in the last bit.
  std::vector<double> moved = s.x;
  const std::vector<double> jiggle = test::perturbed(s.x, 3e-3, 9);
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (group[v] < 0)
      for (int d = 0; d < 3; ++d) moved[3 * v + d] = jiggle[3 * v + d];
  CHECK(s.contact.energy(moved.data()) != s.contact.energy(s.x.data()));
  CHECK(grouped(elastic_terms, moved) == e);
  CHECK(grouped(barrier_terms, moved) == b);
  CHECK(grouped(friction_terms, moved) == f);

  // Every vertex in group -1: nothing is added.
  const std::vector<int32_t> none(model.num_vertices, -1);
  auto untouched = [&](auto&& term) {
    double total[2] = {offset[0], offset[1]};
    term(s.x.data(), none.data(), total);
    return total[0] == offset[0] && total[1] == offset[1];
  };
  CHECK(untouched(elastic_terms));
  CHECK(untouched(barrier_terms));
  CHECK(untouched(friction_terms));
}

TEST_CASE("incremental potential group energy: the terms of each group, weighted as in energy()") {
  ContactSetup s;
  const Model& model = s.model;
  ElasticAssembly elastic(model);
  BarrierPotential contact(model, kDhat);
  StepHistory history;
  IncrementalPotential potential(model, elastic, history, &contact);
  const std::vector<double> x_tilde = test::perturbed(s.x_lag, 1e-2, 6);
  const double scale = 1e-4, contact_scale = 2e-4;
  potential.begin_step(x_tilde, weights_context(scale, contact_scale, true));
  potential.begin_solve(s.x_lag.data());  // candidates at x_lag, the barrier stiffness
  const double kappa = potential.barrier_stiffness();
  REQUIRE(kappa > 0.0);
  contact.build_active_set(s.x_lag.data());
  FrictionPotential friction(model, FrictionTable(2, {0.4, 0.4}), 0.1);
  friction.lag(contact, s.x_lag.data(), kappa, s.x_start.data(), kDt);
  potential.set_friction(&friction);
  const double* x = s.x.data();
  REQUIRE(std::isfinite(potential.energy(x)));

  double all = 0.0;
  const std::vector<int32_t> zero(model.num_vertices, 0);
  potential.group_energy(x, zero.data(), 1, &all);
  CHECK(close(all, potential.energy(x)));

  const std::vector<int32_t> group = groups_of_bodies(model, {1, 1, 0, -1});
  std::vector<double> out = {123.0, 456.0};  // overwritten, not added to
  potential.group_energy(x, group.data(), 2, out.data());
  const Reference e_ref = elastic_reference(model, x, group, 2);
  const Reference b_ref = barrier_reference(model, contact.candidates(), x, group, 2);
  const Reference f_ref = friction_reference(model, contact.candidates(), s.x_lag, s.x_start, s.x, kappa, group, 2);
  for (int32_t g = 0; g < 2; ++g) {
    CAPTURE(g);
    double inertia_gravity = 0.0;
    for (int32_t v = 0; v < model.num_vertices; ++v) {
      if (group[v] != g) continue;
      const Eigen::Vector3d dx = point(x, v) - point(x_tilde.data(), v);
      inertia_gravity += model.mass[v] * (0.5 * dx.squaredNorm() - scale * model.gravity.dot(dx));
    }
    const double expected = inertia_gravity + scale * e_ref.total[g] +
                            contact_scale * (kappa * b_ref.total[g] + f_ref.total[g]);
    CHECK(close(out[g], expected));
  }

  // An inverted tet makes its group's energy infinite and leaves the other group alone: a corner
  // of a tet of body 2 mirrored through the opposite face.
  std::vector<double> bad = s.x;
  const int32_t* tet = &model.tets[4 * int64_t{model.bodies[2].tet_begin}];
  const Eigen::Vector3d p = point(x, tet[0]), b1 = point(x, tet[1]), b2 = point(x, tet[2]), b3 = point(x, tet[3]);
  const Eigen::Vector3d normal = (b2 - b1).cross(b3 - b1).normalized();
  Eigen::Vector3d::Map(&bad[3 * int64_t{tet[0]}]) = p - 2.0 * (p - b1).dot(normal) * normal;
  REQUIRE(!std::isfinite(potential.energy(bad.data())));
  std::vector<double> bad_out(2);
  potential.group_energy(bad.data(), group.data(), 2, bad_out.data());
  CHECK(std::isinf(bad_out[0]));
  CHECK(bad_out[1] == out[1]);
}

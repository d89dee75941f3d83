// The contact part of the Newton system against independent references: the gradient of the
// incremental potential with barrier against finite differences of its energy, the merged sparse
// Hessian against a dense sum of the element and contact blocks, bitwise equality for 1 and
// 2 threads, the active set merged by closest feature against every pair on its own, and the
// cached pair distances through masked sweeps against a fresh evaluation; a sleeping body's pairs
// left out of the searches without losing their energy or any pair a full search finds.
// (Candidates against the brute force: test_candidates.cpp.)
#include "engine/contact/barrier_potential.hpp"
#include "engine/contact/candidates.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "kernels/barrier/barrier.hpp"
#include "kernels/distance/edge_edge_distance.hpp"
#include "kernels/distance/edge_edge_mollifier.hpp"
#include "kernels/distance/point_triangle_distance.hpp"
#include "kernels/projection/psd_projection.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <numeric>
#include <random>

using namespace nexdyn;

namespace {

// Two stacked boxes 0.01 m apart and a ground plane 0.02 m under the lower one: with
// dhat = 0.05 m many vertex-triangle, edge-edge (parallel ones too) and vertex-plane pairs are
// active.
Scene two_boxes() {
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01 },
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.5, 0.5, 0.5], "cells": [2, 2, 2] }, "material": "a" },
                { "box": { "size": [0.4, 0.4, 0.4], "cells": [2, 1, 2] }, "material": "a",
                  "translate": [0.03, 0.46, -0.02] } ]
  })", "contact_two_boxes");
  ObstaclePlane ground;
  ground.point = Eigen::Vector3d(0.0, -0.27, 0.0);
  ground.normal = Eigen::Vector3d::UnitY();
  scene.model.obstacle_planes.push_back(ground);
  return scene;
}

constexpr double kDhat = 0.05;

}  // namespace

TEST_CASE("incremental potential gradient with contact matches finite differences") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  ElasticAssembly elastic(model);
  BarrierPotential contact(model, kDhat);
  StepHistory history;
  IncrementalPotential potential(model, elastic, history, &contact);
  const std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 3);
  const std::vector<double> x_tilde = test::perturbed(x, 1e-2, 4);
  potential.begin_step(x_tilde, weights_context(1e-4, 2e-4, true));
  potential.begin_solve(x.data());
  potential.prepare(x.data(), true);
  REQUIRE(contact.num_active_pairs() > 20);
  REQUIRE(std::isfinite(potential.energy(x.data())));
  std::vector<double> grad(model.num_dofs()), values(potential.pattern().nnz());
  potential.gradient_hessian(x.data(), grad.data(), values.data());

  const double h = 1e-7;
  double max_error = 0.0, max_grad = 0.0;
  std::vector<double> xp = x;
  for (int64_t i = 0; i < model.num_dofs(); ++i) {
    xp[i] = x[i] + h;
    const double ep = potential.energy(xp.data());
    xp[i] = x[i] - h;
    const double em = potential.energy(xp.data());
    xp[i] = x[i];
    max_error = std::max(max_error, std::abs((ep - em) / (2 * h) - grad[i]));
    max_grad = std::max(max_grad, std::abs(grad[i]));
  }
  CHECK(max_grad > 0.0);
  CHECK(max_error < 1e-5 * max_grad);
}

TEST_CASE("merged Newton matrix equals elastic plus contact blocks, on 1 and 2 threads") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  const std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 5);
  const std::vector<double> x_tilde = test::perturbed(x, 1e-2, 6);
  const double scale = 1e-4;

  auto assemble = [&](int threads, std::vector<double>& grad, std::vector<double>& values,
                      Eigen::MatrixXd* reference) {
    test::ThreadsScope limit(threads);
    ElasticAssembly elastic(model);
    BarrierPotential contact(model, kDhat);
    StepHistory history;
    IncrementalPotential potential(model, elastic, history, &contact);
    potential.begin_step(x_tilde, weights_context(scale, 2 * scale, true));
    potential.begin_solve(x.data());
    potential.prepare(x.data(), true);
    grad.assign(model.num_dofs(), 0.0);
    values.assign(potential.pattern().nnz(), 0.0);
    potential.gradient_hessian(x.data(), grad.data(), values.data());
    if (!reference) return;
    // Reference: s * elastic + mass diagonal + every contact slab added densely.
    std::vector<double> egrad(model.num_dofs()), evalues(elastic.pattern().nnz());
    elastic.gradient_hessian(x.data(), egrad.data(), evalues.data());
    Eigen::MatrixXd H = scale * test::dense_from(elastic.pattern(), evalues);
    for (int32_t v = 0; v < model.num_vertices; ++v)
      for (int d = 0; d < 3; ++d) H(3 * v + d, 3 * v + d) += model.mass[v];
    test::add_contact_slabs(contact, H);
    *reference = H;
    CHECK(potential.pattern().nnz() > elastic.pattern().nnz());  // contact added blocks
    const Eigen::MatrixXd assembled = test::dense_from(potential.pattern(), values);
    CHECK((assembled - H).cwiseAbs().maxCoeff() <= 1e-12 * H.cwiseAbs().maxCoeff());
    // Every contact slab is symmetric PSD after projection.
    const std::vector<int64_t>& begin = contact.slab_begin();
    const std::vector<double>& slabs = contact.local_hessians();
    for (int64_t k = 0; k < contact.num_stencils(); ++k) {
      const int64_t n = 3 * test::stencil_size(begin[k + 1] - begin[k]);
      const Eigen::Map<const Eigen::MatrixXd> S(&slabs[begin[k]], n, n);
      CHECK((S - S.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * (1.0 + S.cwiseAbs().maxCoeff()));
      CHECK(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(S).eigenvalues().minCoeff() >=
            -1e-9 * (1.0 + S.cwiseAbs().maxCoeff()));
    }
  };
  std::vector<double> g1, v1, g2, v2;
  Eigen::MatrixXd reference;
  assemble(1, g1, v1, &reference);
  assemble(2, g2, v2, nullptr);
  CHECK(g1 == g2);
  CHECK(v1 == v2);
}

TEST_CASE("CCD-capped step never crosses: the boxes pushed into each other stop apart") {
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  BarrierPotential contact(model, kDhat);
  const std::vector<double> x = model.rest_positions;
  std::vector<double> p(model.num_dofs(), 0.0);
  for (int32_t v = 0; v < model.num_vertices; ++v)
    if (model.vertex_body[v] == 1) p[3 * v + 1] = -0.5;  // would pass 0.49 m through the lower box
  const double alpha = contact.max_step(x.data(), p.data());
  // The gap is 0.01 m along a 0.5 m motion: contact at t = 0.02, the step stops short of it.
  CHECK(alpha > 0.0);
  CHECK(alpha < 0.02);
  CHECK(alpha > 0.015);
  std::vector<double> y(x.size());
  for (size_t i = 0; i < x.size(); ++i) y[i] = x[i] + alpha * p[i];
  contact.find_candidates(y.data(), nullptr);
  CHECK(std::isfinite(contact.energy(y.data())));
  CHECK(contact.min_squared_distance(y.data()) > 0.0);
  const BarrierPotential::Summary summary = contact.summarize(y.data());
  CHECK(summary.min_distance > 0.0);
  CHECK(summary.min_distance < 0.01 * 0.25);
}

namespace {

// 2 x 2 x 1 boxes of 3^3 cells 0.01 m apart with aligned faces (the bench's cube grid, small):
// every surface vertex facing another cube faces one of its vertices, so with dhat = 0.05 m the
// same point-point feature is the closest feature of many vertex-triangle and edge-edge pairs.
Scene aligned_boxes() {
  return test::scene_from_json(R"({
    "materials": { "a": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.3, 0.3, 0.3], "cells": [3, 3, 3] }, "material": "a",
                  "array": { "count": [2, 2, 1], "spacing": [0.31, 0.31, 1.0] } } ]
  })", "contact_aligned_boxes");
}

// The non-merged reference: every active candidate on its own, with the kernels' full 12-DOF
// distance derivatives and the brute-force 12x12 PSD projection. Returns the energy; adds the
// gradient and the dense Hessian.
double pairwise_barrier(const Model& m, const ContactCandidates& c, const double* x, double dhat2,
                        Eigen::VectorXd& grad, Eigen::MatrixXd& H, int64_t& active) {
  auto pt = [&](int32_t v) { return Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]); };
  auto rest = [&](int32_t v) { return Eigen::Vector3d::Map(&m.rest_positions[3 * int64_t{v}]); };
  double energy = 0.0;
  auto add = [&](const int32_t (&s)[4], const Vector12d& g, Matrix12d h) {
    project_psd<12>(h);
    for (int a = 0; a < 4; ++a) {
      grad.segment<3>(3 * s[a]) += g.segment<3>(3 * a);
      for (int b = 0; b < 4; ++b) H.block<3, 3>(3 * s[a], 3 * s[b]) += h.block<3, 3>(3 * a, 3 * b);
    }
  };
  for (const IndexPair& pair : c.vertex_triangle) {
    const int32_t* t = &m.surface_triangles[3 * int64_t{pair.second}];
    const int32_t s[4] = {pair.first, t[0], t[1], t[2]};
    const PointTriangleCase pc = point_triangle_case(pt(s[0]), pt(s[1]), pt(s[2]), pt(s[3]));
    const double d = point_triangle_distance(pt(s[0]), pt(s[1]), pt(s[2]), pt(s[3]), pc);
    if (!(d < dhat2)) continue;
    ++active;
    energy += barrier(d, dhat2);
    const Vector12d gd = point_triangle_distance_gradient(pt(s[0]), pt(s[1]), pt(s[2]), pt(s[3]), pc);
    const Matrix12d hd = point_triangle_distance_hessian(pt(s[0]), pt(s[1]), pt(s[2]), pt(s[3]), pc);
    const double b1 = barrier_first_derivative(d, dhat2), b2 = barrier_second_derivative(d, dhat2);
    add(s, b1 * gd, b2 * gd * gd.transpose() + b1 * hd);
  }
  for (const IndexPair& pair : c.edge_edge) {
    const int32_t* ea = &m.surface_edges[2 * int64_t{pair.first}];
    const int32_t* eb = &m.surface_edges[2 * int64_t{pair.second}];
    const int32_t s[4] = {ea[0], ea[1], eb[0], eb[1]};
    const Eigen::Vector3d a0 = pt(s[0]), a1 = pt(s[1]), b0 = pt(s[2]), b1 = pt(s[3]);
    const EdgeEdgeCase ec = edge_edge_case(a0, a1, b0, b1);
    const double d = edge_edge_distance(a0, a1, b0, b1, ec);
    if (!(d < dhat2)) continue;
    ++active;
    const double eps_x = edge_edge_mollifier_threshold(rest(s[0]), rest(s[1]), rest(s[2]), rest(s[3]));
    const double mo = edge_edge_mollifier(a0, a1, b0, b1, eps_x);
    const Vector12d gm = edge_edge_mollifier_gradient(a0, a1, b0, b1, eps_x);
    const Matrix12d hm = edge_edge_mollifier_hessian(a0, a1, b0, b1, eps_x);
    const Vector12d gd = edge_edge_distance_gradient(a0, a1, b0, b1, ec);
    const Matrix12d hd = edge_edge_distance_hessian(a0, a1, b0, b1, ec);
    const double b = barrier(d, dhat2);
    const double d1 = barrier_first_derivative(d, dhat2), d2 = barrier_second_derivative(d, dhat2);
    energy += mo * b;
    add(s, mo * d1 * gd + b * gm,
        mo * (d2 * gd * gd.transpose() + d1 * hd) + d1 * (gd * gm.transpose() + gm * gd.transpose()) + b * hm);
  }
  return energy;
}

}  // namespace

TEST_CASE("merging equal closest features changes no energy, gradient or Hessian") {
  const Scene scene = aligned_boxes();
  const Model& model = scene.model;
  const double dhat = 0.05, dhat2 = dhat * dhat;
  // At rest (the features coincide exactly) and slightly moved (each vertex over a vertex stays
  // the closest feature of the same pairs, at distances that differ per feature).
  for (const double amount : {0.0, 1e-4}) {
    CAPTURE(amount);
    const std::vector<double> x = test::perturbed(model.rest_positions, amount, 11);
    BarrierPotential contact(model, dhat);
    contact.find_candidates(x.data(), nullptr);
    contact.assemble(x.data(), 1.0, true);

    const int64_t n = model.num_dofs();
    Eigen::VectorXd grad_ref = Eigen::VectorXd::Zero(n);
    Eigen::MatrixXd H_ref = Eigen::MatrixXd::Zero(n, n);
    int64_t active = 0;
    const double energy_ref = pairwise_barrier(model, contact.candidates(), x.data(), dhat2, grad_ref, H_ref, active);

    // Many pairs share a feature, and the multiplicities account for every one of them.
    const std::vector<int32_t>& mult = contact.multiplicities();
    CHECK(contact.num_active_pairs() == active);
    CHECK(std::accumulate(mult.begin(), mult.end(), int64_t{0}) == active);
    CHECK(contact.num_stencils() < active / 2);
    CHECK(*std::max_element(mult.begin(), mult.end()) > 4);

    CHECK(energy_ref > 0.0);
    CHECK(std::abs(contact.active_set_energy(x.data()) - energy_ref) <= 1e-12 * energy_ref);
    CHECK(std::abs(contact.energy(x.data()) - energy_ref) <= 1e-12 * energy_ref);

    Eigen::VectorXd grad = Eigen::VectorXd::Zero(n);
    contact.add_gradient(grad.data());
    CHECK(grad_ref.cwiseAbs().maxCoeff() > 0.0);
    CHECK((grad - grad_ref).cwiseAbs().maxCoeff() <= 1e-12 * grad_ref.cwiseAbs().maxCoeff());

    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    test::add_contact_slabs(contact, H);
    CHECK(H_ref.cwiseAbs().maxCoeff() > 0.0);
    CHECK((H - H_ref).cwiseAbs().maxCoeff() <= 1e-12 * H_ref.cwiseAbs().maxCoeff());
  }
}

TEST_CASE("cached pair distances stay exact through masked sweeps that move one body at a time") {
  // The barrier keeps each candidate's distance and active-set code while its vertices stay put.
  // Move the two boxes in turn along swept, CCD-capped motions (only the moving box's pairs are
  // searched again) and compare the active set and the smallest distance with a fresh
  // evaluation of every candidate after each move.
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  const int64_t n = model.num_dofs();
  std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 3);
  BarrierPotential contact(model, kDhat);
  contact.find_candidates(x.data(), nullptr);
  contact.assemble(x.data(), 1.0, false);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto point = [&](int32_t v) { return Eigen::Vector3d::Map(&x[3 * int64_t{v}]); };
  for (int move = 0; move < 8; ++move) {
    CAPTURE(move);
    const BodyRange& body = model.bodies[move % 2];
    std::vector<uint8_t> moving(model.num_vertices, 0);
    std::vector<double> p(n, 0.0);
    // Towards the other box (and the ground), with some noise per vertex.
    const Eigen::Vector3d shift(0.004 * uniform(rng), (move % 2 ? -0.006 : 0.004), 0.004 * uniform(rng));
    for (int32_t v = body.vertex_begin; v < body.vertex_begin + body.vertex_count; ++v) {
      moving[v] = 1;
      for (int d = 0; d < 3; ++d) p[3 * v + d] = shift[d] + 5e-4 * uniform(rng);
    }
    contact.sweep(x.data(), p.data(), moving.data());
    double alpha = 1.0;
    contact.group_max_steps(x.data(), nullptr, &alpha);
    REQUIRE(alpha > 0.0);
    // Half the CCD-capped step: a full one brings the closest pair about 1,000 times closer in
    // squared distance per move, down to 1e-19 m^2 after eight, where the rounding of that one
    // distance moves its barrier by more than the 1e-12 of the total energy checked below
    // (seen on an AMD EPYC under the sanitizers, whose test files are compiled at -O1).
    alpha *= 0.5;
    // Any point of the sweep may be evaluated: halfway first, then the end (the pairs of the
    // moving box are computed at both).
    std::vector<double> halfway = x;
    for (int64_t i = 0; i < n; ++i) halfway[i] += 0.5 * alpha * p[i];
    contact.assemble(halfway.data(), 1.0, false);
    for (int64_t i = 0; i < n; ++i) x[i] += alpha * p[i];
    contact.assemble(x.data(), 1.0, false);

    // The active set from cached codes against a new potential's (every pair computed afresh),
    // and its energy against the barrier sum over every candidate.
    BarrierPotential fresh(model, kDhat);
    fresh.find_candidates(x.data(), nullptr);
    fresh.assemble(x.data(), 1.0, false);
    CHECK(contact.num_active_pairs() > 0);
    CHECK(contact.num_active_pairs() == fresh.num_active_pairs());
    CHECK(contact.num_stencils() == fresh.num_stencils());
    const double energy = contact.energy(x.data());
    CHECK(energy > 0.0);
    CHECK(std::abs(contact.active_set_energy(x.data()) - energy) <= 1e-12 * energy);
    CHECK(std::abs(fresh.active_set_energy(x.data()) - energy) <= 1e-12 * energy);

    double min_ref = std::numeric_limits<double>::infinity();
    const ContactCandidates& c = contact.candidates();
    for (const IndexPair& pr : c.vertex_triangle) {
      const int32_t* t = &model.surface_triangles[3 * int64_t{pr.second}];
      min_ref = std::min(min_ref, point_triangle_distance(point(pr.first), point(t[0]), point(t[1]), point(t[2])));
    }
    for (const IndexPair& pr : c.edge_edge) {
      const int32_t* a = &model.surface_edges[2 * int64_t{pr.first}];
      const int32_t* b = &model.surface_edges[2 * int64_t{pr.second}];
      min_ref = std::min(min_ref, edge_edge_distance(point(a[0]), point(a[1]), point(b[0]), point(b[1])));
    }
    for (const IndexPair& pr : c.vertex_plane) {
      const ObstaclePlane& plane = model.obstacle_planes[pr.second];
      const double s = (point(pr.first) - plane.point).dot(plane.normal);
      min_ref = std::min(min_ref, s > 0.0 ? s * s : 0.0);
    }
    // The reference computes the same formulas in other compiled copies, which the compiler may
    // fuse differently. The moves drive pairs to 1e-7 m and below, where a signed distance taken
    // from coordinates of about 0.5 m carries an absolute rounding of a few eps, so d = s^2 one of
    // 2 |s| times that (the AddressSanitizer build differed beyond 1e-12 relative at d = 2e-14).
    const double rounding = 16.0 * std::numeric_limits<double>::epsilon() * std::sqrt(min_ref);
    CHECK(std::abs(contact.min_squared_distance(x.data()) - min_ref) <= 1e-12 * min_ref + rounding);
  }
}

namespace {

// The pairs of `all` that have a vertex outside `asleep` (a vertex-plane pair: its vertex).
ContactCandidates pairs_with_an_awake_vertex(const Model& model, const ContactCandidates& all,
                                             const std::vector<uint8_t>& asleep) {
  auto awake = [&](std::initializer_list<int32_t> vertices) {
    return std::any_of(vertices.begin(), vertices.end(), [&](int32_t v) { return !asleep[v]; });
  };
  ContactCandidates out;
  for (const IndexPair& pr : all.vertex_triangle) {
    const int32_t* t = &model.surface_triangles[3 * int64_t{pr.second}];
    if (awake({pr.first, t[0], t[1], t[2]})) out.vertex_triangle.push_back(pr);
  }
  for (const IndexPair& pr : all.edge_edge) {
    const int32_t* a = &model.surface_edges[2 * int64_t{pr.first}];
    const int32_t* b = &model.surface_edges[2 * int64_t{pr.second}];
    if (awake({a[0], a[1], b[0], b[1]})) out.edge_edge.push_back(pr);
  }
  for (const IndexPair& pr : all.vertex_plane)
    if (awake({pr.first})) out.vertex_plane.push_back(pr);
  return out;
}

// Whether every pair of `sub` is in `list` (both sorted, as the searches leave them).
bool holds_all(const ContactCandidates& list, const ContactCandidates& sub) {
  return std::includes(list.vertex_triangle.begin(), list.vertex_triangle.end(), sub.vertex_triangle.begin(),
                       sub.vertex_triangle.end()) &&
         std::includes(list.edge_edge.begin(), list.edge_edge.end(), sub.edge_edge.begin(), sub.edge_edge.end()) &&
         std::includes(list.vertex_plane.begin(), list.vertex_plane.end(), sub.vertex_plane.begin(),
                       sub.vertex_plane.end());
}

}  // namespace

TEST_CASE("the pairs of a sleeping body leave the search, its energy stays, and searches from there miss no pair") {
  // The lower box sleeps: its pairs with the ground and its own pairs have no solved vertex. The
  // search must keep exactly the pairs with a vertex of the upper box (against the brute force),
  // the energy must still count the dropped ones, and the searches of the rest of the step, which
  // look again only at what moved, must still hold every pair a full search holds.
  const Scene scene = two_boxes();
  const Model& model = scene.model;
  const int64_t n = model.num_dofs();
  std::vector<double> x = test::perturbed(model.rest_positions, 2e-3, 5);
  const BodyRange& lower = model.bodies[0];
  const BodyRange& upper = model.bodies[1];
  std::vector<int32_t> asleep;
  std::vector<uint8_t> is_asleep(model.num_vertices, 0);
  for (int32_t v = lower.vertex_begin; v < lower.vertex_begin + lower.vertex_count; ++v) {
    asleep.push_back(v);
    is_asleep[v] = 1;
  }
  BarrierPotential contact(model, kDhat);
  contact.set_asleep(asleep);
  auto check_at = [&](const std::vector<double>& at, bool exact) {
    BarrierPotential full(model, kDhat);
    full.find_candidates(at.data(), nullptr);
    ContactCandidates reference;
    find_contact_candidates_brute_force(model, at.data(), nullptr, 0.5 * kDhat, reference);
    const ContactCandidates awake = pairs_with_an_awake_vertex(model, reference, is_asleep);
    REQUIRE(awake.size() > 0);
    REQUIRE(awake.size() < reference.size());  // the ground's pairs and the lower box's own went
    const ContactCandidates& kept = contact.candidates();
    CHECK(holds_all(kept, awake));
    CHECK(pairs_with_an_awake_vertex(model, kept, is_asleep).size() == kept.size());
    if (exact) CHECK(kept.size() == awake.size());
    const double energy = full.energy(at.data());
    REQUIRE(energy > 0.0);
    CHECK(std::abs(contact.energy(at.data()) - energy) <= 1e-12 * energy);
  };
  contact.find_candidates(x.data(), nullptr);
  check_at(x, true);

  // The upper box moves (it alone: the lower one is held) three times; each search starts from
  // where the last one left off.
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int move = 0; move < 3; ++move) {
    CAPTURE(move);
    std::vector<double> p(n, 0.0);
    const Eigen::Vector3d shift(0.003 * uniform(rng), -0.004, 0.003 * uniform(rng));
    for (int32_t v = upper.vertex_begin; v < upper.vertex_begin + upper.vertex_count; ++v)
      for (int d = 0; d < 3; ++d) p[3 * v + d] = shift[d];
    // The CCD cap of the motion: the same as with every pair searched afresh.
    BarrierPotential full(model, kDhat);
    const double alpha_full = full.max_step(x.data(), p.data());
    const double alpha = contact.max_step(x.data(), p.data());
    CHECK(alpha == alpha_full);
    for (int64_t i = 0; i < n; ++i) x[i] += 0.5 * alpha * p[i];
    contact.find_candidates(x.data(), nullptr);
    check_at(x, false);
  }
  // No one sleeps any more: the search is the full one again.
  contact.set_asleep({});
  contact.find_candidates(x.data(), nullptr);
  BarrierPotential full(model, kDhat);
  full.find_candidates(x.data(), nullptr);
  CHECK(contact.candidates().vertex_triangle == full.candidates().vertex_triangle);
  CHECK(contact.candidates().edge_edge == full.candidates().edge_edge);
  CHECK(contact.candidates().vertex_plane == full.candidates().vertex_plane);
  CHECK(contact.energy(x.data()) == full.energy(x.data()));
}

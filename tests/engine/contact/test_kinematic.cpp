// Moving boundaries and obstacles in contact scenes (engine/potential/kinematic_targets.hpp, issue 4):
// which motions become kinematic, the augmented Lagrangian against its definition, and a wall
// pushing a block across a floor with friction: the block moves with the wall, the push equals
// mu m g, the wall stays exactly on its path, on 1 and 2 threads alike.
#include "engine/potential/kinematic_targets.hpp"
#include "engine/simulation.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <cmath>

using namespace nexdyn;

namespace {

// A box on a floor plane, a wall obstacle (scenes/meshes/wall.obj) and a fixed box boundary;
// `contact` is the "contact" entry or empty for none.
Scene moving_scene(const std::string& contact) {
  const std::string wall = test::scene_path("meshes/wall.obj").string();
  return test::scene_from_json(R"({
    "time": { "dt": 0.005, "integrator": "implicit_euler" },
    "materials": { "m": { "model": "neohookean", "youngs": 1e7, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.1, 0.1, 0.1], "cells": [2, 2, 2] }, "material": "m", "translate": [0, 0.0505, 0] },
                { "box": { "size": [0.1, 0.1, 0.1], "cells": [1, 1, 1] }, "material": "m", "translate": [0.5, 0.0505, 0] } ],
    "boundary": [ { "body": 1, "box_min": [0.4, 0, -1], "box_max": [0.6, 0.2, 1], "velocity": [0, 0, 0.1] },
                  { "body": 0, "box_min": [-1, 0.09, -1], "box_max": [1, 1, 1], "fix": true } ])" +
      (contact.empty() ? std::string() : R"(, "contact": )" + contact + R"(,
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } },
                   { "mesh": ")" + wall + R"(", "scale": [0.02, 0.06, 0.2], "translate": [-0.08, 0.04, 0],
                     "velocity": [0.5, 0, 0] },
                   { "mesh": ")" + wall + R"(", "scale": 0.05, "translate": [0, 0.5, 0] } ])") + "}",
      "kinematic_scene");
}

}  // namespace

TEST_CASE("kinematic: moving boundaries and obstacles are kinematic only with contact") {
  const Scene with = moving_scene("{}");
  const Model& m = with.model;
  // Motions: boundary[0] (moving), boundary[1] (fixed), the wall's own, the static mesh's.
  REQUIRE(m.dirichlet_motions.size() == 4);
  CHECK(m.dirichlet_motions[0].kinematic);
  CHECK_FALSE(m.dirichlet_motions[1].kinematic);
  CHECK(m.dirichlet_motions[2].kinematic);
  CHECK_FALSE(m.dirichlet_motions[3].kinematic);
  // The wall moves about the centre of its bounding box; its vertices are unknowns of the step.
  CHECK((m.dirichlet_motions[2].center - Eigen::Vector3d(-0.08, 0.04, 0)).norm() < 1e-15);
  StepHistory history;
  const KinematicTargets kinematic(m, history);
  int64_t wall = 0, boundary = 0;
  for (int32_t v : kinematic.vertices()) {
    CHECK_FALSE(m.eliminated(v));
    wall += m.dirichlet[v] == 2;
    boundary += m.dirichlet[v] == 0;
  }
  CHECK(wall == 8);
  CHECK(boundary == 8);
  CHECK(static_cast<int64_t>(kinematic.vertices().size()) == 16);

  // Without contact the same boundary is prescribed exactly, as before.
  const Scene without = moving_scene("");
  CHECK_FALSE(without.model.dirichlet_motions[0].kinematic);
  StepHistory other_history;
  CHECK(KinematicTargets(without.model, other_history).empty());
}

TEST_CASE("kinematic: the augmented Lagrangian's gradient and Hessian match its energy") {
  const Scene scene = moving_scene("{}");
  const Model& m = scene.model;
  StepHistory history;
  KinematicTargets kinematic(m, history);
  kinematic.begin_attempt(1e3, 1e-4);
  kinematic.set_targets(test::perturbed(m.rest_positions, 1e-2, 3));
  const std::vector<double> x = test::perturbed(m.rest_positions, 1e-2, 4);
  kinematic.update_multipliers(x.data());  // non-zero multipliers
  const std::vector<double> y = test::perturbed(m.rest_positions, 1e-2, 5);
  std::vector<double> grad(x.size(), 0.0);
  kinematic.add_gradient(y.data(), grad.data());
  std::vector<double> z = y;
  double worst = 0.0, scale = 0.0;
  for (size_t i = 0; i < y.size(); ++i) {
    const double h = 1e-6;
    z[i] = y[i] + h;
    const double up = kinematic.energy(z.data());
    z[i] = y[i] - h;
    const double down = kinematic.energy(z.data());
    z[i] = y[i];
    worst = std::max(worst, std::abs((up - down) / (2 * h) - grad[i]));
    scale = std::max(scale, std::abs(grad[i]));
  }
  CHECK(scale > 0.0);
  CHECK(worst < 1e-7 * scale);
  // The Hessian k_i I3: a gradient difference along one kinematic DOF, against the diagonal.
  CscPattern diagonal;
  diagonal.num_dofs = m.num_dofs();
  for (int64_t i = 0; i < diagonal.num_dofs; ++i) diagonal.diagonal.push_back(i);
  std::vector<double> values(diagonal.num_dofs, 0.0);
  kinematic.add_hessian_diagonal(diagonal, values.data());
  const int64_t dof = 3 * int64_t{kinematic.vertices()[3]} + 1;
  z[dof] += 1e-3;
  std::vector<double> moved(x.size(), 0.0);
  kinematic.add_gradient(z.data(), moved.data());
  CHECK((moved[dof] - grad[dof]) / 1e-3 == test::relative(values[dof], 1e-9));
  CHECK(values[dof] > 0.0);
  // On target the update keeps the multipliers (up to the rounding of x - t).
  std::vector<double> p(x.size());
  kinematic.motion_to_targets(y.data(), p.data());
  std::vector<double> on_target = y;
  for (size_t i = 0; i < y.size(); ++i) on_target[i] += p[i];
  CHECK(kinematic.max_violation(on_target.data()) < 1e-15);
  const Eigen::Vector3d before = kinematic.total_force();
  kinematic.update_multipliers(on_target.data());
  CHECK((kinematic.total_force() - before).norm() <= 1e-12 * before.norm());
}

namespace {

// scenes/block_push.json for `steps` steps on `threads` threads; returns the simulation's state
// and the wall's total force.
struct PushRun {
  std::vector<double> x, v;
  Eigen::Vector3d force;
  double time = 0.0;
};

PushRun push(int threads, int steps) {
  test::ThreadsScope limit(threads);
  const Scene scene = load_scene(test::scene_path("block_push.json"));
  Simulation simulation(scene);
  for (int s = 0; s < steps; ++s) REQUIRE(simulation.step().status == StepStatus::ok);
  return {simulation.state().x, simulation.state().v, simulation.kinematic().total_force(), simulation.state().time};
}

}  // namespace

TEST_CASE("kinematic: a wall at 0.5 m/s pushes a block across a floor with friction 0.5") {
  const PushRun run = push(2, 100);
  CHECK(run.x == push(1, 100).x);
  const Scene scene = load_scene(test::scene_path("block_push.json"));
  const Model& m = scene.model;
  const int32_t block = 27;  // 3 x 3 x 3 vertices, then the wall's 8
  REQUIRE(m.num_vertices == block + 8);
  // The block moves with the wall (it was reached after about 0.05 s).
  double mass = 0.0, momentum = 0.0;
  for (int32_t v = 0; v < block; ++v) {
    mass += m.mass[v];
    momentum += m.mass[v] * run.v[3 * v];
  }
  CHECK(momentum / mass == test::relative(0.5, 1e-3));  // measured 6e-5 off
  // The push is the kinetic friction it overcomes: mu m g along x. Measured 1.9% below it, as is
  // the friction dissipation per step (test_energy_balance.cpp): not yet explained, see issue 17.
  CHECK(run.force.x() == test::relative(0.5 * mass * 9.81, 0.03));
  CHECK(std::abs(run.force.z()) < 1e-3 * run.force.x());  // the tets' diagonals are not symmetric
  // The wall is exactly where its motion puts it.
  for (int32_t v = block; v < m.num_vertices; ++v)
    for (int d = 0; d < 3; ++d)
      CHECK(std::abs(run.x[3 * v + d] - (m.rest_positions[3 * v + d] + (d == 0 ? 0.5 * run.time : 0.0))) < 1e-15);
}

// The Newton solver (engine/solver/newton.hpp) on small problems with known answers, outside any
// simulation: the exact minimiser of a rigid free flight in one iteration, the returned point of a
// nonlinear problem against a much tighter solve, the Armijo condition of every
// group at every iteration, the CCD cap that keeps each iterate on the right side of a plane (and
// caps only the group, and within an island only the body, that needs it), full steps lengthened
// where the projected model is stiffer than the energy, re-lags inside a solve that stop before
// the iteration limit, converged islands left alone, and on failure x at the last accepted
// point; a linear solver that fails (a Hessian that is not positive definite, CHOLMOD out of
// memory) gives a status, not an exception, and the next solve works again. The solver's history (NewtonSolver::set_history) shows what each
// iteration did.
#include "engine/contact/barrier_potential.hpp"
#include "engine/potential/elastic_assembly.hpp"
#include "engine/potential/incremental_potential.hpp"
#include "engine/solver/newton.hpp"
#include "tests/engine/solver/suitesparse_out_of_memory.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

using namespace nexdyn;

namespace {

constexpr double kDt = 0.1;

// One step's incremental potential of a scene, with x_tilde given by the test:
//   E(x) = 1/2 |x - x_tilde|_M^2 + h^2 (Psi(x) - M g . (x - x_tilde)) [+ h^2 kappa B(x)]
// (implicit Euler's weights, h = kDt).
struct Problem {
  Scene scene;
  const Model& model = scene.model;
  ElasticAssembly elastic{model};
  std::unique_ptr<BarrierPotential> contact;
  StepHistory step_history;
  IncrementalPotential potential;
  std::vector<double> x_tilde;
  NewtonSolver solver;
  std::vector<NewtonIterate> history;

  Problem(const std::string& json, const std::string& tag, double dhat = 0.0)
      : Problem(test::scene_from_json(json, tag), dhat) {}
  explicit Problem(Scene s, double dhat = 0.0)
      : scene(std::move(s)),
        contact(dhat > 0.0 ? std::make_unique<BarrierPotential>(model, dhat) : nullptr),
        potential(model, elastic, step_history, contact.get()),
        x_tilde(model.rest_positions),
        solver(model, potential) {
    solver.set_history(&history, true);
  }

  // Solves from x (moved in place) with x_tilde as it is now.
  NewtonResult solve(std::vector<double>& x, double tolerance, int max_iterations = 100, bool extend_steps = true) {
    potential.begin_step(x_tilde, weights_context(kDt * kDt, kDt * kDt, true));
    NewtonSettings settings;
    settings.tolerance = tolerance;
    settings.max_iterations = max_iterations;
    settings.dt = kDt;
    settings.extend_steps = extend_steps;
    return solver.solve(x, settings);
  }

  // The gradient of E at x on the free DOFs (0 on held ones).
  std::vector<double> gradient(const std::vector<double>& x) {
    potential.begin_solve(x.data());
    potential.prepare(x.data(), true);
    std::vector<double> grad(model.num_dofs()), values(potential.pattern().nnz());
    potential.gradient_hessian(x.data(), grad.data(), values.data());
    for (int32_t v = 0; v < model.num_vertices; ++v)
      if (model.eliminated(v))
        for (int d = 0; d < 3; ++d) grad[3 * v + d] = 0.0;
    return grad;
  }

  // The vertices of scene body b.
  std::vector<int32_t> vertices_of(int32_t b) const {
    std::vector<int32_t> out;
    for (int32_t v = 0; v < model.num_vertices; ++v)
      if (model.vertex_body[v] == b) out.push_back(v);
    return out;
  }
};

double max_abs(const std::vector<double>& a) {
  double m = 0.0;
  for (double v : a) m = std::max(m, std::abs(v));
  return m;
}

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

// A soft neo-Hookean bar held at its left end (x = 0) and pulled down by x_tilde: a nonlinear
// problem that takes several Newton iterations; with `free_cube`, also a cube far away in free
// flight, its own island.
std::string bar_json(bool free_cube) {
  return std::string(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.1 },
    "materials": { "soft": { "model": "neohookean", "youngs": 2e4, "poisson": 0.4, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 0.2, 0.2], "cells": [6, 2, 2] }, "material": "soft",
                  "translate": [0.5, 0, 0] })") +
         (free_cube ? R"(,
                { "box": { "size": [0.2, 0.2, 0.2], "cells": [1, 1, 1] }, "material": "soft",
                  "translate": [3, 0, 0] })" : "") +
         R"( ],
    "boundary": [ { "box_min": [-0.01, -1, -1], "box_max": [0.01, 1, 1], "fix": true } ]
  })";
}

// x_tilde of the bar: each vertex displaced down by amount * x^2 (a bend the elasticity resists).
void bend_x_tilde(Problem& p, double amount = 0.3) {
  for (int32_t v = 0; v < p.model.num_vertices; ++v)
    if (!p.model.eliminated(v) && p.model.vertex_body[v] == 0) {
      const double x = p.model.rest_positions[3 * v];
      p.x_tilde[3 * v + 1] -= amount * x * x;
    }
}

// Cube 0 (edge 0.2 m) hangs 5 mm over the plane y = 0; cube 1, the same, is centred at
// `translate` ("x, y, z"). dhat = 1 mm is given to the Problem.
std::string cubes_over_plane(const std::string& translate) {
  return R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.1 },
    "contact": { "dhat": 0.001 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [1, 1, 1] }, "material": "m", "translate": [0, 0.105, 0] },
                { "box": { "size": [0.2, 0.2, 0.2], "cells": [1, 1, 1] }, "material": "m", "translate": [)" +
         translate + R"(] } ],
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ]
  })";
}

// The lowest y of these vertices over every accepted point of the history.
double lowest_height(const std::vector<NewtonIterate>& history, const std::vector<int32_t>& vertices) {
  double lowest = std::numeric_limits<double>::infinity();
  for (const NewtonIterate& it : history)
    for (int32_t v : vertices) lowest = std::min(lowest, it.x[3 * v + 1]);
  return lowest;
}

// The Armijo condition of newton.cpp (sufficient decrease 1e-4 of the slope, with its round-off
// allowance) at every iteration of the history, and the recorded numbers' own sanity.
void check_armijo(const std::vector<NewtonIterate>& history) {
  int64_t groups = 0;
  for (size_t it = 0; it < history.size(); ++it) {
    const NewtonIterate& r = history[it];
    CAPTURE(it);
    REQUIRE(r.step_length.size() == r.ccd_cap.size());
    for (size_t g = 0; g < r.step_length.size(); ++g) {
      CAPTURE(g);
      ++groups;
      CHECK(r.slope[g] < 0.0);  // a descent direction: the projected Hessian is positive definite
      CHECK(r.ccd_cap[g] > 0.0);
      CHECK(r.ccd_cap[g] <= 1.0);
      CHECK(r.step_length[g] > 0.0);
      CHECK(r.step_length[g] <= 1.0);
      const double noise = 1e-13 * std::max(1.0, std::abs(r.start_energy[g]));
      CHECK(r.accepted_energy[g] <= r.start_energy[g] + 1e-4 * r.step_length[g] * r.slope[g] + noise);
    }
  }
  CHECK(groups > 0);
}

}  // namespace

TEST_CASE("newton: a rigid free flight lands exactly on x_tilde + h^2 g in one iteration") {
  // With no strain, the minimiser of E is x_tilde + h^2 g at every vertex. From the rest shape the
  // step to it is a translation, which the elastic Hessian maps to zero, so Newton's first direction
  // is exactly that step; the second iteration finds nothing left to do.
  Problem p(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.1 },
    "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.3, 0.2, 0.4], "cells": [2, 2, 2] }, "material": "m" } ]
  })", "newton_flight");
  const Eigen::Vector3d v(1.0, 2.0, -0.5);  // the body's velocity
  for (int32_t i = 0; i < p.model.num_vertices; ++i)
    for (int d = 0; d < 3; ++d) p.x_tilde[3 * i + d] += kDt * v[d];
  std::vector<double> x = p.model.rest_positions;
  const NewtonResult r = p.solve(x, 1e-9);
  REQUIRE(r.status == StepStatus::ok);
  CHECK(r.iterations == 2);
  REQUIRE(p.history.size() == 2);
  CHECK(p.history[0].moving_islands == 1);
  CHECK(p.history[0].step_length == std::vector<double>{1.0});
  CHECK(p.history[1].moving_islands == 0);
  std::vector<double> expected = p.x_tilde;
  for (int32_t i = 0; i < p.model.num_vertices; ++i)
    for (int d = 0; d < 3; ++d) expected[3 * i + d] += kDt * kDt * p.model.gravity[d];
  // Round-off of one sparse solve with entries of order 1: a few hundred ulps of the coordinates.
  CHECK(max_difference(x, expected) <= 1e-13);
}

TEST_CASE("newton: the returned point is the minimiser to within the last direction, which is below the tolerance") {
  Problem p(bar_json(false), "newton_bar");
  bend_x_tilde(p);
  std::vector<double> x = p.model.rest_positions;
  const double tolerance = 1e-5;  // [m/s] on max|p| / h
  const NewtonResult r = p.solve(x, tolerance);
  REQUIRE(r.status == StepStatus::ok);
  MESSAGE("Newton iterations: ", r.iterations);
  CHECK(r.iterations >= 4);  // the premise: a problem that needs several iterations
  check_armijo(p.history);
  // The solve stops at the first direction below the tolerance and does not take it.
  const double last = p.history.back().increment;
  CHECK(last < tolerance);
  CHECK(p.history.back().moving_islands == 0);
  for (size_t it = 0; it + 1 < p.history.size(); ++it) CHECK(p.history[it].increment >= tolerance);

  // The minimiser itself, to round-off: the same solve continued with a tolerance 1e6 times tighter.
  std::vector<double> x_star = x;
  p.history.clear();
  REQUIRE(p.solve(x_star, 1e-11).status == StepStatus::ok);
  // The direction not taken, p = -H~^-1 g, is the Newton estimate of x* - x. H~ is the
  // PSD-projected Hessian, not the true one, so the estimate is off by the projection's share
  // (measured: 17% here); twice its size bounds the distance with room to spare.
  const double error = max_difference(x, x_star);
  MESSAGE("distance to the minimiser ", error, " m; the last direction ", last * kDt, " m");
  CHECK(error <= 2.0 * last * kDt);
  CHECK(error > 0.0);
  // The gradient vanishes at the minimiser: against its size at the start, relative round-off.
  const double g0 = max_abs(p.gradient(p.model.rest_positions));
  const double g_star = max_abs(p.gradient(x_star));
  MESSAGE("max |gradient|: at the start ", g0, ", at the minimiser ", g_star);
  CHECK(g_star <= 1e-9 * g0);
  CHECK(max_abs(p.gradient(x)) > 1e3 * g_star);  // and x, stopped earlier, is measurably short of it
}

TEST_CASE("newton: a full step that would raise the energy is shortened until it decreases enough") {
  // Bent ten times harder, the bar's first Newton steps overshoot: the linearisation at the
  // straight bar is far from the bent one. Each accepted step must satisfy the Armijo condition.
  Problem p(bar_json(false), "newton_backtrack");
  bend_x_tilde(p, 3.0);
  std::vector<double> x = p.model.rest_positions;
  REQUIRE(p.solve(x, 1e-5).status == StepStatus::ok);
  int64_t shortened = 0;
  for (const NewtonIterate& it : p.history)
    for (double a : it.step_length) shortened += a < 1.0;
  MESSAGE("Newton iterations: ", p.history.size(), ", of which shortened: ", shortened);
  CHECK(shortened > 0);  // the premise: the line search had work to do
  check_armijo(p.history);
  for (const NewtonIterate& it : p.history) CHECK(std::isfinite(p.potential.energy(it.x.data())));
}

TEST_CASE("newton: a full step the energy falls along faster than the model says is lengthened, and the minimiser is reached in fewer iterations") {
  // The bar bent hard has compressed tets whose negative curvature the PSD projection clamps: along
  // the Newton direction the model is stiffer than the energy, and full steps fall short. Solved
  // with and without lengthening (NewtonSolver::extend_step) from the same start.
  auto solve = [](bool extend, std::vector<double>& x, std::vector<NewtonIterate>& history) {
    Problem p(bar_json(false), "newton_extend");
    bend_x_tilde(p, 3.0);
    x = p.model.rest_positions;
    const NewtonResult r = p.solve(x, 1e-5, 100, extend);
    REQUIRE(r.status == StepStatus::ok);
    history = p.history;
    return r.iterations;
  };
  std::vector<double> x_full, x_longer;
  std::vector<NewtonIterate> full, longer;
  const int full_iterations = solve(false, x_full, full);
  const int longer_iterations = solve(true, x_longer, longer);
  int extended = 0;
  for (const NewtonIterate& it : longer) {
    if (!it.extended) continue;
    ++extended;
    // Kept only where the groups' energy fell by more than with the full steps.
    double decrease = 0.0;
    for (size_t g = 0; g < it.start_energy.size(); ++g) decrease += it.start_energy[g] - it.accepted_energy[g];
    CHECK(decrease > it.full_step_decrease);
  }
  for (const NewtonIterate& it : full) CHECK(!it.extended);
  MESSAGE("Newton iterations: ", full_iterations, " with full steps, ", longer_iterations, " lengthened (",
          extended, " of them)");
  CHECK(extended > 0);
  CHECK(longer_iterations < full_iterations);
  check_armijo(longer);  // along the lengthened direction, with its slope
  // The same minimiser: each stops within twice its last direction of it (the test above).
  CHECK(max_difference(x_full, x_longer) <= 4.0 * 1e-5 * kDt);
}

TEST_CASE("newton: re-lags stop while the solve has fewer iterations left than a lag takes, so it converges") {
  // A lag that moves the minimiser (here x_tilde, bent further by each of the first four re-lags,
  // as a new friction lag moves a sliding body) restarts Newton's convergence. Re-lags taken near
  // the iteration limit turned a solve that converged under every lag into a failed one (a crate
  // landing on a rubber mat: four re-lags of 11 to 32 iterations each in a limit of 100).
  constexpr int kMovingLags = 4;
  // Solves with re-lags; `at` gets the iteration count at each re-lag that moved the minimiser.
  auto solve = [](int max_iterations, std::vector<int>& at) {
    Problem p(bar_json(false), "newton_relag");
    bend_x_tilde(p);
    std::vector<double> x = p.model.rest_positions;
    p.potential.begin_step(p.x_tilde, weights_context(kDt * kDt, kDt * kDt, true));
    NewtonSettings settings;
    settings.tolerance = 1e-5;  // [m/s]
    settings.max_iterations = max_iterations;
    settings.dt = kDt;
    settings.relag_below = 1e-4;  // 10 tolerances, as in the simulation
    settings.max_relags = 20;
    settings.relag = [&](const double*) {
      if (static_cast<int>(at.size()) == kMovingLags) return false;  // the lags have settled
      at.push_back(static_cast<int>(p.history.size()));
      bend_x_tilde(p, 0.3);
      p.potential.begin_step(p.x_tilde, weights_context(kDt * kDt, kDt * kDt, true));
      return true;
    };
    return p.solver.solve(x, settings);
  };
  std::vector<int> at;
  const NewtonResult free = solve(1000, at);
  REQUIRE(free.status == StepStatus::ok);
  REQUIRE(at.size() == kMovingLags);
  const int last_cost = at[3] - at[2];  // what the third moving lag took to converge again
  MESSAGE("with no limit in sight: re-lags at iterations ", at[0], ", ", at[1], ", ", at[2], ", ", at[3],
          "; ", free.iterations, " iterations in all");
  REQUIRE(last_cost >= 6);  // the premise: each lag costs several iterations
  REQUIRE(free.iterations - at[3] >= 6);  // ... the fourth too
  // A limit that leaves less than a lag's cost after the fourth re-lag: taken there, the solve
  // could not converge again. It is not taken, and the solve converges under the third lag.
  const int limit = at[3] + last_cost / 2;
  std::vector<int> at_limited;
  const NewtonResult limited = solve(limit, at_limited);
  CAPTURE(limit);
  CHECK(limited.status == StepStatus::ok);
  CHECK(at_limited == std::vector<int>(at.begin(), at.begin() + 3));
}

TEST_CASE("newton: a converged island is not factorised again while another still iterates") {
  Problem p(bar_json(true), "newton_islands");
  bend_x_tilde(p);
  const std::vector<int32_t> cube = p.vertices_of(1);
  for (int32_t v : cube) p.x_tilde[3 * v] += 0.05;  // the cube flies along x
  std::vector<double> x = p.model.rest_positions;
  const NewtonResult r = p.solve(x, 1e-6);
  REQUIRE(r.status == StepStatus::ok);
  REQUIRE(p.history.size() >= 4);
  // The cube's island: one step to its minimiser, one more to see it has converged; from then on
  // only the bar's island is factorised and solved.
  CHECK(p.history[0].solved_islands == 2);
  CHECK(p.history[0].moving_islands == 2);
  CHECK(p.history[1].solved_islands == 2);
  CHECK(p.history[1].moving_islands == 1);
  for (size_t it = 2; it < p.history.size(); ++it) {
    CAPTURE(it);
    CHECK(p.history[it].solved_islands == 1);
  }
  // And the frozen cube is where its exact minimiser is.
  for (int32_t v : cube)
    for (int d = 0; d < 3; ++d) {
      const double expected = p.x_tilde[3 * v + d] + kDt * kDt * p.model.gravity[d];
      CHECK(std::abs(x[3 * v + d] - expected) <= 1e-13);
    }
  check_armijo(p.history);
}

TEST_CASE("newton: vertices held in their islands keep the islands' analyses and give the same minimiser") {
  // As a kinematic boundary is handled: a solve with the bar's tip free, then the tip moved and
  // held. Held in its island (identity rows), the tip leaves the island's pattern as it was: no
  // new analysis. Held out of it, the island loses the tip's vertices and is analysed anew. Both
  // minimise the same energy over the same free DOFs.
  std::vector<double> result[2];
  for (const bool in_islands : {true, false}) {
    CAPTURE(in_islands);
    Problem p(bar_json(false), "newton_hold");
    bend_x_tilde(p);
    std::vector<double> x = p.model.rest_positions;
    const NewtonResult pulled = p.solve(x, 1e-8);
    REQUIRE(pulled.status == StepStatus::ok);
    CHECK(pulled.analyses == 1);
    std::vector<int32_t> tip;
    for (int32_t v = 0; v < p.model.num_vertices; ++v)
      if (p.model.rest_positions[3 * v] > 0.99) tip.push_back(v);
    REQUIRE(tip.size() == 9);
    for (int32_t v : tip) x[3 * v + 1] -= 0.01;
    const std::vector<double> start = x;
    p.solver.hold(tip, true, in_islands);
    const NewtonResult held = p.solve(x, 1e-8);
    REQUIRE(held.status == StepStatus::ok);
    CHECK(held.analyses == (in_islands ? 0 : 1));
    for (int32_t v : tip)
      for (int d = 0; d < 3; ++d) CHECK(x[3 * v + d] == start[3 * v + d]);
    result[in_islands] = x;
  }
  CHECK(max_difference(result[0], result[1]) <= 1e-9);
}

TEST_CASE("newton: the CCD cap keeps every iterate above a plane, and caps only the group that would cross it") {
  // Cube 0 hangs 5 mm over a plane and x_tilde throws it 0.5 m through it; cube 1, far away, flies
  // freely. With dhat = 1 mm the barrier cannot see cube 0 coming: only the CCD stops it.
  Problem p(cubes_over_plane("5, 3, 0"), "newton_plane", 0.001);
  const std::vector<int32_t> falling = p.vertices_of(0), flying = p.vertices_of(1);
  for (int32_t v : falling) p.x_tilde[3 * v + 1] -= 0.5;
  for (int32_t v : flying) p.x_tilde[3 * v] += 0.1;
  std::vector<double> x = p.model.rest_positions;
  const NewtonResult r = p.solve(x, 1e-5);
  REQUIRE(r.status == StepStatus::ok);
  // Every accepted point keeps cube 0 strictly above the plane.
  const double lowest = lowest_height(p.history, falling);
  MESSAGE("lowest vertex of the falling cube over ", p.history.size(), " iterates: ", lowest, " m");
  CHECK(lowest > 0.0);
  for (int32_t v : falling) CHECK(x[3 * v + 1] > 0.0);
  // The first iteration: two groups (the cubes are far apart), the falling one capped, the flying
  // one taking its whole step, which lands it on its minimiser.
  REQUIRE(p.history.size() >= 2);
  const NewtonIterate& first = p.history[0];
  REQUIRE(first.ccd_cap.size() == 2);
  const auto capped = std::count_if(first.ccd_cap.begin(), first.ccd_cap.end(), [](double a) { return a < 1.0; });
  CHECK(capped == 1);
  const size_t free_group = first.ccd_cap[0] < 1.0 ? 1 : 0;
  CHECK(first.ccd_cap[free_group] == 1.0);
  CHECK(first.step_length[free_group] == 1.0);
  CHECK(first.ccd_cap[1 - free_group] < 0.05);  // 5 mm of a 0.5 m fall
  for (int32_t v : flying)
    for (int d = 0; d < 3; ++d)
      CHECK(std::abs(first.x[3 * v + d] - (p.x_tilde[3 * v + d] + kDt * kDt * p.model.gravity[d])) <= 1e-13);
  check_armijo(p.history);
}

TEST_CASE("newton: a body the CCD caps does not hold back the other bodies of its island") {
  // Two cubes side by side, 0.5 mm apart (inside dhat: one island, joined by their barrier), both
  // thrown 0.1 m down by x_tilde. Cube 0 hangs 5 mm over a plane, cube 1 15 cm: only cube 0 would
  // cross the plane, and the two slide along their facing sides, which the CCD checks along the
  // motion the two caps give together. So cube 1 takes its whole step while cube 0 is capped.
  Problem p(cubes_over_plane("0.2005, 0.25, 0"), "newton_body_caps", 0.001);
  const std::vector<int32_t> low = p.vertices_of(0), high = p.vertices_of(1);
  for (int32_t v : low) p.x_tilde[3 * v + 1] -= 0.1;
  for (int32_t v : high) p.x_tilde[3 * v + 1] -= 0.1;
  std::vector<double> x = p.model.rest_positions;
  const NewtonResult r = p.solve(x, 1e-5);
  REQUIRE(r.status == StepStatus::ok);
  REQUIRE(p.history.size() >= 2);
  const NewtonIterate& first = p.history[0];
  REQUIRE(first.solved_islands == 1);  // one island: the cubes' barrier joins them
  REQUIRE(first.ccd_cap.size() == 1);
  CHECK(first.ccd_cap[0] < 0.06);  // its smallest cap: cube 0's, 5 mm of a 0.1 m fall
  CHECK(first.step_length[0] == 1.0);
  // How far each cube's lowest vertex went down in the first iteration.
  auto drop = [&](const std::vector<int32_t>& vertices) {
    double d = 0.0;
    for (int32_t v : vertices) d = std::max(d, p.model.rest_positions[3 * v + 1] - first.x[3 * v + 1]);
    return d;
  };
  MESSAGE("first iteration: cube 0 down ", drop(low), " m, cube 1 down ", drop(high), " m");
  CHECK(drop(low) < 0.005);  // still above the plane
  CHECK(drop(high) > 0.05);  // most of its 0.1 m; one cap for the island would hold it under 5 mm
  CHECK(lowest_height(p.history, low) > 0.0);
  check_armijo(p.history);
}

TEST_CASE("newton: a failed solve leaves x at its last accepted point, and an infinite start untouched") {
  Problem p(bar_json(false), "newton_fail");
  bend_x_tilde(p);
  const std::vector<double> x0 = p.model.rest_positions;
  std::vector<double> x = x0;
  const NewtonResult r = p.solve(x, 1e-9, 3);
  CHECK(r.status == StepStatus::max_iterations);
  CHECK(r.message.find("did not converge") != std::string::npos);
  REQUIRE(p.history.size() == 3);
  CHECK(x == p.history.back().x);  // bit for bit
  CHECK(p.potential.energy(x.data()) < p.potential.energy(x0.data()));

  // A start with an inverted tet: refused before any iteration, x unchanged, the tet named.
  std::vector<double> bad = x0;
  const int32_t* tet = &p.model.tets[0];
  for (int d = 0; d < 3; ++d) std::swap(bad[3 * tet[0] + d], bad[3 * tet[1] + d]);
  const std::vector<double> bad_before = bad;
  p.history.clear();
  const NewtonResult inverted = p.solve(bad, 1e-5);
  CHECK(inverted.status == StepStatus::non_finite);
  CHECK(inverted.message.find("tet 0 of body 0") != std::string::npos);
  CHECK(bad == bad_before);
  CHECK(p.history.empty());
}

TEST_CASE("newton: a Hessian that is not positive definite is factorization_failed on every island path") {
  // A free box with its masses negated: the inertia term 1/2 |x - x_tilde|^2_M is then concave,
  // and along a rigid translation, which the (projected) elastic Hessian maps to zero, the
  // Hessian's curvature is minus the total mass. One cell is a dense island (24 DOFs), 4 x 2 x 2
  // cells a simplicial CHOLMOD one (135), 5 x 4 x 4 a supernodal one (450).
  struct Case {
    const char* cells;
    const char* reason;
  };
  for (const Case c : {Case{"[1, 1, 1]", "matrix not positive definite (dense island of 24 DOFs)"},
                       Case{"[4, 2, 2]", "matrix not positive definite at column "},
                       Case{"[5, 4, 4]", "matrix not positive definite at column "}}) {
    CAPTURE(c.cells);
    Scene scene = test::scene_from_json(std::string(R"({
      "gravity": [0, -9.81, 0], "time": { "dt": 0.1 },
      "materials": { "m": { "model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
      "bodies": [ { "box": { "size": [0.4, 0.3, 0.3], "cells": )") + c.cells + R"( }, "material": "m" } ]
    })", "newton_indefinite");
    for (double& m : scene.model.mass) m = -m;
    Problem p(std::move(scene));
    for (int32_t v = 0; v < p.model.num_vertices; ++v) p.x_tilde[3 * v] += 0.01;
    std::vector<double> x = p.model.rest_positions;
    NewtonResult r;
    REQUIRE_NOTHROW(r = p.solve(x, 1e-5));
    CHECK(r.status == StepStatus::factorization_failed);
    CHECK(r.message.rfind(std::string("factorisation failed at Newton iteration 0: ") + c.reason, 0) == 0);
    CHECK(r.iterations == 0);
    CHECK(x == p.model.rest_positions);  // bit for bit
    CHECK(p.history.empty());
  }
}

TEST_CASE("newton: CHOLMOD out of memory is linear_solver_failed, x untouched, and the next solve is as if it had not been") {
  Problem p(bar_json(false), "newton_out_of_memory");
  bend_x_tilde(p);
  const std::vector<double> x0 = p.model.rest_positions;
  const std::string prefix = "the linear solver failed at Newton iteration 0: ";

  // The bar's island (162 DOFs, simplicial CHOLMOD) cannot be analysed.
  std::vector<double> x = x0;
  NewtonResult r;
  {
    test::SuiteSparseOutOfMemory no_memory;
    REQUIRE_NOTHROW(r = p.solve(x, 1e-5));
  }
  CHECK(r.status == StepStatus::linear_solver_failed);
  CHECK(r.message.rfind(prefix + "CHOLMOD symbolic analysis of a 162 x 162 matrix with ", 0) == 0);
  CHECK(r.message.find("failed: out of memory (CHOLMOD_OUT_OF_MEMORY)") != std::string::npos);
  CHECK(x == x0);
  CHECK(p.history.empty());

  // With memory again the island is analysed afresh and the solve converges.
  std::vector<double> reference = x0;
  REQUIRE(p.solve(reference, 1e-5).status == StepStatus::ok);
  CHECK(reference != x0);

  // The analysis is kept now: the numeric factorisation is what fails.
  p.history.clear();
  {
    test::SuiteSparseOutOfMemory no_memory;
    REQUIRE_NOTHROW(r = p.solve(x, 1e-5));
  }
  CHECK(r.status == StepStatus::linear_solver_failed);
  CHECK(r.message == prefix + "CHOLMOD numeric factorisation of a 162 x 162 matrix failed: out of memory "
                              "(CHOLMOD_OUT_OF_MEMORY)");
  CHECK(x == x0);
  CHECK(p.history.empty());

  // And the same solve once more with memory: the same point as before, bit for bit.
  REQUIRE(p.solve(x, 1e-5).status == StepStatus::ok);
  CHECK(x == reference);
}

// "solver.method": "linearized" (engine/solver/linearized_step.hpp): one linear solve of the
// potential's quadratic model per step. It agrees with Newton's step to second order in the step
// (implicit Euler; Newmark and generalized-alpha with damping), its CHOLMOD and matrix-free
// conjugate-gradient paths agree to the solver tolerance, and its steps do not depend on the
// thread count. Projective Dynamics as a solver method follows Newton's steps under each
// scheme, and lands a block on a plane under the default integrator with its energy guard.
// Also: what the methods do not support is refused with one line naming the key.
#include "engine/simulation.hpp"
#include "engine/solver/linearized_step.hpp"
#include "tests/engine/cantilever_support.hpp"
#include "tests/engine/test_support.hpp"
#include "tests/threads_support.hpp"

#include <doctest/doctest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <string>
#include <vector>

using namespace nexdyn;

namespace {

// The clamped rubber beam of test_analytic_dynamics.cpp under full gravity.
std::string beam_json(double dt, const std::string& solver, const std::string& material_extra = "",
                      const std::string& cells = "20, 2, 2", const std::string& integrator = "implicit_euler") {
  return R"({
    "gravity": [0, -9.81, 0],
    "time": { "dt": )" + std::to_string(dt) + R"(, "integrator": ")" + integrator + R"(" },
    "solver": { "tolerance": 1e-10)" + solver + R"( },
    "materials": { "rubber": { "model": "neohookean", "youngs": 1e7, "poisson": 0.3, "density": 1000)" +
         material_extra + R"( } },
    "bodies": [ { "box": { "size": [2.0, 0.2, 0.2], "cells": [)" + cells + R"(] }, "material": "rubber" } ],
    "boundary": [ { "box_min": [-1.001, -1, -1], "box_max": [-0.999, 1, 1], "fix": true } ]
  })";
}

// One step from rest shape with the beam swinging up, v_y = 3 ((x + 1) / 2)^2 m/s: large enough
// a rotation that the linearisation's error shows. The energy guard is off: the step compared is
// the named scheme's. (Under generalized-alpha with stiffness damping the guard retakes this
// first step with implicit Euler: the scheme alone puts the stiffly damped modes' share of a_0
// into x_tilde and the total energy rises, by 28% on test_damping.cpp's beam.)
std::vector<double> one_step(double dt, const std::string& solver, const std::string& integrator = "implicit_euler",
                             const std::string& material_extra = "") {
  Scene scene = test::scene_from_json(beam_json(dt, solver, material_extra, "20, 2, 2", integrator), "linearized_step");
  scene.time.energy_guard = false;
  for (int32_t v = 0; v < scene.model.num_vertices; ++v) {
    const double s = (scene.model.rest_positions[3 * v] + 1.0) / 2.0;
    if (scene.model.dirichlet[v] < 0) scene.initial.v[3 * v + 1] = 3.0 * s * s;
  }
  Simulation sim(scene);
  REQUIRE(sim.step().status == StepStatus::ok);
  return sim.state().x;
}

// The one-line message of loading the scene, or "<loaded>".
std::string scene_error_of(const std::string& json) {
  try {
    test::scene_from_json(json, "method_refused");
  } catch (const SceneError& e) {
    return e.what();
  }
  return "<loaded>";
}

double max_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::abs(a[i] - b[i]));
  return m;
}

}  // namespace

TEST_CASE("linearized: one step matches Newton's to second order in dt, with damping under Newmark and generalized-alpha") {
  // The linearised step solves the quadratic model of the step's potential at x_n; Newton
  // minimises the potential itself. Their difference is the model's error, which must fall 4x
  // per halving of dt whatever the scheme's weights s and k (damping's Hessian s k D and its
  // gradient D v(x), engine/terms/damping_term.hpp), with CHOLMOD (the potential's own Hessian)
  // and with conjugate gradients (which rebuild H = M + s K + s k D from s and k themselves): a
  // step that used implicit Euler's k = h / s under Newmark (h gamma c_a / s) would not be the
  // model of the step Newton takes, and its error would not fall with dt.
  struct Case {
    const char* integrator;
    bool damped;
  };
  const std::string damping = R"(, "damping": {"mass": 0.5, "stiffness": 0.004})";
  for (const Case& c : {Case{"implicit_euler", false}, Case{"implicit_euler", true}, Case{"newmark", true},
                        Case{"generalized_alpha", true}}) {
    for (const char* linear : {"cholmod", "pcg"}) {
      const std::string scheme = std::string(c.integrator) + (c.damped ? ", damped, " : ", ") + linear;
      const std::string material = c.damped ? damping : "";
      const std::string method = R"(, "method": "linearized", "linear": ")" + std::string(linear) + "\"";
      double previous = 0.0;
      for (double dt : {0.01, 0.005, 0.0025}) {
        CAPTURE(scheme);
        CAPTURE(dt);
        const double error = max_difference(one_step(dt, method, c.integrator, material), one_step(dt, "", c.integrator, material));
        MESSAGE(scheme << ", dt = " << dt << ": max |x_linearized - x_newton| = " << error << " m");
        CHECK(error > 0.0);
        if (previous > 0.0) {
          MESSAGE("  ratio to the step twice as long: " << previous / error);
          CHECK(previous / error > 3.5);  // 4 for O(dt^2)
        }
        previous = error;
      }
    }
  }
}

TEST_CASE("linearized: conjugate gradients and CHOLMOD agree to the solver tolerance, with damping") {
  auto run = [](const std::string& linear) {
    Scene scene = test::scene_from_json(
        beam_json(0.01, R"(, "method": "linearized", "linear": ")" + linear + "\"",
                  R"(, "damping": {"mass": 0.5, "stiffness": 0.004})"),
        "linearized_" + linear);
    Simulation sim(scene);
    for (int i = 0; i < 10; ++i) REQUIRE(sim.step().status == StepStatus::ok);
    return sim.state().x;
  };
  const double difference = max_difference(run("cholmod"), run("pcg"));
  MESSAGE("10 steps: max |x_cholmod - x_pcg| = " << difference << " m");
  // CG stops at 1e-3 of the tolerance (1e-10 m/s) per step of 0.01 s.
  CHECK(difference < 10 * 1e-10 * 0.01);
}

TEST_CASE("linearized: steps are bitwise the same on 1 and 2 threads, CHOLMOD and CG") {
  // Under ThreadSanitizer (its own build) two steps, the first and one that starts from a step's
  // state: the same parallel loops, half the time (4 steps took 220 s there, most of CI's margin).
#ifdef __SANITIZE_THREAD__
  constexpr int kSteps = 2;
#else
  constexpr int kSteps = 4;
#endif
  for (const char* linear : {"cholmod", "pcg"}) {
    CAPTURE(linear);
    auto final_x = [&](int threads) {
      test::ThreadsScope limit(threads);
      // 1,525 vertices: the step's vector loops (kLinearizedGrain entries a chunk) are cut in two.
      Scene scene = test::scene_from_json(
          beam_json(0.01, R"(, "method": "linearized", "linear": ")" + std::string(linear) + "\"",
                    R"(, "damping": {"mass": 0.5, "stiffness": 0.004})", "60, 4, 4"),
          "linearized_threads");
      CHECK(scene.model.num_dofs() > kLinearizedGrain);
      Simulation sim(scene);
      for (int i = 0; i < kSteps; ++i) REQUIRE(sim.step().status == StepStatus::ok);
      return sim.state().x;
    };
    CHECK(final_x(1) == final_x(2));
  }
}

TEST_CASE("solver.method: what a method does not support is refused, naming the key") {
  const std::string contact = R"({
    "time": { "dt": 0.01 },
    "solver": { "method": "linearized" },
    "contact": {},
    "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ]
  })";
  CHECK(scene_error_of(contact).find("solver.method") != std::string::npos);
  CHECK(scene_error_of(contact).find("does not support contact") != std::string::npos);
  const std::string pd_material = R"({
    "solver": { "method": "projective_dynamics" },
    "materials": { "m": { "model": "neohookean", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ]
  })";
  CHECK(scene_error_of(pd_material).find("materials.m.model") != std::string::npos);
  const std::string linear_alone = R"({
    "solver": { "linear": "pcg" },
    "materials": { "m": { "model": "arap", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ]
  })";
  CHECK(scene_error_of(linear_alone).find("solver.linear") != std::string::npos);
  const std::string explicit_scheme = R"({
    "time": { "integrator": "central_difference" },
    "solver": { "method": "linearized" },
    "materials": { "m": { "model": "arap", "youngs": 1e6, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ]
  })";
  CHECK(scene_error_of(explicit_scheme).find("is explicit") != std::string::npos);
  const std::string bad_damping = R"({
    "materials": { "m": { "model": "arap", "youngs": 1e6, "poisson": 0.3, "density": 1000,
                          "damping": { "mass": -1 } } },
    "bodies": [ { "box": { "size": [1, 1, 1], "cells": [1, 1, 1] }, "material": "m" } ]
  })";
  CHECK(scene_error_of(bad_damping).find("materials.m.damping.mass") != std::string::npos);
}

TEST_CASE("projective dynamics as solver.method: the arap cantilever follows Newton's steps under implicit Euler, Newmark and generalized-alpha") {
  // PD minimises the same incremental potential as Newton, with the scheme's weight s and its
  // predictor x_tilde; after the solve the scheme's update (v, a, abar) is shared. So on the arap
  // material, whatever the scheme, the two methods must take the same steps to their tolerance:
  // a PD step that used implicit Euler's s = h^2 instead of Newmark's h^2 / 4 or
  // generalized-alpha's 8/9 h^2 c_a would drift from Newton's by centimetres within 10 steps. The
  // energy guard (the default) stays on and must not retake a step in either run: the scheme
  // named is the one compared.
  auto run = [](const std::string& method, const std::string& integrator) {
    Scene scene = test::scene_from_json(R"({
      "gravity": [0, -9.81, 0], "time": { "dt": 0.01, "integrator": ")" + integrator + R"(" },
      "solver": { "tolerance": 1e-7, "method": ")" + method + R"(" },
      "materials": { "m": { "model": "arap", "youngs": 1e7, "poisson": 0.3, "density": 1000 } },
      "bodies": [ { "box": { "size": [2.0, 0.2, 0.2], "cells": [20, 2, 2] }, "material": "m" } ],
      "boundary": [ { "box_min": [-1.001, -1, -1], "box_max": [-0.999, 1, 1], "fix": true } ] })",
                                        "pd_method_" + method);
    Simulation sim(scene);
    int iterations = 0, guarded = 0;
    for (int i = 0; i < 10; ++i) {
      REQUIRE(sim.step().status == StepStatus::ok);
      iterations += sim.last_stats().newton_iterations;
      guarded += sim.last_stats().guarded_steps;
    }
    MESSAGE(integrator << ", " << method << ": " << iterations << " iterations in 10 steps, tip at "
                       << test::tip_y(scene.model, sim.state().x) << " m, " << guarded << " guarded steps");
    CHECK(guarded == 0);
    return sim.state().x;
  };
  for (const char* integrator : {"implicit_euler", "newmark", "generalized_alpha"}) {
    const std::string scheme = integrator;
    CAPTURE(scheme);
    const double difference = max_difference(run("newton", integrator), run("projective_dynamics", integrator));
    MESSAGE(std::string(integrator) << ": max |x_newton - x_pd| after 10 steps: " << difference << " m");
    // Both stop at 1e-7 m/s of their own step: the positions agree far below the sag (cm).
    CHECK(difference < 1e-5);
  }
}

TEST_CASE("projective dynamics as solver.method: a block lands on a plane, never behind it, and rests") {
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01, "integrator": "implicit_euler" },
    "solver": { "method": "projective_dynamics" },
    "contact": {},
    "materials": { "m": { "model": "arap", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "m", "translate": [0, 0.11, 0] } ],
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ] })",
                                      "pd_plane");
  Simulation sim(scene);
  for (int i = 0; i < 60; ++i) {
    REQUIRE(sim.step().status == StepStatus::ok);
    CHECK(sim.last_stats().min_distance >= 0.0);
  }
  // Resting: the bottom's 9 vertices on the plane, the motion all but gone. What is left
  // (4.5e-5 J, 3 mm/s) is the plane penalty's: each solve lets the bottom sink by about 1% of
  // the load's response before the exact projection lifts it back, and the body above follows
  // (projective_dynamics.hpp; a stiffer penalty removes it but stalls sliding contacts).
  CHECK(sim.last_stats().contacts == 9);
  CHECK(sim.last_stats().min_distance == doctest::Approx(0.0).epsilon(1e-9));
  const double released = 8.0 * 9.81 * 0.01;  // m g h of the 1 cm fall [J]
  CHECK(sim.last_stats().kinetic_energy < 1e-4 * released);
}

namespace {

struct PlaneRun {
  double start = 0.0, highest_rise = -HUGE_VAL, largest_in_motion = 0.0, worst_margin_use = -HUGE_VAL;
  int guarded = 0, landed = -1, behind = 0;
  int64_t final_contacts = 0;
};

// The PD block of the test above, 1 cm over the plane, 60 steps of 0.01 s under generalized-alpha
// at rho_inf with the energy guard on or off. Per step: the rise of the total energy (kinetic +
// elastic + gravity; PD has no barrier) above its start, against the guard's margin, 1e-3 of the
// largest energy in motion seen plus 1e-10 of the gravity energy (docs/scenes.md, "The energy
// guard"), and the steps that left a vertex behind the plane.
PlaneRun pd_block_on_plane(double rho_inf, bool guard) {
  Scene scene = test::scene_from_json(R"({
    "gravity": [0, -9.81, 0], "time": { "dt": 0.01, "rho_inf": )" + std::to_string(rho_inf) + R"( },
    "solver": { "method": "projective_dynamics" },
    "contact": {},
    "materials": { "m": { "model": "arap", "youngs": 1e5, "poisson": 0.3, "density": 1000 } },
    "bodies": [ { "box": { "size": [0.2, 0.2, 0.2], "cells": [2, 2, 2] }, "material": "m", "translate": [0, 0.11, 0] } ],
    "obstacles": [ { "plane": { "point": [0, 0, 0], "normal": [0, 1, 0] } } ] })",
                                      "pd_plane_guard");
  REQUIRE(scene.time.integrator.name == "generalized_alpha");
  REQUIRE(scene.time.energy_guard);  // the default
  scene.time.energy_guard = guard;
  Simulation sim(scene);
  StepStats start;
  sim.measure(start);
  PlaneRun run;
  run.start = start.total_energy;
  for (int i = 0; i < 60; ++i) {
    REQUIRE(sim.step().status == StepStatus::ok);
    const StepStats& st = sim.last_stats();
    run.guarded += st.guarded_steps;
    if (st.min_distance < 0.0) ++run.behind;
    if (run.landed < 0 && st.contacts > 0) run.landed = i;
    run.largest_in_motion = std::max(run.largest_in_motion, st.kinetic_energy + st.elastic_energy);
    const double margin = 1e-3 * run.largest_in_motion + 1e-10 * std::abs(st.gravity_energy);
    const double rise = st.total_energy - start.total_energy;
    run.highest_rise = std::max(run.highest_rise, rise);
    run.worst_margin_use = std::max(run.worst_margin_use, rise / margin);
  }
  run.final_contacts = sim.last_stats().contacts;
  MESSAGE("rho_inf " << rho_inf << std::string(guard ? " with" : " without") << " the guard: landed at step " << run.landed
                     << "; highest rise of the total energy above its start " << run.highest_rise << " J ("
                     << run.worst_margin_use << " of the guard's margin), largest energy in motion "
                     << run.largest_in_motion << " J; " << run.guarded << " guarded steps; " << run.behind
                     << " steps behind the plane; " << run.final_contacts << " vertices on the plane at the end");
  return run;
}

}  // namespace

TEST_CASE("projective dynamics as solver.method: under generalized-alpha with the energy guard a block lands on a plane, never behind it, and gains no energy") {
  // PD's plane constraints are smooth forces of its step, not end-of-step impulses like the
  // barrier's (engine/simulation_solve.cpp), so under generalized-alpha they enter the
  // acceleration history, the way docs/scenes.md ("How contact forces enter the update") says
  // pumps energy into bouncing bodies. At the default rho_inf 0.5 the scheme alone gains none
  // here; at 0.8 alone the block gains 0.78 J, as much as its 1 cm fall released (424 times the
  // guard's margin). With the guard, at both, every step completes, no vertex is ever behind the
  // plane (the projections), and the total energy never rises above its start by more than the
  // guard's margin (measured: not at all at 0.5; at 0.8 9e-14 J, 2 steps retaken).
  for (double rho_inf : {0.5, 0.8}) {
    CAPTURE(rho_inf);
    const PlaneRun run = pd_block_on_plane(rho_inf, true);
    CHECK(run.landed >= 0);
    CHECK(run.largest_in_motion > 0.5);  // the 1 cm fall of 8 kg released 0.78 J
    CHECK(run.behind == 0);
    CHECK(run.worst_margin_use <= 1.0);
    if (rho_inf == 0.5) CHECK(run.guarded == 0);
    else CHECK(run.guarded > 0);
  }
  // The control: at 0.8 without the guard the block does gain energy, so the guard had work.
  const PlaneRun alone = pd_block_on_plane(0.8, false);
  CHECK(alone.worst_margin_use > 10.0);
}

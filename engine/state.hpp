// State: what the integrator advances, as flat buffers of the same shape as Model's positions.
//
// Positions are packed xyz doubles so that `x` is directly the degree-of-freedom vector that the
// Newton solver and CHOLMOD see. Written by the integrator's update kernels (engine/integrator.cpp:
// x_tilde by predict_x_tilde; v, a, a_bar by update_implicit and update_explicit) and by the step's
// stages in Simulation (engine/simulation.cpp: x at finish; the impulsive forces taken back out of
// a and a_bar in update_with_contact; the held vertices' x, v and a in prescribe); besides those,
// only the sleeping bodies (engine/sleeping.cpp: a body put to sleep has its v set to zero) and a
// checkpoint's restore (Simulation::adopt) touch it.
#pragma once

#include <cstdint>
#include <vector>

namespace nexdyn {

struct State {
  int64_t step = 0;    // number of completed steps
  double time = 0.0;   // [s]
  std::vector<double> x;        // (num_vertices x 3) positions x_n [m]
  std::vector<double> v;        // (num_vertices x 3) velocities v_n [m/s]
  std::vector<double> a;        // (num_vertices x 3) accelerations a_n = M^-1 f(x_n) [m/s^2]
  // (num_vertices x 3) the acceleration the Newmark update of x and v uses [m/s^2]: a itself,
  // except under generalized-alpha, whose auxiliary acceleration it is (engine/integrator.hpp)
  std::vector<double> a_bar;
  std::vector<double> x_tilde;  // (num_vertices x 3) predictor of the step being solved [m]
};

}  // namespace nexdyn

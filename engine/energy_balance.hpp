// The energy balance of a step (issue 16): where the change of the total energy came from.
//
//   total_{n+1} - total_n = boundary_work - friction_dissipated - damping_dissipated + kappa_energy
//                           + integrator_energy
//
// total = kinetic + elastic + gravity + kappa B, the total_energy column of stats.csv.
// - boundary_work: what the held vertices (moving boundaries, kinematic obstacles) did on the
//   rest: the sum over held vertices of F . dx, F the force that keeps a held vertex on its path,
//   F = m a - f(x). Its inertia and gravity parts are exact (the held kinetic energy's change,
//   -m g . dx); the elastic force is averaged over the step's two ends (trapezoidal rule, as
//   Newmark treats it); contact and friction act at the end of the step, as they do in the
//   step (engine/incremental_potential.hpp). Fixed vertices do no work.
// - friction_dissipated: grad D(x_{n+1}) . (x_{n+1} - x_n) over all vertices = sum over the
//   friction contacts of mu N f1(|u|) |u| >= 0, the lagged friction force times the slip.
// - damping_dissipated: dx^T D dx / h, the energy the Rayleigh damping force -D v took out over
//   the step: >= 0, and its exact work under implicit Euler and under Newmark on a linear problem
//   (Simulation::account_damping). stats.csv reports its running sum since the start.
// - kappa_energy: (kappa_{n+1} - kappa_n) B(x_{n+1}): the barrier energy that a raised barrier
//   stiffness added at the configuration it was raised in, not earned by any motion.
// - integrator_energy: the rest, what the time integration itself created (> 0) or took out
//   (< 0): Newmark's error on a nonlinear problem, generalized-alpha's and Euler's numerical
//   damping, and the impulsive contact treatment.
// Joint forces do no work in the exact problem; their augmented Lagrangian's small violation
// work is part of integrator_energy.
#pragma once

#include "engine/model.hpp"

#include <vector>

namespace nexdyn {

struct EnergyBalance {
  double boundary_work = 0.0;        // [J] put in by moving boundaries and obstacles
  double friction_dissipated = 0.0;  // [J] taken out by friction (>= 0)
  double damping_dissipated = 0.0;   // [J] taken out by Rayleigh damping (stats.csv: cumulative)
  double kappa_energy = 0.0;         // [J] put in by raising the barrier stiffness
  double integrator_energy = 0.0;    // [J] put in (> 0) or taken out (< 0) by the time integration

  EnergyBalance& operator+=(const EnergyBalance& o) {
    boundary_work += o.boundary_work;
    friction_dissipated += o.friction_dissipated;
    damping_dissipated += o.damping_dissipated;
    kappa_energy += o.kappa_energy;
    integrator_energy += o.integrator_energy;
    return *this;
  }
};

// Kinetic energy of the held vertices [J].
double held_kinetic_energy(const Model& model, const std::vector<double>& v);

// Whether some held vertex moves between x_old and x_new (only then is there boundary work).
bool held_vertices_move(const Model& model, const std::vector<double>& x_old, const std::vector<double>& x_new);

// The boundary work of the motion x_old -> x_new without the held kinetic energy's change (the
// caller adds it): sum over held vertices of (-m g + (g_old + g_new) / 2 - f_end) . dx, with
// g the elastic energy's gradients at the two ends (3n) and f_end the forces that act at the
// end of the step (3n each; empty = none), contact and friction.
double boundary_work(const Model& model, const std::vector<double>& x_old, const std::vector<double>& x_new,
                     const std::vector<double>& elastic_gradient_old,
                     const std::vector<double>& elastic_gradient_new,
                     const std::vector<const std::vector<double>*>& end_forces);

// -f . (x_new - x_old) over all vertices for the friction force f (3n): the energy friction took
// out over the motion (0 for an empty f).
double friction_dissipation(const std::vector<double>& x_old, const std::vector<double>& x_new,
                            const std::vector<double>& friction_force);

}  // namespace nexdyn

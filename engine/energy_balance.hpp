// What the energy balance of a step (EnergyBalance, engine/step_result.hpp) is booked from: the
// held vertices' kinetic energy and the boundary work of a motion.
#pragma once

#include "engine/model.hpp"
#include "engine/step_result.hpp"

#include <vector>

namespace nexdyn {

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

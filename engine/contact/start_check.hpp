// The start state of a contact scene must be intersection-free: IPC's barrier is infinite at
// distance 0, and no line search can leave a state where surfaces already cross.
#pragma once

#include "engine/model.hpp"

#include <string>

namespace nexdyn {

// Empty when the start positions are valid, else one sentence naming the two bodies (as the scene
// file's "bodies[i]" / "obstacles[i]", with the copy number for arrays):
//   * two surface triangles touch or intersect (triangles sharing a vertex excepted);
//   * a body's surface vertex lies on or behind an obstacle plane;
//   * a body lies entirely inside another closed body.
std::string initial_contact_problem(const Model& model);

// "bodies[2]", "bodies[0] (copy 7 of its array)", "obstacles[1]".
std::string body_label(const Model& model, int32_t body);

}  // namespace nexdyn

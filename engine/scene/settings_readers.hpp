// Readers of a scene's settings objects: "time", "solver", "contact" (with its
// "friction_pairs"), "output" and "materials" (docs/scenes.md lists every key).
//
// Each reader checks its object's keys, reads each value with the typed readers of
// json_reader.hpp and fills the settings struct of scene.hpp, leaving defaults where a key is
// absent. They read one object each; the checks that tie several together (contact needs an
// implicit integrator, ...) are load_scene's (scene.cpp).
#pragma once

#include "engine/model.hpp"
#include "engine/scene/json_reader.hpp"
#include "engine/scene/scene.hpp"

#include <cstdint>
#include <map>
#include <string>

namespace nexdyn::scene_io {

void read_time(const json& j, const Where& w, TimeSettings& time);
void read_solver(const json& j, const Where& w, SolverSettings& solver);
void read_output(const json& j, const Where& w, OutputSettings& output);

// Every key of "contact" but "friction_pairs", which names materials: read_friction_pairs reads
// it once they are known. A "contact" object switches contact on ("contact": {} is enough);
// "enabled": false keeps the settings in the file but turns contact off.
void read_contact(const json& j, const Where& w, ContactSettings& contact);

// Material index by name, in the order of "materials".
using MaterialIds = std::map<std::string, int32_t>;

// The index of a material named by `value`, a string naming an entry of "materials".
int32_t material_id(const json& value, const Where& w, const MaterialIds& material_ids);

// "friction_pairs": [{ "materials": [a, b], "friction": mu_k, "static_friction": mu_s }, ...],
// appended to contact.friction_pairs with a <= b.
void read_friction_pairs(const json& j, const Where& w, const MaterialIds& material_ids,
                         ContactSettings& contact);

// The "materials" object (`j`, at `w`): appends each to `materials` in file order and returns
// their ids by name. At least one, at most limits.max_materials.
MaterialIds read_materials(const json& j, const Where& w, const SceneLimits& limits,
                           std::vector<Material>& materials);

}  // namespace nexdyn::scene_io

// The model builder: appends a scene's "bodies", "boundary", "joints" and "obstacles" to the
// flat buffers of Model (model.hpp) and the start velocities to State.
//
// Bodies are appended as ranges; a mesh file used by several bodies (or an "array") is read
// once. Each body copy is placed (scale, rotate, translate, array offset) and its per-tet rest
// data (Dm^-1, volume, lumped mass) computed with the elasticity kernels' tet_rest_shape, after
// checking that placing did not overflow a position or flatten a tet. Obstacle meshes (.obj
// triangles or the boundary of a .msh) come after all bodies as bodies without tets: mass 0,
// every vertex on a Dirichlet motion, one shared fixed motion for the static ones
// (build_obstacles.cpp); obstacle planes go to Model::obstacle_planes; joints are attached to
// the tets of their bodies (build_joints.cpp).
#pragma once

#include "engine/model.hpp"
#include "engine/scene/json_reader.hpp"
#include "engine/scene/scene.hpp"
#include "engine/scene/settings_readers.hpp"
#include "engine/state.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <string>

namespace nexdyn::scene_io {

// Appends every entry of the scene's "bodies", "boundary", "joints" and "obstacles" (`root` is
// the whole file, at `w`) to `model`, whose materials must be in place, and each vertex's start
// velocity to `initial.v`. With contact, moving boundaries and obstacles become kinematic
// (DirichletMotion::kinematic). Meshes are found relative to `scene_dir`; bodies given as
// surfaces keep their tets in `surface_cache_dir` (empty: they are made and not kept).
void build_model(const json& root, const Where& w, const std::filesystem::path& scene_dir,
                 const MaterialIds& material_ids, const SceneLimits& limits, bool contact_enabled,
                 const std::filesystem::path& surface_cache_dir, Model& model, State& initial);

// ---- shared by the body and the obstacle builders --------------------------------------------

// The placement of a mesh: scale, then rotate (degrees about x, then y, then z), then translate,
// all about the mesh's own origin. Bodies and obstacle meshes share it so that the two kinds of
// entry cannot drift apart in meaning.
struct Transform {
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();  // rotate * scale
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();   // [m]
};

// The "scale", "rotate_deg" and "translate" keys of entry `j`.
Transform read_transform(const json& j, const Where& w);

// The rigid motion keys of a "boundary" or moving obstacle entry: "velocity", "angular_velocity"
// with "axis", and "center" (default `center`).
DirichletMotion read_motion(const json& j, const Where& w, const Eigen::Vector3d& center);

// A "boundary" entry's box ("box_min", "box_max", into lo and hi) and its motion: "fix": true,
// or the keys of read_motion about the box's centre. Tet and MPM scenes share it.
DirichletMotion read_box_motion(const json& j, const Where& w, Eigen::Vector3d& lo, Eigen::Vector3d& hi);

// The "plane" object of an "obstacles" entry (`plane`, at `wp`): its point and unit normal.
void read_plane_geometry(const json& plane, const Where& wp, Eigen::Vector3d& point, Eigen::Vector3d& normal);

// Fails at `w` when adding `vertices` and `tets` to the model would pass the scene's limits;
// `what` says what is being added ("1000000 copies of a 4-vertex, 1-tet body").
void check_size(const Model& model, int64_t vertices, int64_t tets, const SceneLimits& limits,
                const std::string& what, const Where& w);

// Appends the "obstacles" array `obstacles` (at `w`), after every body and boundary entry
// (build_obstacles.cpp).
void append_obstacles(const json& obstacles, const Where& w, const std::filesystem::path& scene_dir,
                      const MaterialIds& material_ids, const SceneLimits& limits, Model& model,
                      State& initial);

// Appends the "joints" array `joints` (at `w`) on the bodies already in `model`, of which the
// scene has `num_scene_bodies` entries (build_joints.cpp).
void append_joints(const json& joints, const Where& w, Model& model, int64_t num_scene_bodies);

}  // namespace nexdyn::scene_io

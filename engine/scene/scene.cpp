// load_scene: JSON -> validated settings -> flat Model buffers and the initial State.
//
// The work is shared by three layers, each in its own file: the strict JSON reader
// (json_reader.hpp: typed values, key paths in every message), the settings readers
// (settings_readers.hpp: "time", "solver", "contact", "output", "materials") and the model
// builder (build_model.hpp: bodies, boundary, joints, obstacles). This file reads the file, runs
// them in the order that decides which error a file with several problems reports, checks what
// ties settings together, and sets up the initial state.
#include "engine/scene/scene.hpp"

#include "engine/contact/start_check.hpp"
#include "engine/scene/build_model.hpp"
#include "engine/scene/json_reader.hpp"
#include "engine/scene/mpm_scene.hpp"
#include "engine/scene/settings_readers.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <fstream>

namespace nexdyn {

using namespace scene_io;  // this file only puts its pieces together
namespace fs = std::filesystem;

namespace {

json parse_scene_file(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw SceneError(one_line(file.string() + ": cannot open the scene file"));
  try {
    return json::parse(in);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e999
    throw SceneError(one_line(file.string() + ": not valid JSON: " + e.what()));
  }
}

// "name", by default the file's stem. It is the default output folder (out/<name>): "." or ".."
// would write outside it.
std::string read_scene_name(const json& root, const Where& w, const fs::path& file) {
  const std::string name = root.contains("name") ? string(root["name"], w["name"]) : file.stem().string();
  bool bad_name = name.empty() || name == "." || name == ".." || name.find('/') != std::string::npos;
  for (char c : name) bad_name = bad_name || static_cast<unsigned char>(c) < 32 || c == 127;
  if (bad_name)
    w["name"].fail("expected a non-empty name without '/' or control characters, not \".\" or \"..\"",
                   root.contains("name") ? root["name"] : json(name));
  return name;
}

// "gravity", "time", "solver", "contact" (but its "friction_pairs") and "output", and the checks
// that tie them together.
void read_settings(const json& root, const Where& w, Scene& scene, bool mpm) {
  if (root.contains("gravity")) scene.model.gravity = vec3(root["gravity"], w["gravity"]);
  if (root.contains("time")) read_time(root["time"], w["time"], scene.time);
  if (root.contains("solver")) read_solver(root["solver"], w["solver"], scene.solver);
  if (root.contains("contact")) read_contact(root["contact"], w["contact"], scene.contact);
  if (root.contains("output")) read_output(root["output"], w["output"], scene.output);
  // A camera without "up" takes the direction against gravity, known only now.
  if (scene.output.camera && scene.output.camera->up.norm() == 0.0) {
    CameraSettings& camera = *scene.output.camera;
    camera.up = scene.model.gravity.norm() > 0.0 ? Eigen::Vector3d(-scene.model.gravity.normalized())
                                                 : Eigen::Vector3d::UnitY();
    if (camera.up.cross(camera.target - camera.position).norm() == 0.0)
      w["output"]["camera"].fail("looks straight along the up direction (against gravity); give \"up\"");
  }
  // IPC's barrier lives inside the implicit solve: an explicit step (beta = 0) has no
  // minimisation to add it to, so it could not keep bodies apart.
  // MPM's planes act on grid nodes, which an explicit step can hold as well as an implicit one.
  if (!mpm && scene.contact.enabled && scene.time.integrator.is_explicit())
    w["time"]["integrator"].fail("contact needs an implicit integrator (beta > 0); \"" +
                                 scene.time.integrator.name + "\" is explicit (beta = 0)");
  const bool has_obstacles = root.contains("obstacles") && !(root["obstacles"].is_array() && root["obstacles"].empty());
  // Obstacles act on bodies only through contact; without it they would silently do nothing.
  if (has_obstacles && !scene.contact.enabled) w["obstacles"].fail("obstacles need contact; add \"contact\": {}");
}

// What "linearized" and "projective_dynamics" do not support is refused here, naming the key
// that asks for it (docs/scenes.md, "solver.method").
void check_solver_method(const Where& w, const Scene& scene) {
  const SolverMethod method = scene.solver.method;
  if (method == SolverMethod::newton) return;
  const Where where = w["solver"]["method"];
  const std::string name = method == SolverMethod::linearized ? "linearized" : "projective_dynamics";
  const IntegratorParams& scheme = scene.time.integrator;
  if (scheme.is_static || scheme.is_explicit())
    where.fail("\"" + name + "\" solves implicit steps; the integrator \"" + scheme.name + "\" is " +
               (scheme.is_static ? "static" : "explicit"));
  if (!scene.model.joints.empty()) where.fail("\"" + name + "\" does not support \"joints\" (use \"newton\")");
  if (method == SolverMethod::linearized && scene.contact.enabled)
    where.fail("\"linearized\" does not support contact (use \"newton\")");
  if (method == SolverMethod::projective_dynamics) {
    if (scene.contact.has_friction())
      where.fail("\"projective_dynamics\" does not support friction (use \"newton\")");
    int32_t tet_bodies = 0;
    for (const BodyRange& body : scene.model.bodies) {
      if (body.obstacle)
        where.fail("\"projective_dynamics\" supports plane obstacles only, not obstacle meshes (use \"newton\")");
      ++tet_bodies;
    }
    if (scene.contact.enabled && tet_bodies > 1)
      where.fail("\"projective_dynamics\" supports contact with plane obstacles only, not between bodies "
                 "(use \"newton\")");
    for (const Material& m : scene.model.materials) {
      if (!m.arap)
        w["materials"][m.name]["model"].fail("\"projective_dynamics\" needs the \"arap\" model, not \"" +
                                             std::string(material_model_name(m.model)) + "\"");
      if (m.damping.any())
        w["materials"][m.name]["damping"].fail("\"projective_dynamics\" does not support damping (use \"newton\")");
    }
  }
}

// What affine bodies do not support yet is refused here, naming the key that asks for it.
void check_affine_bodies(const Where& w, const Scene& scene) {
  const Model& model = scene.model;
  if (model.affine_bodies.empty()) return;
  if (scene.solver.method != SolverMethod::newton)
    w["solver"]["method"].fail("affine bodies (material model \"affine\") need the \"newton\" method");
  // Without inertia nothing but contact holds an affine body's rotation (its orthogonality
  // potential is flat along rotations). (Boundaries: build_model.cpp, read_boundary.)
  if (scene.time.integrator.is_static)
    w["time"]["integrator"].fail("affine bodies need a dynamic integrator: a static solve leaves their rotation free");
  // Their orthogonality potential is stiff by design: a 10 cm box at the default stiffness rings
  // at about 1e4 rad/s, so an explicit scheme is stable only below 1e-4 s (affine_spin at 0.01 s
  // failed its sixth step, and every halving after it).
  if (scene.time.integrator.is_explicit())
    w["time"]["integrator"].fail("affine bodies need an implicit integrator: their orthogonality potential is "
                                 "too stiff for an explicit step");
}

// The start of the run: at rest positions with the bodies' velocities (already in initial.v) and
// zero acceleration (the simulation sets the consistent one). With contact, the start must be
// free of intersections.
void set_initial_state(Scene& scene) {
  scene.initial.x = scene.model.rest_positions;
  scene.initial.a.assign(scene.initial.x.size(), 0.0);
  scene.initial.x_tilde = scene.initial.x;
  if (scene.contact.enabled) {
    const std::string problem = initial_contact_problem(scene.model);
    if (!problem.empty()) throw SceneError(one_line(scene.file.string() + ": " + problem));
  }
}

}  // namespace

std::string scene_name(const fs::path& file) {
  const json root = parse_scene_file(file);
  return read_scene_name(root, Where(file, ""), file);
}

Scene load_scene(const fs::path& file, const SceneLimits& limits, const fs::path& mesh_cache_dir) {
  const json root = parse_scene_file(file);
  const Where w(file, "");
  check_keys(root, w, {"name", "gravity", "time", "solver", "contact", "materials", "bodies", "obstacles",
                       "boundary", "joints", "output", "mpm"});
  Scene scene;
  scene.file = file;
  scene.name = read_scene_name(root, w, file);
  const bool mpm = is_mpm_scene(root);
  read_settings(root, w, scene, mpm);

  if (!root.contains("materials")) w.fail("missing key \"materials\"");
  const MaterialIds material_ids = read_materials(root["materials"], w["materials"], limits, scene.model.materials);
  if (root.contains("contact") && root["contact"].contains("friction_pairs"))
    read_friction_pairs(root["contact"]["friction_pairs"], w["contact"]["friction_pairs"], material_ids, scene.contact);

  if (mpm) {
    for (const Material& m : scene.model.materials)
      if (m.affine)
        w["materials"][m.name]["model"].fail("\"affine\" is for bodies of tets; particle bodies (MPM) cannot use it");
    build_mpm_model(root, w, file.parent_path(), limits, scene);
    return scene;
  }
  build_model(root, w, file.parent_path(), material_ids, limits, scene.contact.enabled, mesh_cache_dir, scene.model,
              scene.initial);
  check_solver_method(w, scene);
  check_affine_bodies(w, scene);
  set_initial_state(scene);
  return scene;
}

}  // namespace nexdyn

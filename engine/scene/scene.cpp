// Scene loading: JSON -> validated settings -> flat Model buffers and the initial State.
//
// The reader walks the document with a key path ("bodies[1].box.cells") so that every error
// names the file, the key and the value. Bodies are appended to the shared buffers as ranges;
// a mesh file used by several bodies (or an "array") is read once.
#include "engine/scene/scene.hpp"

#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/tet_mesh.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>

namespace nexdyn {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// Where in the file a value sits, for error messages.
class Where {
 public:
  Where(const fs::path& file, std::string path) : file_(file), path_(std::move(path)) {}
  Where operator[](const std::string& key) const {
    return Where(file_, path_.empty() ? key : path_ + "." + key);
  }
  Where operator[](size_t index) const {
    return Where(file_, path_ + "[" + std::to_string(index) + "]");
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw SceneError(file_.string() + ": " + (path_.empty() ? "" : path_ + ": ") + what);
  }
  [[noreturn]] void fail(const std::string& what, const json& value) const {
    fail(what + ", got " + value.dump());
  }

 private:
  const fs::path& file_;
  std::string path_;
};

void check_keys(const json& object, const Where& where, std::initializer_list<const char*> allowed) {
  if (!object.is_object()) where.fail("expected an object", object);
  for (const auto& item : object.items()) {
    bool known = false;
    for (const char* key : allowed) known = known || item.key() == key;
    if (!known) {
      std::string list;
      for (const char* key : allowed) list += std::string(list.empty() ? "" : ", ") + key;
      where[item.key()].fail("unknown key (allowed here: " + list + ")");
    }
  }
}

double number(const json& value, const Where& where) {
  if (!value.is_number()) where.fail("expected a number", value);
  const double d = value.get<double>();
  if (!std::isfinite(d)) where.fail("expected a finite number", value);
  return d;
}

double positive(const json& value, const Where& where) {
  const double d = number(value, where);
  if (!(d > 0.0)) where.fail("expected a positive number", value);
  return d;
}

int64_t integer(const json& value, const Where& where, int64_t min_value) {
  if (!value.is_number_integer()) where.fail("expected an integer", value);
  const int64_t i = value.get<int64_t>();
  if (i < min_value) where.fail("expected an integer >= " + std::to_string(min_value), value);
  return i;
}

Eigen::Vector3d vec3(const json& value, const Where& where) {
  if (!value.is_array() || value.size() != 3) where.fail("expected an array of 3 numbers", value);
  return {number(value[0], where[0]), number(value[1], where[1]), number(value[2], where[2])};
}

std::string string(const json& value, const Where& where) {
  if (!value.is_string()) where.fail("expected a string", value);
  return value.get<std::string>();
}

bool boolean(const json& value, const Where& where) {
  if (!value.is_boolean()) where.fail("expected true or false", value);
  return value.get<bool>();
}

// ---- settings ----------------------------------------------------------------------------------

void read_time(const json& j, const Where& w, TimeSettings& time) {
  check_keys(j, w, {"dt", "steps", "integrator", "alpha", "beta", "gamma", "initial_acceleration"});
  if (j.contains("dt")) time.dt = positive(j["dt"], w["dt"]);
  if (j.contains("steps")) time.steps = integer(j["steps"], w["steps"], 1);
  if (j.contains("integrator")) {
    const std::string name = string(j["integrator"], w["integrator"]);
    const auto preset = integrator_preset(name);
    if (!preset) {
      std::string list;
      for (const std::string& n : integrator_preset_names()) list += (list.empty() ? "" : ", ") + n;
      w["integrator"].fail("unknown integrator \"" + name + "\" (known: " + list + ")");
    }
    time.integrator = *preset;
  }
  const bool custom = j.contains("alpha") || j.contains("beta") || j.contains("gamma");
  if (custom) {
    if (time.integrator.is_static) w.fail("alpha, beta and gamma cannot be combined with \"static\"");
    if (j.contains("alpha")) time.integrator.alpha = positive(j["alpha"], w["alpha"]);
    if (j.contains("beta")) time.integrator.beta = number(j["beta"], w["beta"]);
    if (j.contains("gamma")) time.integrator.gamma = number(j["gamma"], w["gamma"]);
    if (time.integrator.beta < 0.0 || time.integrator.beta > 0.5)
      w["beta"].fail("expected 0 <= beta <= 0.5", j.value("beta", json(time.integrator.beta)));
    if (time.integrator.gamma < 0.0 || time.integrator.gamma > 1.0)
      w["gamma"].fail("expected 0 <= gamma <= 1", j.value("gamma", json(time.integrator.gamma)));
    time.integrator.name = "custom";
  }
  if (j.contains("initial_acceleration")) {
    const std::string mode = string(j["initial_acceleration"], w["initial_acceleration"]);
    if (mode == "consistent") time.consistent_initial_acceleration = true;
    else if (mode == "zero") time.consistent_initial_acceleration = false;
    else w["initial_acceleration"].fail("expected \"consistent\" or \"zero\"", j["initial_acceleration"]);
  }
}

void read_solver(const json& j, const Where& w, SolverSettings& solver) {
  check_keys(j, w, {"tolerance", "max_iterations"});
  if (j.contains("tolerance")) solver.tolerance = positive(j["tolerance"], w["tolerance"]);
  if (j.contains("max_iterations"))
    solver.max_iterations = static_cast<int>(integer(j["max_iterations"], w["max_iterations"], 1));
}

void read_contact(const json& j, const Where& w, ContactSettings& contact) {
  check_keys(j, w, {"enabled", "dhat", "friction", "epsv"});
  if (j.contains("enabled")) contact.enabled = boolean(j["enabled"], w["enabled"]);
  if (j.contains("dhat")) contact.dhat = positive(j["dhat"], w["dhat"]);
  if (j.contains("friction")) {
    contact.friction = number(j["friction"], w["friction"]);
    if (contact.friction < 0.0) w["friction"].fail("expected a number >= 0", j["friction"]);
  }
  if (j.contains("epsv")) contact.epsv = positive(j["epsv"], w["epsv"]);
}

void read_output(const json& j, const Where& w, OutputSettings& output) {
  check_keys(j, w, {"every", "formats"});
  if (j.contains("every")) output.every = integer(j["every"], w["every"], 1);
  if (j.contains("formats")) {
    const json& f = j["formats"];
    if (!f.is_array()) w["formats"].fail("expected an array of \"vtu\" and/or \"obj\"", f);
    output.vtu = output.obj = false;
    for (size_t i = 0; i < f.size(); ++i) {
      const std::string name = string(f[i], w["formats"][i]);
      if (name == "vtu") output.vtu = true;
      else if (name == "obj") output.obj = true;
      else w["formats"][i].fail("unknown output format (known: vtu, obj)", f[i]);
    }
  }
}

Material read_material(const std::string& name, const json& j, const Where& w) {
  check_keys(j, w, {"model", "youngs", "poisson", "density"});
  for (const char* key : {"model", "youngs", "poisson", "density"})
    if (!j.contains(key)) w.fail(std::string("missing key \"") + key + "\"");
  Material m;
  m.name = name;
  const std::string model = string(j["model"], w["model"]);
  const auto parsed = material_model_from_name(model);
  if (!parsed) w["model"].fail("unknown material model \"" + model +
                               "\" (known: linear, stvk, corotated, neohookean)");
  m.model = *parsed;
  m.youngs = positive(j["youngs"], w["youngs"]);
  m.poisson = number(j["poisson"], w["poisson"]);
  if (!(m.poisson > -1.0 && m.poisson < 0.5))
    w["poisson"].fail("expected -1 < poisson < 0.5", j["poisson"]);
  m.density = positive(j["density"], w["density"]);
  m.lame = lame_from_young_poisson(m.youngs, m.poisson);
  return m;
}

// ---- bodies ------------------------------------------------------------------------------------

// One entry of "bodies" before expansion of its array.
struct BodySpec {
  const TetMesh* mesh = nullptr;
  const SurfaceMesh* surface = nullptr;
  int32_t material = 0;
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();  // rotate * scale
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
  std::array<int64_t, 3> count = {1, 1, 1};
  Eigen::Vector3d spacing = Eigen::Vector3d::Zero();
};

struct MeshCache {
  std::map<std::string, std::pair<TetMesh, SurfaceMesh>> entries;  // std::map: stable addresses
};

Eigen::Matrix3d rotation_xyz_degrees(const Eigen::Vector3d& deg) {
  const Eigen::Vector3d r = deg * (M_PI / 180.0);
  return (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX())).toRotationMatrix();
}

BodySpec read_body(const json& j, const Where& w, const fs::path& scene_dir,
                   const std::map<std::string, int32_t>& material_ids, MeshCache& cache) {
  check_keys(j, w, {"mesh", "box", "material", "translate", "rotate_deg", "scale", "velocity", "array"});
  BodySpec body;
  if (j.contains("mesh") == j.contains("box")) w.fail("give exactly one of \"mesh\" and \"box\"");
  std::string key;
  if (j.contains("mesh")) {
    const std::string rel = string(j["mesh"], w["mesh"]);
    const fs::path path = scene_dir / rel;
    key = "mesh:" + path.lexically_normal().string();
    if (!cache.entries.count(key)) {
      if (!fs::exists(path)) w["mesh"].fail("mesh file not found: " + path.string());
      TetMesh mesh;
      try {
        mesh = read_msh(path);
      } catch (const std::exception& e) {
        w["mesh"].fail(e.what());
      }
      SurfaceMesh surface = extract_surface(mesh);
      cache.entries.emplace(key, std::make_pair(std::move(mesh), std::move(surface)));
    }
  } else {
    const json& box = j["box"];
    const Where wb = w["box"];
    check_keys(box, wb, {"size", "cells"});
    if (!box.contains("size") || !box.contains("cells")) wb.fail("needs \"size\" and \"cells\"");
    const Eigen::Vector3d size = vec3(box["size"], wb["size"]);
    if (!(size.array() > 0.0).all()) wb["size"].fail("expected 3 positive numbers", box["size"]);
    const json& cells = box["cells"];
    if (!cells.is_array() || cells.size() != 3) wb["cells"].fail("expected 3 positive integers", cells);
    std::array<int, 3> n{};
    for (int d = 0; d < 3; ++d) {
      const int64_t c = integer(cells[d], wb["cells"][d], 1);
      if (c > 1000) wb["cells"][d].fail("at most 1000 cells per side", cells[d]);
      n[d] = static_cast<int>(c);
    }
    key = "box:" + box.dump();
    if (!cache.entries.count(key)) {
      TetMesh mesh = make_box_mesh(size, n);
      SurfaceMesh surface = extract_surface(mesh);
      cache.entries.emplace(key, std::make_pair(std::move(mesh), std::move(surface)));
    }
  }
  body.mesh = &cache.entries.at(key).first;
  body.surface = &cache.entries.at(key).second;

  if (!j.contains("material")) w.fail("missing key \"material\"");
  const std::string material = string(j["material"], w["material"]);
  const auto found = material_ids.find(material);
  if (found == material_ids.end()) w["material"].fail("no material named \"" + material + "\" in \"materials\"");
  body.material = found->second;

  Eigen::Matrix3d scale = Eigen::Matrix3d::Identity();
  if (j.contains("scale")) {
    if (j["scale"].is_array()) {
      const Eigen::Vector3d s = vec3(j["scale"], w["scale"]);
      if (!(s.array() > 0.0).all()) w["scale"].fail("expected positive scale factors", j["scale"]);
      scale = s.asDiagonal();
    } else {
      scale *= positive(j["scale"], w["scale"]);
    }
  }
  Eigen::Matrix3d rotate = Eigen::Matrix3d::Identity();
  if (j.contains("rotate_deg")) rotate = rotation_xyz_degrees(vec3(j["rotate_deg"], w["rotate_deg"]));
  body.linear = rotate * scale;
  if (j.contains("translate")) body.translate = vec3(j["translate"], w["translate"]);
  if (j.contains("velocity")) body.velocity = vec3(j["velocity"], w["velocity"]);
  if (j.contains("array")) {
    const json& a = j["array"];
    const Where wa = w["array"];
    check_keys(a, wa, {"count", "spacing"});
    if (!a.contains("count")) wa.fail("missing key \"count\"");
    const json& count = a["count"];
    if (!count.is_array() || count.size() != 3) wa["count"].fail("expected 3 positive integers", count);
    for (int d = 0; d < 3; ++d) body.count[d] = integer(count[d], wa["count"][d], 1);
    if (body.count[0] * body.count[1] * body.count[2] > 1000000)
      wa["count"].fail("more than 1,000,000 copies", count);
    if (a.contains("spacing")) body.spacing = vec3(a["spacing"], wa["spacing"]);
  }
  return body;
}

// Appends one transformed copy of a body to the model and the initial state.
void append_body(const BodySpec& spec, const Eigen::Vector3d& offset, int32_t scene_entry,
                 Model& model, State& state) {
  const TetMesh& mesh = *spec.mesh;
  const SurfaceMesh& surface = *spec.surface;
  BodyRange range;
  range.vertex_begin = model.num_vertices;
  range.vertex_count = mesh.num_vertices();
  range.tet_begin = model.num_tets;
  range.tet_count = mesh.num_tets();
  range.triangle_begin = static_cast<int32_t>(model.surface_triangles.size() / 3);
  range.triangle_count = static_cast<int32_t>(surface.triangles.size() / 3);
  range.edge_begin = static_cast<int32_t>(model.surface_edges.size() / 2);
  range.edge_count = static_cast<int32_t>(surface.edges.size() / 2);
  range.scene_entry = scene_entry;
  const int32_t body_id = static_cast<int32_t>(model.bodies.size());
  const int32_t base = range.vertex_begin;

  for (int32_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d p = spec.linear * Eigen::Vector3d::Map(&mesh.positions[3 * v]) +
                              spec.translate + offset;
    for (int d = 0; d < 3; ++d) {
      model.rest_positions.push_back(p[d]);
      state.v.push_back(spec.velocity[d]);
    }
    model.mass.push_back(0.0);
    model.vertex_body.push_back(body_id);
    model.dirichlet.push_back(-1);
  }
  const double density = model.materials[spec.material].density;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) {
    int32_t ids[4];
    for (int c = 0; c < 4; ++c) ids[c] = base + mesh.tets[4 * t + c];
    Eigen::Matrix3d Dm;
    const Eigen::Vector3d x0 = Eigen::Vector3d::Map(&model.rest_positions[3 * ids[0]]);
    for (int c = 0; c < 3; ++c)
      Dm.col(c) = Eigen::Vector3d::Map(&model.rest_positions[3 * ids[c + 1]]) - x0;
    const double volume = Dm.determinant() / 6.0;
    const Eigen::Matrix3d inv = Dm.inverse();
    for (int c = 0; c < 4; ++c) {
      model.tets.push_back(ids[c]);
      model.mass[ids[c]] += density * volume / 4.0;
    }
    model.Dm_inv.insert(model.Dm_inv.end(), inv.data(), inv.data() + 9);
    model.rest_volume.push_back(volume);
    model.tet_material.push_back(spec.material);
  }
  for (int32_t i : surface.triangles) model.surface_triangles.push_back(base + i);
  for (int32_t i : surface.edges) model.surface_edges.push_back(base + i);
  for (int32_t i : surface.vertices) model.surface_vertices.push_back(base + i);

  if (!model.material_batches.empty() && model.material_batches.back().material == spec.material)
    model.material_batches.back().tet_end += range.tet_count;
  else
    model.material_batches.push_back({range.tet_begin, range.tet_begin + range.tet_count, spec.material});
  model.num_vertices += range.vertex_count;
  model.num_tets += range.tet_count;
  model.bodies.push_back(range);
}

void read_boundary(const json& j, const Where& w, Model& model, int64_t num_scene_bodies) {
  check_keys(j, w, {"body", "box_min", "box_max", "fix", "velocity", "angular_velocity", "axis", "center"});
  if (!j.contains("box_min") || !j.contains("box_max")) w.fail("needs \"box_min\" and \"box_max\"");
  const Eigen::Vector3d lo = vec3(j["box_min"], w["box_min"]);
  const Eigen::Vector3d hi = vec3(j["box_max"], w["box_max"]);
  if (!(lo.array() <= hi.array()).all()) w["box_max"].fail("box_max must be >= box_min in x, y and z", j["box_max"]);
  std::optional<int64_t> only_entry;
  if (j.contains("body")) {
    only_entry = integer(j["body"], w["body"], 0);
    if (*only_entry >= num_scene_bodies)
      w["body"].fail("no such body (the scene has " + std::to_string(num_scene_bodies) + ")", j["body"]);
  }
  DirichletMotion motion;
  const bool fix = j.contains("fix");
  if (fix && !boolean(j["fix"], w["fix"])) w["fix"].fail("\"fix\" can only be true; leave it out for a moving boundary");
  if (fix && (j.contains("velocity") || j.contains("angular_velocity")))
    w.fail("\"fix\" cannot be combined with \"velocity\" or \"angular_velocity\"");
  if (!fix && !j.contains("velocity") && !j.contains("angular_velocity"))
    w.fail("give \"fix\": true, a \"velocity\" or an \"angular_velocity\"");
  if (j.contains("velocity")) motion.velocity = vec3(j["velocity"], w["velocity"]);
  if (j.contains("angular_velocity")) {
    motion.angular_velocity = number(j["angular_velocity"], w["angular_velocity"]);
    if (!j.contains("axis")) w.fail("\"angular_velocity\" needs an \"axis\"");
  }
  if (j.contains("axis")) {
    const Eigen::Vector3d axis = vec3(j["axis"], w["axis"]);
    if (axis.norm() == 0.0) w["axis"].fail("the axis must not be zero", j["axis"]);
    motion.axis = axis.normalized();
  }
  if (j.contains("center")) motion.center = vec3(j["center"], w["center"]);
  else motion.center = 0.5 * (lo + hi);

  const int32_t id = static_cast<int32_t>(model.dirichlet_motions.size());
  int64_t selected = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    if (only_entry && model.bodies[model.vertex_body[v]].scene_entry != *only_entry) continue;
    const Eigen::Vector3d p = Eigen::Vector3d::Map(&model.rest_positions[3 * v]);
    if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) {
      if (model.dirichlet[v] >= 0 && model.dirichlet[v] != id)
        w.fail("selects vertex " + std::to_string(v) + " already held by boundary[" +
               std::to_string(model.dirichlet[v]) + "]");
      model.dirichlet[v] = id;
      ++selected;
    }
  }
  if (selected == 0) w.fail("the box selects no vertex");
  model.dirichlet_motions.push_back(motion);
}

}  // namespace

Scene load_scene(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw SceneError(file.string() + ": cannot open the scene file");
  json root;
  try {
    root = json::parse(in);
  } catch (const json::parse_error& e) {
    throw SceneError(file.string() + ": not valid JSON: " + e.what());
  }
  const Where w(file, "");
  check_keys(root, w, {"name", "gravity", "time", "solver", "contact", "materials", "bodies",
                       "obstacles", "boundary", "joints", "output"});
  Scene scene;
  scene.file = file;
  scene.name = root.contains("name") ? string(root["name"], w["name"]) : file.stem().string();
  if (scene.name.empty() || scene.name.find('/') != std::string::npos)
    w["name"].fail("expected a non-empty name without '/'", root["name"]);
  if (root.contains("gravity")) scene.model.gravity = vec3(root["gravity"], w["gravity"]);
  if (root.contains("time")) read_time(root["time"], w["time"], scene.time);
  if (root.contains("solver")) read_solver(root["solver"], w["solver"], scene.solver);
  if (root.contains("contact")) read_contact(root["contact"], w["contact"], scene.contact);
  if (root.contains("output")) read_output(root["output"], w["output"], scene.output);
  if (scene.contact.enabled)
    w["contact"]["enabled"].fail("contact is not available in this version of the engine yet");
  for (const char* later : {"obstacles", "joints"})
    if (root.contains(later) && !(root[later].is_array() && root[later].empty()))
      w[later].fail("not available in this version of the engine yet");

  // Materials.
  if (!root.contains("materials")) w.fail("missing key \"materials\"");
  const json& materials = root["materials"];
  if (!materials.is_object() || materials.empty()) w["materials"].fail("expected a non-empty object of named materials");
  std::map<std::string, int32_t> material_ids;
  for (const auto& item : materials.items()) {
    material_ids[item.key()] = static_cast<int32_t>(scene.model.materials.size());
    scene.model.materials.push_back(read_material(item.key(), item.value(), w["materials"][item.key()]));
  }

  // Bodies.
  if (!root.contains("bodies")) w.fail("missing key \"bodies\"");
  const json& bodies = root["bodies"];
  if (!bodies.is_array() || bodies.empty()) w["bodies"].fail("expected a non-empty array of bodies");
  MeshCache cache;
  const fs::path scene_dir = file.parent_path();
  for (size_t b = 0; b < bodies.size(); ++b) {
    const BodySpec spec = read_body(bodies[b], w["bodies"][b], scene_dir, material_ids, cache);
    for (int64_t i = 0; i < spec.count[0]; ++i)
      for (int64_t k = 0; k < spec.count[1]; ++k)
        for (int64_t l = 0; l < spec.count[2]; ++l) {
          const Eigen::Vector3d offset(i * spec.spacing.x(), k * spec.spacing.y(), l * spec.spacing.z());
          if (int64_t{scene.model.num_vertices} + spec.mesh->num_vertices() > (int64_t{1} << 30))
            w["bodies"][b].fail("the scene exceeds 2^30 vertices");
          append_body(spec, offset, static_cast<int32_t>(b), scene.model, scene.initial);
        }
  }

  // Boundary conditions.
  if (root.contains("boundary")) {
    const json& boundary = root["boundary"];
    if (!boundary.is_array()) w["boundary"].fail("expected an array", boundary);
    for (size_t i = 0; i < boundary.size(); ++i)
      read_boundary(boundary[i], w["boundary"][i], scene.model, static_cast<int64_t>(bodies.size()));
  }

  scene.initial.x = scene.model.rest_positions;
  scene.initial.a.assign(scene.initial.x.size(), 0.0);
  scene.initial.x_tilde = scene.initial.x;
  return scene;
}

}  // namespace nexdyn

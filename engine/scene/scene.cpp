// Scene loading: JSON -> validated settings -> flat Model buffers and the initial State.
//
// The reader walks the document with a key path ("bodies[1].box.cells") so that every error
// names the file, the key and the value. Bodies are appended to the shared buffers as ranges;
// a mesh file used by several bodies (or an "array") is read once. Obstacle meshes (.obj
// triangles or the boundary of a .msh) are appended after all bodies as bodies without tets:
// mass 0, every vertex on one shared fixed Dirichlet motion (model.hpp); obstacle planes go to
// Model::obstacle_planes.
#include "engine/scene/scene.hpp"

#include "engine/contact/start_check.hpp"
#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/obj_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/tet_mesh.hpp"
#include "kernels/distance/point_triangle_distance.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>

namespace nexdyn {

namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// ---- messages ----------------------------------------------------------------------------------
// Every message is one line a user can read, whatever the file holds: values are shown cut to
// about kShownChars characters (a megabyte string or a 100,000-deep array would otherwise be
// dumped whole, recursively), and control characters from keys, names or paths become '?'.

constexpr size_t kShownChars = 60;
constexpr size_t kMaxMessageChars = 1000;

void show_into(const json& value, std::string& out) {
  if (out.size() > kShownChars) return;
  if (value.is_array()) {
    out += '[';
    for (size_t i = 0; i < value.size() && out.size() <= kShownChars; ++i) {
      if (i > 0) out += ',';
      show_into(value[i], out);  // each level adds a '[': the budget bounds the depth
    }
    out += ']';
  } else if (value.is_object()) {
    out += '{';
    bool first = true;
    for (const auto& item : value.items()) {
      if (out.size() > kShownChars) break;
      if (!first) out += ',';
      first = false;
      out += json(item.key()).dump() + ':';
      show_into(item.value(), out);
    }
    out += '}';
  } else {
    out += value.dump();
  }
}

// `value` as JSON text, at most about kShownChars characters ("..." marks a cut).
std::string show(const json& value) {
  std::string out;
  show_into(value, out);
  if (out.size() > kShownChars) out = out.substr(0, kShownChars) + "...";
  return out;
}

// The whole message on one line and of a bounded length.
std::string one_line(std::string message) {
  for (char& c : message)
    if (static_cast<unsigned char>(c) < 32 || c == 127) c = '?';
  if (message.size() > kMaxMessageChars) message = message.substr(0, kMaxMessageChars) + "...";
  return message;
}

// A key of the file as it appears in a key path: short keys as they are, others shown as JSON.
std::string key_text(const std::string& key) {
  bool plain = key.size() <= 40;
  for (char c : key) plain = plain && static_cast<unsigned char>(c) >= 32 && c != 127 && c != '"';
  return plain ? key : show(json(key));
}

// Where in the file a value sits, for error messages.
class Where {
 public:
  Where(const fs::path& file, std::string path) : file_(file), path_(std::move(path)) {}
  Where operator[](const std::string& key) const {
    return Where(file_, path_.empty() ? key_text(key) : path_ + "." + key_text(key));
  }
  Where operator[](size_t index) const {
    return Where(file_, path_ + "[" + std::to_string(index) + "]");
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw SceneError(one_line(file_.string() + ": " + (path_.empty() ? "" : path_ + ": ") + what));
  }
  [[noreturn]] void fail(const std::string& what, const json& value) const {
    fail(what + ", got " + show(value));
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
  // Above INT64_MAX nlohmann keeps an unsigned number, which get<int64_t> would wrap negative.
  if (value.is_number_unsigned() && value.get<uint64_t>() > uint64_t(std::numeric_limits<int64_t>::max()))
    where.fail("expected an integer below 2^63", value);
  const int64_t i = value.get<int64_t>();
  if (i < min_value) where.fail("expected an integer >= " + std::to_string(min_value), value);
  return i;
}

// An integer stored in an int: bounded before the cast, so that 2^32 + 1 cannot become 1.
int bounded_int(const json& value, const Where& where, int min_value, int max_value) {
  const int64_t i = integer(value, where, min_value);
  if (i > max_value)
    where.fail("expected an integer from " + std::to_string(min_value) + " to " + std::to_string(max_value), value);
  return static_cast<int>(i);
}

Eigen::Vector3d vec3(const json& value, const Where& where) {
  if (!value.is_array() || value.size() != 3) where.fail("expected an array of 3 numbers", value);
  return {number(value[0], where[0]), number(value[1], where[1]), number(value[2], where[2])};
}

std::string string(const json& value, const Where& where) {
  if (!value.is_string()) where.fail("expected a string", value);
  return value.get<std::string>();
}

double non_negative(const json& value, const Where& where) {
  const double x = number(value, where);
  if (x < 0.0) where.fail("expected a number >= 0", value);
  return x;
}

// Static friction below kinetic friction is not a physical surface.
void check_static_friction(double mu_s, double mu_k, const Where& where) {
  if (mu_s < mu_k)
    where.fail("static friction must be at least the kinetic \"friction\" " + show(json(mu_k)), json(mu_s));
}

bool boolean(const json& value, const Where& where) {
  if (!value.is_boolean()) where.fail("expected true or false", value);
  return value.get<bool>();
}

// ---- settings ----------------------------------------------------------------------------------

void read_time(const json& j, const Where& w, TimeSettings& time) {
  check_keys(j, w, {"dt", "steps", "integrator", "rho_inf", "alpha", "beta", "gamma", "alpha_m", "alpha_f",
                    "initial_acceleration", "energy_guard"});
  if (j.contains("energy_guard")) time.energy_guard = boolean(j["energy_guard"], w["energy_guard"]);
  if (j.contains("dt")) time.dt = positive(j["dt"], w["dt"]);
  if (j.contains("steps")) time.steps = integer(j["steps"], w["steps"], 1);
  if (j.contains("integrator")) {
    const std::string name = string(j["integrator"], w["integrator"]);
    const auto preset = integrator_preset(name);
    if (!preset) {
      std::string list;
      for (const std::string& n : integrator_preset_names()) list += (list.empty() ? "" : ", ") + n;
      w["integrator"].fail("unknown integrator " + show(json(name)) + " (known: " + list + ")");
    }
    time.integrator = *preset;
  }
  if (j.contains("rho_inf")) {
    if (time.integrator.name != "generalized_alpha")
      w["rho_inf"].fail("rho_inf belongs to \"integrator\": \"generalized_alpha\", not " +
                        show(json(time.integrator.name)), j["rho_inf"]);
    const double rho = number(j["rho_inf"], w["rho_inf"]);
    if (!(rho >= 0.0 && rho <= 1.0)) w["rho_inf"].fail("expected 0 <= rho_inf <= 1", j["rho_inf"]);
    time.integrator = generalized_alpha(rho);
  }
  const bool weights = j.contains("alpha_m") || j.contains("alpha_f");
  const bool custom = weights || j.contains("alpha") || j.contains("beta") || j.contains("gamma");
  if (custom) {
    // Custom parameters start from the named scheme; without one, from the plain family's
    // reference, newmark (not from the default, whose generalized-alpha weights would stay).
    if (!j.contains("integrator") && !j.contains("rho_inf")) time.integrator = *integrator_preset("newmark");
    IntegratorParams& p = time.integrator;
    if (p.is_static) w.fail("alpha, beta, gamma, alpha_m and alpha_f cannot be combined with \"static\"");
    if (weights) {
      // Generalized-alpha weights: beta and gamma follow them (second order, the most
      // high-frequency damping for the weights) unless given as well.
      if (j.contains("alpha_m")) p.alpha_m = number(j["alpha_m"], w["alpha_m"]);
      if (j.contains("alpha_f")) p.alpha_f = number(j["alpha_f"], w["alpha_f"]);
      if (!(p.alpha_f >= 0.0 && p.alpha_f <= 0.5))
        w["alpha_f"].fail("expected 0 <= alpha_f <= 0.5", j.value("alpha_f", json(p.alpha_f)));
      if (!(p.alpha_m >= -1.0 && p.alpha_m <= p.alpha_f))
        w["alpha_m"].fail("expected -1 <= alpha_m <= alpha_f (" + show(json(p.alpha_f)) + ")",
                          j.value("alpha_m", json(p.alpha_m)));
      p = generalized_alpha_weights(p.alpha_m, p.alpha_f);
    }
    if (j.contains("alpha")) p.alpha = positive(j["alpha"], w["alpha"]);
    if (j.contains("beta")) p.beta = number(j["beta"], w["beta"]);
    if (j.contains("gamma")) p.gamma = number(j["gamma"], w["gamma"]);
    if (p.beta < 0.0 || p.beta > 0.5)
      w["beta"].fail("expected 0 <= beta <= 0.5", j.value("beta", json(p.beta)));
    if (p.gamma < 0.0 || p.gamma > 1.0)
      w["gamma"].fail("expected 0 <= gamma <= 1", j.value("gamma", json(p.gamma)));
    if ((p.alpha_m != 0.0 || p.alpha_f != 0.0) && p.is_explicit())
      w["beta"].fail("generalized-alpha weights need an implicit scheme (beta > 0)", json(p.beta));
    p.name = "custom";
  }
  if (j.contains("initial_acceleration")) {
    const std::string mode = string(j["initial_acceleration"], w["initial_acceleration"]);
    if (mode == "consistent") time.consistent_initial_acceleration = true;
    else if (mode == "zero") time.consistent_initial_acceleration = false;
    else w["initial_acceleration"].fail("expected \"consistent\" or \"zero\"", j["initial_acceleration"]);
  }
}

void read_solver(const json& j, const Where& w, SolverSettings& solver) {
  check_keys(j, w, {"tolerance", "max_iterations", "joint_tolerance", "substep_halvings"});
  if (j.contains("substep_halvings")) {
    // Bounded before the cast to int: 2^32 must not wrap to 0.
    const int64_t halvings = integer(j["substep_halvings"], w["substep_halvings"], 0);
    if (halvings > kMaxSubstepHalvings)
      w["substep_halvings"].fail("expected at most " + std::to_string(kMaxSubstepHalvings) + " (dt / 65536)",
                                 j["substep_halvings"]);
    solver.substep_halvings = static_cast<int>(halvings);
  }
  if (j.contains("tolerance")) solver.tolerance = positive(j["tolerance"], w["tolerance"]);
  if (j.contains("joint_tolerance")) solver.joint_tolerance = positive(j["joint_tolerance"], w["joint_tolerance"]);
  if (j.contains("max_iterations"))
    solver.max_iterations = bounded_int(j["max_iterations"], w["max_iterations"], 1, std::numeric_limits<int>::max());
}

// A "contact" object switches contact on ("contact": {} is enough); "enabled": false keeps the
// settings in the file but turns contact off.
void read_contact(const json& j, const Where& w, ContactSettings& contact) {
  check_keys(j, w, {"enabled", "dhat", "friction", "static_friction", "friction_pairs", "epsv",
                    "friction_iterations"});
  contact.enabled = j.contains("enabled") ? boolean(j["enabled"], w["enabled"]) : true;
  if (j.contains("dhat")) contact.dhat = positive(j["dhat"], w["dhat"]);
  if (j.contains("friction")) contact.friction = non_negative(j["friction"], w["friction"]);
  if (j.contains("static_friction")) {
    contact.static_friction = non_negative(j["static_friction"], w["static_friction"]);
    check_static_friction(contact.static_friction, contact.friction, w["static_friction"]);
  }
  if (j.contains("epsv")) contact.epsv = positive(j["epsv"], w["epsv"]);
  if (j.contains("friction_iterations")) {
    const json& value = j["friction_iterations"];
    if (value.is_string() && value.get<std::string>() == "converged") contact.friction_iterations = -1;
    else if (value.is_number_integer()) contact.friction_iterations = bounded_int(value, w["friction_iterations"], 1, std::numeric_limits<int>::max());
    else w["friction_iterations"].fail("expected an integer >= 1 or \"converged\"", value);
  }
  // "friction_pairs" names materials: read by read_friction_pairs once they are known.
}

// A material name of the scene's "materials".
int32_t material_id(const json& value, const Where& w, const std::map<std::string, int32_t>& material_ids) {
  const std::string name = string(value, w);
  const auto found = material_ids.find(name);
  if (found == material_ids.end()) w.fail("no material named " + show(json(name)) + " in \"materials\"");
  return found->second;
}

// "friction_pairs": [{ "materials": [a, b], "friction": mu_k, "static_friction": mu_s }, ...].
void read_friction_pairs(const json& j, const Where& w, const std::map<std::string, int32_t>& material_ids,
                         ContactSettings& contact) {
  if (!j.is_array()) w.fail("expected an array", j);
  std::set<std::pair<int32_t, int32_t>> given;  // a set: a long list must not take quadratic time
  for (size_t i = 0; i < j.size(); ++i) {
    const json& entry = j[i];
    const Where we = w[i];
    if (!entry.is_object()) we.fail("expected an object", entry);
    check_keys(entry, we, {"materials", "friction", "static_friction"});
    if (!entry.contains("materials") || !entry.contains("friction")) we.fail("needs \"materials\" and \"friction\"");
    const json& names = entry["materials"];
    if (!names.is_array() || names.size() != 2) we["materials"].fail("expected two material names", names);
    ContactSettings::FrictionPair pair;
    pair.a = material_id(names[0], we["materials"][0], material_ids);
    pair.b = material_id(names[1], we["materials"][1], material_ids);
    if (pair.a > pair.b) std::swap(pair.a, pair.b);
    pair.friction = non_negative(entry["friction"], we["friction"]);
    pair.static_friction = pair.friction;
    if (entry.contains("static_friction")) {
      pair.static_friction = non_negative(entry["static_friction"], we["static_friction"]);
      check_static_friction(pair.static_friction, pair.friction, we["static_friction"]);
    }
    if (!given.insert({pair.a, pair.b}).second) we["materials"].fail("this pair of materials is already given", names);
    contact.friction_pairs.push_back(pair);
  }
}

void read_output(const json& j, const Where& w, OutputSettings& output) {
  check_keys(j, w, {"every", "formats", "checkpoint_every"});
  if (j.contains("every")) output.every = integer(j["every"], w["every"], 1);
  if (j.contains("checkpoint_every"))
    output.checkpoint_every = integer(j["checkpoint_every"], w["checkpoint_every"], 0);
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
  if (!parsed) w["model"].fail("unknown material model " + show(json(model)) +
                               " (known: linear, stvk, corotated, neohookean)");
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

// The placement of a mesh: scale, then rotate (degrees about x, then y, then z), then translate,
// all about the mesh's own origin. Bodies and obstacle meshes share it so that the two kinds of
// entry cannot drift apart in meaning.
struct Transform {
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();  // rotate * scale
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();   // [m]
};

Transform read_transform(const json& j, const Where& w) {
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
  Transform t;
  t.linear = rotate * scale;
  if (j.contains("translate")) t.translate = vec3(j["translate"], w["translate"]);
  return t;
}

// Fails at `w` when adding `vertices` and `tets` to the model would pass the scene's limits;
// `what` says what is being added ("1000000 copies of a 4-vertex, 1-tet body").
void check_size(const Model& model, int64_t vertices, int64_t tets, const SceneLimits& limits,
                const std::string& what, const Where& w) {
  const int64_t total_vertices = model.num_vertices + vertices;
  const int64_t total_tets = model.num_tets + tets;
  if (total_vertices > limits.max_vertices)
    w.fail(what + " would give the scene " + std::to_string(total_vertices) +
           " vertices, more than the limit of " + std::to_string(limits.max_vertices));
  if (total_tets > limits.max_tets)
    w.fail(what + " would give the scene " + std::to_string(total_tets) + " tets, more than the limit of " +
           std::to_string(limits.max_tets));
}

// Reads one "bodies" entry; its mesh is read or built (once per file or box), after checking
// that the body and all its copies fit in the scene's limits next to what `model` already holds.
BodySpec read_body(const json& j, const Where& w, const fs::path& scene_dir,
                   const std::map<std::string, int32_t>& material_ids, MeshCache& cache,
                   const Model& model, const SceneLimits& limits) {
  check_keys(j, w, {"mesh", "box", "material", "translate", "rotate_deg", "scale", "velocity", "array"});
  BodySpec body;
  if (j.contains("mesh") == j.contains("box")) w.fail("give exactly one of \"mesh\" and \"box\"");
  std::string key;
  if (j.contains("mesh")) {
    const std::string rel = string(j["mesh"], w["mesh"]);
    const fs::path path = scene_dir / rel;
    key = "mesh:" + path.lexically_normal().string();
    if (!cache.entries.count(key)) {
      std::error_code error;  // the throwing fs::exists would escape with its own message
      if (!fs::exists(path, error)) w["mesh"].fail("mesh file not found: " + path.string());
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
      const int64_t vertices = int64_t{n[0] + 1} * (n[1] + 1) * (n[2] + 1);
      const int64_t tets = kTetsPerBoxCell * int64_t{n[0]} * n[1] * n[2];
      check_size(model, vertices, tets, limits,
                 "a box of " + show(cells) + " cells (" + std::to_string(vertices) + " vertices, " +
                     std::to_string(tets) + " tets)",
                 wb["cells"]);
      TetMesh mesh = make_box_mesh(size, n);
      SurfaceMesh surface = extract_surface(mesh);
      cache.entries.emplace(key, std::make_pair(std::move(mesh), std::move(surface)));
    }
  }
  body.mesh = &cache.entries.at(key).first;
  body.surface = &cache.entries.at(key).second;

  if (!j.contains("material")) w.fail("missing key \"material\"");
  body.material = material_id(j["material"], w["material"], material_ids);

  const Transform transform = read_transform(j, w);
  body.linear = transform.linear;
  body.translate = transform.translate;
  if (j.contains("velocity")) body.velocity = vec3(j["velocity"], w["velocity"]);
  if (j.contains("array")) {
    const json& a = j["array"];
    const Where wa = w["array"];
    check_keys(a, wa, {"count", "spacing"});
    if (!a.contains("count")) wa.fail("missing key \"count\"");
    const json& count = a["count"];
    if (!count.is_array() || count.size() != 3) wa["count"].fail("expected 3 positive integers", count);
    for (int d = 0; d < 3; ++d) {
      body.count[d] = integer(count[d], wa["count"][d], 1);
      if (body.count[d] > 1000000) wa["count"].fail("more than 1,000,000 copies", count);
    }
    // Each factor is at most 10^6 now, so the product cannot overflow.
    if (body.count[0] * body.count[1] * body.count[2] > 1000000)
      wa["count"].fail("more than 1,000,000 copies", count);
    if (a.contains("spacing")) body.spacing = vec3(a["spacing"], wa["spacing"]);
  }
  const int64_t copies = body.count[0] * body.count[1] * body.count[2];
  check_size(model, copies * body.mesh->num_vertices(), copies * body.mesh->num_tets(), limits,
             std::to_string(copies) + (copies == 1 ? " copy" : " copies") + " of a " +
                 std::to_string(body.mesh->num_vertices()) + "-vertex, " + std::to_string(body.mesh->num_tets()) +
                 "-tet body",
             j.contains("array") ? w["array"]["count"] : w);
  return body;
}

// Appends one transformed copy of a body to the model and the initial state. Returns what is
// wrong with the copy, empty when nothing is: a transform can overflow a position to infinity
// (translate 1e308 plus an array spacing) or flatten tets that were fine in the mesh's own frame
// (scale [1, 1, 1e-300]), and the elastic kernels need finite rest positions and invertible Dm.
std::string append_body(const BodySpec& spec, const Eigen::Vector3d& offset, int32_t scene_entry,
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
  range.material = spec.material;
  const int32_t body_id = static_cast<int32_t>(model.bodies.size());
  const int32_t base = range.vertex_begin;

  for (int32_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d p = spec.linear * Eigen::Vector3d::Map(&mesh.positions[3 * v]) +
                              spec.translate + offset;
    if (!p.allFinite())
      return "vertex " + std::to_string(v) + " of the mesh is not finite once placed (translate, scale "
             "or array spacing too large)";
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
    const double longest = std::max({Dm.col(0).norm(), Dm.col(1).norm(), Dm.col(2).norm(),
                                     (Dm.col(1) - Dm.col(0)).norm(), (Dm.col(2) - Dm.col(0)).norm(),
                                     (Dm.col(2) - Dm.col(1)).norm()});
    if (!(volume > kDegenerateTetRelativeVolume * longest * longest * longest) || !inv.allFinite())
      return "tet " + std::to_string(t) + " of the mesh is degenerate once placed (volume " + show(json(volume)) +
             "): size or scale too small or too uneven, or translate too large for its size";
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
  return "";
}

// The rigid motion keys of a "boundary" or moving obstacle entry: "velocity", "angular_velocity"
// with "axis", and "center" (default `center`).
DirichletMotion read_motion(const json& j, const Where& w, const Eigen::Vector3d& center) {
  DirichletMotion motion;
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
  motion.center = j.contains("center") ? vec3(j["center"], w["center"]) : center;
  return motion;
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
  const bool fix = j.contains("fix");
  if (fix && !boolean(j["fix"], w["fix"])) w["fix"].fail("\"fix\" can only be true; leave it out for a moving boundary");
  if (fix && (j.contains("velocity") || j.contains("angular_velocity")))
    w.fail("\"fix\" cannot be combined with \"velocity\" or \"angular_velocity\"");
  if (!fix && !j.contains("velocity") && !j.contains("angular_velocity"))
    w.fail("give \"fix\": true, a \"velocity\" or an \"angular_velocity\"");
  const DirichletMotion motion = read_motion(j, w, 0.5 * (lo + hi));

  const int32_t id = static_cast<int32_t>(model.dirichlet_motions.size());
  int64_t selected = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    const BodyRange& body = model.bodies[model.vertex_body[v]];
    // Obstacle vertices already follow their own fixed motion, and an obstacle's scene_entry
    // counts "obstacles" entries, not "bodies" entries, so "body" must never match it.
    if (body.obstacle) continue;
    if (only_entry && body.scene_entry != *only_entry) continue;
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

// ---- joints ------------------------------------------------------------------------------------

// The tet of body `b` nearest to `point` (distance 0 when inside; the lowest index on ties) and
// the point's barycentric weights in it, extrapolated when it lies outside.
void attach_to_body(const Model& model, const BodyRange& body, const Eigen::Vector3d& point,
                    int32_t (&vertex)[4], double (&weight)[4]) {
  auto X = [&](int32_t v) { return Eigen::Vector3d::Map(&model.rest_positions[3 * int64_t{v}]); };
  double best = std::numeric_limits<double>::infinity();
  int32_t best_tet = body.tet_begin;
  for (int32_t t = body.tet_begin; t < body.tet_begin + body.tet_count && best > 0.0; ++t) {
    const int32_t* c = &model.tets[4 * int64_t{t}];
    // Inside: every face sees the point on its inner side; else the nearest face's distance.
    double d = 0.0;
    bool inside = true;
    constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
    double nearest_face = std::numeric_limits<double>::infinity();
    for (const auto& f : kFace) {
      const Eigen::Vector3d a = X(c[f[0]]), b = X(c[f[1]]), e = X(c[f[2]]);
      inside = inside && (b - a).cross(e - a).dot(point - a) <= 0.0;
      nearest_face = std::min(nearest_face, point_triangle_distance(point, a, b, e));
    }
    if (!inside) d = nearest_face;
    if (d < best) {
      best = d;
      best_tet = t;
    }
  }
  const int32_t* c = &model.tets[4 * int64_t{best_tet}];
  Eigen::Matrix3d edges;
  edges << X(c[1]) - X(c[0]), X(c[2]) - X(c[0]), X(c[3]) - X(c[0]);
  const Eigen::Vector3d l = edges.inverse() * (point - X(c[0]));
  weight[0] = 1.0 - l.sum();
  for (int k = 0; k < 3; ++k) weight[k + 1] = l[k];
  for (int k = 0; k < 4; ++k) vertex[k] = c[k];
}

// The one body made from "bodies" entry `entry` (an "array" entry makes several: ambiguous).
const BodyRange& joint_body(const json& value, const Where& w, const Model& model,
                            int64_t num_scene_bodies) {
  const int64_t entry = integer(value, w, 0);
  if (entry >= num_scene_bodies)
    w.fail("no such body (the scene has " + std::to_string(num_scene_bodies) + ")", value);
  const BodyRange* found = nullptr;
  for (const BodyRange& body : model.bodies) {
    if (body.obstacle || body.scene_entry != entry) continue;
    if (found) w.fail("body " + std::to_string(entry) + " is an \"array\" of several bodies; a joint needs one", value);
    found = &body;
  }
  return *found;
}

void read_joint(const json& j, const Where& w, int32_t scene_entry, Model& model,
                int64_t num_scene_bodies) {
  check_keys(j, w, {"type", "body", "bodies", "point"});
  if (!j.contains("type")) w.fail("missing key \"type\" (\"pin\" or \"ball\")");
  if (!j.contains("point")) w.fail("missing key \"point\"");
  const std::string type = string(j["type"], w["type"]);
  const Eigen::Vector3d point = vec3(j["point"], w["point"]);
  Joint joint;
  joint.scene_entry = scene_entry;
  if (type == "pin") {
    if (!j.contains("body") || j.contains("bodies")) w.fail("a pin takes \"body\" (one index), not \"bodies\"");
    joint.type = JointType::pin;
    joint.count = 4;
    int32_t v[4];
    double weight[4];
    attach_to_body(model, joint_body(j["body"], w["body"], model, num_scene_bodies), point, v, weight);
    for (int k = 0; k < 4; ++k) {
      joint.vertex[k] = v[k];
      joint.coefficient[k] = weight[k];
    }
    joint.offset = -point;
  } else if (type == "ball") {
    if (!j.contains("bodies") || j.contains("body")) w.fail("a ball joint takes \"bodies\" (two indices), not \"body\"");
    const json& pair = j["bodies"];
    if (!pair.is_array() || pair.size() != 2) w["bodies"].fail("expected two body indices", pair);
    const BodyRange& a = joint_body(pair[0], w["bodies"][0], model, num_scene_bodies);
    const BodyRange& b = joint_body(pair[1], w["bodies"][1], model, num_scene_bodies);
    if (&a == &b) w["bodies"].fail("a ball joint needs two different bodies", pair);
    joint.type = JointType::ball;
    joint.count = 8;
    for (int side = 0; side < 2; ++side) {
      int32_t v[4];
      double weight[4];
      attach_to_body(model, side == 0 ? a : b, point, v, weight);
      for (int k = 0; k < 4; ++k) {
        joint.vertex[4 * side + k] = v[k];
        joint.coefficient[4 * side + k] = side == 0 ? weight[k] : -weight[k];
      }
    }
  } else {
    w["type"].fail("expected \"pin\" or \"ball\"", j["type"]);
  }
  model.joints.push_back(joint);
}

// ---- obstacles ---------------------------------------------------------------------------------

// A static obstacle mesh in its own frame: a triangle surface with no volume. Only vertices used
// by a triangle are kept (a .msh obstacle loses its interior nodes, an .obj its stray "v" lines),
// so that every obstacle vertex is a surface vertex.
struct ObstacleMesh {
  std::vector<double> positions;   // (num_vertices x 3) [m], in the file's frame
  std::vector<int32_t> triangles;  // (num_triangles x 3) local vertex ids, winding of the file
  std::vector<int32_t> edges;      // (num_edges x 2) unique edges of the triangles, a < b, sorted
};

ObstacleMesh obstacle_from_obj(ObjMesh&& obj) {
  ObstacleMesh mesh;
  mesh.positions = std::move(obj.positions);
  mesh.triangles = std::move(obj.triangles);
  return mesh;
}

// The boundary surface of a tet mesh as an obstacle: read_msh, then extract_surface.
ObstacleMesh read_msh_surface(const fs::path& path) {
  const TetMesh tets = read_msh(path);
  const SurfaceMesh surface = extract_surface(tets);
  ObstacleMesh mesh;
  mesh.positions = tets.positions;
  mesh.triangles = surface.triangles;
  for (int32_t t = 0; t < surface.num_triangles(); ++t) {
    auto p = [&](int c) { return Eigen::Vector3d::Map(&mesh.positions[3 * size_t(surface.triangles[3 * t + c])]); };
    if (is_degenerate_triangle(p(0), p(1), p(2)))
      throw SceneError(path.string() + ": boundary triangle " + std::to_string(t) + " is degenerate (zero area)");
  }
  return mesh;
}

// Drops the vertices no triangle uses (keeping the others in file order) and lists the edges.
void compact_and_find_edges(ObstacleMesh& mesh) {
  const size_t n = mesh.positions.size() / 3;
  std::vector<int32_t> new_id(n, -1);
  for (int32_t v : mesh.triangles) new_id[v] = 0;
  std::vector<double> kept;
  int32_t next = 0;
  for (size_t v = 0; v < n; ++v) {
    if (new_id[v] < 0) continue;
    new_id[v] = next++;
    kept.insert(kept.end(), &mesh.positions[3 * v], &mesh.positions[3 * v] + 3);
  }
  mesh.positions = std::move(kept);
  for (int32_t& v : mesh.triangles) v = new_id[v];

  std::vector<std::pair<int32_t, int32_t>> edges;
  edges.reserve(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); t += 3)
    for (int c = 0; c < 3; ++c) {
      const int32_t a = mesh.triangles[t + c], b = mesh.triangles[t + (c + 1) % 3];
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  mesh.edges.clear();
  for (const auto& [a, b] : edges) mesh.edges.insert(mesh.edges.end(), {a, b});
}

struct ObstacleCache {
  std::map<std::string, ObstacleMesh> entries;  // by normalised path; std::map: stable addresses
};

const ObstacleMesh& read_obstacle_mesh(const json& j, const Where& w, const fs::path& scene_dir,
                                       ObstacleCache& cache) {
  const std::string rel = string(j["mesh"], w["mesh"]);
  const fs::path path = scene_dir / rel;
  const std::string key = path.lexically_normal().string();
  if (const auto found = cache.entries.find(key); found != cache.entries.end()) return found->second;
  std::string extension = path.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".obj" && extension != ".msh")
    w["mesh"].fail("expected an .obj or .msh file", j["mesh"]);
  std::error_code error;  // the throwing fs::exists would escape with its own message
  if (!fs::exists(path, error)) w["mesh"].fail("mesh file not found: " + path.string());
  ObstacleMesh mesh;
  try {
    mesh = extension == ".obj" ? obstacle_from_obj(read_obj(path)) : read_msh_surface(path);
  } catch (const std::exception& e) {  // MeshError from the readers, SceneError from the surface
    w["mesh"].fail(e.what());
  }
  compact_and_find_edges(mesh);
  return cache.entries.emplace(key, std::move(mesh)).first->second;
}

// Appends an obstacle mesh as a body: no tets, mass 0, every vertex on the Dirichlet motion
// `motion` (the shared fixed one, or the obstacle's own), zero initial velocity (the simulation
// prescribes it). Its triangles join the collision surface.
// Returns what is wrong with the placed mesh (as append_body), empty when nothing is.
std::string append_obstacle(const ObstacleMesh& mesh, const Transform& transform, int32_t scene_entry,
                            int32_t material, int32_t motion, Model& model, State& state) {
  BodyRange range;
  range.vertex_begin = model.num_vertices;
  range.vertex_count = static_cast<int32_t>(mesh.positions.size() / 3);
  range.tet_begin = model.num_tets;
  range.tet_count = 0;
  range.triangle_begin = static_cast<int32_t>(model.surface_triangles.size() / 3);
  range.triangle_count = static_cast<int32_t>(mesh.triangles.size() / 3);
  range.edge_begin = static_cast<int32_t>(model.surface_edges.size() / 2);
  range.edge_count = static_cast<int32_t>(mesh.edges.size() / 2);
  range.scene_entry = scene_entry;
  range.obstacle = true;
  range.material = material;
  const int32_t body_id = static_cast<int32_t>(model.bodies.size());
  const int32_t base = range.vertex_begin;

  for (int32_t v = 0; v < range.vertex_count; ++v) {
    const Eigen::Vector3d p = transform.linear * Eigen::Vector3d::Map(&mesh.positions[3 * size_t(v)]) +
                              transform.translate;
    if (!p.allFinite())
      return "vertex " + std::to_string(v) + " of the mesh is not finite once placed (translate or scale "
             "too large)";
    for (int d = 0; d < 3; ++d) {
      model.rest_positions.push_back(p[d]);
      state.v.push_back(0.0);
    }
    model.mass.push_back(0.0);
    model.vertex_body.push_back(body_id);
    model.dirichlet.push_back(motion);
  }
  auto X = [&](int32_t v) { return Eigen::Vector3d::Map(&model.rest_positions[3 * size_t(base + v)]); };
  for (size_t t = 0; t < mesh.triangles.size(); t += 3)
    if (is_degenerate_triangle(X(mesh.triangles[t]), X(mesh.triangles[t + 1]), X(mesh.triangles[t + 2])))
      return "triangle " + std::to_string(t / 3) + " of the mesh is degenerate once placed: scale too small or "
             "too uneven, or translate too large for its size";
  for (int32_t i : mesh.triangles) model.surface_triangles.push_back(base + i);
  for (int32_t i : mesh.edges) model.surface_edges.push_back(base + i);
  // Every vertex is used by a triangle (compact_and_find_edges), and base exceeds every earlier
  // id, so surface_vertices stays sorted.
  for (int32_t v = 0; v < range.vertex_count; ++v) model.surface_vertices.push_back(base + v);
  model.num_vertices += range.vertex_count;
  model.bodies.push_back(range);
  return "";
}

// One entry of "obstacles": a plane or a mesh, static or moving. `fixed_motion` is the id of the
// shared fixed Dirichlet motion of static meshes, created on the first one (-1 until then).
void read_obstacle(const json& j, const Where& w, int32_t scene_entry, const fs::path& scene_dir,
                   const std::map<std::string, int32_t>& material_ids, ObstacleCache& cache,
                   int32_t& fixed_motion, const SceneLimits& limits, Model& model, State& state) {
  if (!j.is_object()) w.fail("expected an object", j);
  if (j.contains("plane") == j.contains("mesh")) w.fail("give exactly one of \"plane\" and \"mesh\"");
  // Only friction reads an obstacle's material (contact.friction_pairs).
  const int32_t material = j.contains("material") ? material_id(j["material"], w["material"], material_ids) : -1;
  if (j.contains("plane")) {
    check_keys(j, w, {"plane", "material"});
    const json& plane = j["plane"];
    const Where wp = w["plane"];
    check_keys(plane, wp, {"point", "normal"});
    if (!plane.contains("point") || !plane.contains("normal")) wp.fail("needs \"point\" and \"normal\"");
    ObstaclePlane p;
    p.point = vec3(plane["point"], wp["point"]);
    // Divided by its largest component first, so that [1e308, 1e308, 0] does not overflow.
    const Eigen::Vector3d given = vec3(plane["normal"], wp["normal"]);
    const double largest = given.cwiseAbs().maxCoeff();
    const Eigen::Vector3d normal = largest > 0.0 ? Eigen::Vector3d(given / largest) : given;
    const double length = normal.norm();
    if (!(length > 0.0) || !std::isfinite(length)) wp["normal"].fail("the normal must not be zero", plane["normal"]);
    p.normal = normal / length;
    p.scene_entry = scene_entry;
    p.material = material;
    model.obstacle_planes.push_back(p);
    return;
  }
  check_keys(j, w, {"mesh", "material", "translate", "rotate_deg", "scale", "velocity", "angular_velocity",
                    "axis", "center"});
  const ObstacleMesh& mesh = read_obstacle_mesh(j, w, scene_dir, cache);
  const Transform transform = read_transform(j, w);
  const int64_t vertices = static_cast<int64_t>(mesh.positions.size() / 3);
  check_size(model, vertices, 0, limits, "an obstacle mesh of " + std::to_string(vertices) + " vertices", w["mesh"]);
  int32_t motion_id = fixed_motion;
  if (j.contains("velocity") || j.contains("angular_velocity")) {
    // A moving obstacle: its own motion, about the centre of its bounding box by default.
    Eigen::AlignedBox3d box;
    for (size_t v = 0; 3 * v < mesh.positions.size(); ++v)
      box.extend(transform.linear * Eigen::Vector3d::Map(&mesh.positions[3 * v]) + transform.translate);
    motion_id = static_cast<int32_t>(model.dirichlet_motions.size());
    model.dirichlet_motions.push_back(read_motion(j, w, box.center()));
  } else if (fixed_motion < 0) {
    fixed_motion = motion_id = static_cast<int32_t>(model.dirichlet_motions.size());
    model.dirichlet_motions.push_back(DirichletMotion{});  // velocity 0, angular velocity 0
  }
  const std::string problem = append_obstacle(mesh, transform, scene_entry, material, motion_id, model, state);
  if (!problem.empty()) w.fail(problem);
}

}  // namespace

Scene load_scene(const fs::path& file, const SceneLimits& limits) {
  std::ifstream in(file);
  if (!in) throw SceneError(one_line(file.string() + ": cannot open the scene file"));
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e999
    throw SceneError(one_line(file.string() + ": not valid JSON: " + e.what()));
  }
  const Where w(file, "");
  check_keys(root, w, {"name", "gravity", "time", "solver", "contact", "materials", "bodies",
                       "obstacles", "boundary", "joints", "output"});
  Scene scene;
  scene.file = file;
  scene.name = root.contains("name") ? string(root["name"], w["name"]) : file.stem().string();
  // The name is the default output folder (out/<name>): "." or ".." would write outside it.
  bool bad_name = scene.name.empty() || scene.name == "." || scene.name == ".." ||
                  scene.name.find('/') != std::string::npos;
  for (char c : scene.name) bad_name = bad_name || static_cast<unsigned char>(c) < 32 || c == 127;
  if (bad_name)
    w["name"].fail("expected a non-empty name without '/' or control characters, not \".\" or \"..\"",
                   root.contains("name") ? root["name"] : json(scene.name));
  if (root.contains("gravity")) scene.model.gravity = vec3(root["gravity"], w["gravity"]);
  if (root.contains("time")) read_time(root["time"], w["time"], scene.time);
  if (root.contains("solver")) read_solver(root["solver"], w["solver"], scene.solver);
  if (root.contains("contact")) read_contact(root["contact"], w["contact"], scene.contact);
  if (root.contains("output")) read_output(root["output"], w["output"], scene.output);
  // IPC's barrier lives inside the implicit solve: an explicit step (beta = 0) has no
  // minimisation to add it to, so it could not keep bodies apart.
  if (scene.contact.enabled && scene.time.integrator.is_explicit())
    w["time"]["integrator"].fail("contact needs an implicit integrator (beta > 0); \"" +
                                 scene.time.integrator.name + "\" is explicit (beta = 0)");
  const bool has_obstacles = root.contains("obstacles") && !(root["obstacles"].is_array() && root["obstacles"].empty());
  // Obstacles act on bodies only through contact; without it they would silently do nothing.
  if (has_obstacles && !scene.contact.enabled)
    w["obstacles"].fail("obstacles need contact; add \"contact\": {}");

  // Materials.
  if (!root.contains("materials")) w.fail("missing key \"materials\"");
  const json& materials = root["materials"];
  if (!materials.is_object() || materials.empty()) w["materials"].fail("expected a non-empty object of named materials");
  if (static_cast<int64_t>(materials.size()) > limits.max_materials)
    w["materials"].fail(std::to_string(materials.size()) + " materials, more than the limit of " +
                        std::to_string(limits.max_materials));
  std::map<std::string, int32_t> material_ids;
  for (const auto& item : materials.items()) {
    material_ids[item.key()] = static_cast<int32_t>(scene.model.materials.size());
    scene.model.materials.push_back(read_material(item.key(), item.value(), w["materials"][item.key()]));
  }
  if (root.contains("contact") && root["contact"].contains("friction_pairs"))
    read_friction_pairs(root["contact"]["friction_pairs"], w["contact"]["friction_pairs"], material_ids, scene.contact);

  // Bodies.
  if (!root.contains("bodies")) w.fail("missing key \"bodies\"");
  const json& bodies = root["bodies"];
  if (!bodies.is_array() || bodies.empty()) w["bodies"].fail("expected a non-empty array of bodies");
  MeshCache cache;
  const fs::path scene_dir = file.parent_path();
  for (size_t b = 0; b < bodies.size(); ++b) {
    const BodySpec spec =
        read_body(bodies[b], w["bodies"][b], scene_dir, material_ids, cache, scene.model, limits);
    for (int64_t i = 0; i < spec.count[0]; ++i)
      for (int64_t k = 0; k < spec.count[1]; ++k)
        for (int64_t l = 0; l < spec.count[2]; ++l) {
          const Eigen::Vector3d offset(i * spec.spacing.x(), k * spec.spacing.y(), l * spec.spacing.z());
          const std::string problem = append_body(spec, offset, static_cast<int32_t>(b), scene.model, scene.initial);
          if (!problem.empty())
            w["bodies"][b].fail((spec.count == std::array<int64_t, 3>{1, 1, 1}
                                     ? std::string()
                                     : "copy (" + std::to_string(i) + ", " + std::to_string(k) + ", " +
                                           std::to_string(l) + ") of the array: ") +
                                problem);
        }
  }

  // Boundary conditions.
  if (root.contains("boundary")) {
    const json& boundary = root["boundary"];
    if (!boundary.is_array()) w["boundary"].fail("expected an array", boundary);
    for (size_t i = 0; i < boundary.size(); ++i)
      read_boundary(boundary[i], w["boundary"][i], scene.model, static_cast<int64_t>(bodies.size()));
  }

  // Joints, on the bodies' tets.
  if (root.contains("joints")) {
    const json& joints = root["joints"];
    if (!joints.is_array()) w["joints"].fail("expected an array", joints);
    for (size_t i = 0; i < joints.size(); ++i)
      read_joint(joints[i], w["joints"][i], static_cast<int32_t>(i), scene.model,
                 static_cast<int64_t>(bodies.size()));
  }

  // Obstacles, after every body and every boundary entry: "bodies" entries keep their body
  // indices, and the shared fixed motion of obstacle meshes comes after the "boundary" motions.
  if (root.contains("obstacles")) {
    const json& obstacles = root["obstacles"];
    if (!obstacles.is_array()) w["obstacles"].fail("expected an array", obstacles);
    ObstacleCache obstacle_cache;
    int32_t fixed_motion = -1;
    for (size_t i = 0; i < obstacles.size(); ++i)
      read_obstacle(obstacles[i], w["obstacles"][i], static_cast<int32_t>(i), scene_dir, material_ids,
                    obstacle_cache, fixed_motion, limits, scene.model, scene.initial);
  }

  // With contact, moving boundaries and obstacles push bodies: their vertices become unknowns
  // held by an augmented Lagrangian (Model::eliminated).
  for (DirichletMotion& motion : scene.model.dirichlet_motions)
    motion.kinematic = scene.contact.enabled && motion.moves();
  scene.initial.x = scene.model.rest_positions;
  scene.initial.a.assign(scene.initial.x.size(), 0.0);
  scene.initial.x_tilde = scene.initial.x;
  if (scene.contact.enabled) {
    const std::string problem = initial_contact_problem(scene.model);
    if (!problem.empty()) throw SceneError(one_line(file.string() + ": " + problem));
  }
  return scene;
}

}  // namespace nexdyn

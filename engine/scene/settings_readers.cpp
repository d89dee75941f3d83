// Readers of the settings objects of a scene file (see settings_readers.hpp).
#include "engine/scene/settings_readers.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <limits>
#include <set>
#include <utility>

namespace nexdyn::scene_io {

namespace {

// Static friction below kinetic friction is not a physical surface.
void check_static_friction(double mu_s, double mu_k, const Where& where) {
  if (mu_s < mu_k)
    where.fail("static friction must be at least the kinetic \"friction\" " + show(json(mu_k)), json(mu_s));
}

// "alpha", "beta", "gamma", "alpha_m" and "alpha_f" of "time": a custom scheme.
void read_custom_integrator(const json& j, const Where& w, TimeSettings& time) {
  const bool weights = j.contains("alpha_m") || j.contains("alpha_f");
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
  if (p.beta < 0.0 || p.beta > 0.5) w["beta"].fail("expected 0 <= beta <= 0.5", j.value("beta", json(p.beta)));
  if (p.gamma < 0.0 || p.gamma > 1.0) w["gamma"].fail("expected 0 <= gamma <= 1", j.value("gamma", json(p.gamma)));
  if ((p.alpha_m != 0.0 || p.alpha_f != 0.0) && p.is_explicit())
    w["beta"].fail("generalized-alpha weights need an implicit scheme (beta > 0)", json(p.beta));
  p.name = "custom";
}

// "damping": {"mass": a2, "stiffness": a1}, Rayleigh damping D = a1 K + a2 M.
RayleighDamping read_damping(const json& j, const Where& w) {
  if (!j.is_object()) w.fail("expected an object with \"mass\" and/or \"stiffness\"", j);
  check_keys(j, w, {"mass", "stiffness"});
  RayleighDamping damping;
  if (j.contains("mass")) damping.mass = non_negative(j["mass"], w["mass"]);
  if (j.contains("stiffness")) damping.stiffness = non_negative(j["stiffness"], w["stiffness"]);
  return damping;
}

// An affine material (issue 40): a density and the orthogonality stiffness kappa, no elastic
// moduli (the body does not deform; kappa only holds it to a rotation).
Material read_affine_material(const std::string& name, const json& j, const Where& w) {
  for (const char* key : {"youngs", "poisson"})
    if (j.contains(key))
      w[key].fail("an \"affine\" material has no \"" + std::string(key) +
                  "\": it does not deform; give \"stiffness\" (the orthogonality stiffness, Pa) instead");
  if (j.contains("damping")) w["damping"].fail("an \"affine\" material does not support damping yet");
  check_keys(j, w, {"model", "density", "stiffness"});
  if (!j.contains("density")) w.fail("missing key \"density\"");
  Material m;
  m.name = name;
  m.affine = true;
  m.density = positive(j["density"], w["density"]);
  m.stiffness = j.contains("stiffness") ? positive(j["stiffness"], w["stiffness"]) : kAffineStiffness;
  return m;
}

Material read_material(const std::string& name, const json& j, const Where& w) {
  if (!j.is_object()) w.fail("expected an object", j);
  if (!j.contains("model")) w.fail("missing key \"model\"");
  const std::string model = string(j["model"], w["model"]);
  if (model == "affine") return read_affine_material(name, j, w);
  check_keys(j, w, {"model", "youngs", "poisson", "density", "damping"});
  for (const char* key : {"youngs", "poisson", "density"})
    if (!j.contains(key)) w.fail(std::string("missing key \"") + key + "\"");
  Material m;
  m.name = name;
  m.arap = model == "arap";
  const auto parsed = m.arap ? std::optional(MaterialModel::corotated) : material_model_from_name(model);
  if (!parsed)
    w["model"].fail("unknown material model " + show(json(model)) +
                    " (known: linear, stvk, corotated, neohookean, arap, affine)");
  m.model = *parsed;
  m.youngs = positive(j["youngs"], w["youngs"]);
  m.poisson = number(j["poisson"], w["poisson"]);
  if (!(m.poisson > -1.0 && m.poisson < 0.5)) w["poisson"].fail("expected -1 < poisson < 0.5", j["poisson"]);
  m.density = positive(j["density"], w["density"]);
  m.lame = lame_from_young_poisson(m.youngs, m.poisson);
  if (m.arap) m.lame.lambda = 0.0;  // mu ||F - R||^2 has no volume term
  if (j.contains("damping")) m.damping = read_damping(j["damping"], w["damping"]);
  return m;
}

// "sleep": true, false, or {"velocity": v, "steps": k} (on, with these thresholds).
void read_sleep(const json& j, const Where& w, SleepSettings& sleep) {
  if (j.is_boolean()) {
    sleep.enabled = j.get<bool>();
    return;
  }
  if (!j.is_object()) w.fail("expected true, false or an object with \"velocity\" and \"steps\"", j);
  check_keys(j, w, {"velocity", "steps"});
  sleep.enabled = true;
  if (j.contains("velocity")) sleep.velocity = positive(j["velocity"], w["velocity"]);
  if (j.contains("steps")) sleep.steps = bounded_int(j["steps"], w["steps"], 1, 1 << 20);
}

}  // namespace

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
  if (j.contains("alpha_m") || j.contains("alpha_f") || j.contains("alpha") || j.contains("beta") ||
      j.contains("gamma"))
    read_custom_integrator(j, w, time);
  if (j.contains("initial_acceleration")) {
    const std::string mode = string(j["initial_acceleration"], w["initial_acceleration"]);
    if (mode == "consistent") time.consistent_initial_acceleration = true;
    else if (mode == "zero") time.consistent_initial_acceleration = false;
    else w["initial_acceleration"].fail("expected \"consistent\" or \"zero\"", j["initial_acceleration"]);
  }
}

void read_solver(const json& j, const Where& w, SolverSettings& solver) {
  check_keys(j, w, {"method", "linear", "chebyshev", "tolerance", "max_iterations", "joint_tolerance",
                    "substep_halvings", "sleep"});
  if (j.contains("method")) {
    const std::string method = string(j["method"], w["method"]);
    if (method == "newton") solver.method = SolverMethod::newton;
    else if (method == "linearized") solver.method = SolverMethod::linearized;
    else if (method == "projective_dynamics") solver.method = SolverMethod::projective_dynamics;
    else w["method"].fail("expected \"newton\", \"linearized\" or \"projective_dynamics\"", j["method"]);
  }
  if (j.contains("linear")) {
    const std::string linear = string(j["linear"], w["linear"]);
    if (linear == "cholmod") solver.linear = LinearSolverKind::cholmod;
    else if (linear == "pcg") solver.linear = LinearSolverKind::pcg;
    else w["linear"].fail("expected \"cholmod\" or \"pcg\"", j["linear"]);
    if (solver.method != SolverMethod::linearized)
      w["linear"].fail("belongs to \"method\": \"linearized\" (Newton and Projective Dynamics use CHOLMOD)",
                       j["linear"]);
  }
  if (j.contains("chebyshev")) {
    const json& c = j["chebyshev"];
    if (solver.method != SolverMethod::projective_dynamics)
      w["chebyshev"].fail("belongs to \"method\": \"projective_dynamics\"", c);
    if (c.is_boolean()) {
      solver.chebyshev = c.get<bool>();
    } else if (c.is_object()) {
      check_keys(c, w["chebyshev"], {"rho"});
      if (!c.contains("rho")) w["chebyshev"].fail("expected {\"rho\": r} with 0 < r < 1");
      solver.chebyshev = true;
      solver.chebyshev_rho = number(c["rho"], w["chebyshev"]["rho"]);
      if (!(solver.chebyshev_rho > 0.0 && solver.chebyshev_rho < 1.0))
        w["chebyshev"]["rho"].fail("expected 0 < rho < 1", c["rho"]);
    } else {
      w["chebyshev"].fail("expected true, false or {\"rho\": r}", c);
    }
  }
  if (j.contains("sleep")) read_sleep(j["sleep"], w["sleep"], solver.sleep);
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
    if (value.is_string() && value.get<std::string>() == "converged")
      contact.friction_iterations = -1;
    else if (value.is_number_integer())
      contact.friction_iterations = bounded_int(value, w["friction_iterations"], 1, std::numeric_limits<int>::max());
    else
      w["friction_iterations"].fail("expected an integer >= 1 or \"converged\"", value);
  }
}

// "output.camera": position and target required, up and fov_deg optional.
CameraSettings read_camera(const json& j, const Where& w) {
  check_keys(j, w, {"position", "target", "up", "fov_deg"});
  if (!j.contains("position") || !j.contains("target")) w.fail("needs \"position\" and \"target\"");
  CameraSettings camera;
  camera.position = vec3(j["position"], w["position"]);
  camera.target = vec3(j["target"], w["target"]);
  if ((camera.target - camera.position).norm() == 0.0) w["target"].fail("equals \"position\"", j["target"]);
  if (j.contains("up")) {
    camera.up = vec3(j["up"], w["up"]);
    if (camera.up.norm() == 0.0 || camera.up.cross(camera.target - camera.position).norm() == 0.0)
      w["up"].fail("must be non-zero and not along the view direction", j["up"]);
  }
  if (j.contains("fov_deg")) {
    camera.fov_deg = positive(j["fov_deg"], w["fov_deg"]);
    if (camera.fov_deg >= 170.0) w["fov_deg"].fail("expected a field of view below 170 degrees", j["fov_deg"]);
  }
  return camera;
}

void read_output(const json& j, const Where& w, OutputSettings& output) {
  check_keys(j, w, {"every", "formats", "checkpoint_every", "camera"});
  if (j.contains("camera")) output.camera = read_camera(j["camera"], w["camera"]);
  if (j.contains("every")) output.every = integer(j["every"], w["every"], 1);
  if (j.contains("checkpoint_every"))
    output.checkpoint_every = integer(j["checkpoint_every"], w["checkpoint_every"], 0);
  if (j.contains("formats")) {
    const json& f = j["formats"];
    if (!f.is_array()) w["formats"].fail("expected an array of \"vtu\", \"obj\" and \"bodies\"", f);
    output.vtu = output.obj = output.bodies = false;
    for (size_t i = 0; i < f.size(); ++i) {
      const std::string name = string(f[i], w["formats"][i]);
      if (name == "vtu") output.vtu = true;
      else if (name == "obj") output.obj = true;
      else if (name == "bodies") output.bodies = true;
      else w["formats"][i].fail("unknown output format (known: vtu, obj, bodies)", f[i]);
    }
  }
}

int32_t material_id(const json& value, const Where& w, const MaterialIds& material_ids) {
  const std::string name = string(value, w);
  const auto found = material_ids.find(name);
  if (found == material_ids.end()) w.fail("no material named " + show(json(name)) + " in \"materials\"");
  return found->second;
}

void read_friction_pairs(const json& j, const Where& w, const MaterialIds& material_ids,
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

MaterialIds read_materials(const json& j, const Where& w, const SceneLimits& limits,
                           std::vector<Material>& materials) {
  if (!j.is_object() || j.empty()) w.fail("expected a non-empty object of named materials");
  if (static_cast<int64_t>(j.size()) > limits.max_materials)
    w.fail(std::to_string(j.size()) + " materials, more than the limit of " + std::to_string(limits.max_materials));
  MaterialIds material_ids;
  for (const auto& item : j.items()) {
    material_ids[item.key()] = static_cast<int32_t>(materials.size());
    materials.push_back(read_material(item.key(), item.value(), w[item.key()]));
  }
  return material_ids;
}

}  // namespace nexdyn::scene_io

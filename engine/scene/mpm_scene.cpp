// Particle bodies, the "mpm" grid and its boundary conditions (see mpm_scene.hpp).
#include "engine/scene/mpm_scene.hpp"

#include "engine/mesh/msh_reader.hpp"
#include "engine/mpm/grid.hpp"
#include "engine/scene/build_model.hpp"
#include "engine/mesh/tet_mesh.hpp"

#include <Eigen/LU>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>

namespace nexdyn::scene_io {

namespace fs = std::filesystem;

namespace {

// A grid this large would not fit in memory next to anything else (56 bytes per node and the
// solver's 72 more): 50 M nodes is 6.4 GB.
constexpr int64_t kMaxGridNodes = 50'000'000;

void read_grid(const json& j, const Where& w, MpmModel& mpm) {
  check_keys(j, w, {"grid_spacing", "domain_min", "domain_max"});
  for (const char* key : {"grid_spacing", "domain_min", "domain_max"})
    if (!j.contains(key)) w.fail(std::string("missing key \"") + key + "\"");
  mpm.grid_spacing = positive(j["grid_spacing"], w["grid_spacing"]);
  mpm.domain_min = vec3(j["domain_min"], w["domain_min"]);
  mpm.domain_max = vec3(j["domain_max"], w["domain_max"]);
  double nodes = 1.0;
  for (int a = 0; a < 3; ++a) {
    const double extent = mpm.domain_max[a] - mpm.domain_min[a];
    if (!(extent >= 4.0 * mpm.grid_spacing))
      w["domain_max"].fail("the domain must be at least 4 grid cells long on each axis (grid_spacing " +
                               show(json(mpm.grid_spacing)) + ")",
                           j["domain_max"]);
    nodes *= std::ceil(extent / mpm.grid_spacing) + 1.0;
  }
  if (!(nodes <= double(kMaxGridNodes)))
    w["grid_spacing"].fail("the grid would have " + show(json(nodes)) + " nodes, more than " +
                               std::to_string(kMaxGridNodes) + " (56 bytes each); use a larger spacing or a smaller domain",
                           j["grid_spacing"]);
}

// K^3 particles per cell of a box centred on the origin, placed by `transform`.
void sample_box(const json& j, const Where& w, const Transform& transform, double h, double density,
                const Eigen::Vector3d& velocity, int32_t material, const SceneLimits& limits, Particles& out) {
  check_keys(j, w, {"size", "per_cell"});
  if (!j.contains("size")) w.fail("missing key \"size\"");
  const Eigen::Vector3d size = vec3(j["size"], w["size"]);
  if (!(size.array() > 0.0).all()) w["size"].fail("expected 3 numbers > 0", j["size"]);
  const int K = j.contains("per_cell") ? bounded_int(j["per_cell"], w["per_cell"], 1, 8) : 2;
  int64_t count[3];
  double total = 1.0;
  for (int a = 0; a < 3; ++a) {
    const double cells = std::max(1.0, std::round(transform.linear.col(a).norm() * size[a] / h));
    total *= cells * K;
    count[a] = static_cast<int64_t>(std::min(cells * K, 1e9));
  }
  if (!(total + double(out.size()) <= double(limits.max_vertices)))
    w.fail("the box would make " + show(json(total)) + " particles, more than the scene limit of " +
           std::to_string(limits.max_vertices));
  const Eigen::Vector3d edge(size[0] / count[0], size[1] / count[1], size[2] / count[2]);
  const double volume = std::abs(transform.linear.determinant()) * edge.prod();
  for (int64_t k = 0; k < count[2]; ++k)
    for (int64_t jj = 0; jj < count[1]; ++jj)
      for (int64_t i = 0; i < count[0]; ++i) {
        const Eigen::Vector3d local = -0.5 * size + Eigen::Vector3d((i + 0.5) * edge[0], (jj + 0.5) * edge[1], (k + 0.5) * edge[2]);
        out.push_back(density * volume, volume, transform.linear * local + transform.translate, velocity, material);
      }
}

// K particles per tet of a .msh mesh (K = 1: the centroid; K = 4: the points of the symmetric
// 4-point rule, each with a quarter of the tet's volume).
void sample_mesh(const json& j, const Where& w, const fs::path& scene_dir, const Transform& transform, double density,
                 const Eigen::Vector3d& velocity, int32_t material, const SceneLimits& limits, Particles& out) {
  check_keys(j, w, {"mesh", "per_tet"});
  const fs::path path = scene_dir / string(j["mesh"], w["mesh"]);
  if (path.extension() != ".msh") w["mesh"].fail("particles are sampled in the tets of a .msh file", j["mesh"]);
  std::error_code error;
  if (!fs::exists(path, error)) w["mesh"].fail("mesh file not found: " + path.string());
  const int K = j.contains("per_tet") ? bounded_int(j["per_tet"], w["per_tet"], 1, 4) : 1;
  if (K != 1 && K != 4) w["per_tet"].fail("expected 1 (the centroid) or 4 (the 4-point rule)", j["per_tet"]);
  TetMesh mesh;
  try {
    mesh = read_msh(path);
  } catch (const std::exception& e) {
    w["mesh"].fail(e.what());
  }
  if (double(mesh.num_tets()) * K + double(out.size()) > double(limits.max_vertices))
    w.fail("the mesh would make more particles than the scene limit of " + std::to_string(limits.max_vertices));
  const double a = 0.5854101966249685, b = 0.1381966011250105;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) {
    Eigen::Vector3d x[4];
    for (int c = 0; c < 4; ++c)
      x[c] = transform.linear * Eigen::Vector3d::Map(&mesh.positions[3 * mesh.tets[4 * t + c]]) + transform.translate;
    const double volume = signed_tet_volume(x[0], x[1], x[2], x[3]);
    if (!(volume > 0.0)) w["mesh"].fail("tet " + std::to_string(t) + " has no volume once placed");
    const Eigen::Vector3d sum = x[0] + x[1] + x[2] + x[3];
    if (K == 1) {
      out.push_back(density * volume, volume, 0.25 * sum, velocity, material);
      continue;
    }
    for (int c = 0; c < 4; ++c)
      out.push_back(0.25 * density * volume, 0.25 * volume, b * sum + (a - b) * x[c], velocity, material);
  }
}

void read_particle_body(const json& j, const Where& w, const fs::path& scene_dir, const MaterialIds& material_ids,
                        const SceneLimits& limits, int32_t body, MpmModel& mpm) {
  if (j.is_object() && (j.contains("mesh") || j.contains("box")))
    w.fail("a scene with particle bodies cannot also have tet bodies (\"mesh\" or \"box\"): MPM and FEM bodies "
           "do not meet yet");
  check_keys(j, w, {"particles", "material", "translate", "rotate_deg", "scale", "velocity", "angular_velocity"});
  if (!j.contains("particles")) w.fail("missing key \"particles\"");
  if (!j.contains("material")) w.fail("missing key \"material\"");
  const int32_t material = material_id(j["material"], w["material"], material_ids);
  const Transform transform = read_transform(j, w);
  const Eigen::Vector3d velocity = j.contains("velocity") ? vec3(j["velocity"], w["velocity"]) : Eigen::Vector3d::Zero();
  const json& p = j["particles"];
  const Where wp = w["particles"];
  if (!p.is_object()) wp.fail("expected an object", p);
  const double density = mpm.materials[material].density;
  const int64_t before = mpm.initial.size();
  if (p.contains("box") == p.contains("mesh")) wp.fail("give exactly one of \"box\" and \"mesh\"");
  if (p.contains("box")) {
    check_keys(p, wp, {"box"});
    sample_box(p["box"], wp["box"], transform, mpm.grid_spacing, density, velocity, material, limits, mpm.initial);
  } else {
    sample_mesh(p, wp, scene_dir, transform, density, velocity, material, limits, mpm.initial);
  }
  if (j.contains("angular_velocity")) {
    // Spun about the body's centre of mass: v_p += omega x (x_p - c), and the affine velocity
    // C_p = [omega]x, the gradient of that rigid velocity field (which the grid then holds exactly).
    const Eigen::Vector3d omega = vec3(j["angular_velocity"], w["angular_velocity"]);
    Particles& P = mpm.initial;
    Eigen::Vector3d moment = Eigen::Vector3d::Zero();
    double mass = 0.0;
    for (int64_t q = before; q < P.size(); ++q) {
      moment += P.mass[q] * P.position(q);
      mass += P.mass[q];
    }
    const Eigen::Vector3d centre = moment / mass;
    Eigen::Matrix3d spin;
    spin << 0.0, -omega.z(), omega.y(), omega.z(), 0.0, -omega.x(), -omega.y(), omega.x(), 0.0;
    for (int64_t q = before; q < P.size(); ++q) {
      Eigen::Vector3d::Map(&P.v[3 * q]) += omega.cross(P.position(q) - centre);
      Eigen::Matrix3d::Map(&P.C[9 * q]) = spin;
    }
  }
  // Every particle's stencil must lie on the grid.
  const Grid grid = grid_geometry(mpm.grid_spacing, mpm.domain_min, mpm.domain_max);
  for (int64_t q = before; q < mpm.initial.size(); ++q) {
    if (stencil_inside(grid, bspline_stencil(grid, &mpm.initial.x[3 * q]))) continue;
    const Eigen::Vector3d x = mpm.initial.position(q);
    wp.fail("a particle at " + show(json{x[0], x[1], x[2]}) +
            " is not inside mpm.domain_min .. domain_max with 1.5 grid cells to spare");
  }
  mpm.particle_body.resize(static_cast<size_t>(mpm.initial.size()), body);
}

void read_plane(const json& j, const Where& w, MpmModel& mpm) {
  if (j.is_object() && j.contains("mesh"))
    w["mesh"].fail("MPM scenes take plane obstacles only: mesh contact is not supported with particle bodies");
  check_keys(j, w, {"plane", "material", "condition"});
  if (!j.contains("plane")) w.fail("missing key \"plane\"");
  MpmPlane p;
  read_plane_geometry(j["plane"], w["plane"], p.point, p.normal);
  if (j.contains("material")) w["material"].fail("MPM planes take contact.friction; per-material friction is not supported");
  if (j.contains("condition")) {
    const std::string c = string(j["condition"], w["condition"]);
    if (c == "separating") p.condition = PlaneCondition::separating;
    else if (c == "slip") p.condition = PlaneCondition::slip;
    else if (c == "sticky") p.condition = PlaneCondition::sticky;
    else w["condition"].fail("expected \"separating\", \"slip\" or \"sticky\"", j["condition"]);
  }
  mpm.planes.push_back(p);
}

void read_box(const json& j, const Where& w, MpmModel& mpm) {
  check_keys(j, w, {"box_min", "box_max", "fix", "velocity", "angular_velocity", "axis", "center"});
  MpmBox box;
  box.motion = read_box_motion(j, w, box.box_min, box.box_max);
  bool selects = false;
  for (int64_t q = 0; q < mpm.initial.size() && !selects; ++q) {
    const Eigen::Vector3d x = mpm.initial.position(q);
    selects = (x.array() >= box.box_min.array()).all() && (x.array() <= box.box_max.array()).all();
  }
  if (!selects) w.fail("the box holds no particle at the start");
  mpm.boxes.push_back(box);
}

// What MPM scenes do not read is refused rather than ignored.
void refuse_unsupported(const json& root, const Where& w, const Scene& scene) {
  if (root.contains("joints") && !(root["joints"].is_array() && root["joints"].empty()))
    w["joints"].fail("joints are not supported with particle bodies");
  if (root.contains("contact") && root["contact"].is_object())
    for (const char* key : {"dhat", "epsv", "static_friction", "friction_pairs", "friction_iterations"})
      if (root["contact"].contains(key))
        w["contact"][key].fail("not used by MPM scenes: planes act on the grid nodes, with contact.friction only");
  if (scene.solver.method != SolverMethod::newton)
    w["solver"]["method"].fail("MPM scenes are solved by Newton (\"newton\")");
  if (scene.output.obj) w["output"]["formats"].fail("MPM frames are point clouds (.vtu): \"obj\" has no surface to write");
  if (scene.output.bodies)
    w["output"]["formats"].fail("MPM frames are point clouds (.vtu): \"bodies\" is for tet and affine bodies");
  for (const Material& m : scene.model.materials)
    if (m.damping.any()) w["materials"][m.name]["damping"].fail("damping is not supported with particle bodies");
}

}  // namespace

bool is_mpm_scene(const json& root) {
  if (!root.is_object()) return false;
  if (root.contains("mpm")) return true;
  if (!root.contains("bodies") || !root["bodies"].is_array()) return false;
  for (const json& body : root["bodies"])
    if (body.is_object() && body.contains("particles")) return true;
  return false;
}

void build_mpm_model(const json& root, const Where& w, const fs::path& scene_dir, const SceneLimits& limits,
                     Scene& scene) {
  refuse_unsupported(root, w, scene);
  if (!root.contains("bodies") || !root["bodies"].is_array() || root["bodies"].empty())
    w["bodies"].fail("an MPM scene needs at least one body with \"particles\"");
  const json& bodies = root["bodies"];
  if (!root.contains("mpm")) {
    for (size_t i = 0; i < bodies.size(); ++i)
      if (bodies[i].is_object() && bodies[i].contains("particles"))
        w["bodies"][i]["particles"].fail("particle bodies need the top-level \"mpm\" key (grid_spacing, domain_min, "
                                         "domain_max)");
  }
  MpmModel mpm;
  read_grid(root["mpm"], w["mpm"], mpm);
  mpm.gravity = scene.model.gravity;
  mpm.materials = scene.model.materials;
  mpm.friction = scene.contact.friction;
  MaterialIds material_ids;
  for (size_t m = 0; m < mpm.materials.size(); ++m) material_ids[mpm.materials[m].name] = static_cast<int32_t>(m);
  for (size_t i = 0; i < bodies.size(); ++i)
    read_particle_body(bodies[i], w["bodies"][i], scene_dir, material_ids, limits, static_cast<int32_t>(i), mpm);
  mpm.num_bodies = static_cast<int32_t>(bodies.size());
  if (root.contains("obstacles")) {
    const json& obstacles = root["obstacles"];
    if (!obstacles.is_array()) w["obstacles"].fail("expected an array", obstacles);
    for (size_t i = 0; i < obstacles.size(); ++i) read_plane(obstacles[i], w["obstacles"][i], mpm);
  }
  if (root.contains("boundary")) {
    const json& boundary = root["boundary"];
    if (!boundary.is_array()) w["boundary"].fail("expected an array", boundary);
    for (size_t i = 0; i < boundary.size(); ++i) read_box(boundary[i], w["boundary"][i], mpm);
  }
  scene.mpm = std::move(mpm);
}

}  // namespace nexdyn::scene_io

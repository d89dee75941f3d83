// The model builder's obstacles (see build_model.hpp): analytic planes, and triangle meshes (.obj,
// or the boundary of a .msh) appended as bodies without tets, static or moving.
#include "engine/scene/build_model.hpp"

#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/obj_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/tet_mesh.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

namespace nexdyn::scene_io {

namespace fs = std::filesystem;

namespace {

// A static obstacle mesh in its own frame: a triangle surface with no volume. Only vertices used
// by a triangle are kept (a .msh obstacle loses its interior nodes, an .obj its stray "v" lines),
// so that every obstacle vertex is a surface vertex.
struct ObstacleMesh {
  std::vector<double> positions;   // (num_vertices x 3) [m], in the file's frame
  std::vector<int32_t> triangles;  // (num_triangles x 3) local vertex ids, winding of the file
  std::vector<int32_t> edges;      // (num_edges x 2) unique edges of the triangles, a < b, sorted
};

struct ObstacleCache {
  std::map<std::string, ObstacleMesh> entries;  // by normalised path; std::map: stable addresses
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

// The mesh named by the entry's "mesh", read once per file.
const ObstacleMesh& read_obstacle_mesh(const json& j, const Where& w, const fs::path& scene_dir,
                                       ObstacleCache& cache) {
  const fs::path path = scene_dir / string(j["mesh"], w["mesh"]);
  const std::string key = path.lexically_normal().string();
  if (const auto found = cache.entries.find(key); found != cache.entries.end()) return found->second;
  std::string extension = path.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension != ".obj" && extension != ".msh") w["mesh"].fail("expected an .obj or .msh file", j["mesh"]);
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
    const Eigen::Vector3d p =
        transform.linear * Eigen::Vector3d::Map(&mesh.positions[3 * size_t(v)]) + transform.translate;
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

// An entry with a "plane": appended to Model::obstacle_planes.
void read_obstacle_plane(const json& j, const Where& w, int32_t scene_entry, int32_t material, Model& model) {
  check_keys(j, w, {"plane", "material"});
  ObstaclePlane p;
  read_plane_geometry(j["plane"], w["plane"], p.point, p.normal);
  p.scene_entry = scene_entry;
  p.material = material;
  model.obstacle_planes.push_back(p);
}

// One entry of "obstacles": a plane or a mesh, static or moving. `fixed_motion` is the id of the
// shared fixed Dirichlet motion of static meshes, created on the first one (-1 until then).
void read_obstacle(const json& j, const Where& w, int32_t scene_entry, const fs::path& scene_dir,
                   const MaterialIds& material_ids, ObstacleCache& cache, int32_t& fixed_motion,
                   const SceneLimits& limits, Model& model, State& state) {
  if (!j.is_object()) w.fail("expected an object", j);
  if (j.contains("plane") == j.contains("mesh")) w.fail("give exactly one of \"plane\" and \"mesh\"");
  // Only friction reads an obstacle's material (contact.friction_pairs).
  const int32_t material = j.contains("material") ? material_id(j["material"], w["material"], material_ids) : -1;
  if (j.contains("plane")) {
    read_obstacle_plane(j, w, scene_entry, material, model);
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

void read_plane_geometry(const json& plane, const Where& wp, Eigen::Vector3d& point, Eigen::Vector3d& normal) {
  check_keys(plane, wp, {"point", "normal"});
  if (!plane.contains("point") || !plane.contains("normal")) wp.fail("needs \"point\" and \"normal\"");
  point = vec3(plane["point"], wp["point"]);
  // Divided by its largest component first, so that [1e308, 1e308, 0] does not overflow.
  const Eigen::Vector3d given = vec3(plane["normal"], wp["normal"]);
  const double largest = given.cwiseAbs().maxCoeff();
  const Eigen::Vector3d scaled = largest > 0.0 ? Eigen::Vector3d(given / largest) : given;
  const double length = scaled.norm();
  if (!(length > 0.0) || !std::isfinite(length)) wp["normal"].fail("the normal must not be zero", plane["normal"]);
  normal = scaled / length;
}

void append_obstacles(const json& obstacles, const Where& w, const fs::path& scene_dir,
                      const MaterialIds& material_ids, const SceneLimits& limits, Model& model, State& initial) {
  if (!obstacles.is_array()) w.fail("expected an array", obstacles);
  ObstacleCache cache;
  int32_t fixed_motion = -1;
  for (size_t i = 0; i < obstacles.size(); ++i)
    read_obstacle(obstacles[i], w[i], static_cast<int32_t>(i), scene_dir, material_ids, cache, fixed_motion, limits,
                  model, initial);
}

}  // namespace nexdyn::scene_io

// The model builder's bodies, boundary conditions and joints (see build_model.hpp; obstacles are
// in build_obstacles.cpp).
#include "engine/scene/build_model.hpp"

#include "engine/mesh/box_mesher.hpp"
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/surface.hpp"
#include "engine/mesh/tet_mesh.hpp"
#include "engine/scene/surface_body.hpp"
#include "kernels/affine/affine_body.hpp"
#include "kernels/elasticity/elasticity.hpp"
#include "kernels/projection/sym_eigen3.hpp"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <utility>

namespace nexdyn::scene_io {

namespace fs = std::filesystem;

namespace {

// ---- bodies --------------------------------------------------------------------------------------

// A body's mesh and its surface, read or built once per file or box.
using BodyMesh = std::pair<TetMesh, SurfaceMesh>;

struct MeshCache {
  std::map<std::string, BodyMesh> entries;  // by "mesh:<path>[|<TetGen switches>]" or "box:<json>";
                                            // std::map: stable addresses
  fs::path surface_cache_dir;               // tetrahedralised surfaces are kept here (empty: not kept)
};

// One entry of "bodies" before expansion of its array.
struct BodySpec {
  const TetMesh* mesh = nullptr;
  const SurfaceMesh* surface = nullptr;
  int32_t material = 0;
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();  // rotate * scale
  Eigen::Vector3d translate = Eigen::Vector3d::Zero();   // [m]
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();    // [m/s] of the centre of mass
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  // [rad/s] about the centre of mass
  std::array<int64_t, 3> count = {1, 1, 1};              // copies along x, y, z
  Eigen::Vector3d spacing = Eigen::Vector3d::Zero();     // [m] between copies
};

Eigen::Matrix3d rotation_xyz_degrees(const Eigen::Vector3d& deg) {
  const Eigen::Vector3d r = deg * (M_PI / 180.0);
  return (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX())).toRotationMatrix();
}

// A surface body's "tetrahedralize" keys (`j`, at `w`).
TetrahedralizeSettings read_tetrahedralize(const json& j, const Where& w) {
  check_keys(j, w, {"max_volume", "min_quality", "refine_surface"});
  TetrahedralizeSettings settings;
  if (j.contains("refine_surface")) settings.refine_surface = boolean(j["refine_surface"], w["refine_surface"]);
  if (j.contains("max_volume")) settings.max_volume = non_negative(j["max_volume"], w["max_volume"]);
  if (j.contains("min_quality")) {
    settings.min_quality = non_negative(j["min_quality"], w["min_quality"]);
    if (settings.min_quality > kMaxMinQuality)
      w["min_quality"].fail(tetrahedralize_settings_problem(settings), j["min_quality"]);
  }
  return settings;
}

// The mesh named by the entry's "mesh": a .msh tet mesh, or a closed surface (.obj, .stl, .ply)
// filled with tets (surface_body.hpp) as its "tetrahedralize" keys say.
const BodyMesh& read_mesh_entry(const json& j, const Where& w, const fs::path& scene_dir, MeshCache& cache) {
  const fs::path path = scene_dir / string(j["mesh"], w["mesh"]);
  const bool surface_file = is_surface_file(path);
  if (j.contains("tetrahedralize") && !surface_file)
    w["tetrahedralize"].fail("applies to surface meshes (.obj, .stl, .ply) only; \"mesh\" is " + path.string());
  const TetrahedralizeSettings settings =
      j.contains("tetrahedralize") ? read_tetrahedralize(j["tetrahedralize"], w["tetrahedralize"])
                                   : TetrahedralizeSettings{};
  const std::string key = "mesh:" + path.lexically_normal().string() + (surface_file ? "|" + tetgen_switches(settings) : "");
  if (const auto found = cache.entries.find(key); found != cache.entries.end()) return found->second;
  std::error_code error;  // the throwing fs::exists would escape with its own message
  if (!fs::exists(path, error)) w["mesh"].fail("mesh file not found: " + path.string());
  TetMesh mesh;
  try {
    mesh = surface_file ? surface_body(path, settings, cache.surface_cache_dir).mesh : read_msh(path);
  } catch (const std::exception& e) {
    w["mesh"].fail(e.what());
  }
  SurfaceMesh surface = extract_surface(mesh);
  return cache.entries.emplace(key, BodyMesh(std::move(mesh), std::move(surface))).first->second;
}

// The box mesh of the entry's "box" (`box`, at `wb`), checked against the limits before it is built.
const BodyMesh& read_box_entry(const json& box, const Where& wb, MeshCache& cache, const Model& model,
                               const SceneLimits& limits) {
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
  const std::string key = "box:" + box.dump();
  if (const auto found = cache.entries.find(key); found != cache.entries.end()) return found->second;
  const int64_t vertices = int64_t{n[0] + 1} * (n[1] + 1) * (n[2] + 1);
  const int64_t tets = kTetsPerBoxCell * int64_t{n[0]} * n[1] * n[2];
  check_size(model, vertices, tets, limits,
             "a box of " + show(cells) + " cells (" + std::to_string(vertices) + " vertices, " +
                 std::to_string(tets) + " tets)",
             wb["cells"]);
  TetMesh mesh = make_box_mesh(size, n);
  SurfaceMesh surface = extract_surface(mesh);
  return cache.entries.emplace(key, BodyMesh(std::move(mesh), std::move(surface))).first->second;
}

// The entry's "array" (`a`, at `wa`): copy counts and spacing.
void read_array(const json& a, const Where& wa, BodySpec& body) {
  check_keys(a, wa, {"count", "spacing"});
  if (!a.contains("count")) wa.fail("missing key \"count\"");
  const json& count = a["count"];
  if (!count.is_array() || count.size() != 3) wa["count"].fail("expected 3 positive integers", count);
  for (int d = 0; d < 3; ++d) {
    body.count[d] = integer(count[d], wa["count"][d], 1);
    if (body.count[d] > 1000000) wa["count"].fail("more than 1,000,000 copies", count);
  }
  // Each factor is at most 10^6 now, so the product cannot overflow.
  if (body.count[0] * body.count[1] * body.count[2] > 1000000) wa["count"].fail("more than 1,000,000 copies", count);
  if (a.contains("spacing")) body.spacing = vec3(a["spacing"], wa["spacing"]);
}

// Reads one "bodies" entry; its mesh is read or built (once per file or box), after checking
// that the body and all its copies fit in the scene's limits next to what `model` already holds.
BodySpec read_body(const json& j, const Where& w, const fs::path& scene_dir, const MaterialIds& material_ids,
                   MeshCache& cache, const Model& model, const SceneLimits& limits) {
  check_keys(j, w, {"mesh", "box", "material", "translate", "rotate_deg", "scale", "velocity", "angular_velocity",
                    "array", "tetrahedralize"});
  if (j.contains("mesh") == j.contains("box")) w.fail("give exactly one of \"mesh\" and \"box\"");
  const BodyMesh& mesh = j.contains("mesh") ? read_mesh_entry(j, w, scene_dir, cache)
                                            : read_box_entry(j["box"], w["box"], cache, model, limits);
  BodySpec body;
  body.mesh = &mesh.first;
  body.surface = &mesh.second;
  if (!j.contains("material")) w.fail("missing key \"material\"");
  body.material = material_id(j["material"], w["material"], material_ids);
  const Transform transform = read_transform(j, w);
  body.linear = transform.linear;
  body.translate = transform.translate;
  if (j.contains("velocity")) body.velocity = vec3(j["velocity"], w["velocity"]);
  if (j.contains("angular_velocity")) body.angular_velocity = vec3(j["angular_velocity"], w["angular_velocity"]);
  if (j.contains("array")) read_array(j["array"], w["array"], body);
  const int64_t copies = body.count[0] * body.count[1] * body.count[2];
  const int64_t vertices = body.mesh->num_vertices(), tets = body.mesh->num_tets();
  check_size(model, copies * vertices, copies * tets, limits,
             std::to_string(copies) + (copies == 1 ? " copy" : " copies") + " of a " + std::to_string(vertices) +
                 "-vertex, " + std::to_string(tets) + "-tet body",
             j.contains("array") ? w["array"]["count"] : w);
  return body;
}

// Appends the tets of a body whose vertices start at `base` in the model: ids, Dm^-1, rest
// volume, material, and a quarter of each tet's mass to each corner. Returns what is wrong, empty
// when nothing is: the elastic kernels need an invertible, positively oriented Dm that is not
// flat up to round-off (kDegenerateTetRelativeVolume).
//
// Out of line on purpose: how GCC rounds Dm^-1 and the volume (which products it fuses into FMAs,
// what it vectorizes) depends on the code the kernel is inlined into, and scenes are to keep
// their bits from one version of the builder to the next.
[[gnu::noinline]] std::string append_tets(const TetMesh& mesh, int32_t base, int32_t material, Model& model) {
  const double density = model.materials[material].density;
  for (int32_t t = 0; t < mesh.num_tets(); ++t) {
    int32_t ids[4];
    for (int c = 0; c < 4; ++c) ids[c] = base + mesh.tets[4 * t + c];
    Eigen::Matrix3d Dm;  // rest edges [X1-X0, X2-X0, X3-X0]
    const Eigen::Vector3d x0 = Eigen::Vector3d::Map(&model.rest_positions[3 * ids[0]]);
    for (int c = 0; c < 3; ++c) Dm.col(c) = Eigen::Vector3d::Map(&model.rest_positions[3 * ids[c + 1]]) - x0;
    Eigen::Matrix3d Dm_inv;
    double volume = 0.0;
    tet_rest_shape_from_edges(Dm, Dm_inv, volume);
    const double longest = std::max({Dm.col(0).norm(), Dm.col(1).norm(), Dm.col(2).norm(),
                                     (Dm.col(1) - Dm.col(0)).norm(), (Dm.col(2) - Dm.col(0)).norm(),
                                     (Dm.col(2) - Dm.col(1)).norm()});
    // volume > (a bound >= 0) implies det(Dm) > 0, what tet_rest_shape_from_edges returns.
    if (!(volume > kDegenerateTetRelativeVolume * longest * longest * longest) || !Dm_inv.allFinite())
      return "tet " + std::to_string(t) + " of the mesh is degenerate once placed (volume " + show(json(volume)) +
             "): size or scale too small or too uneven, or translate too large for its size";
    for (int c = 0; c < 4; ++c) {
      model.tets.push_back(ids[c]);
      model.mass[ids[c]] += density * volume / 4.0;
    }
    model.Dm_inv.insert(model.Dm_inv.end(), Dm_inv.data(), Dm_inv.data() + 9);
    model.rest_volume.push_back(volume);
    model.tet_material.push_back(material);
  }
  return "";
}

// Adds omega x (x - c) to the velocities of `count` vertices from `first`, c their centre of
// mass. The lumped masses give the exact centre: each tet puts a quarter of its mass on each
// corner, and the mean of the corners is the tet's centroid.
void spin_about_centre_of_mass(const Eigen::Vector3d& omega, int32_t first, int32_t count, const Model& model,
                               State& state) {
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  double mass = 0.0;
  for (int32_t v = first; v < first + count; ++v) {
    moment += model.mass[v] * Eigen::Vector3d::Map(&model.rest_positions[3 * v]);
    mass += model.mass[v];
  }
  const Eigen::Vector3d centre = moment / mass;
  for (int32_t v = first; v < first + count; ++v)
    Eigen::Vector3d::Map(&state.v[3 * v]) += omega.cross(Eigen::Vector3d::Map(&model.rest_positions[3 * v]) - centre);
}

// The range a body copy will take at the end of the model's arrays: `vertices` vertices, `tets`
// tets and its surface's triangles and edges.
BodyRange next_body_range(const Model& model, const SurfaceMesh& surface, int32_t vertices, int32_t tets,
                          int32_t scene_entry, int32_t material) {
  BodyRange range;
  range.vertex_begin = model.num_vertices;
  range.vertex_count = vertices;
  range.tet_begin = model.num_tets;
  range.tet_count = tets;
  range.triangle_begin = static_cast<int32_t>(model.surface_triangles.size() / 3);
  range.triangle_count = static_cast<int32_t>(surface.triangles.size() / 3);
  range.edge_begin = static_cast<int32_t>(model.surface_edges.size() / 2);
  range.edge_count = static_cast<int32_t>(surface.edges.size() / 2);
  range.scene_entry = scene_entry;
  range.material = material;
  return range;
}

// Appends one copy of an affine body (Model::AffineBody): its mesh vertices as followers, then
// its four nodes p, c_0, c_1, c_2 (engine/coordinate_map.hpp), at rest p = c (the centre of mass)
// and c_j = the principal axes R e_j, with masses m and L_j = rho lambda_j (lambda_j the
// eigenvalues of the second moment S = R diag(lambda) R^T, integrated exactly over the placed
// tets). A follower gets y = R^T (X - c) and, like the nodes, the velocity of the rigid motion
// (velocity, angular_velocity about c), so that x = J q and v = J q' hold from the start.
std::string append_affine_body(const BodySpec& spec, const Eigen::Vector3d& offset, int32_t scene_entry,
                               Model& model, State& state) {
  const TetMesh& mesh = *spec.mesh;
  const SurfaceMesh& surface = *spec.surface;
  const Material& material = model.materials[spec.material];
  const int32_t n = mesh.num_vertices();
  std::vector<double> placed(3 * int64_t{n});
  for (int32_t v = 0; v < n; ++v) {
    const Eigen::Vector3d p = spec.linear * Eigen::Vector3d::Map(&mesh.positions[3 * v]) + spec.translate + offset;
    if (!p.allFinite())
      return "vertex " + std::to_string(v) + " of the mesh is not finite once placed (translate, scale "
             "or array spacing too large)";
    Eigen::Vector3d::Map(&placed[3 * v]) = p;
  }
  const AffineMassProperties props = affine_mass_properties(placed, mesh.tets);
  Eigen::Vector3d lambda;
  Eigen::Matrix3d R;
  sym_eigen3(props.second_moment, lambda, R);  // ascending
  if (R.determinant() < 0.0) R.col(2) = -R.col(2);
  if (!(props.volume > 0.0) || !(lambda[0] > 1e-12 * lambda[2]) || !R.allFinite())
    return "the affine body has no volume, or is flat, once placed (volume " + show(json(props.volume)) +
           " m^3): its mass matrix would be singular";

  // Vertices appended since the last affine body (tet bodies) are their own nodes.
  model.follows.resize(model.num_vertices, Model::kOwnNode);
  model.follower_rest.resize(3 * int64_t{model.num_vertices}, 0.0);
  const int32_t body_id = static_cast<int32_t>(model.bodies.size());
  const int32_t affine_id = static_cast<int32_t>(model.affine_bodies.size());
  // Its tets gave its mass: it has no elastic tets.
  const BodyRange range = next_body_range(model, surface, n + 4, 0, scene_entry, spec.material);
  const int32_t base = range.vertex_begin;
  const Eigen::Vector3d& c = props.center;
  const Eigen::Vector3d& w = spec.angular_velocity;

  auto push_vertex = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& v, double mass, int32_t follows,
                         const Eigen::Vector3d& y) {
    for (int d = 0; d < 3; ++d) {
      model.rest_positions.push_back(x[d]);
      state.v.push_back(v[d]);
      model.follower_rest.push_back(y[d]);
    }
    model.mass.push_back(mass);
    model.vertex_body.push_back(body_id);
    model.dirichlet.push_back(-1);
    model.follows.push_back(follows);
  };
  for (int32_t v = 0; v < n; ++v) {
    const Eigen::Vector3d X = Eigen::Vector3d::Map(&placed[3 * v]);
    push_vertex(X, spec.velocity + w.cross(X - c), 0.0, affine_id, R.transpose() * (X - c));
  }
  const double density = material.density;
  push_vertex(c, spec.velocity, density * props.volume, Model::kCentreNode, Eigen::Vector3d::Zero());
  for (int j = 0; j < 3; ++j)
    push_vertex(R.col(j), w.cross(R.col(j)), density * lambda[j], Model::kAxisNode, Eigen::Vector3d::Zero());

  AffineBody body;
  body.body = body_id;
  body.node = base + n;
  body.follower_begin = base;
  body.follower_count = n;
  body.volume = props.volume;
  body.stiffness = material.stiffness;
  body.frame = R;
  model.affine_bodies.push_back(body);
  for (int32_t i : mesh.tets) model.affine_tets.push_back(base + i);
  for (int32_t i : surface.triangles) model.surface_triangles.push_back(base + i);
  for (int32_t i : surface.edges) model.surface_edges.push_back(base + i);
  for (int32_t i : surface.vertices) model.surface_vertices.push_back(base + i);
  model.num_vertices += range.vertex_count;
  model.bodies.push_back(range);
  return "";
}

// Appends one transformed copy of a body to the model and the initial state. Returns what is
// wrong with the copy, empty when nothing is: a transform can overflow a position to infinity
// (translate 1e308 plus an array spacing) or flatten tets that were fine in the mesh's own frame
// (scale [1, 1, 1e-300]), and the elastic kernels need finite rest positions and invertible Dm.
std::string append_body(const BodySpec& spec, const Eigen::Vector3d& offset, int32_t scene_entry, Model& model,
                        State& state) {
  if (model.materials[spec.material].affine) return append_affine_body(spec, offset, scene_entry, model, state);
  const TetMesh& mesh = *spec.mesh;
  const SurfaceMesh& surface = *spec.surface;
  const BodyRange range =
      next_body_range(model, surface, mesh.num_vertices(), mesh.num_tets(), scene_entry, spec.material);
  const int32_t body_id = static_cast<int32_t>(model.bodies.size());
  const int32_t base = range.vertex_begin;

  for (int32_t v = 0; v < mesh.num_vertices(); ++v) {
    const Eigen::Vector3d p = spec.linear * Eigen::Vector3d::Map(&mesh.positions[3 * v]) + spec.translate + offset;
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
  if (std::string problem = append_tets(mesh, base, spec.material, model); !problem.empty()) return problem;
  if (!spec.angular_velocity.isZero())
    spin_about_centre_of_mass(spec.angular_velocity, base, mesh.num_vertices(), model, state);
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

// Every entry of "bodies" (`bodies`, at `w`), each copy of an "array" as its own body.
void append_bodies(const json& bodies, const Where& w, const fs::path& scene_dir, const MaterialIds& material_ids,
                   const SceneLimits& limits, const fs::path& surface_cache_dir, Model& model, State& initial) {
  MeshCache cache;
  cache.surface_cache_dir = surface_cache_dir;
  for (size_t b = 0; b < bodies.size(); ++b) {
    const BodySpec spec = read_body(bodies[b], w[b], scene_dir, material_ids, cache, model, limits);
    for (int64_t i = 0; i < spec.count[0]; ++i)
      for (int64_t k = 0; k < spec.count[1]; ++k)
        for (int64_t l = 0; l < spec.count[2]; ++l) {
          const Eigen::Vector3d offset(i * spec.spacing.x(), k * spec.spacing.y(), l * spec.spacing.z());
          const std::string problem = append_body(spec, offset, static_cast<int32_t>(b), model, initial);
          if (problem.empty()) continue;
          const bool single = spec.count == std::array<int64_t, 3>{1, 1, 1};
          w[b].fail((single ? std::string()
                            : "copy (" + std::to_string(i) + ", " + std::to_string(k) + ", " + std::to_string(l) +
                                  ") of the array: ") +
                    problem);
        }
  }
}

// ---- boundary conditions -------------------------------------------------------------------------

void read_boundary(const json& j, const Where& w, Model& model, int64_t num_scene_bodies) {
  check_keys(j, w, {"body", "box_min", "box_max", "fix", "velocity", "angular_velocity", "axis", "center"});
  Eigen::Vector3d lo, hi;
  const DirichletMotion motion = read_box_motion(j, w, lo, hi);
  std::optional<int64_t> only_entry;
  if (j.contains("body")) {
    only_entry = integer(j["body"], w["body"], 0);
    if (*only_entry >= num_scene_bodies)
      w["body"].fail("no such body (the scene has " + std::to_string(num_scene_bodies) + ")", j["body"]);
  }

  const int32_t id = static_cast<int32_t>(model.dirichlet_motions.size());
  int64_t selected = 0;
  for (int32_t v = 0; v < model.num_vertices; ++v) {
    const BodyRange& body = model.bodies[model.vertex_body[v]];
    // Obstacle vertices already follow their own fixed motion, and an obstacle's scene_entry
    // counts "obstacles" entries, not "bodies" entries, so "body" must never match it.
    if (body.obstacle) continue;
    if (only_entry && body.scene_entry != *only_entry) continue;
    // An affine body's nodes are coordinates, not points of it: a box never selects them. It
    // selects the followers (points of the body), and a body one of whose points it holds is
    // held whole: its four nodes take the boundary (at rest, A stays the identity and p the
    // centre; a moving box would have to turn the axis nodes as directions, not yet done).
    if (!model.follows.empty() && model.follows[v] < Model::kOwnNode) continue;
    const Eigen::Vector3d p = Eigen::Vector3d::Map(&model.rest_positions[3 * v]);
    if (!(p.array() >= lo.array()).all() || !(p.array() <= hi.array()).all()) continue;
    const bool follower = model.follows_body(v);
    if (follower && motion.moves())
      w.fail("selects a vertex of body " + std::to_string(body.scene_entry) +
             ", an affine body: only a fixed boundary (no velocity or angular_velocity) can hold one yet");
    int32_t held[4] = {v, -1, -1, -1};
    if (follower)
      for (int k = 0; k < 4; ++k) held[k] = model.affine_bodies[model.follows[v]].node + k;
    for (int32_t h : held) {
      if (h < 0) continue;
      if (model.dirichlet[h] >= 0 && model.dirichlet[h] != id)
        w.fail("selects vertex " + std::to_string(v) + " already held by boundary[" +
               std::to_string(model.dirichlet[h]) + "]");
      model.dirichlet[h] = id;
    }
    ++selected;
  }
  if (selected == 0) w.fail("the box selects no vertex");
  model.dirichlet_motions.push_back(motion);
}

}  // namespace

// ---- shared with build_obstacles.cpp -------------------------------------------------------------

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

DirichletMotion read_box_motion(const json& j, const Where& w, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  if (!j.contains("box_min") || !j.contains("box_max")) w.fail("needs \"box_min\" and \"box_max\"");
  lo = vec3(j["box_min"], w["box_min"]);
  hi = vec3(j["box_max"], w["box_max"]);
  if (!(lo.array() <= hi.array()).all()) w["box_max"].fail("box_max must be >= box_min in x, y and z", j["box_max"]);
  const bool fix = j.contains("fix");
  if (fix && !boolean(j["fix"], w["fix"])) w["fix"].fail("\"fix\" can only be true; leave it out for a moving boundary");
  if (fix && (j.contains("velocity") || j.contains("angular_velocity")))
    w.fail("\"fix\" cannot be combined with \"velocity\" or \"angular_velocity\"");
  if (!fix && !j.contains("velocity") && !j.contains("angular_velocity"))
    w.fail("give \"fix\": true, a \"velocity\" or an \"angular_velocity\"");
  return read_motion(j, w, 0.5 * (lo + hi));
}

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

void check_size(const Model& model, int64_t vertices, int64_t tets, const SceneLimits& limits,
                const std::string& what, const Where& w) {
  const int64_t total_vertices = model.num_vertices + vertices;
  const int64_t total_tets = model.num_tets + tets;
  if (total_vertices > limits.max_vertices)
    w.fail(what + " would give the scene " + std::to_string(total_vertices) + " vertices, more than the limit of " +
           std::to_string(limits.max_vertices));
  if (total_tets > limits.max_tets)
    w.fail(what + " would give the scene " + std::to_string(total_tets) + " tets, more than the limit of " +
           std::to_string(limits.max_tets));
}

// ---- the whole model -----------------------------------------------------------------------------

void build_model(const json& root, const Where& w, const fs::path& scene_dir, const MaterialIds& material_ids,
                 const SceneLimits& limits, bool contact_enabled, const fs::path& surface_cache_dir, Model& model,
                 State& initial) {
  if (!root.contains("bodies")) w.fail("missing key \"bodies\"");
  const json& bodies = root["bodies"];
  if (!bodies.is_array() || bodies.empty()) w["bodies"].fail("expected a non-empty array of bodies");
  append_bodies(bodies, w["bodies"], scene_dir, material_ids, limits, surface_cache_dir, model, initial);
  const int64_t num_scene_bodies = static_cast<int64_t>(bodies.size());
  // Tet bodies after the last affine body are their own nodes (boundaries below read follows).
  if (!model.affine_bodies.empty()) {
    model.follows.resize(model.num_vertices, Model::kOwnNode);
    model.follower_rest.resize(3 * int64_t{model.num_vertices}, 0.0);
  }

  if (root.contains("boundary")) {
    const json& boundary = root["boundary"];
    if (!boundary.is_array()) w["boundary"].fail("expected an array", boundary);
    for (size_t i = 0; i < boundary.size(); ++i)
      read_boundary(boundary[i], w["boundary"][i], model, num_scene_bodies);
  }

  // Joints, on the bodies' tets.
  if (root.contains("joints")) append_joints(root["joints"], w["joints"], model, num_scene_bodies);

  // Obstacles, after every body and every boundary entry: "bodies" entries keep their body
  // indices, and the shared fixed motion of obstacle meshes comes after the "boundary" motions.
  if (root.contains("obstacles"))
    append_obstacles(root["obstacles"], w["obstacles"], scene_dir, material_ids, limits, model, initial);

  // With contact, moving boundaries and obstacles push bodies: their vertices become unknowns
  // held by an augmented Lagrangian (Model::eliminated).
  for (DirichletMotion& motion : model.dirichlet_motions) motion.kinematic = contact_enabled && motion.moves();

  // Obstacle vertices, appended after the bodies, are their own nodes.
  if (!model.affine_bodies.empty()) {
    model.follows.resize(model.num_vertices, Model::kOwnNode);
    model.follower_rest.resize(3 * int64_t{model.num_vertices}, 0.0);
  }
}

}  // namespace nexdyn::scene_io

// view.json writer and reader (see view_file.hpp).
#include "engine/render/view_file.hpp"

#include "engine/mesh/mesh_file.hpp"

#include <nlohmann/json.hpp>

#include <stdexcept>

namespace nexdyn {

namespace {

using json = nlohmann::json;

json to_json(const Eigen::Vector3d& v) { return json::array({v.x(), v.y(), v.z()}); }

Eigen::Vector3d vector_at(const json& j, const char* key) {
  const json& a = j.at(key);
  if (!a.is_array() || a.size() != 3) throw std::runtime_error(std::string("\"") + key + "\" is not 3 numbers");
  Eigen::Vector3d v;
  for (int d = 0; d < 3; ++d) v[d] = a.at(static_cast<size_t>(d)).get<double>();
  if (!v.allFinite()) throw std::runtime_error(std::string("\"") + key + "\" is not finite");
  return v;
}

}  // namespace

SceneView scene_view(const Scene& scene) {
  const Model& model = scene.model;
  SceneView view;
  if (model.gravity.norm() > 0.0) view.up = -model.gravity.normalized();
  for (const ObstaclePlane& plane : model.obstacle_planes) view.planes.push_back({plane.point, plane.normal});
  if (scene.mpm)
    for (const MpmPlane& plane : scene.mpm->planes) view.planes.push_back({plane.point, plane.normal});
  for (size_t t = 0; t + 2 < model.surface_triangles.size(); t += 3)
    if (model.bodies[model.vertex_body[model.surface_triangles[t]]].obstacle)
      for (int c = 0; c < 3; ++c) view.obstacle_triangles.push_back(static_cast<uint32_t>(model.surface_triangles[t + c]));
  if (scene.output.camera) {
    const CameraSettings& c = *scene.output.camera;
    RenderCamera camera;
    camera.position = c.position;
    camera.target = c.target;
    camera.up = c.up;  // the scene loader filled a missing up from gravity
    camera.fov_deg = c.fov_deg;
    view.camera = camera;
  }
  return view;
}

std::string view_document(const SceneView& view) {
  json j;
  j["format"] = 1;
  j["up"] = to_json(view.up);
  j["planes"] = json::array();
  for (const RenderInput::Plane& p : view.planes)
    j["planes"].push_back({{"point", to_json(p.point)}, {"normal", to_json(p.normal)}});
  j["obstacle_triangles"] = view.obstacle_triangles;
  if (view.camera)
    j["camera"] = {{"position", to_json(view.camera->position)}, {"target", to_json(view.camera->target)},
                   {"up", to_json(view.camera->up)}, {"fov_deg", view.camera->fov_deg}};
  return j.dump() + "\n";
}

SceneView read_view(const std::filesystem::path& run_dir) {
  const std::filesystem::path file = run_dir / "view.json";
  SceneView view;
  std::error_code error;
  if (!std::filesystem::exists(file, error)) return view;
  try {
    const json j = json::parse(read_mesh_file(file));
    if (j.at("format").get<int>() != 1) throw std::runtime_error("unknown format");
    view.up = vector_at(j, "up").normalized();
    for (const json& p : j.at("planes")) view.planes.push_back({vector_at(p, "point"), vector_at(p, "normal").normalized()});
    view.obstacle_triangles = j.at("obstacle_triangles").get<std::vector<uint32_t>>();
    if (view.obstacle_triangles.size() % 3 != 0) throw std::runtime_error("obstacle_triangles not in threes");
    if (j.contains("camera")) {
      const json& c = j["camera"];
      RenderCamera camera;
      camera.position = vector_at(c, "position");
      camera.target = vector_at(c, "target");
      camera.up = vector_at(c, "up");
      camera.fov_deg = c.at("fov_deg").get<double>();
      view.camera = camera;
    }
  } catch (const std::exception& e) {
    throw std::runtime_error(file.string() + ": malformed (" + e.what() + ")");
  }
  return view;
}

}  // namespace nexdyn

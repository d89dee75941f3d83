// DIR/view.json: what `nexdyn render` needs of a run that its frames do not hold. The VTU frames
// carry the bodies (points, tets, velocity, body id) and the obstacle meshes' points, but not the
// obstacle planes, the obstacle meshes' triangles, the direction of gravity or the scene's
// output.camera; `nexdyn run` writes them here once, at the start of a fresh run.
#pragma once

#include "engine/render/renderer.hpp"
#include "engine/scene/scene.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nexdyn {

struct SceneView {
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();  // against gravity (+y without gravity)
  std::vector<RenderInput::Plane> planes;         // the obstacle planes
  std::vector<uint32_t> obstacle_triangles;       // (num x 3) global point ids of obstacle meshes
  std::optional<RenderCamera> camera;             // the scene's output.camera
};

// The view of a loaded scene, and its JSON text (view.json).
SceneView scene_view(const Scene& scene);
std::string view_document(const SceneView& view);

// Reads DIR/view.json; a run folder without one (written before view.json existed) gives the
// default view: no planes or obstacle triangles, y up. Throws std::runtime_error naming the file
// when it exists but is malformed.
SceneView read_view(const std::filesystem::path& run_dir);

}  // namespace nexdyn

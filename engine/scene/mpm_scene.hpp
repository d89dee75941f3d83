// The scene reader's MPM part (issue 23): particle bodies, the top-level "mpm" grid, plane
// obstacles as grid boundary conditions and "boundary" boxes on grid nodes, into Scene::mpm.
// Every key is in docs/scenes.md, "MPM: particle bodies".
#pragma once

#include "engine/scene/json_reader.hpp"
#include "engine/scene/scene.hpp"
#include "engine/scene/settings_readers.hpp"

#include <filesystem>

namespace nexdyn::scene_io {

// Whether the file describes an MPM scene: it has "mpm", or a body has "particles".
bool is_mpm_scene(const json& root);

// Builds scene.mpm from the file (`root`, at `w`), whose settings and materials are read. Refuses,
// naming the key, what MPM scenes do not support: tet bodies beside particle bodies, obstacle
// meshes, joints, contact keys other than "friction", solver methods other than Newton, damping.
void build_mpm_model(const json& root, const Where& w, const std::filesystem::path& scene_dir,
                     const SceneLimits& limits, Scene& scene);

}  // namespace nexdyn::scene_io

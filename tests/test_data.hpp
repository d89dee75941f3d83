// Where the tests and benchmarks find the files they read: all of them are inside the repository
// (tests/data/ and scenes/; `tests/data/*/README.md` names each file's origin and licence).
#pragma once

#include <filesystem>
#include <string>

namespace nexdyn::test {

// A file under tests/data/, e.g. test_data("ccd/vertex-face.txt").
inline std::filesystem::path test_data(const std::string& relative) {
  return std::filesystem::path(NEXDYN_SOURCE_DIR) / "tests" / "data" / relative;
}

// An IPC tet mesh by its path under the IPC repository's input/tetMeshes/ ("torus.msh",
// "arch/largeArch.01.msh"): those the shipped scenes use are in scenes/meshes/, the rest in
// tests/data/ipc-meshes/tetMeshes/.
inline std::filesystem::path ipc_tet_mesh(const std::string& name) {
  const std::filesystem::path here = test_data("ipc-meshes/tetMeshes/" + name);
  return std::filesystem::exists(here) ? here : std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes" / "meshes" / name;
}

// The same for a triangle surface under input/triMeshes/ ("cube.obj", "erleben/hole.obj").
inline std::filesystem::path ipc_tri_mesh(const std::string& name) {
  const std::filesystem::path here = test_data("ipc-meshes/triMeshes/" + name);
  return std::filesystem::exists(here) ? here : std::filesystem::path(NEXDYN_SOURCE_DIR) / "scenes" / "meshes" / name;
}

}  // namespace nexdyn::test

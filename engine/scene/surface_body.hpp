// Bodies given as closed triangle surfaces (.obj, .stl, .ply): read, checked, tetrahedralised
// with TetGen (engine/mesh/tetrahedralize.hpp), and cached.
//
// Tetrahedralising takes from milliseconds to minutes, and a run, its resume and the next run of
// the same scene all need the same tets, so the result is kept beside the output as
// DIR/meshes/NAME-CHECKSUM.msh. The checksum covers the surface file's bytes, the TetGen switches
// the settings make and a format number, so a changed input or setting gets a new file and an
// unchanged one reuses its file. A cached file that cannot be read is made again.
#pragma once

#include "engine/mesh/tet_mesh.hpp"
#include "engine/mesh/tetrahedralize.hpp"

#include <cstdint>
#include <filesystem>
#include <string>

namespace nexdyn {

// .obj, .stl or .ply, in any letter case.
bool is_surface_file(const std::filesystem::path& path);

struct SurfaceBody {
  TetMesh mesh;
  std::filesystem::path cache_file;  // empty when no cache folder was given
  bool reused = false;               // read from cache_file rather than tetrahedralised
};

// The cache file's name for this input and settings: "<stem>-<16 hex digits>.msh".
std::string surface_cache_name(const std::filesystem::path& surface_file, const std::string& file_bytes,
                               const TetrahedralizeSettings& settings);

// Reads and checks the surface, then takes its tets from `cache_dir` or makes them (and, with a
// cache folder, writes them there). An empty cache_dir only tetrahedralises. Throws MeshError
// with one line naming the file on a bad surface, or std::runtime_error on a cache write error.
SurfaceBody surface_body(const std::filesystem::path& surface_file, const TetrahedralizeSettings& settings,
                         const std::filesystem::path& cache_dir);

}  // namespace nexdyn

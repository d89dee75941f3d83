// Surface files as bodies, with the mesh cache (see surface_body.hpp).
#include "engine/scene/surface_body.hpp"

#include "engine/atomic_file.hpp"
#include "engine/mesh/mesh_file.hpp"
#include "engine/mesh/msh_reader.hpp"
#include "engine/mesh/msh_writer.hpp"
#include "engine/mesh/surface_check.hpp"
#include "engine/mesh/surface_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>

namespace nexdyn {

namespace fs = std::filesystem;

namespace {

// Bumped whenever the same input and settings could give other tets (a TetGen upgrade, another
// way of calling it), so that no stale cache file is reused.
constexpr const char* kCacheFormat = "nexdyn surface tets 1, TetGen 1.5.0";

// 64-bit FNV-1a: a fast, well-spread checksum; the cache needs to tell inputs apart, not resist
// an adversary.
uint64_t fnv1a(std::string_view bytes, uint64_t hash = 0xcbf29ce484222325ull) {
  for (unsigned char c : bytes) {
    hash ^= c;
    hash *= 0x100000001b3ull;
  }
  return hash;
}

}  // namespace

bool is_surface_file(const fs::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension == ".obj" || extension == ".stl" || extension == ".ply";
}

std::string surface_cache_name(const fs::path& surface_file, const std::string& file_bytes,
                               const TetrahedralizeSettings& settings) {
  uint64_t hash = fnv1a(kCacheFormat);
  hash = fnv1a("\n" + tetgen_switches(settings) + "\n", hash);
  hash = fnv1a(file_bytes, hash);
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
  return surface_file.stem().string() + "-" + hex + ".msh";
}

SurfaceBody surface_body(const fs::path& surface_file, const TetrahedralizeSettings& settings,
                         const fs::path& cache_dir) {
  const std::string name = surface_file.string();
  if (const std::string problem = tetrahedralize_settings_problem(settings); !problem.empty())
    throw MeshError(name + ": " + problem);
  SurfaceBody body;
  const std::string bytes = read_mesh_file(surface_file);
  if (!cache_dir.empty()) {
    body.cache_file = cache_dir / surface_cache_name(surface_file, bytes, settings);
    std::error_code error;
    if (fs::is_regular_file(body.cache_file, error)) {
      try {
        body.mesh = read_msh(body.cache_file);
        body.reused = true;
        return body;
      } catch (const MeshError&) {
        // A damaged cache file (a crash mid-write cannot make one, a hand edit can): make it again.
      }
    }
  }
  const TriangleSurface surface = checked_closed_surface(read_triangle_surface(surface_file), name);
  body.mesh = tetrahedralize_surface(surface.positions, surface.triangles, settings, name);
  if (!cache_dir.empty()) {
    std::error_code error;
    fs::create_directories(cache_dir, error);
    if (error) throw std::runtime_error(cache_dir.string() + ": cannot create the mesh cache folder: " + error.message());
    write_file_atomically(body.cache_file, msh_document(body.mesh));
  }
  return body;
}

}  // namespace nexdyn

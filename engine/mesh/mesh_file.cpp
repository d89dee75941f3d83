// Whole-file reads for the mesh readers (see mesh_file.hpp).
#include "engine/mesh/mesh_file.hpp"

#include <cstdio>
#include <system_error>

namespace nexdyn {

std::string read_mesh_file(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code error;
  if (!std::filesystem::is_regular_file(path, error))
    throw MeshError(name + ": cannot open mesh file (" +
                    (std::filesystem::exists(path, error) ? "not a regular file" : "no such file") + ")");
  std::FILE* file = std::fopen(name.c_str(), "rb");
  if (file == nullptr) throw MeshError(name + ": cannot open mesh file for reading");
  // Read straight into the string (sized from the file system when it knows the size), then
  // append whatever remains, so a file that grows or lies about its size is still read whole.
  std::string text;
  const auto size = std::filesystem::file_size(path, error);
  if (!error) text.resize(static_cast<std::size_t>(size));
  text.resize(std::fread(text.data(), 1, text.size(), file));
  char buffer[1 << 16];
  std::size_t got = 0;
  while ((got = std::fread(buffer, 1, sizeof buffer, file)) > 0) text.append(buffer, got);
  const bool read_failed = std::ferror(file) != 0;
  std::fclose(file);
  if (read_failed) throw MeshError(name + ": read error");
  return text;
}

}  // namespace nexdyn

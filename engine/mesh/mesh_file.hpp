// Reading a mesh file into memory, shared by the .msh and .obj readers.
//
// Both readers parse text held in memory (so the fuzzers can feed them bytes directly); this is
// the one place that turns a path into that text, with the same MeshError messages for a
// missing, special or unreadable file.
#pragma once

#include <filesystem>
#include <string>

#include "engine/mesh/mesh_error.hpp"

namespace nexdyn {

// The whole file. Throws MeshError naming the file when it is missing, not a regular file (a
// folder, a FIFO) or cannot be read.
std::string read_mesh_file(const std::filesystem::path& path);

}  // namespace nexdyn

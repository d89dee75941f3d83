// Files written whole or not at all: a reader (ParaView, a resumed run, the mesh cache) never
// sees a half-written file, even when the run is killed in the middle of a write.
#pragma once

#include <filesystem>
#include <string>

namespace nexdyn {

// Writes `contents` to "<path>.tmp", flushes it and renames it onto path. Throws
// std::runtime_error naming the file on any I/O error (path itself is then left as it was).
void write_file_atomically(const std::filesystem::path& path, const std::string& contents);

}  // namespace nexdyn

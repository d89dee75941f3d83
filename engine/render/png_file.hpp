// PNG files of rendered pictures through libpng: written whole under a temporary name and renamed
// into place (as every output file of the engine), and read back for tests and tools.
#pragma once

#include "engine/render/renderer.hpp"

#include <filesystem>

namespace nexdyn {

// 8-bit RGB, no time stamp or other chunk that would change between runs: the same Image gives
// the same bytes. Throws std::runtime_error naming the file on failure.
void write_png(const std::filesystem::path& path, const Image& image);

// Reads an 8-bit RGB or RGBA PNG (alpha dropped). Throws std::runtime_error naming the file.
Image read_png(const std::filesystem::path& path);

}  // namespace nexdyn

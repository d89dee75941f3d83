// Reading back what `nexdyn run` wrote: the frame list of scene.pvd and the arrays of one VTU
// frame (engine/output/frame_writer.cpp's layout: raw appended data, UInt64 block headers).
//
// Only our own files are read, but they may be truncated, edited or from another program, so
// every size and offset is checked against the file before it is used: a bad file is one
// std::runtime_error line naming it and what is wrong, never a read past the end.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace nexdyn {

struct FrameEntry {
  double time = 0.0;                // [s]
  int64_t number = 0;               // NNNNNN of frames/frame_NNNNNN.vtu
  std::filesystem::path file;       // absolute or relative to the working folder
};

// The frames listed in DIR/scene.pvd, in file order. Throws when it is missing or malformed.
std::vector<FrameEntry> read_frame_list(const std::filesystem::path& run_dir);

struct FrameData {
  std::vector<double> points;    // (num_points x 3) [m]
  std::vector<int32_t> tets;     // (num_tets x 4) point ids
  std::vector<double> velocity;  // (num_points x 3) [m/s]
  std::vector<int32_t> body;     // (num_points) body id of each point
  std::vector<double> radius;    // (num_points) particle radius [m]: a particle cloud (MPM), no tets
  int32_t num_points() const { return static_cast<int32_t>(points.size() / 3); }
};

// Parses VTU bytes as written by vtu_document; `name` for messages.
FrameData parse_vtu_frame(std::string_view bytes, std::string_view name);
FrameData read_vtu_frame(const std::filesystem::path& file);

}  // namespace nexdyn

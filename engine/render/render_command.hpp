// `nexdyn render DIR`: PNG pictures of a run's frames (renderer.hpp), one frame or all of them,
// and with ffmpeg on the machine a video of them.
#pragma once

#include "engine/render/frame_reader.hpp"
#include "engine/render/renderer.hpp"
#include "engine/render/view_file.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace nexdyn {

struct RenderOptions {
  std::filesystem::path run_dir;                // the output folder of `nexdyn run`
  std::filesystem::path out_dir;                // empty: DIR/render
  std::optional<int64_t> frame;                 // NNNNNN of frame_NNNNNN.vtu; none: the last frame
  bool all = false;                             // every frame of scene.pvd, in parallel
  int width = 1280, height = 720;
  std::optional<RenderCamera> camera;           // none: the scene's output.camera, else fitted
  ColorBy color = ColorBy::body;                // or ColorBy::value: speed
  std::filesystem::path video;                  // with `all`: an .mp4 of the pictures (ffmpeg)
  double fps = 0.0;                             // of the video; 0: from the frames' times, 1 to 60
};

// What every picture of a run shares: the camera (the options', else the scene's, else fitted to
// the bounds of the first and last frames, so it stays put through a video), the grid spacing
// and the planes drawn (the obstacle planes, or a ground grid under the bodies when none faces
// up).
struct RenderSetting {
  RenderCamera camera;
  std::vector<RenderInput::Plane> planes;
  double grid_spacing = 0.1;
};
RenderSetting choose_render_setting(const RenderOptions& options, const SceneView& view, const FrameData& first,
                                    const FrameData& last);

// The picture of one frame: its surface (extracted from its tets) and the obstacle triangles.
Image render_frame(const FrameData& frame, const SceneView& view, const RenderSetting& setting,
                   const RenderOptions& options, const std::string& name);

// The checks of the options that need no file: sizes, video without all. "" when fine.
std::string render_options_problem(const RenderOptions& options);

// Renders what the options ask; returns the files written (pictures, then the video). Throws
// std::runtime_error with one line (naming the file) on bad input; pictures are written whole.
std::vector<std::filesystem::path> render_run(const RenderOptions& options);

// Parses "--camera" text "EX,EY,EZ,TX,TY,TZ[,FOV]" (eye, target, vertical field of view in
// degrees); `up` fills the camera's up. Throws std::runtime_error saying what is wrong.
RenderCamera parse_camera(const std::string& text, const Eigen::Vector3d& up);

}  // namespace nexdyn

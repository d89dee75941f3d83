// `nexdyn render` (see render_command.hpp).
#include "engine/render/render_command.hpp"

#include "engine/mesh/surface.hpp"
#include "engine/parallel.hpp"
#include "engine/render/frame_reader.hpp"
#include "engine/render/png_file.hpp"
#include "engine/render/view_file.hpp"

#include <Eigen/Geometry>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace nexdyn {

namespace fs = std::filesystem;

namespace {

// The points drawn: every point of a particle frame, the tets' corners of a tet frame (an affine
// body's node points, its coordinates, are in no tet and are not drawn).
std::vector<uint8_t> drawn_points(const FrameData& frame) {
  std::vector<uint8_t> drawn(frame.num_points(), frame.tets.empty() ? 1 : 0);
  for (int32_t v : frame.tets) drawn[v] = 1;
  return drawn;
}

void bounds_of(const FrameData& frame, Eigen::Vector3d& lower, Eigen::Vector3d& upper) {
  const std::vector<uint8_t> drawn = drawn_points(frame);
  for (int32_t v = 0; v < frame.num_points(); ++v) {
    if (!drawn[v]) continue;
    const Eigen::Vector3d p(frame.points[3 * v], frame.points[3 * v + 1], frame.points[3 * v + 2]);
    lower = lower.cwiseMin(p);
    upper = upper.cwiseMax(p);
  }
}

}  // namespace

RenderSetting choose_render_setting(const RenderOptions& options, const SceneView& view, const FrameData& first,
                                    const FrameData& last) {
  Eigen::Vector3d lower = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), upper = -lower;
  bounds_of(first, lower, upper);
  bounds_of(last, lower, upper);
  if (!lower.allFinite() || !upper.allFinite()) lower = upper = Eigen::Vector3d::Zero();
  RenderSetting s;
  s.grid_spacing = round_grid_spacing((upper - lower).maxCoeff());
  s.planes = view.planes;
  // A ground grid under the bodies when no obstacle plane faces up: something to stand on for the
  // eye, a measure of size and of motion.
  const bool has_floor = std::any_of(s.planes.begin(), s.planes.end(),
                                     [&](const RenderInput::Plane& p) { return p.normal.dot(view.up) > 0.9; });
  if (!has_floor) {
    double lowest = std::numeric_limits<double>::infinity();
    for (const FrameData* f : {&first, &last}) {
      const std::vector<uint8_t> drawn = drawn_points(*f);
      for (int32_t v = 0; v < f->num_points(); ++v)
        if (drawn[v]) lowest = std::min(lowest, Eigen::Vector3d(&f->points[3 * v]).dot(view.up));
    }
    if (!std::isfinite(lowest)) lowest = 0.0;
    const double gap = 0.02 * std::max((upper - lower).norm(), 1e-3);
    s.planes.push_back({(lowest - gap) * view.up, view.up});
  }
  if (options.camera) s.camera = *options.camera;
  else if (view.camera) s.camera = *view.camera;
  else
    s.camera = fit_camera(lower, upper, view.up, 40.0, static_cast<double>(options.width) / options.height);
  return s;
}

namespace {

// A particle cloud as one small icosahedron per particle (12 corners, 20 outward triangles), so
// the triangle tracer draws it; each corner carries its particle's body and speed.
RenderInput particle_input(const FrameData& frame) {
  const double g = (1.0 + std::sqrt(5.0)) / 2.0, scale = 1.0 / std::sqrt(1.0 + g * g);
  const double corner[12][3] = {{-1, g, 0}, {1, g, 0},  {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                                {0, -1, -g}, {0, 1, -g}, {g, 0, -1},  {g, 0, 1},  {-g, 0, -1}, {-g, 0, 1}};
  const uint32_t face[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  RenderInput in;
  const int32_t n = frame.num_points();
  in.positions.reserve(static_cast<size_t>(n) * 36);
  in.triangles.reserve(static_cast<size_t>(n) * 60);
  for (int32_t p = 0; p < n; ++p) {
    const uint32_t base = static_cast<uint32_t>(in.positions.size() / 3);
    const double r = frame.radius[p] * scale;
    for (const auto& c : corner)
      for (int d = 0; d < 3; ++d) in.positions.push_back(static_cast<float>(frame.points[3 * p + d] + r * c[d]));
    for (const auto& f : face) {
      for (uint32_t c : f) in.triangles.push_back(base + c);
      in.triangle_body.push_back(frame.body[p]);
    }
  }
  return in;
}

RenderInput render_input(const FrameData& frame, const SceneView& view, const RenderSetting& setting, ColorBy color,
                         const std::string& file) {
  if (!frame.radius.empty()) {
    RenderInput in = particle_input(frame);
    if (color == ColorBy::value) {
      in.vertex_value.reserve(in.positions.size() / 3);
      float top = 0.0f;
      for (int32_t p = 0; p < frame.num_points(); ++p) {
        const float speed = static_cast<float>(Eigen::Vector3d(&frame.velocity[3 * p]).norm());
        in.vertex_value.insert(in.vertex_value.end(), 12, speed);
        top = std::max(top, speed);
      }
      in.value_max = top;
    }
    in.planes = setting.planes;
    in.grid_spacing = setting.grid_spacing;
    in.up = view.up;
    return in;
  }
  RenderInput in;
  in.positions.assign(frame.points.begin(), frame.points.end());
  const SurfaceMesh surface = extract_surface(frame.tets, frame.num_points());
  in.triangles.assign(surface.triangles.begin(), surface.triangles.end());
  for (size_t t = 0; t < surface.triangles.size(); t += 3) in.triangle_body.push_back(frame.body[surface.triangles[t]]);
  for (uint32_t id : view.obstacle_triangles)
    if (id >= static_cast<uint32_t>(frame.num_points()))
      throw std::runtime_error(file + ": view.json names point " + std::to_string(id) + " but the frame has " +
                               std::to_string(frame.num_points()));
  in.triangles.insert(in.triangles.end(), view.obstacle_triangles.begin(), view.obstacle_triangles.end());
  in.triangle_body.resize(in.triangles.size() / 3, -1);
  if (color == ColorBy::value) {
    in.vertex_value.resize(static_cast<size_t>(frame.num_points()));
    float top = 0.0f;
    for (int32_t v = 0; v < frame.num_points(); ++v) {
      const Eigen::Vector3d u(&frame.velocity[3 * v]);
      in.vertex_value[v] = static_cast<float>(u.norm());
      top = std::max(top, in.vertex_value[v]);
    }
    in.value_max = top;
  }
  in.planes = setting.planes;
  in.grid_spacing = setting.grid_spacing;
  in.up = view.up;
  return in;
}

}  // namespace

Image render_frame(const FrameData& frame, const SceneView& view, const RenderSetting& setting,
                   const RenderOptions& options, const std::string& name) {
  const RenderInput in = render_input(frame, view, setting, options.color, name);
  return render_image(in, setting.camera, options.width, options.height, options.color);
}

namespace {

fs::path picture_name(const fs::path& out_dir, int64_t number) {
  char name[64];
  std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(number));
  return out_dir / name;
}

bool program_on_path(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::stringstream dirs(path ? path : "");
  std::string dir;
  while (std::getline(dirs, dir, ':'))
    if (!dir.empty() && access((fs::path(dir) / name).c_str(), X_OK) == 0) return true;
  return false;
}

// ffmpeg over `pictures` in their order, into `video` (written under a temporary name and renamed
// into place). Frame numbers step by output.every, so ffmpeg reads numbered links in a folder
// of their own, removed afterwards.
void encode_video(const std::vector<fs::path>& pictures, const fs::path& video, double fps) {
  const fs::path links = video.parent_path() / (video.stem().string() + ".frames");
  const fs::path partial = video.parent_path() / (video.stem().string() + ".partial" + video.extension().string());
  std::error_code ec;
  fs::remove_all(links, ec);
  fs::create_directories(links, ec);
  if (ec) throw std::runtime_error(links.string() + ": cannot create the folder: " + ec.message());
  for (size_t k = 0; k < pictures.size(); ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.png", k);
    fs::create_symlink(fs::absolute(pictures[k]), links / name, ec);
    if (ec) throw std::runtime_error((links / name).string() + ": cannot link: " + ec.message());
  }
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.6g", fps);
  std::vector<std::string> args = {"ffmpeg", "-y", "-loglevel", "error", "-framerate", rate, "-i",
                                   (links / "%06d.png").string(), "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2",
                                   "-pix_fmt", "yuv420p", partial.string()};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  int status = -1;
  if (posix_spawnp(&pid, "ffmpeg", nullptr, nullptr, argv.data(), environ) == 0) waitpid(pid, &status, 0);
  fs::remove_all(links, ec);
  if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    fs::remove(partial, ec);
    throw std::runtime_error(video.string() + ": ffmpeg failed (its message is above)");
  }
  fs::rename(partial, video, ec);
  if (ec) throw std::runtime_error(video.string() + ": cannot rename into place: " + ec.message());
}

}  // namespace

std::string render_options_problem(const RenderOptions& o) {
  if (o.width < 16 || o.height < 16 || o.width > 16384 || o.height > 16384)
    return "--size must be between 16x16 and 16384x16384";
  if (o.all && o.frame) return "give --frame or --all, not both";
  if (!o.video.empty() && !o.all) return "--video needs --all";
  if (!o.video.empty() && o.video.extension() != ".mp4") return "--video expects an .mp4 file name";
  if (!(o.fps >= 0.0) || o.fps > 1000.0) return "--fps must be between 0 (from the frames) and 1000";
  return "";
}

RenderCamera parse_camera(const std::string& text, const Eigen::Vector3d& up) {
  std::vector<double> v;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double x = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(x))
      throw std::runtime_error("--camera: \"" + item + "\" is not a number");
    v.push_back(x);
  }
  if (v.size() != 6 && v.size() != 7)
    throw std::runtime_error("--camera expects EX,EY,EZ,TX,TY,TZ[,FOV] (eye, target, field of view in degrees)");
  RenderCamera camera;
  camera.position = Eigen::Vector3d(v[0], v[1], v[2]);
  camera.target = Eigen::Vector3d(v[3], v[4], v[5]);
  camera.up = up;
  if (v.size() == 7) camera.fov_deg = v[6];
  if ((camera.target - camera.position).norm() == 0.0) throw std::runtime_error("--camera: the eye is on the target");
  if (!(camera.fov_deg > 0.0 && camera.fov_deg < 170.0))
    throw std::runtime_error("--camera: the field of view must be between 0 and 170 degrees");
  if (camera.up.cross(camera.target - camera.position).norm() == 0.0)
    throw std::runtime_error("--camera: looks straight along the up direction; move the eye aside");
  return camera;
}

std::vector<fs::path> render_run(const RenderOptions& options) {
  if (const std::string problem = render_options_problem(options); !problem.empty())
    throw std::runtime_error(problem);
  if (!options.video.empty() && !program_on_path("ffmpeg"))
    throw std::runtime_error("--video needs ffmpeg (Debian package ffmpeg), which is not on the PATH");
  const std::vector<FrameEntry> frames = read_frame_list(options.run_dir);
  const SceneView view = read_view(options.run_dir);

  std::vector<FrameEntry> chosen;
  if (options.all) chosen = frames;
  else if (!options.frame) chosen = {frames.back()};
  else {
    const auto found = std::find_if(frames.begin(), frames.end(),
                                    [&](const FrameEntry& f) { return f.number == *options.frame; });
    if (found == frames.end())
      throw std::runtime_error((options.run_dir / "scene.pvd").string() + ": no frame " + std::to_string(*options.frame) +
                               " (frames " + std::to_string(frames.front().number) + " to " +
                               std::to_string(frames.back().number) + ")");
    chosen = {*found};
  }
  const FrameData first = read_vtu_frame(frames.front().file);
  const FrameData last = frames.size() > 1 ? read_vtu_frame(frames.back().file) : first;
  const RenderSetting setting = choose_render_setting(options, view, first, last);

  const fs::path out_dir = options.out_dir.empty() ? options.run_dir / "render" : options.out_dir;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw std::runtime_error(out_dir.string() + ": cannot create the folder: " + ec.message());

  // Each frame is read, traced and written on its own; frames run side by side, and each
  // picture's rows in parallel inside. An error in any frame stops the command with its line.
  std::vector<fs::path> written(chosen.size());
  std::vector<std::string> errors(chosen.size());
  parallel_for(
      static_cast<int64_t>(chosen.size()),
      [&](int64_t begin, int64_t end) {
        for (int64_t k = begin; k < end; ++k) {
          try {
            const FrameData frame = read_vtu_frame(chosen[k].file);
            const Image image = render_frame(frame, view, setting, options, chosen[k].file.string());
            written[k] = picture_name(out_dir, chosen[k].number);
            write_png(written[k], image);
          } catch (const std::exception& e) {
            errors[k] = e.what();
          }
        }
      },
      1);
  for (const std::string& error : errors)
    if (!error.empty()) throw std::runtime_error(error);
  if (!options.video.empty()) {
    double fps = options.fps;
    if (fps == 0.0) {
      const double interval = frames.size() > 1 ? (frames.back().time - frames.front().time) / (frames.size() - 1) : 0.0;
      fps = interval > 0.0 ? std::clamp(1.0 / interval, 1.0, 60.0) : 25.0;
    }
    encode_video(written, options.video, fps);
    written.push_back(options.video);
  }
  return written;
}

}  // namespace nexdyn

// MPM runs end to end (issue 38): a moving boundary box carries the particles inside it on its
// rigid motion while the rest deforms; the particle radius `nexdyn run` writes into its VTU frames
// is 0.5 cbrt(|J| V0), and a rendered frame covers the pixels the cube's geometry predicts; a
// run killed or stopped mid-way and resumed writes the same stats.csv and frames as one never
// stopped.
#include "engine/mpm/mpm_simulation.hpp"
#include "engine/render/frame_reader.hpp"
#include "engine/render/png_file.hpp"
#include "engine/render/render_command.hpp"
#include "engine/render/view_file.hpp"
#include "tests/engine/cli/child_process.hpp"
#include "tests/engine/test_support.hpp"

#include <doctest/doctest.h>

#include <Eigen/Geometry>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>


using namespace nexdyn;
namespace fs = std::filesystem;

namespace {

void run_steps(MpmSimulation& simulation, int steps) {
  for (int k = 0; k < steps; ++k) {
    const StepOutcome outcome = simulation.step();
    REQUIRE_MESSAGE(outcome.status == StepStatus::ok, outcome.message);
  }
}

}  // namespace

TEST_CASE("mpm boundary box moving with velocity or angular velocity carries the particles inside it rigidly") {
  // A bar of 0.25 x 0.075 x 0.075 m along x under gravity; a boundary box holds its left half
  // (x <= 0; the box reaches far beyond the bar in y and z, so only its face x = 0 cuts the bar)
  // and moves it rigidly, p(t) = c + v t + R(axis, w t) (p0 - c). Every grid node inside the
  // carried box is prescribed on that motion; a particle whose 27 stencil nodes are all
  // prescribed moves by sum_i w_ip u_i, which the B-splines' linear reproduction makes exactly the
  // rigid map of its own position (and F <- R F, v the box's velocity at the particle). The
  // stencil's nodes lie within 1.5 h of the particle on each axis, so after turning by at most
  // 0.2 rad within 1.5 h (cos 0.2 + sin 0.2) = 1.77 h of it along the box's x: particles that
  // start 2 h = 5 cm inside the face (x0 <= -0.05) are held whole. The right half is free: it
  // sags under gravity and lags behind the box, so it must deform.
  struct Case {
    std::string name;
    std::string motion;
    Eigen::Vector3d velocity, center, axis;
    double omega;
  };
  const Case cases[] = {
      {"velocity", R"("velocity": [0, 0.3, 0.2])", {0, 0.3, 0.2}, {0, 0, 0}, {0, 0, 1}, 0.0},
      {"angular_velocity", R"("velocity": [0.1, 0, 0], "angular_velocity": 2, "axis": [0, 0, 1], "center": [-0.06, 0, 0])",
       {0.1, 0, 0}, {-0.06, 0, 0}, {0, 0, 1}, 2.0},
  };
  const double h = 0.025, dt = 0.01;
  const int steps = 10;
  for (const Case& c : cases) {
    CAPTURE(c.name);
    const std::string json = R"({"gravity": [0, -9.81, 0], "time": {"dt": 0.01, "steps": 10, "integrator": "newmark"},
      "mpm": {"grid_spacing": 0.025, "domain_min": [-0.35, -0.35, -0.35], "domain_max": [0.35, 0.35, 0.35]},
      "materials": {"m": {"model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000}},
      "bodies": [{"particles": {"box": {"size": [0.25, 0.075, 0.075], "per_cell": 2}}, "material": "m"}],
      "boundary": [{"box_min": [-1, -1, -1], "box_max": [0, 1, 1], )" +
                             c.motion + "}]}";
    const Scene scene = test::scene_from_json(json, "mpm_moving_box");
    MpmSimulation simulation(scene);
    run_steps(simulation, steps);
    const double t = simulation.state().time;
    REQUIRE(t == doctest::Approx(steps * dt));
    const Eigen::Matrix3d R = Eigen::AngleAxisd(c.omega * t, c.axis.normalized()).toRotationMatrix();
    const Particles& start = scene.mpm->initial;
    const Particles& now = simulation.state().particles;
    int held = 0;
    double position_error = 0.0, velocity_error = 0.0, F_error = 0.0;
    double free_displacement = 0.0, free_strain = 0.0;
    for (int64_t p = 0; p < now.size(); ++p) {
      const Eigen::Vector3d p0 = start.position(p);
      const Eigen::Vector3d rigid = c.center + c.velocity * t + R * (p0 - c.center);
      if (p0.x() <= -2.0 * h) {
        ++held;
        position_error = std::max(position_error, (now.position(p) - rigid).norm());
        const Eigen::Vector3d v = c.velocity + (c.omega * c.axis).cross(rigid - c.center - c.velocity * t);
        velocity_error = std::max(velocity_error, (now.velocity(p) - v).norm());
        F_error = std::max(F_error, (now.deformation(p) - R).norm());
      } else if (p0.x() >= 0.06) {
        // The free end, against where the box's motion would have carried it.
        free_displacement = std::max(free_displacement, (now.position(p) - rigid).norm());
        free_strain = std::max(free_strain, (R.transpose() * now.deformation(p) - Eigen::Matrix3d::Identity()).norm());
      }
    }
    MESSAGE(c.name << ": " << held << " particles held, largest deviation from the rigid motion " << position_error
                   << " m, of the velocity " << velocity_error << " m/s, |F - R| " << F_error
                   << "; the free end is off the rigid motion by up to " << free_displacement
                   << " m, |R^T F - I| up to " << free_strain);
    CHECK(held == 6 * 6 * 6);
    CHECK(position_error < 1e-12);
    CHECK(velocity_error < 1e-10);
    CHECK(F_error < 1e-12);
    // Measured: the free end is 17 mm (velocity) and 23 mm (angular velocity) off the rigid
    // motion, |R^T F - I| up to 0.24 and 0.26.
    CHECK(free_displacement > 5e-3);
    CHECK(free_strain > 0.05);
  }
}

namespace {

// A 10 cm cube of 512 particles (h 2.5 cm, 2 per cell per axis) thrown down and sideways onto a
// plane with friction: it lands within a few steps, so its particles are squashed (J != 1) and
// the plane, friction and (under generalized-alpha, the default) the particles' abar all carry
// over from step to step.
std::string thrown_cube_scene(int steps, int every, const std::string& integrator) {
  return R"({"gravity": [0, -9.81, 0], "time": {"dt": 0.005, "steps": )" + std::to_string(steps) +
         R"(, "integrator": ")" + integrator + R"("},
    "mpm": {"grid_spacing": 0.025, "domain_min": [-0.2, -0.1, -0.2], "domain_max": [0.3, 0.3, 0.2]},
    "materials": {"m": {"model": "neohookean", "youngs": 1e5, "poisson": 0.3, "density": 1000}},
    "bodies": [{"particles": {"box": {"size": [0.1, 0.1, 0.1], "per_cell": 2}}, "material": "m",
                "translate": [0, 0.075, 0], "velocity": [1, -2, 0]}],
    "contact": {"friction": 0.3}, "obstacles": [{"plane": {"point": [0, 0, 0], "normal": [0, 1, 0]}}],
    "output": {"every": )" + std::to_string(every) + "}}";
}

int64_t pixels_differing(const Image& a, const Image& b) {
  int64_t count = 0;
  for (size_t p = 0; p < a.rgb.size(); p += 3)
    count += a.rgb[p] != b.rgb[p] || a.rgb[p + 1] != b.rgb[p + 1] || a.rgb[p + 2] != b.rgb[p + 2];
  return count;
}

}  // namespace

TEST_CASE("mpm run: the VTU radius is 0.5 cbrt(|J| V0) before and after the cube is squashed") {
  // The frames `nexdyn run` wrote, read back (engine/render/frame_reader.hpp), against the same
  // scene stepped here: the points are the particles' positions, and each radius is half the edge
  // of a cube of the particle's current volume |det F| V0 (frame_writer.cpp). The positions agree
  // to 1e-10 m, not bit for bit: under the sanitizers this test's own file is compiled at -O0, and
  // the linker may take its copies of inline engine functions (no FMAs) for this process while the
  // program keeps its -O3 ones. Written as floats, positions of 0.1 m would be up to 3e-9 m off.
  const fs::path dir = test::temp_dir("mpm_radius");
  const fs::path file = test::write_text(dir / "cube.json", thrown_cube_scene(6, 3, "newmark"));
  const test::CommandResult r = test::run_cli("run " + file.string() + " --quiet --out " + (dir / "out").string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  const Scene scene = load_scene(file);
  MpmSimulation simulation(scene);
  const double V0 = std::pow(0.025 / 2, 3);  // (h / per_cell)^3
  double largest_J_change = 0.0;
  for (const int frame : {0, 3, 6}) {
    CAPTURE(frame);
    if (frame > 0) run_steps(simulation, 3);
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06d.vtu", frame);
    const FrameData data = read_vtu_frame(dir / "out" / "frames" / name);
    const Particles& now = simulation.state().particles;
    REQUIRE(data.num_points() == now.size());
    REQUIRE(data.radius.size() == static_cast<size_t>(now.size()));
    REQUIRE(data.points.size() == now.x.size());
    double farthest = 0.0;
    for (size_t i = 0; i < now.x.size(); ++i) farthest = std::max(farthest, std::abs(data.points[i] - now.x[i]));
    CHECK(farthest <= 1e-10);
    double worst = 0.0, J_change = 0.0;
    for (int64_t p = 0; p < now.size(); ++p) {
      REQUIRE(now.volume0[p] == doctest::Approx(V0).epsilon(1e-12));
      const double J = now.deformation(p).determinant();
      const double expected = 0.5 * std::cbrt(std::abs(J) * now.volume0[p]);
      worst = std::max(worst, std::abs(data.radius[p] - expected) / expected);
      J_change = std::max(J_change, std::abs(J - 1.0));
    }
    MESSAGE("frame " << frame << ": largest |J - 1| " << J_change << ", largest relative radius error " << worst
                     << ", positions off by at most " << farthest << " m");
    CHECK(worst < 1e-14);
    if (frame == 0) CHECK(J_change == 0.0);  // rest shape: every radius is 0.5 cbrt(V0) = h / 4
    largest_J_change = std::max(largest_J_change, J_change);
  }
  // The check would not see a radius that ignores J unless J moved: the landing squashed the cube.
  CHECK(largest_J_change > 0.01);
}

TEST_CASE("mpm render: the particles of a frame cover the pixels their icosahedra predict") {
  // Frame 0 of a run (the cube at rest shape, centre (0, 0.075, 0), 8 x 8 x 8 particles 12.5 mm
  // apart), read back and drawn by render_frame (one icosahedron of circumradius `radius` per
  // particle, engine/render/render_command.cpp) from 100 m away on the cube's z axis with a
  // 0.1 deg field of view: nearly orthographic (the cube's depth is 0.1% of the distance), so the
  // 8 particles of a column project onto one another, and the picture shows 8 x 8 columns.
  // Along z an icosahedron of that orientation projects to a hexagon of area 2 g^3 / (1 + g^2)
  // R^2 = 2.342 R^2 (g the golden ratio), 0.585 of the 2R x 2R square each particle has in the
  // cube's face, and the hexagons of neighbours do not overlap (half-width 0.851 R). So the
  // particles cover 64 hexagons, 0.585 of the cube's projected face. Measured: 0.991 of 64
  // hexagons; at sizes 280 to 400 pixels and from 400 m 0.990 to 1.006 (where the hexagons'
  // edges fall between pixel centres), from 20 m up to 1.02 (perspective: the back particles of
  // a column peek out beside the front one). A radius 2% off changes the area by 4%. The same
  // frame with no particles gives the background; no planes are drawn (their shadows would count
  // too).
  const fs::path dir = test::temp_dir("mpm_render");
  const fs::path file = test::write_text(dir / "cube.json", thrown_cube_scene(1, 1, "newmark"));
  const fs::path out = dir / "out";
  REQUIRE(test::run_cli("run " + file.string() + " --quiet --out " + out.string()).exit_code == 0);
  const FrameData frame = read_vtu_frame(out / "frames" / "frame_000000.vtu");
  REQUIRE(frame.num_points() == 512);
  const SceneView view = read_view(out);

  const int size = 300;
  const double distance = 100.0, fov = 0.1, R = 0.0125 / 2;
  const Eigen::Vector3d centre(0, 0.075, 0);
  RenderOptions options;
  options.run_dir = out;
  options.width = options.height = size;
  options.camera = RenderCamera{centre + Eigen::Vector3d(0, 0, distance), centre, Eigen::Vector3d::UnitY(), fov};
  // `nexdyn render` with this camera draws what render_frame does (with the scene's plane).
  {
    char camera[128];
    std::snprintf(camera, sizeof camera, "0,0.075,%g,0,0.075,0,%g", distance, fov);
    const test::CommandResult r = test::run_cli("render " + out.string() + " --frame 0 --size 300x300 --camera " + camera);
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const RenderSetting setting = choose_render_setting(options, view, frame, frame);
    CHECK(read_png(out / "render" / "frame_000000.png").rgb == render_frame(frame, view, setting, options, "f").rgb);
  }
  RenderSetting setting = choose_render_setting(options, view, frame, frame);
  setting.planes.clear();
  FrameData empty;
  const int64_t covered =
      pixels_differing(render_frame(frame, view, setting, options, "f"), render_frame(empty, view, setting, options, "e"));
  // Pixels per metre at the cube's front face, 99.95 m from the eye.
  const double scale = size / (2.0 * std::tan(0.5 * fov * M_PI / 180.0) * (distance - 0.05));
  const double face = std::pow(0.1 * scale, 2);
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  const double hexagon = 2.0 * g * g * g / (1.0 + g * g) * std::pow(R * scale, 2);
  MESSAGE("particles cover " << covered << " pixels; the cube's face projects to " << face << ", 64 hexagons to "
                             << 64 * hexagon << " (ratio " << covered / (64 * hexagon) << ")");
  CHECK(covered < face);
  CHECK(static_cast<double>(covered) == test::relative(64 * hexagon, 0.03));
}

namespace {

using test::read_bytes;
using test::run_outputs;
using test::spawn_cli;
using test::wait_child;

std::vector<int64_t> checkpoint_steps(const fs::path& out) {
  std::vector<int64_t> steps;
  std::error_code ec;
  if (!fs::is_directory(out / "checkpoints", ec)) return steps;
  for (const auto& entry : fs::directory_iterator(out / "checkpoints", ec)) {
    const std::string name = entry.path().filename().string();
    if (entry.path().extension() == ".ckpt" && name.rfind("checkpoint_", 0) == 0)
      steps.push_back(std::stoll(name.substr(11, 9)));
  }
  std::sort(steps.begin(), steps.end());
  return steps;
}

int64_t data_rows(const fs::path& file) { return static_cast<int64_t>(test::read_lines(file).size()) - 1; }

}  // namespace

TEST_CASE("mpm kill and resume: a particle run killed or stopped at chosen steps writes what an unstopped run does") {
  // The thrown cube (generalized-alpha, a plane with friction) for 20 steps, a frame every 4 and
  // a checkpoint every 5 steps, run once straight through and once stopped again and again:
  // SIGKILL as step 3 begins (no checkpoint yet: run afresh), SIGKILL just after checkpoint 10 is
  // written, SIGKILL after the stats row of step 13, SIGTERM at step 16's second Newton iteration
  // (the run abandons that step, writes a checkpoint of step 15 and exits with 128 + 15), SIGINT
  // after the row of step 18;
  // each time resumed from the newest checkpoint. The stopped run must end with the same
  // stats.csv (but for wall_seconds), scene.pvd and frame files, byte for byte: the MPM
  // checkpoint must carry every particle's x, v, F, C and abar, and the energy the next row's
  // integrator_energy is measured from.
  const fs::path dir = test::temp_dir("mpm_kill_resume");
  const fs::path file = test::write_text(dir / "cube.json", thrown_cube_scene(20, 4, "generalized_alpha"));
  const fs::path full = dir / "full", stopped = dir / "stopped";
  auto run_into = [&](const fs::path& out) {
    return std::vector<std::string>{"run", file.string(), "--checkpoint-every", "5", "--quiet", "--out", out.string()};
  };
  const std::vector<std::string> resume = {"resume", stopped.string(), "--quiet"};
  REQUIRE(wait_child(spawn_cli(run_into(full))).exited(0));
  REQUIRE(data_rows(full / "stats.csv") == 20);

  CHECK(wait_child(spawn_cli(run_into(stopped), "KILL@3")).killed_by(SIGKILL));
  CHECK(data_rows(stopped / "stats.partial.csv") == 2);
  CHECK(checkpoint_steps(stopped).empty());

  CHECK(wait_child(spawn_cli(run_into(stopped), "KILL@10:checkpoint")).killed_by(SIGKILL));
  CHECK(data_rows(stopped / "stats.partial.csv") == 10);
  CHECK(checkpoint_steps(stopped) == std::vector<int64_t>{5, 10});

  CHECK(wait_child(spawn_cli(resume, "KILL@13:row")).killed_by(SIGKILL));
  CHECK(data_rows(stopped / "stats.partial.csv") == 13);
  CHECK(checkpoint_steps(stopped) == std::vector<int64_t>{5, 10});

  // SIGTERM inside step 16's Newton solve: the step is abandoned, and step 15 is the last.
  CHECK(wait_child(spawn_cli(resume, "TERM@16:newton2")).exited(128 + SIGTERM));
  CHECK(data_rows(stopped / "stats.partial.csv") == 15);
  CHECK(checkpoint_steps(stopped) == std::vector<int64_t>{10, 15});

  CHECK(wait_child(spawn_cli(resume, "INT@18:row")).exited(128 + SIGINT));
  CHECK(data_rows(stopped / "stats.partial.csv") == 18);
  CHECK(checkpoint_steps(stopped) == std::vector<int64_t>{15, 18});

  REQUIRE(wait_child(spawn_cli(resume)).exited(0));
  REQUIRE(fs::exists(stopped / "stats.csv"));
  CHECK_FALSE(fs::exists(stopped / "stats.partial.csv"));
  CHECK(fs::is_empty(stopped / "checkpoints"));
  const auto expected = run_outputs(full), got = run_outputs(stopped);
  CHECK(expected.size() == 2 + 6);  // stats.csv, scene.pvd and frames 0, 4, ..., 20
  CHECK(got.size() == expected.size());
  for (const auto& [name, bytes] : expected) {
    CAPTURE(name);
    const auto it = got.find(name);
    REQUIRE(it != got.end());
    CHECK(it->second == bytes);
  }
}

// nexdyn: the command-line program (DESIGN.md section 6).
//   nexdyn run SCENE.json [--out DIR] [--steps N] [--threads K] [--integrator NAME] [--quiet]
//              [--checkpoint-every K] [--rho-inf R] [--energy-guard on|off]
//   nexdyn resume DIR [--threads K] [--quiet]
//   nexdyn check SCENE.json
//   nexdyn ccd QUERIES.txt   (narrow-phase CCD over a query file with ground truth; one line)
//   nexdyn mesh SURFACE OUT.msh [--max-volume V] [--min-quality Q] [--refine-surface]   (fill with tets)
//   nexdyn render DIR [--frame N|--all] [--out PNGDIR] [--size WxH] [--camera EX,EY,EZ,TX,TY,TZ[,FOV]]
//                 [--color body|speed] [--video OUT.mp4 [--fps F]] [--threads K]
//   nexdyn plot DIR [--out PNGDIR] [--size WxH]   (PNG charts of a run's stats.csv and timings.csv)
//   nexdyn sweep SCENE --set KEY=V1,V2,... --out DIR [...]   (the Python module's sweep, docs/python.md)
//   nexdyn --version
// Exit code 0 on success, 1 for a failed step or bad input, 2 for a usage error, 130 / 143 for a
// run stopped by SIGINT / SIGTERM; otherwise one clear line on stderr.
#include "engine/allocation.hpp"
#include "engine/ccd_queries.hpp"
#include "engine/mpm/mpm_simulation.hpp"
#include "engine/plot/stats_plot.hpp"
#include "engine/mesh/msh_writer.hpp"
#include "engine/output/frame_writer.hpp"
#include "engine/parallel.hpp"
#include "engine/render/render_command.hpp"
#include "engine/render/view_file.hpp"
#include "engine/run.hpp"
#include "engine/scene/scene.hpp"
#include "engine/scene/surface_body.hpp"
#include "kernels/isa.hpp"
#include "nexdyn_version.hpp"  // generated at build time (engine/cli/version.cmake)

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace {

using namespace nexdyn;

// Exit codes (README, "Exit codes"): 0 done, 1 a failed step or bad input, 2 a usage error,
// 128 + the signal for a run stopped by SIGINT (130) or SIGTERM (143).
constexpr int kExitUsage = 2;

void print_tet_summary(const Scene& scene);

// An MPM scene's lines of print_summary.
void print_mpm_summary(const Scene& scene) {
  const MpmModel& mpm = *scene.mpm;
  const Grid grid = grid_geometry(mpm.grid_spacing, mpm.domain_min, mpm.domain_max);
  std::printf("scene %s (%s)\n", scene.name.c_str(), scene.file.string().c_str());
  std::printf("  MPM: bodies %d, particles %lld, total mass %.6g kg, grid %d x %d x %d nodes (h %.6g m)\n",
              mpm.num_bodies, static_cast<long long>(mpm.initial.size()), total_mass(mpm.initial), grid.nodes[0],
              grid.nodes[1], grid.nodes[2], mpm.grid_spacing);
  std::printf("  materials %zu, boundary boxes %zu, planes %zu\n", mpm.materials.size(), mpm.boxes.size(),
              mpm.planes.size());
}

void print_summary(const Scene& scene) {
  if (scene.mpm) {
    print_mpm_summary(scene);
  } else {
    print_tet_summary(scene);
  }
  const IntegratorParams& p = scene.time.integrator;
  std::printf("  integrator %s (alpha %.6g, beta %.6g, gamma %.6g", p.name.c_str(), p.alpha, p.beta, p.gamma);
  if (p.alpha_m != 0.0 || p.alpha_f != 0.0) std::printf(", alpha_m %.6g, alpha_f %.6g", p.alpha_m, p.alpha_f);
  if (!std::isnan(p.rho_inf)) std::printf(", rho_inf %.6g", p.rho_inf);
  std::printf("), dt %.6g s, steps %lld\n", scene.time.dt, static_cast<long long>(scene.time.steps));
}

void print_tet_summary(const Scene& scene) {
  const Model& m = scene.model;
  double total_mass = 0.0;
  for (int32_t v = 0; v < m.num_vertices; ++v) total_mass += m.translational_mass(v);
  std::printf("scene %s (%s)\n", scene.name.c_str(), scene.file.string().c_str());
  std::printf("  bodies %zu, vertices %d, tets %d, surface triangles %zu, DOFs %lld\n", m.bodies.size(),
              m.num_vertices, m.num_tets, m.surface_triangles.size() / 3,
              static_cast<long long>(m.num_dofs()));
  if (!m.affine_bodies.empty())
    std::printf("  affine bodies %zu (12 coordinates each, in the vertex and DOF counts)\n", m.affine_bodies.size());
  size_t obstacle_meshes = 0;
  for (const BodyRange& b : m.bodies) obstacle_meshes += b.obstacle;
  // Obstacle meshes share one extra fixed motion after the "boundary" entries; not counted here.
  const size_t boundary_entries = m.dirichlet_motions.size() - (obstacle_meshes > 0 ? 1 : 0);
  std::printf("  materials %zu, total mass %.6g kg, boundary conditions %zu, obstacle planes %zu, "
              "obstacle meshes %zu\n", m.materials.size(), total_mass, boundary_entries,
              m.obstacle_planes.size(), obstacle_meshes);
}

}  // namespace

namespace {

// Option checks that speak the engine's words: "--threads must be at least 1 (got 0)".
CLI::Validator at_least(long long least) {
  return CLI::Validator(
      [least](std::string& text) -> std::string {
        long long value = 0;
        size_t used = 0;
        try {
          value = std::stoll(text, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (used == 0 || used != text.size()) return "must be a whole number (got \"" + text + "\")";
        if (value < least) return "must be at least " + std::to_string(least) + " (got " + text + ")";
        return "";
      },
      "INT >= " + std::to_string(least));
}

CLI::Validator one_of(std::vector<std::string> names) {
  std::string list;
  for (size_t i = 0; i < names.size(); ++i) list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return CLI::Validator(
      [names, list](std::string& text) -> std::string {
        for (const std::string& name : names)
          if (text == name) return "";
        return "must be " + list + " (got \"" + text + "\")";
      },
      list);
}

// Everything the command line sets.
struct CliArgs {
  std::string scene_path, out_dir, integrator, energy_guard, resume_dir, check_path, ccd_path;
  int64_t steps = -1, checkpoint_every = -1;
  int threads = 0;
  bool quiet = false;
  double rho_inf = std::numeric_limits<double>::quiet_NaN();
  CLI::App *run = nullptr, *resume = nullptr, *check = nullptr, *ccd = nullptr, *render = nullptr,
           *plot = nullptr, *mesh = nullptr, *sweep = nullptr;
  // nexdyn mesh
  std::string mesh_in, mesh_out;
  TetrahedralizeSettings tetrahedralize;
  // nexdyn plot
  std::string plot_dir, plot_out, plot_size = "1200x800";
  // nexdyn render
  std::string render_dir, render_out, render_size = "1280x720", render_camera, render_color = "body", video;
  int64_t render_frame = -1;
  bool render_all = false;
  double fps = 0.0;
};

void define_cli(CLI::App& app, CliArgs& a) {
  app.require_subcommand(1);
  a.run = app.add_subcommand("run", "Run a scene and write stats.csv and frames");
  a.run->add_option("scene", a.scene_path, "Scene JSON file")->required();
  a.run->add_option("--out", a.out_dir, "Output folder (default out/<scene name>)");
  a.run->add_option("--steps", a.steps, "Number of steps (default: the scene's time.steps)")
      ->check(at_least(1));
  a.run->add_option("--threads", a.threads, "Worker threads (default: all cores)")->check(at_least(1));
  a.run->add_option("--integrator", a.integrator, "Override the scene's integrator preset");
  a.run->add_option("--rho-inf", a.rho_inf, "Spectral radius at infinity of generalized_alpha (0 to 1)");
  a.run->add_option("--energy-guard", a.energy_guard, "on or off: retake with implicit Euler any step whose "
                    "integration would create energy (default: the scene's time.energy_guard, on)")
      ->check(one_of({"on", "off"}));
  a.run->add_flag("--quiet", a.quiet, "No progress bar or summary");
  a.run->add_option("--checkpoint-every", a.checkpoint_every,
                    "Steps between checkpoints (default: the scene's output.checkpoint_every, 100; 0: only "
                    "on SIGINT/SIGTERM)")
      ->check(at_least(0));
  a.resume = app.add_subcommand("resume", "Continue a stopped run from its newest valid checkpoint");
  a.resume->add_option("dir", a.resume_dir, "The run's output folder")->required();
  a.resume->add_option("--threads", a.threads, "Worker threads (default: all cores)")->check(at_least(1));
  a.resume->add_flag("--quiet", a.quiet, "No progress bar or summary");
  a.check = app.add_subcommand("check", "Validate a scene and print its size");
  a.check->add_option("scene", a.check_path, "Scene JSON file")->required();
  a.ccd = app.add_subcommand("ccd", "Run the narrow-phase CCD over a query file and print one line");
  a.ccd->add_option("queries", a.ccd_path, "CCD query file (data/ccd/README.txt)")->required();
  a.plot = app.add_subcommand("plot", "Draw a run's stats.csv and timings.csv as PNG charts (gnuplot)");
  a.plot->add_option("dir", a.plot_dir, "The run's output folder")->required();
  a.plot->add_option("--out", a.plot_out, "Folder of the PNGs (default DIR/plots)");
  a.plot->add_option("--size", a.plot_size, "Width x height of each PNG in pixels (default 1200x800)");
  a.mesh = app.add_subcommand("mesh", "Fill a closed surface (.obj, .stl, .ply) with tets and write a .msh");
  a.mesh->add_option("surface", a.mesh_in, "Closed triangle surface")->required();
  a.mesh->add_option("out", a.mesh_out, "The .msh file to write")->required();
  a.mesh->add_option("--max-volume", a.tetrahedralize.max_volume, "Largest tet volume (default 0: no bound)");
  a.mesh->add_option("--min-quality", a.tetrahedralize.min_quality,
                     "Smallest tet quality, 1 = regular (default 0.306; 0: no refinement; at most 0.557)");
  a.mesh->add_flag("--refine-surface", a.tetrahedralize.refine_surface,
                   "Let TetGen split the surface triangles (points on them) so that the bounds hold there too");
  a.render = app.add_subcommand("render", "Ray-trace PNG pictures of a run's frames (and a video with ffmpeg)");
  a.render->add_option("dir", a.render_dir, "The run's output folder")->required();
  a.render->add_option("--frame", a.render_frame, "Frame number N of frames/frame_N.vtu (default: the last)")
      ->check(at_least(0));
  a.render->add_flag("--all", a.render_all, "Every frame, in parallel");
  a.render->add_option("--out", a.render_out, "Folder of the pictures (default DIR/render)");
  a.render->add_option("--size", a.render_size, "Picture size WxH in pixels (default 1280x720)");
  a.render->add_option("--camera", a.render_camera, "EX,EY,EZ,TX,TY,TZ[,FOV]: eye, target, vertical field of view "
                       "[deg] (default: the scene's output.camera, else fitted to the bodies)");
  a.render->add_option("--color", a.render_color, "Colour bodies by \"body\" or by \"speed\" (default body)")
      ->check(one_of({"body", "speed"}));
  a.render->add_option("--video", a.video, "With --all: also an .mp4 of the pictures (needs ffmpeg)");
  a.render->add_option("--fps", a.fps, "Frames per second of the video (default: from the frames' times)");
  a.render->add_option("--threads", a.threads, "Worker threads (default: all cores)")->check(at_least(1));
  a.sweep = app.add_subcommand("sweep", "Run the product of parameter lists on a Dask cluster (python3 -m nexdyn "
                               "sweep --help; docs/python.md)");
  a.sweep->prefix_command();  // every argument after it is the Python sweep's (--help too)
  a.sweep->set_help_flag();
}

// `nexdyn sweep ...` is `python3 -m nexdyn sweep ...` with this build's Python module: the
// process becomes that Python (its exit code is the sweep's).
int run_sweep(const CliArgs& a) {
#ifdef NEXDYN_PYTHON_DIR
  std::string path = NEXDYN_PYTHON_DIR;
  if (const char* old = std::getenv("PYTHONPATH"); old && *old) path += std::string(":") + old;
  setenv("PYTHONPATH", path.c_str(), 1);
  std::vector<std::string> args = {NEXDYN_PYTHON_EXECUTABLE, "-m", "nexdyn", "sweep"};
  for (const std::string& arg : a.sweep->remaining()) args.push_back(arg);
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  execv(argv[0], argv.data());
  throw std::runtime_error(std::string("sweep: cannot start ") + NEXDYN_PYTHON_EXECUTABLE + ": " + std::strerror(errno));
#else
  (void)a;
  throw std::runtime_error("sweep: this nexdyn was built without the Python module (NEXDYN_PYTHON=OFF)");
#endif
}

int run_mesh(const CliArgs& a) {
  const std::filesystem::path out = a.mesh_out;
  if (out.extension() != ".msh") throw std::runtime_error(out.string() + ": expected a .msh file name");
  const auto start = std::chrono::steady_clock::now();
  const SurfaceBody body = surface_body(a.mesh_in, a.tetrahedralize, {});
  write_file_atomically(out, msh_document(body.mesh));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s: %d vertices, %d tets, volume %.9g, %.3f s\n", out.string().c_str(), body.mesh.num_vertices(),
              body.mesh.num_tets(), mesh_volume(body.mesh), seconds);
  return 0;
}

int run_render(const CliArgs& a) {
  RenderOptions o;
  o.run_dir = a.render_dir;
  o.out_dir = a.render_out;
  if (a.render_frame >= 0) o.frame = a.render_frame;
  o.all = a.render_all;
  char x = 0;
  int consumed = 0;
  if (std::sscanf(a.render_size.c_str(), "%d%c%d%n", &o.width, &x, &o.height, &consumed) != 3 || x != 'x' ||
      consumed != static_cast<int>(a.render_size.size()))
    throw std::runtime_error("--size expects WxH, for example 1920x1080, not \"" + a.render_size + "\"");
  if (!a.render_camera.empty()) o.camera = parse_camera(a.render_camera, read_view(o.run_dir).up);
  o.color = a.render_color == "speed" ? ColorBy::value : ColorBy::body;
  o.video = a.video;
  o.fps = a.fps;
  const std::vector<std::filesystem::path> written = render_run(o);
  if (written.size() <= 3)
    for (const auto& file : written) std::printf("%s\n", file.string().c_str());
  else
    std::printf("%zu pictures in %s\n", written.size() - (o.video.empty() ? 0 : 1),
                written.front().parent_path().string().c_str());
  if (written.size() > 3 && !o.video.empty()) std::printf("%s\n", o.video.string().c_str());
  return 0;
}

int run_ccd(const CliArgs& a) {
  const CcdQueryStats s = run_ccd_queries(a.ccd_path);
  std::printf("queries=%lld positives=%lld false_negatives=%lld false_positives=%lld seconds=%.6f "
              "queries_per_second=%.1f\n",
              static_cast<long long>(s.queries), static_cast<long long>(s.positives),
              static_cast<long long>(s.false_negatives), static_cast<long long>(s.false_positives),
              s.seconds, s.seconds > 0.0 ? double(s.queries) / s.seconds : 0.0);
  return 0;
}

// Prints a line if the run is unfinished, then the path of every PNG written.
int run_plot(const CliArgs& a) {
  PlotOptions options;
  options.run_dir = a.plot_dir;
  options.out_dir = a.plot_out;
  parse_plot_size(a.plot_size, options.width, options.height);
  const PlotResult result = plot_run(options);
  if (result.partial)
    std::printf("no stats.csv: plotted the %zu rows of %s (the run is under way, was stopped or failed)\n",
                result.rows, result.stats_file.string().c_str());
  for (const std::filesystem::path& png : result.pngs) std::printf("%s\n", png.string().c_str());
  return 0;
}

int run_check(const CliArgs& a) {
  Scene scene = load_scene(a.check_path);
  if (scene.mpm) {
    MpmSimulation validate(scene);  // the particles are on the grid (checked by the loader)
  } else {
    Simulation validate(scene);  // builds the assembly and checks the initial forces
  }
  print_summary(scene);
  std::printf("ok\n");
  return 0;
}

// Runs (or resumes) a scene; `out` gets its output folder.
RunSummary run_or_resume(const CliArgs& a, std::filesystem::path& out) {
  if (*a.resume) {
    out = a.resume_dir;
    if (!a.quiet) std::printf("resuming the run in %s\n", out.string().c_str());
    RunSummary summary = resume_run(out, !a.quiet && isatty(STDERR_FILENO));
    if (!a.quiet) std::printf("resumed after step %lld\n", static_cast<long long>(summary.first_step - 1));
    return summary;
  }
  // The output folder first: tetrahedralised surface bodies are kept in its meshes/ folder.
  const std::filesystem::path out_dir =
      a.out_dir.empty() ? std::filesystem::path("out") / scene_name(a.scene_path) : std::filesystem::path(a.out_dir);
  // A folder that exists may be another run's: its lock before anything goes into it (a new one
  // is locked as the run starts).
  std::shared_ptr<OutputLock> lock;
  if (std::error_code ec; std::filesystem::is_directory(out_dir, ec)) lock = OutputLock::acquire(out_dir);
  Scene scene = load_scene(a.scene_path, {}, out_dir / "meshes");
  override_integrator(scene, a.integrator, a.rho_inf);
  if (!a.energy_guard.empty()) scene.time.energy_guard = a.energy_guard == "on";
  RunOptions options;
  options.out_dir = out_dir;
  options.steps = a.steps;
  options.progress = !a.quiet && isatty(STDERR_FILENO);
  options.checkpoint_every = a.checkpoint_every;
  options.integrator = a.integrator;
  options.rho_inf = a.rho_inf;
  options.energy_guard = a.energy_guard;
  options.lock = std::move(lock);
  out = options.out_dir;
  if (!a.quiet) print_summary(scene);
  return run_scene(scene, options);
}

// The exit code and the last lines of a run: 0 done, 1 a failed step, 128 + signal interrupted.
int report(const RunSummary& summary, const std::filesystem::path& out, bool quiet) {
  const std::string partial = (out / "stats.partial.csv").string();
  if (!summary.ok) {
    std::fprintf(stderr, "nexdyn: error: %s (rows of the %lld completed steps are in %s; the last good "
                 "state is in %s)\n", summary.message.c_str(), static_cast<long long>(summary.steps_done),
                 partial.c_str(), summary.checkpoint.c_str());
    return 1;
  }
  if (summary.interrupted) {
    if (!quiet) {
      std::printf("stopped: %lld steps in %.3f s, output in %s\n", static_cast<long long>(steps_run(summary)),
                  summary.wall_seconds, out.string().c_str());
      if (steps_run(summary) > 0) std::printf("%s\n", profile_line(summary).c_str());
    }
    std::fprintf(stderr, "nexdyn: interrupted by %s after step %lld; checkpoint %s; continue with: nexdyn "
                 "resume %s\n", summary.signal == SIGINT ? "SIGINT" : "SIGTERM",
                 static_cast<long long>(summary.steps_done), summary.checkpoint.c_str(), out.string().c_str());
    return 128 + summary.signal;
  }
  if (!quiet) {
    std::printf("done: %lld steps in %.3f s, output in %s\n", static_cast<long long>(steps_run(summary)),
                summary.wall_seconds, out.string().c_str());
    std::printf("%s\n", profile_line(summary).c_str());
    if (summary.retried_steps > 0)
      std::printf("steps retried in halves: %lld (the retries column of stats.csv); the first, %s\n",
                  static_cast<long long>(summary.retried_steps), summary.first_retry.c_str());
  }
  return 0;
}

// A test hook: with NEXDYN_TEST_SPLIT_LOOPS=FILE in the environment, the process writes into FILE,
// when it exits, how many parallel loops it cut into several chunks (engine/parallel.hpp), so
// that the tests comparing --threads 1 and 2 can check that the run had work to share out.
void report_split_loops_at_exit() {
  static std::string file;
  if (const char* path = std::getenv("NEXDYN_TEST_SPLIT_LOOPS")) {
    file = path;
    std::atexit([] {
      if (FILE* f = std::fopen(file.c_str(), "w")) {
        std::fprintf(f, "%lld\n", static_cast<long long>(split_loop_count().load()));
        std::fclose(f);
      }
    });
  }
}

}  // namespace

int main(int argc, char** argv) {
  keep_freed_memory();
  report_split_loops_at_exit();
  CLI::App app{"NexDynIPC: incremental potential simulation of elastic tet bodies", "nexdyn"};
  CliArgs a;
  define_cli(app, a);
  app.set_version_flag("--version", std::string("nexdyn ") + NEXDYN_VERSION + " (commit " + NEXDYN_COMMIT + ")");
  if (argc == 1) {  // no command: the list of them, as a usage error
    std::printf("%s", app.help().c_str());
    return kExitUsage;
  }
  if (argv[1][0] != '-') {  // a command the program does not have
    std::string known;
    bool found = false;
    for (const CLI::App* command : app.get_subcommands({})) {
      known += (known.empty() ? "" : ", ") + command->get_name();
      found = found || command->get_name() == argv[1];
    }
    if (!found) {
      std::fprintf(stderr, "nexdyn: error: unknown command \"%s\" (the commands: %s)\n", argv[1], known.c_str());
      return kExitUsage;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line: CLI11 says "--threads: must be ..."; the engine says "--threads must be ...".
    std::string message = e.what();
    if (const size_t colon = message.find(": "); message.rfind("--", 0) == 0 && colon != std::string::npos &&
                                                 message.find(' ') > colon)
      message.erase(colon, 1);
    std::fprintf(stderr, "nexdyn: error: %s (nexdyn --help lists the commands and options)\n", message.c_str());
    return kExitUsage;
  }
  try {
    std::unique_ptr<tbb::global_control> thread_limit;
    if (a.threads > 0)
      thread_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                           static_cast<size_t>(a.threads));
    active_isa();  // a bad NEXDYN_ISA is an error here, before any output is written
    if (*a.ccd) return run_ccd(a);
    if (*a.check) return run_check(a);
    if (*a.render) return run_render(a);
    if (*a.mesh) return run_mesh(a);
    if (*a.plot) return run_plot(a);
    if (*a.sweep) return run_sweep(a);
    std::filesystem::path out;
    const RunSummary summary = run_or_resume(a, out);
    return report(summary, out, a.quiet);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nexdyn: error: %s\n", e.what());
    return 1;
  }
}

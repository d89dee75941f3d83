// `nexdyn run`: steps a scene and writes stats.csv, timings.csv, frames and scene.pvd into the
// output folder; `nexdyn resume`: continues such a run from its newest valid checkpoint.
//
// Honest outputs: stats.csv and timings.csv only exist once the run has finished every step;
// while running (or after a failure) the rows so far are in stats.partial.csv and
// timings.partial.csv. Frames and scene.pvd are renamed into
// place whole, so every file that exists is complete.
//
// Checkpoints (engine/output/checkpoint_file.hpp) go to DIR/checkpoints/checkpoint_NNNNNNNNN.ckpt
// every output.checkpoint_every steps, on SIGINT and SIGTERM (the step under way is abandoned at
// its next safe point, engine/stop_request.hpp, and the last finished step is written; a second
// signal ends the process at once), and when a step fails (the last good state). The newest two
// are kept; a run that finishes removes them. Each holds the Simulation (State and solver
// history), how far stats.partial.csv and timings.partial.csv had got, the frames listed in
// scene.pvd, and the scene file's path and checksum. Resuming truncates the partial files back
// to that point and takes the same steps again, so a run killed at any moment and resumed
// writes the same stats.csv (but for wall_seconds) and the same frames as one never stopped.
#pragma once

#include "engine/mpm/mpm_simulation.hpp"
#include "engine/run_lock.hpp"
#include "engine/run_record.hpp"
#include "engine/run_signals.hpp"
#include "engine/scene/scene.hpp"
#include "engine/simulation.hpp"
#include "engine/step_profile.hpp"

#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>

namespace nexdyn {

// A test hook: with NEXDYN_TEST_SIGNAL=SIGNAL@STEP[:PLACE] in the environment (SIGNAL one of KILL,
// TERM, INT, STOP (the run suspends itself there: a test of the folder's lock); PLACE one of begin (the default), row, checkpoint, newton, newtonN) a run sends itself
// that signal at step STEP: as the step begins, just after its stats row is written (before its
// frame and timings row), just after its checkpoint file is in place (before older ones are
// removed), or inside the step as its Nth Newton iteration begins (newton: the first; counted
// over all the step's solves and retried attempts).
// Signal and kill-and-resume tests use it to stop a run at a known point on any machine; the run
// says on stderr that the hook is set. A malformed value is an error naming the variable.
inline constexpr const char* kTestSignalVariable = "NEXDYN_TEST_SIGNAL";

// The exact header of stats.csv (DESIGN.md section 6); later features append columns after it.
inline constexpr const char* kStatsHeader =
    "step,time,kinetic_energy,elastic_energy,gravity_energy,barrier_energy,total_energy,"
    "momentum_x,momentum_y,momentum_z,newton_iterations,contacts,min_distance,wall_seconds";
// The energy balance of each step (engine/energy_balance.hpp), the last columns: the change of
// total_energy from the row before (or from the start) is
// boundary_work - friction_dissipated + kappa_energy + integrator_energy - (the change of
// damping_dissipated); then guarded_steps, the (sub)steps the energy guard retook with implicit
// Euler, sleeping_bodies, the bodies asleep at the end of the step (engine/sleeping.hpp), and
// damping_dissipated, the energy Rayleigh damping has taken out since the start (cumulative).
inline constexpr const char* kBalanceColumns =
    ",boundary_work,friction_dissipated,kappa_energy,integrator_energy,guarded_steps,sleeping_bodies,"
    "damping_dissipated";
// The angular momentum about the origin (issue 40), after the balance: sum m x cross v over the
// vertices, with each particle's APIC spin for particle bodies.
inline constexpr const char* kAngularMomentumColumns = ",angular_momentum_x,angular_momentum_y,angular_momentum_z";

// timings.csv: per step, the wall time of each phase (engine/step_profile.hpp, exclusive), of
// the rest of the step, of writing its stats row and frames, and the total, in milliseconds.
std::string timings_header();

struct RunOptions {
  std::filesystem::path out_dir;  // created if missing
  int64_t steps = -1;             // -1: the scene's time.steps
  bool progress = false;          // draw a progress bar on stderr
  int64_t checkpoint_every = -1;  // -1: the scene's output.checkpoint_every; 0: only on a signal
  std::string integrator;         // --integrator given to run (recorded for resume), or empty
  double rho_inf = std::numeric_limits<double>::quiet_NaN();  // --rho-inf (recorded), or NaN
  std::string energy_guard;       // --energy-guard "on" or "off" (recorded), or empty
  // The output folder's lock (run_lock.hpp) when the caller took it already (nexdyn run takes it
  // before it loads the scene, whose surface meshes go into the folder); else Runner::start does.
  std::shared_ptr<OutputLock> lock;
};

// The integrator of the command line (--integrator NAME, --rho-inf R) in place of the scene's:
// an empty name keeps the scene's scheme, a NaN rho_inf its rho_inf. Throws std::runtime_error
// naming the option and the value.
void override_integrator(Scene& scene, const std::string& name, double rho_inf);

struct RunSummary {
  bool ok = true;
  bool interrupted = false;      // stopped by SIGINT or SIGTERM (ok stays true)
  int signal = 0;                // which
  int64_t first_step = 1;        // the first step this process took (> 1 after a resume)
  int64_t steps_done = 0;        // the last completed step
  std::string checkpoint;        // the newest checkpoint written, if any
  double wall_seconds = 0.0;
  std::string message;  // why the run stopped early
  // Where the steps' time went: the sum of the steps' wall_seconds, its split by phase, and the
  // Newton iterations of all steps.
  double step_seconds = 0.0;
  StepProfile profile;
  double output_seconds = 0.0;  // stats rows and frames (not part of step_seconds)
  int64_t newton_iterations = 0;
  double peak_factor_bytes = 0.0;  // Cholesky factors held at once, at most
  // Steps taken in halves after a failed attempt (retries > 0), and the first one's failure:
  // "step N: [status] message (a step of dt s from t = T s)".
  int64_t retried_steps = 0;
  std::string first_retry;
};

// The steps this process took.
inline int64_t steps_run(const RunSummary& s) { return s.steps_done - s.first_step + 1; }

// "time per step: 12.3 ms = broad phase 1.2 + CCD 0.3 + ... + other 0.1; output 0.4 ms per step;
// Newton iterations per step: 4.5; peak Cholesky factors 1.2 MB", or "" when no step was done.
std::string profile_line(const RunSummary& summary);

// stats.csv's header for this scene: kStatsHeader, joint_violation with joints, retries, then
// kBalanceColumns.
std::string stats_header(const Scene& scene);
std::string stats_row(const StepStats& s);

// A run under way: a simulation (tets or particles), the output folder it writes as it goes
// (none when out_dir is empty: it only steps) and the record its checkpoints keep. run_scene and
// resume_run step one to its end; the Python module (engine/python) one step at a time.
class Runner {
 public:
  // A fresh run of `scene`, which must outlive the runner. With an output folder: locks it (or
  // refuses, naming the process that writes it), clears its old frames and checkpoints, writes
  // view.json, the rows files' headers and frame 0.
  static std::unique_ptr<Runner> start(const Scene& scene, const RunOptions& options);
  // Continues the run in the output folder `source` from its newest valid checkpoint (a
  // checkpoint that fails its checks is skipped with a line on stderr), writing on into the
  // folder, which it locks first (or refuses, writing nothing); or, when `source` is a checkpoint file, from it without an output folder. Throws
  // CheckpointError when there is nothing valid to resume.
  static std::unique_ptr<Runner> resume(const std::filesystem::path& source, bool progress);
  virtual ~Runner();
  Runner(const Runner&) = delete;
  Runner& operator=(const Runner&) = delete;

  // The next step, then its stats and timings rows, its frame and its periodic checkpoint. A failed
  // step leaves the state before it, writes a checkpoint of that (with an output folder) and sets
  // summary().ok to false with the reason in summary().message. A step stopped by a request
  // (StepStatus::stopped) leaves the state before it and writes nothing: the caller decides.
  virtual StepOutcome step() = 0;
  bool finished() const { return record_.steps_done >= record_.total_steps; }
  // A checkpoint of the last step: into the output folder's checkpoints/ when `file` is empty
  // (the newest two kept), else into `file` (a run without a folder needs one). Its path.
  virtual std::filesystem::path checkpoint(const std::filesystem::path& file = {}) = 0;
  // Ends the run: when every step is done, stats.csv and timings.csv take their final names and
  // the checkpoints go. Fills the summary's totals and lets the folder's lock go. Only close()
  // may be called after it.
  virtual const RunSummary& close() = 0;

  const Scene& scene() const { return scene_; }
  bool has_output() const { return !out_.empty(); }
  const std::filesystem::path& out_dir() const { return out_; }
  int64_t steps_done() const { return record_.steps_done; }
  int64_t total_steps() const { return record_.total_steps; }
  const RunSummary& summary() const { return summary_; }
  virtual const StepStats& last_stats() const = 0;
  virtual double time() const = 0;
  // The simulation being stepped: exactly one of the two is not null.
  virtual Simulation* simulation() = 0;
  virtual MpmSimulation* mpm_simulation() = 0;

 protected:
  Runner(const Scene& scene, std::unique_ptr<Scene> owned, std::filesystem::path out, RunRecord record,
         SignalHook hook);
  const Scene& scene_;
  std::unique_ptr<Scene> owned_scene_;  // a resumed run's scene, read from the checkpoint's record
  std::filesystem::path out_;
  RunRecord record_;
  SignalHook hook_;
  RunSummary summary_;
  std::shared_ptr<OutputLock> lock_;  // the output folder's, until close()
};

// A fresh run into options.out_dir, to its end (or a failed step, or SIGINT / SIGTERM: then
// with a checkpoint of the last finished step, the step under way abandoned).
RunSummary run_scene(const Scene& scene, const RunOptions& options);

// Continues the run in `out_dir` from its newest valid checkpoint (a checkpoint that fails its
// checks is skipped with a line on stderr). Throws CheckpointError when there is none, when the
// run had finished, or when the scene file changed since.
RunSummary resume_run(const std::filesystem::path& out_dir, bool progress);

}  // namespace nexdyn

// The run loop behind `nexdyn run` (see run.hpp).
#include "engine/run.hpp"

#include "engine/mpm/mpm_simulation.hpp"
#include "engine/output/checkpoint_file.hpp"
#include "engine/output/frame_writer.hpp"
#include "engine/output/step_checkpoint.hpp"
#include "engine/render/view_file.hpp"
#include "engine/run_record.hpp"
#include "engine/run_signals.hpp"
#include "engine/stop_request.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace nexdyn {

namespace fs = std::filesystem;

void override_integrator(Scene& scene, const std::string& name, double rho_inf) {
  if (!name.empty()) {
    const auto preset = integrator_preset(name);
    if (!preset) {
      std::string list;
      for (const std::string& n : integrator_preset_names()) list += (list.empty() ? "" : ", ") + n;
      throw std::runtime_error("--integrator: unknown integrator \"" + name + "\" (known: " + list + ")");
    }
    if (scene.contact.enabled && preset->is_explicit())
      throw std::runtime_error("--integrator: " + name + " is explicit, and explicit schemes cannot "
                               "keep contact intersection-free (the scene has contact)");
    scene.time.integrator = *preset;
  }
  if (std::isnan(rho_inf)) return;
  char value[32];
  std::snprintf(value, sizeof value, "%g", rho_inf);
  if (!(rho_inf >= 0.0 && rho_inf <= 1.0))
    throw std::runtime_error(std::string("--rho-inf: expected 0 <= rho_inf <= 1, got ") + value);
  if (scene.time.integrator.name != "generalized_alpha")
    throw std::runtime_error(std::string("--rho-inf ") + value + ": only generalized_alpha has it (the integrator is \"" +
                             scene.time.integrator.name + "\"; add --integrator generalized_alpha)");
  scene.time.integrator = generalized_alpha(rho_inf);
}

std::string stats_header(const Scene& scene) {
  return std::string(kStatsHeader) + (scene.model.joints.empty() ? "" : ",joint_violation") + ",retries" +
         kBalanceColumns + kAngularMomentumColumns;
}

std::string stats_row(const StepStats& s) {
  char buf[1024];
  std::snprintf(buf, sizeof(buf),
                "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d,%lld,%.17g,%.6g",
                static_cast<long long>(s.step), s.time, s.kinetic_energy, s.elastic_energy,
                s.gravity_energy, s.barrier_energy, s.total_energy, s.momentum.x(), s.momentum.y(),
                s.momentum.z(), s.newton_iterations, static_cast<long long>(s.contacts),
                s.min_distance, s.wall_seconds);
  std::string row = buf;
  if (s.joint_violation) {
    std::snprintf(buf, sizeof(buf), ",%.17g", *s.joint_violation);
    row += buf;
  }
  row += "," + std::to_string(s.retries);
  const EnergyBalance& b = s.balance;
  std::snprintf(buf, sizeof(buf), ",%.17g,%.17g,%.17g,%.17g,%d,%d,%.17g", b.boundary_work, b.friction_dissipated,
                b.kappa_energy, b.integrator_energy, s.guarded_steps, s.sleeping_bodies, s.damping_dissipated);
  row += buf;
  std::snprintf(buf, sizeof(buf), ",%.17g,%.17g,%.17g", s.angular_momentum.x(), s.angular_momentum.y(),
                s.angular_momentum.z());
  return row + buf;
}

namespace {

// A one-line progress bar redrawn in place on a terminal, at most ten times a second.
class ProgressBar {
 public:
  ProgressBar(bool enabled, int64_t total) : enabled_(enabled), total_(total) {}
  void update(int64_t done, double sim_time, bool force = false) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!force && now - last_ < std::chrono::milliseconds(100)) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    const double rate = elapsed > 0 ? done / elapsed : 0.0;
    const double eta = rate > 0 ? (total_ - done) / rate : 0.0;
    constexpr int kWidth = 30;
    const int filled = static_cast<int>(kWidth * done / std::max<int64_t>(total_, 1));
    std::string bar(filled, '#');
    bar.resize(kWidth, '.');
    std::fprintf(stderr, "\r[%s] step %lld/%lld  t=%.4g s  %.1f steps/s  ETA %.0f s   ", bar.c_str(),
                 static_cast<long long>(done), static_cast<long long>(total_), sim_time, rate, eta);
    std::fflush(stderr);
  }
  void finish() {
    if (enabled_) std::fprintf(stderr, "\n");
  }
  bool enabled() const { return enabled_; }

 private:
  bool enabled_;
  int64_t total_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_{};
};

void remove_old_frames(const fs::path& frames_dir) {
  std::error_code ec;
  if (!fs::exists(frames_dir, ec)) return;
  for (const auto& entry : fs::directory_iterator(frames_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("frame_", 0) == 0) fs::remove(entry.path(), ec);
  }
}

}  // namespace

std::string profile_line(const RunSummary& summary) {
  if (steps_run(summary) <= 0) return "";
  const double per_step_ms = 1e3 / double(steps_run(summary));
  std::string line;
  char buf[96];
  double phases = 0.0;
  for (size_t p = 0; p < kStepPhaseNames.size(); ++p) {
    const double seconds = summary.profile.seconds(static_cast<StepPhase>(p));
    phases += seconds;
    std::snprintf(buf, sizeof buf, "%s %s %.3g", line.empty() ? "" : " +", kStepPhaseNames[p], seconds * per_step_ms);
    line += buf;
  }
  std::snprintf(buf, sizeof buf, " + other %.3g", std::max(0.0, summary.step_seconds - phases) * per_step_ms);
  line += buf;
  char head[64];
  std::snprintf(head, sizeof head, "time per step: %.4g ms =", summary.step_seconds * per_step_ms);
  std::snprintf(buf, sizeof buf, "; output %.3g ms per step; Newton iterations per step: %.3g",
                summary.output_seconds * per_step_ms, double(summary.newton_iterations) / double(steps_run(summary)));
  std::string tail = buf;
  std::snprintf(buf, sizeof buf, "; peak Cholesky factors %.3g MB", summary.peak_factor_bytes / (1024.0 * 1024.0));
  tail += buf;
  if (rusage usage{}; getrusage(RUSAGE_SELF, &usage) == 0) {  // ru_maxrss: kilobytes on Linux
    std::snprintf(buf, sizeof buf, "; peak memory %.4g MB", double(usage.ru_maxrss) / 1024.0);
    tail += buf;
  }
  return head + line + tail;
}

std::string timings_header() {
  std::string header = "step";
  for (const char* column : kStepPhaseColumns) header += std::string(",") + column;
  return header + ",other_ms,output_ms,total_ms";
}

namespace {

// One timings.csv row: the phases' share of this step (the profile's growth since `before`).
std::string timings_row(int64_t step, const StepProfile& before, const StepProfile& after, double step_seconds,
                        double output_seconds) {
  std::string row = std::to_string(step);
  char buf[32];
  double phases = 0.0;
  for (size_t p = 0; p < kStepPhaseColumns.size(); ++p) {
    const double seconds = after.seconds(StepPhase(p)) - before.seconds(StepPhase(p));
    phases += seconds;
    std::snprintf(buf, sizeof buf, ",%.6g", 1e3 * seconds);
    row += buf;
  }
  std::snprintf(buf, sizeof buf, ",%.6g", 1e3 * std::max(0.0, step_seconds - phases));
  row += buf;
  std::snprintf(buf, sizeof buf, ",%.6g", 1e3 * output_seconds);
  row += buf;
  std::snprintf(buf, sizeof buf, ",%.6g", 1e3 * (step_seconds + output_seconds));
  return row + buf;
}

// An output file written as NAME.partial.csv while the run goes, renamed to NAME.csv at the end.
class RowFile {
 public:
  // A new file with its header; or, with `resume_bytes` >= 0, the partial file of an earlier run
  // cut back to that many bytes and appended to.
  RowFile(const fs::path& out, const std::string& name, const std::string& header, int64_t resume_bytes = -1)
      : partial_(out / (name + ".partial.csv")), final_(out / (name + ".csv")) {
    std::error_code ec;
    if (resume_bytes >= 0) {
      const auto size = fs::file_size(partial_, ec);
      if (ec || static_cast<int64_t>(size) < resume_bytes)
        throw CheckpointError(partial_.string() + " is shorter than when the checkpoint was written");
      // Rows are appended under the header already there: it must be this version's (a run
      // written before a column was added would get rows longer than its header).
      std::string first;
      std::ifstream existing(partial_);
      std::getline(existing, first);
      if (first != header)
        throw CheckpointError(partial_.string() + ": its header is not the one this version of nexdyn writes (\"" +
                              header + "\"): the run was written by another version; run it again");
      fs::resize_file(partial_, static_cast<uintmax_t>(resume_bytes), ec);
      if (ec) throw std::runtime_error(partial_.string() + ": cannot truncate: " + ec.message());
      file_.open(partial_, std::ios::app);
    } else {
      file_.open(partial_, std::ios::trunc);
    }
    fs::remove(final_, ec);
    if (!file_) throw std::runtime_error(partial_.string() + ": cannot open for writing");
    if (resume_bytes < 0) write(header);
  }
  // Each row goes to the operating system at once: `tail -f` follows the run, and a killed run
  // leaves the rows of every step it finished.
  void write(const std::string& row) {
    file_ << row << '\n';
    file_.flush();
    if (!file_) throw std::runtime_error(partial_.string() + ": write failed (disk full?)");
  }
  // Bytes written so far, all handed to the operating system.
  int64_t bytes() {
    file_.flush();
    if (!file_) throw std::runtime_error(partial_.string() + ": write failed (disk full?)");
    return static_cast<int64_t>(file_.tellp());
  }
  // Closes the file; renames it into place when `complete`.
  void finish(bool complete) {
    file_.close();
    if (!complete) return;
    std::error_code ec;
    fs::rename(partial_, final_, ec);
    if (ec) throw std::runtime_error(final_.string() + ": cannot rename into place: " + ec.message());
  }

 private:
  fs::path partial_, final_;
  std::ofstream file_;
};

// The frame files of the two kinds of simulation: tets and surfaces, or a particle cloud.
std::string frame_vtu(const Scene& scene, const Simulation& simulation) {
  return vtu_document(scene.model, simulation.state().x, simulation.state().v);
}
std::string frame_obj(const Scene& scene, const Simulation& simulation) {
  return obj_document(scene.model, simulation.state().x);
}
std::string frame_vtu(const Scene& scene, const MpmSimulation& simulation) {
  return vtu_particles_document(simulation.state().particles, scene.mpm->particle_body, scene.mpm->materials);
}
std::string frame_obj(const Scene&, const MpmSimulation&) {
  throw std::logic_error("MPM scenes have no surface to write (the scene reader refuses output.obj)");
}
std::string frame_bodies(const Scene& scene, const Simulation& simulation) {
  return bodies_document(scene.model, simulation.state().x, simulation.state().v);
}
std::string frame_bodies(const Scene&, const MpmSimulation&) {
  throw std::logic_error("MPM scenes have no bodies file (the scene reader refuses output.bodies)");
}

// The runner of either kind of simulation. Without an output folder it only steps.
template <typename Sim>
class RunnerOf final : public Runner {
 public:
  // A fresh run (`stats` and `timings` null without an output folder), or a resumed one whose
  // rows files are open at the end of record.steps_done's rows.
  RunnerOf(const Scene& scene, std::unique_ptr<Scene> owned, std::unique_ptr<Sim> simulation, RunRecord record,
           fs::path out, std::unique_ptr<RowFile> stats, std::unique_ptr<RowFile> timings, bool progress, bool fresh,
           const SignalHook& hook)
      : Runner(scene, std::move(owned), std::move(out), std::move(record), hook),
        simulation_(std::move(simulation)),
        stats_(std::move(stats)),
        timings_(std::move(timings)),
        progress_(progress, record_.total_steps),
        before_(simulation_->profile()) {
    summary_.first_step = record_.steps_done + 1;
    summary_.steps_done = record_.steps_done;
    if (fresh) write_frame(0);
  }

  StepOutcome step() override {
    if (closed_) throw std::logic_error("Runner::step after close");
    if (finished()) throw std::logic_error("Runner::step past the run's last step");
    const int64_t step = record_.steps_done + 1;
    hook_.at(step, SignalHook::Place::begin);
    hook_.arm(step);
    const auto step_start = std::chrono::steady_clock::now();
    const StepOutcome outcome = simulation_->step();
    hook_.disarm(step);
    if (outcome.status == StepStatus::stopped) {  // the state is still that of the step before
      summary_.interrupted = true;
      summary_.signal = stop_requested();
      // The abandoned work is in the profile's phases: in the steps' time too, so that they add up.
      summary_.step_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - step_start).count();
      return outcome;
    }
    if (outcome.status != StepStatus::ok) {
      summary_.ok = false;
      char buf[128];
      std::snprintf(buf, sizeof(buf), "step %lld (t = %.6g s) failed [%s]: ", static_cast<long long>(step),
                    simulation_->state().time + scene_.time.dt, std::string(step_status_name(outcome.status)).c_str());
      summary_.message = buf + outcome.message;
      if (has_output()) checkpoint({});
      return outcome;
    }
    const StepStats& stats = simulation_->last_stats();
    if (const std::string& why = stats.retried_because; !why.empty()) {
      const std::string line = "step " + std::to_string(step) + ": " + why;
      if (summary_.retried_steps++ == 0) summary_.first_retry = line;
      if (progress_.enabled()) std::fprintf(stderr, "\nnexdyn: retried in halves, %s\n", line.c_str());
    }
    summary_.step_seconds += stats.wall_seconds;
    summary_.newton_iterations += stats.newton_iterations;
    const auto output_start = std::chrono::steady_clock::now();
    if (stats_) stats_->write(stats_row(stats));
    hook_.at(step, SignalHook::Place::row);
    if (has_output() && step % scene_.output.every == 0) write_frame(step);
    const double output_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - output_start).count();
    summary_.output_seconds += output_seconds;
    if (timings_) timings_->write(timings_row(step, before_, simulation_->profile(), stats.wall_seconds, output_seconds));
    before_ = simulation_->profile();
    summary_.steps_done = record_.steps_done = step;
    progress_.update(step, simulation_->state().time, finished());
    if (has_output() && record_.checkpoint_every > 0 && step % record_.checkpoint_every == 0 && !finished())
      checkpoint({});
    return outcome;
  }

  fs::path checkpoint(const fs::path& file) override {
    if (closed_) throw std::logic_error("Runner::checkpoint after close");
    if (file.empty() && !has_output())
      throw std::runtime_error("a run without an output folder needs a file to write its checkpoint to");
    CheckpointWriter state;
    save_simulation(state, *simulation_);
    if (!file.empty()) {
      CheckpointWriter payload;
      RunRecord record = record_;
      record.stats_bytes = record.timings_bytes = 0;  // a file outside the run: no rows to cut back to
      put_record(payload, record);
      write_checkpoint_file(file, payload.bytes() + state.bytes());
      return file;
    }
    if (last_checkpoint_step_ == record_.steps_done) return summary_.checkpoint;
    record_.stats_bytes = stats_->bytes();
    record_.timings_bytes = timings_->bytes();
    summary_.checkpoint = write_checkpoint(out_, record_, state.bytes(), hook_).string();
    last_checkpoint_step_ = record_.steps_done;
    return summary_.checkpoint;
  }

  const RunSummary& close() override {
    if (closed_) return summary_;
    closed_ = true;
    progress_.finish();
    const bool complete = summary_.ok && finished();
    if (stats_) stats_->finish(complete);
    if (timings_) timings_->finish(complete);
    if (complete && has_output()) {
      remove_checkpoints(out_);
      summary_.checkpoint.clear();
    }
    summary_.profile = simulation_->profile();
    summary_.peak_factor_bytes = simulation_->peak_factor_bytes();
    summary_.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    lock_.reset();
    return summary_;
  }

  const StepStats& last_stats() const override { return simulation_->last_stats(); }
  double time() const override { return simulation_->state().time; }
  Simulation* simulation() override {
    if constexpr (std::is_same_v<Sim, Simulation>) return simulation_.get();
    return nullptr;
  }
  MpmSimulation* mpm_simulation() override {
    if constexpr (std::is_same_v<Sim, MpmSimulation>) return simulation_.get();
    return nullptr;
  }

 private:
  void write_frame(int64_t frame) {
    if (!has_output()) return;
    const fs::path frames_dir = out_ / "frames";
    const Sim& simulation = *simulation_;
    if (scene_.output.vtu) {
      const std::string name = frame_file_name(frame, "vtu");
      write_file_atomically(frames_dir / name, frame_vtu(scene_, simulation));
      record_.pvd_frames.emplace_back(simulation.state().time, "frames/" + name);
      write_file_atomically(out_ / "scene.pvd", pvd_document(record_.pvd_frames));
    }
    if (scene_.output.obj) write_file_atomically(frames_dir / frame_file_name(frame, "obj"), frame_obj(scene_, simulation));
    if (scene_.output.bodies)
      write_file_atomically(frames_dir / bodies_file_name(frame), frame_bodies(scene_, simulation));
  }

  std::unique_ptr<Sim> simulation_;
  std::unique_ptr<RowFile> stats_, timings_;
  ProgressBar progress_;
  StepProfile before_;
  int64_t last_checkpoint_step_ = -1;
  bool closed_ = false;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

template <typename Sim>
std::unique_ptr<Runner> make_runner(const Scene& scene, std::unique_ptr<Scene> owned, std::unique_ptr<Sim> simulation,
                                    RunRecord record, const fs::path& out, std::unique_ptr<RowFile> stats,
                                    std::unique_ptr<RowFile> timings, bool progress, bool fresh,
                                    const SignalHook& hook) {
  return std::make_unique<RunnerOf<Sim>>(scene, std::move(owned), std::move(simulation), std::move(record), out,
                                         std::move(stats), std::move(timings), progress, fresh, hook);
}

// A simulation restored from a checkpoint payload: the record, the scene it names (checked
// against the record's checksums), the simulation. CheckpointError when the checkpoint does not fit.
struct Restored {
  RunRecord record;
  std::unique_ptr<Scene> scene;
  std::unique_ptr<Simulation> simulation;
  std::unique_ptr<MpmSimulation> mpm_simulation;
};

Restored restore(const std::string& payload, const fs::path& file, const fs::path& mesh_cache_dir) {
  Restored r;
  CheckpointReader in(payload, file.string());
  r.record = get_record(in);
  // The scene must be the one the run started from: a changed file is not this run.
  if (file_crc(r.record.scene_file) != r.record.scene_crc)
    throw std::runtime_error(r.record.scene_file.string() + " changed since the run started; resuming it "
                             "would not continue the same run");
  r.scene = std::make_unique<Scene>(load_scene(r.record.scene_file, {}, mesh_cache_dir));
  if (model_crc(*r.scene) != r.record.model_crc)
    throw std::runtime_error(r.record.scene_file.string() + ": a mesh changed since the run started; "
                             "resuming would not continue the same run");
  try {
    override_integrator(*r.scene, r.record.integrator, r.record.rho_inf);
    if (!r.record.energy_guard.empty()) r.scene->time.energy_guard = r.record.energy_guard == "on";
  } catch (const std::runtime_error& e) {
    in.fail(std::string("the recorded integrator: ") + e.what());
  }
  int64_t restored_step = 0;
  if (r.scene->mpm) {
    r.mpm_simulation = std::make_unique<MpmSimulation>(*r.scene);
    restore_simulation(in, *r.mpm_simulation);
    restored_step = r.mpm_simulation->state().step;
  } else {
    r.simulation = std::make_unique<Simulation>(*r.scene);
    restore_simulation(in, *r.simulation);
    restored_step = r.simulation->state().step;
  }
  in.expect_end();
  if (restored_step != r.record.steps_done) in.fail("the state is not that of the recorded step");
  return r;
}

std::unique_ptr<Runner> resume_from_file(const fs::path& file, const SignalHook& hook) {
  Restored r = restore(read_checkpoint_file(file), file, {});
  const Scene& scene = *r.scene;
  if (r.mpm_simulation)
    return make_runner(scene, std::move(r.scene), std::move(r.mpm_simulation), std::move(r.record), {}, nullptr,
                       nullptr, false, false, hook);
  return make_runner(scene, std::move(r.scene), std::move(r.simulation), std::move(r.record), {}, nullptr, nullptr,
                     false, false, hook);
}

}  // namespace

Runner::Runner(const Scene& scene, std::unique_ptr<Scene> owned, fs::path out, RunRecord record, SignalHook hook)
    : scene_(scene), owned_scene_(std::move(owned)), out_(std::move(out)), record_(std::move(record)), hook_(hook) {}

Runner::~Runner() = default;

std::unique_ptr<Runner> Runner::start(const Scene& scene, const RunOptions& options) {
  const SignalHook hook = signal_hook_from_environment();  // a malformed hook: an error before any output
  const fs::path out = options.out_dir;
  RunRecord record;
  record.scene_file = fs::absolute(scene.file);
  record.scene_crc = file_crc(scene.file);
  record.model_crc = model_crc(scene);
  record.integrator = options.integrator;
  record.rho_inf = options.rho_inf;
  record.energy_guard = options.energy_guard;
  record.total_steps = options.steps >= 0 ? options.steps : scene.time.steps;
  record.checkpoint_every = options.checkpoint_every >= 0 ? options.checkpoint_every : scene.output.checkpoint_every;
  std::unique_ptr<RowFile> stats, timings;
  std::shared_ptr<OutputLock> lock = options.lock;
  if (!out.empty()) {
    const fs::path frames_dir = out / "frames";
    std::error_code ec;
    fs::create_directories(out, ec);
    if (ec) throw std::runtime_error(out.string() + ": cannot create the output folder: " + ec.message());
    if (!lock) lock = OutputLock::acquire(out);
    fs::create_directories(frames_dir, ec);
    if (ec) throw std::runtime_error(frames_dir.string() + ": cannot create the output folder: " + ec.message());
    remove_old_frames(frames_dir);
    remove_checkpoints(out);
    fs::remove(out / "scene.pvd", ec);
    // What `nexdyn render` needs beside the frames (engine/render/view_file.hpp).
    write_file_atomically(out / "view.json", view_document(scene_view(scene)));
    stats = std::make_unique<RowFile>(out, "stats", stats_header(scene));
    timings = std::make_unique<RowFile>(out, "timings", timings_header());
  }
  std::unique_ptr<Runner> runner =
      scene.mpm ? make_runner(scene, nullptr, std::make_unique<MpmSimulation>(scene), std::move(record), out,
                              std::move(stats), std::move(timings), options.progress, true, hook)
                : make_runner(scene, nullptr, std::make_unique<Simulation>(scene), std::move(record), out,
                              std::move(stats), std::move(timings), options.progress, true, hook);
  runner->lock_ = std::move(lock);
  return runner;
}

std::unique_ptr<Runner> Runner::resume(const fs::path& source, bool progress) {
  std::error_code ec;
  const SignalHook hook = signal_hook_from_environment();  // a malformed hook: an error before any output
  if (fs::is_regular_file(source, ec)) return resume_from_file(source, hook);
  const fs::path& out = source;
  auto check_unfinished = [&] {
    if (fs::exists(out / "stats.partial.csv", ec)) return;
    if (fs::exists(out / "stats.csv", ec))
      throw CheckpointError(out.string() + ": the run finished (stats.csv is complete); nothing to resume");
    throw CheckpointError(out.string() + ": no run to resume here (no stats.partial.csv)");
  };
  check_unfinished();  // before the lock: a folder without a run gets no lock file
  std::shared_ptr<OutputLock> lock = OutputLock::acquire(out);
  check_unfinished();  // again: the run that held the lock may have finished meanwhile
  const std::vector<fs::path> found = list_checkpoints(out);
  if (found.empty()) throw CheckpointError(out.string() + ": no checkpoint in " + checkpoint_folder(out).string());
  for (const fs::path& path : found) {
    Restored r;
    std::unique_ptr<RowFile> stats, timings;
    try {
      r = restore(read_checkpoint_file(path), path, out / "meshes");
      stats = std::make_unique<RowFile>(out, "stats", stats_header(*r.scene), r.record.stats_bytes);
      timings = std::make_unique<RowFile>(out, "timings", timings_header(), r.record.timings_bytes);
    } catch (const CheckpointError& e) {
      std::fprintf(stderr, "nexdyn: skipping checkpoint %s\n", e.what());
      continue;
    }
    // Frames past the checkpoint are written again; the ones before are listed in its record.
    const Scene& scene = *r.scene;
    std::unique_ptr<Runner> runner =
        r.mpm_simulation ? make_runner(scene, std::move(r.scene), std::move(r.mpm_simulation), std::move(r.record),
                                       out, std::move(stats), std::move(timings), progress, false, hook)
                         : make_runner(scene, std::move(r.scene), std::move(r.simulation), std::move(r.record), out,
                                       std::move(stats), std::move(timings), progress, false, hook);
    runner->lock_ = std::move(lock);
    return runner;
  }
  throw CheckpointError(out.string() + ": no valid checkpoint (every one was skipped, reasons above)");
}

namespace {

// Steps a runner to its end, or until a step fails, or until SIGINT or SIGTERM (which abandon the
// step under way at its next safe point, or come between two steps): then with a checkpoint of
// the last finished step.
RunSummary run_to_end(Runner& runner) {
  StopSignals signals;
  int stopped_by = 0;
  while (!runner.finished()) {
    const StepStatus status = runner.step().status;
    if (status != StepStatus::ok && status != StepStatus::stopped) break;
    if (signals.received() != 0 && (status == StepStatus::stopped || !runner.finished())) {
      stopped_by = signals.received();
      runner.checkpoint();
      break;
    }
  }
  RunSummary summary = runner.close();
  if (stopped_by != 0) {
    summary.interrupted = true;
    summary.signal = stopped_by;
  }
  return summary;
}

}  // namespace

RunSummary run_scene(const Scene& scene, const RunOptions& options) {
  if (options.out_dir.empty()) throw std::logic_error("run_scene needs an output folder");
  return run_to_end(*Runner::start(scene, options));
}

RunSummary resume_run(const fs::path& out, bool progress) {
  std::error_code ec;
  if (fs::is_regular_file(out, ec))
    throw CheckpointError(out.string() + ": a file; nexdyn resume takes the output folder of a run");
  return run_to_end(*Runner::resume(out, progress));
}

}  // namespace nexdyn

// The run loop behind `nexdyn run` (see run.hpp).
#include "engine/run.hpp"

#include "engine/output/frame_writer.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace nexdyn {

namespace fs = std::filesystem;

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
  return row;
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
  if (summary.steps_done <= 0) return "";
  const double per_step_ms = 1e3 / double(summary.steps_done);
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
  std::snprintf(buf, sizeof buf, "; Newton iterations per step: %.3g",
                double(summary.newton_iterations) / double(summary.steps_done));
  return head + line + buf;
}

RunSummary run_scene(const Scene& scene, const RunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const int64_t total_steps = options.steps >= 0 ? options.steps : scene.time.steps;
  const fs::path out = options.out_dir;
  const fs::path frames_dir = out / "frames";
  std::error_code ec;
  fs::create_directories(frames_dir, ec);
  if (ec) throw std::runtime_error(frames_dir.string() + ": cannot create the output folder: " + ec.message());
  remove_old_frames(frames_dir);
  fs::remove(out / "stats.csv", ec);
  fs::remove(out / "scene.pvd", ec);

  const fs::path partial = out / "stats.partial.csv";
  std::ofstream stats(partial, std::ios::trunc);
  if (!stats) throw std::runtime_error(partial.string() + ": cannot open for writing");
  stats << kStatsHeader << (scene.model.joints.empty() ? "" : ",joint_violation") << '\n';

  Simulation simulation(scene);
  std::vector<std::pair<double, std::string>> pvd_frames;
  auto write_frame = [&](int64_t frame) {
    const State& s = simulation.state();
    if (scene.output.vtu) {
      const std::string name = frame_file_name(frame, "vtu");
      write_file_atomically(frames_dir / name, vtu_document(scene.model, s.x, s.v));
      pvd_frames.emplace_back(s.time, "frames/" + name);
      write_file_atomically(out / "scene.pvd", pvd_document(pvd_frames));
    }
    if (scene.output.obj)
      write_file_atomically(frames_dir / frame_file_name(frame, "obj"), obj_document(scene.model, s.x));
  };

  RunSummary summary;
  ProgressBar progress(options.progress, total_steps);
  write_frame(0);
  for (int64_t step = 1; step <= total_steps; ++step) {
    const StepOutcome outcome = simulation.step();
    if (outcome.status != StepStatus::ok) {
      summary.ok = false;
      char buf[128];
      std::snprintf(buf, sizeof(buf), "step %lld (t = %.6g s) failed [%s]: ", static_cast<long long>(step),
                    simulation.state().time + scene.time.dt, std::string(step_status_name(outcome.status)).c_str());
      summary.message = buf + outcome.message;
      break;
    }
    stats << stats_row(simulation.last_stats()) << '\n';
    summary.step_seconds += simulation.last_stats().wall_seconds;
    summary.newton_iterations += simulation.last_stats().newton_iterations;
    if (!stats) throw std::runtime_error(partial.string() + ": write failed (disk full?)");
    if (step % scene.output.every == 0) write_frame(step);
    summary.steps_done = step;
    progress.update(step, simulation.state().time, step == total_steps);
  }
  progress.finish();
  stats.close();
  if (summary.ok) {
    fs::rename(partial, out / "stats.csv", ec);
    if (ec) throw std::runtime_error((out / "stats.csv").string() + ": cannot rename into place: " + ec.message());
  }
  summary.profile = simulation.profile();
  summary.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace nexdyn

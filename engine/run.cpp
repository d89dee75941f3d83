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
  std::snprintf(buf, sizeof buf, "; output %.3g ms per step; Newton iterations per step: %.3g",
                summary.output_seconds * per_step_ms, double(summary.newton_iterations) / double(summary.steps_done));
  std::string tail = buf;
  std::snprintf(buf, sizeof buf, "; peak Cholesky factors %.3g MB", summary.peak_factor_bytes / (1024.0 * 1024.0));
  return head + line + tail + buf;
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
  RowFile(const fs::path& out, const std::string& name, const std::string& header)
      : partial_(out / (name + ".partial.csv")), final_(out / (name + ".csv")), file_(partial_, std::ios::trunc) {
    std::error_code ec;
    fs::remove(final_, ec);
    if (!file_) throw std::runtime_error(partial_.string() + ": cannot open for writing");
    write(header);
  }
  void write(const std::string& row) {
    file_ << row << '\n';
    if (!file_) throw std::runtime_error(partial_.string() + ": write failed (disk full?)");
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

}  // namespace

RunSummary run_scene(const Scene& scene, const RunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  const int64_t total_steps = options.steps >= 0 ? options.steps : scene.time.steps;
  const fs::path out = options.out_dir;
  const fs::path frames_dir = out / "frames";
  std::error_code ec;
  fs::create_directories(frames_dir, ec);
  if (ec) throw std::runtime_error(frames_dir.string() + ": cannot create the output folder: " + ec.message());
  remove_old_frames(frames_dir);
  fs::remove(out / "scene.pvd", ec);

  RowFile stats(out, "stats", std::string(kStatsHeader) + (scene.model.joints.empty() ? "" : ",joint_violation"));
  RowFile timings(out, "timings", timings_header());

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
  StepProfile before = simulation.profile();
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
    const double step_seconds = simulation.last_stats().wall_seconds;
    summary.step_seconds += step_seconds;
    summary.newton_iterations += simulation.last_stats().newton_iterations;
    const auto output_start = std::chrono::steady_clock::now();
    stats.write(stats_row(simulation.last_stats()));
    if (step % scene.output.every == 0) write_frame(step);
    const double output_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - output_start).count();
    summary.output_seconds += output_seconds;
    timings.write(timings_row(step, before, simulation.profile(), step_seconds, output_seconds));
    before = simulation.profile();
    summary.steps_done = step;
    progress.update(step, simulation.state().time, step == total_steps);
  }
  progress.finish();
  stats.finish(summary.ok);
  timings.finish(summary.ok);
  summary.profile = simulation.profile();
  summary.peak_factor_bytes = simulation.peak_factor_bytes();
  summary.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace nexdyn

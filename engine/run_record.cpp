// The run record of a checkpoint and the checkpoints' folder (see run_record.hpp).
#include "engine/run_record.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <system_error>

namespace nexdyn {

namespace fs = std::filesystem;

namespace {
constexpr const char* kRunTag = "nexdyn run";
}  // namespace


uint32_t file_crc(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CheckpointError(path.string() + ": cannot read the scene file");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return crc32(bytes.data(), bytes.size());
}

uint32_t model_crc(const Scene& scene) {
  auto add = [](uint32_t crc, const auto& v) { return crc32(v.data(), v.size() * sizeof(v[0]), crc); };
  const Model& m = scene.model;
  uint32_t crc = add(0, m.rest_positions);
  crc = add(crc, m.tets);
  crc = add(crc, m.mass);
  crc = add(crc, m.dirichlet);
  if (scene.mpm) {
    crc = add(crc, scene.mpm->initial.x);
    crc = add(crc, scene.mpm->initial.mass);
  }
  return crc;
}

void put_record(CheckpointWriter& out, const RunRecord& r) {
  out.put_string(kRunTag);
  out.put_string(r.scene_file.string());
  out.put(r.scene_crc);
  out.put(r.model_crc);
  out.put_string(r.integrator);
  out.put(r.rho_inf);
  out.put_string(r.energy_guard);
  out.put(r.total_steps);
  out.put(r.checkpoint_every);
  out.put(r.steps_done);
  out.put(r.stats_bytes);
  out.put(r.timings_bytes);
  out.put<uint64_t>(r.pvd_frames.size());
  for (const auto& [time, name] : r.pvd_frames) {
    out.put(time);
    out.put_string(name);
  }
}

RunRecord get_record(CheckpointReader& in) {
  if (in.get_string() != kRunTag) in.fail("not a checkpoint of `nexdyn run`");
  RunRecord r;
  r.scene_file = in.get_string();
  r.scene_crc = in.get<uint32_t>();
  r.model_crc = in.get<uint32_t>();
  r.integrator = in.get_string();
  r.rho_inf = in.get<double>();
  r.energy_guard = in.get_string();
  r.total_steps = in.get<int64_t>();
  r.checkpoint_every = in.get<int64_t>();
  r.steps_done = in.get<int64_t>();
  r.stats_bytes = in.get<int64_t>();
  r.timings_bytes = in.get<int64_t>();
  if (r.steps_done < 0 || r.steps_done > r.total_steps || r.checkpoint_every < 0 || r.stats_bytes < 0 ||
      r.timings_bytes < 0)
    in.fail("inconsistent run record");
  const uint64_t frames = in.get<uint64_t>();
  if (frames > static_cast<uint64_t>(r.steps_done) + 1) in.fail("more frames than steps");
  for (uint64_t k = 0; k < frames; ++k) {
    const double time = in.get<double>();
    r.pvd_frames.emplace_back(time, in.get_string());
  }
  return r;
}

fs::path checkpoint_folder(const fs::path& out) { return out / "checkpoints"; }

std::vector<fs::path> list_checkpoints(const fs::path& out) {
  std::vector<fs::path> found;
  std::error_code ec;
  if (!fs::is_directory(checkpoint_folder(out), ec)) return found;
  for (const auto& entry : fs::directory_iterator(checkpoint_folder(out), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("checkpoint_", 0) == 0 && entry.path().extension() == ".ckpt") found.push_back(entry.path());
  }
  std::sort(found.begin(), found.end(), [](const fs::path& a, const fs::path& b) { return a.filename() > b.filename(); });
  return found;
}

void remove_checkpoints(const fs::path& out) {
  std::error_code ec;
  for (const fs::path& path : list_checkpoints(out)) fs::remove(path, ec);
}

fs::path write_checkpoint(const fs::path& out, const RunRecord& record, const std::string& snapshot,
                          SignalHook& hook) {
  CheckpointWriter payload;
  put_record(payload, record);
  std::string bytes = payload.bytes();
  bytes += snapshot;
  char name[64];
  std::snprintf(name, sizeof name, "checkpoint_%09lld.ckpt", static_cast<long long>(record.steps_done));
  std::error_code ec;
  fs::create_directories(checkpoint_folder(out), ec);
  const fs::path path = checkpoint_folder(out) / name;
  write_checkpoint_file(path, bytes);
  hook.at(record.steps_done, SignalHook::Place::checkpoint);
  const std::vector<fs::path> all = list_checkpoints(out);
  for (size_t k = 2; k < all.size(); ++k) fs::remove(all[k], ec);
  return path;
}

}  // namespace nexdyn

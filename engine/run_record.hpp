// What `nexdyn run` keeps of a run in its checkpoints besides the simulation (RunRecord: the scene
// file and its checksums, the command line's overrides, how far the run got, how long its rows
// files were), and the checkpoints' folder: DIR/checkpoints/checkpoint_NNNNNNNNN.ckpt, the newest
// two kept. A checkpoint's payload is the record followed by the simulation's part
// (engine/output/step_checkpoint.hpp); the file format is engine/output/checkpoint_file.hpp.
#pragma once

#include "engine/output/checkpoint_file.hpp"
#include "engine/run_signals.hpp"
#include "engine/scene/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace nexdyn {

// What a checkpoint records of the run, besides the Simulation.
struct RunRecord {
  std::filesystem::path scene_file;       // absolute
  uint32_t scene_crc = 0;    // of the scene file's bytes
  uint32_t model_crc = 0;    // of the model built from it (meshes included)
  std::string integrator;    // --integrator override, or empty
  double rho_inf = std::numeric_limits<double>::quiet_NaN();  // --rho-inf override, or NaN
  std::string energy_guard;  // --energy-guard override ("on", "off"), or empty
  int64_t total_steps = 0;
  int64_t checkpoint_every = 0;
  int64_t steps_done = 0;
  int64_t stats_bytes = 0, timings_bytes = 0;
  std::vector<std::pair<double, std::string>> pvd_frames;
};

// CRC-32 of a file's bytes (CheckpointError when it cannot be read), and of the model a scene
// built (positions, tets, masses, boundaries; MPM particles): a resume refuses a changed scene.
uint32_t file_crc(const std::filesystem::path& path);
uint32_t model_crc(const Scene& scene);

void put_record(CheckpointWriter& out, const RunRecord& record);
// CheckpointError naming the fault when the payload does not start with a run record.
RunRecord get_record(CheckpointReader& in);

std::filesystem::path checkpoint_folder(const std::filesystem::path& out);
// The checkpoints in `out`, newest first.
std::vector<std::filesystem::path> list_checkpoints(const std::filesystem::path& out);
void remove_checkpoints(const std::filesystem::path& out);
// Writes a checkpoint of `snapshot` (a simulation saved after record.steps_done) and keeps the
// newest two; returns its path. The hook may stop the process once the file is in place.
std::filesystem::path write_checkpoint(const std::filesystem::path& out, const RunRecord& record,
                                       const std::string& snapshot, SignalHook& hook);

}  // namespace nexdyn

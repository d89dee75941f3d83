// A simulation's part of a checkpoint. For tet bodies the State and the StepHistory, nothing else
// (everything else the engine keeps between steps is a cache rebuilt from these two); for
// particle bodies the MpmState and the energy the last row was measured from. Written into and
// read from the payload of a checkpoint file (checkpoint_file.hpp); run.cpp adds the run's own
// record. The simulations know nothing of checkpoints: they hand out their state and adopt one.
#pragma once

#include "engine/mpm/mpm_simulation.hpp"
#include "engine/output/checkpoint_file.hpp"
#include "engine/simulation.hpp"
#include "engine/state.hpp"
#include "engine/step_history.hpp"

#include <cstdint>

namespace nexdyn {

// The sizes a checkpoint of this scene must have.
struct StepCheckpointShape {
  int64_t num_dofs = 0;
  int32_t num_vertices = 0;
  int64_t num_joints = 0;
  int64_t num_kinematic = 0;  // kinematic vertices
  bool has_contact = false;
  int32_t num_bodies = 0;
};

void write_step_checkpoint(CheckpointWriter& out, const State& state, const StepHistory& history);

// Reads what write_step_checkpoint wrote and checks it against `shape` (sizes, finite values,
// vertex pairs of this model); CheckpointError naming the fault otherwise, with `state` and
// `history` untouched. On success x_tilde is x, and the contact pattern is marked for a rebuild.
void read_step_checkpoint(CheckpointReader& in, const StepCheckpointShape& shape, State& state,
                          StepHistory& history);

// The whole simulation: what its next steps depend on, written, or read back, checked against the
// simulation's scene and adopted (CheckpointError naming the fault otherwise, the simulation
// untouched). A restored simulation takes the same steps as the saved one, bit for bit.
void save_simulation(CheckpointWriter& out, const Simulation& simulation);
void restore_simulation(CheckpointReader& in, Simulation& simulation);
void save_simulation(CheckpointWriter& out, const MpmSimulation& simulation);
void restore_simulation(CheckpointReader& in, MpmSimulation& simulation);

}  // namespace nexdyn

// State and StepHistory in a checkpoint payload (see step_checkpoint.hpp).
#include "engine/output/step_checkpoint.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace nexdyn {

namespace {

bool all_finite(const std::vector<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

constexpr const char* kMpmCheckpointTag = "nexdyn mpm state 1";

bool finite_non_negative(double value) { return std::isfinite(value) && value >= 0.0; }

void write_pairs(CheckpointWriter& out, const std::vector<std::pair<int32_t, int32_t>>& pairs) {
  std::vector<int32_t> flat;
  flat.reserve(2 * pairs.size());
  for (const auto& [j, i] : pairs) {
    flat.push_back(j);
    flat.push_back(i);
  }
  out.put_vector(flat);
}

std::vector<std::pair<int32_t, int32_t>> read_pairs(CheckpointReader& in, const StepCheckpointShape& shape) {
  const std::vector<int32_t> flat = in.get_vector<int32_t>();
  if (flat.size() % 2 != 0) in.fail("odd number of contact pattern ids");
  if (!shape.has_contact && !flat.empty()) in.fail("contact pattern pairs for a scene without contact");
  std::vector<std::pair<int32_t, int32_t>> pairs;
  pairs.reserve(flat.size() / 2);
  for (size_t k = 0; k < flat.size(); k += 2) {
    const int32_t j = flat[k], i = flat[k + 1];
    if (!(i >= 0 && i < j && j < shape.num_vertices))
      in.fail("contact pattern pair (" + std::to_string(j) + ", " + std::to_string(i) +
              ") is not a vertex pair J > I of this model");
    if (!pairs.empty() && !(pairs.back() < std::make_pair(j, i))) in.fail("contact pattern pairs out of order");
    pairs.emplace_back(j, i);
  }
  return pairs;
}

// The sleeping bodies' fields: all empty (sleeping off), or one count and one group per body
// (group -1 or a body id) and a finite anchor per DOF.
void read_sleep(CheckpointReader& in, const StepCheckpointShape& shape, StepHistory& h) {
  h.rest_steps = in.get_vector<int32_t>();
  h.sleep_group = in.get_vector<int32_t>();
  h.rest_anchor = in.get_vector<double>();
  if (h.rest_steps.empty() && h.sleep_group.empty() && h.rest_anchor.empty()) return;
  if (static_cast<int64_t>(h.rest_steps.size()) != shape.num_bodies ||
      static_cast<int64_t>(h.sleep_group.size()) != shape.num_bodies ||
      static_cast<int64_t>(h.rest_anchor.size()) != shape.num_dofs)
    in.fail("sleeping bodies' record of the wrong size");
  for (size_t b = 0; b < h.rest_steps.size(); ++b)
    if (h.rest_steps[b] < 0 || h.sleep_group[b] < -1 || h.sleep_group[b] >= shape.num_bodies)
      in.fail("sleeping bodies' record out of range at body " + std::to_string(b));
  if (!all_finite(h.rest_anchor)) in.fail("non-finite rest anchor");
}

}  // namespace

void write_step_checkpoint(CheckpointWriter& out, const State& state, const StepHistory& history) {
  out.put(state.step);
  out.put(state.time);
  out.put_vector(state.x);
  out.put_vector(state.v);
  out.put_vector(state.a);
  out.put_vector(state.a_bar);
  out.put(history.kappa);
  out.put(history.kappa_max);
  out.put<uint8_t>(history.kappa_from_contact);
  out.put_vector(history.contact_memory);
  out.put_vector(history.joint_multipliers);
  out.put(history.joint_stiffening);
  out.put_vector(history.kinematic_multipliers);
  out.put(history.kinematic_multiplier_scale);
  out.put(history.kinematic_stiffening);
  write_pairs(out, history.contact_pattern_pairs);
  out.put_vector(history.rest_steps);
  out.put_vector(history.sleep_group);
  out.put_vector(history.rest_anchor);
  out.put(history.energy_before);
  out.put(history.integrator_created);
  out.put(history.energy_scale);
  out.put(history.damping_dissipated);
}

void read_step_checkpoint(CheckpointReader& in, const StepCheckpointShape& shape, State& state_out,
                          StepHistory& history_out) {
  const int64_t n = shape.num_dofs;
  State state;
  state.step = in.get<int64_t>();
  state.time = in.get<double>();
  state.x = in.get_vector<double>(n);
  state.v = in.get_vector<double>(n);
  state.a = in.get_vector<double>(n);
  state.a_bar = in.get_vector<double>(n);
  if (state.step < 0 || !std::isfinite(state.time)) in.fail("negative step, or non-finite time");
  for (const std::vector<double>* field : {&state.x, &state.v, &state.a, &state.a_bar})
    if (!all_finite(*field)) in.fail("non-finite positions, velocities or accelerations");
  state.x_tilde = state.x;

  StepHistory h;
  h.kappa = in.get<double>();
  h.kappa_max = in.get<double>();
  h.kappa_from_contact = in.get<uint8_t>() != 0;
  if (!finite_non_negative(h.kappa) || !finite_non_negative(h.kappa_max))
    in.fail("barrier stiffness is not a finite number >= 0");
  h.contact_memory = in.get_vector<double>();
  if (!h.contact_memory.empty() && static_cast<int64_t>(h.contact_memory.size()) != n)
    in.fail("contact memory of the wrong size");
  if (!all_finite(h.contact_memory)) in.fail("non-finite contact memory");
  h.joint_multipliers = in.get_vector<double>(3 * shape.num_joints);
  h.joint_stiffening = in.get<double>();
  h.kinematic_multipliers = in.get_vector<double>(3 * shape.num_kinematic);
  h.kinematic_multiplier_scale = in.get<double>();
  h.kinematic_stiffening = in.get<double>();
  if (!all_finite(h.joint_multipliers) || !all_finite(h.kinematic_multipliers))
    in.fail("non-finite joint or kinematic multipliers");
  if (!(h.joint_stiffening >= 1.0 && std::isfinite(h.joint_stiffening)) ||
      !(h.kinematic_stiffening >= 1.0 && std::isfinite(h.kinematic_stiffening)) ||
      !(h.kinematic_multiplier_scale > 0.0 && std::isfinite(h.kinematic_multiplier_scale)))
    in.fail("stiffening or multiplier scale out of range");
  h.contact_pattern_pairs = read_pairs(in, shape);
  h.contact_pattern_stamp = StepHistory::kContactPatternUnbuilt;
  read_sleep(in, shape, h);
  h.energy_before = in.get<double>();
  h.integrator_created = in.get<double>();
  h.energy_scale = in.get<double>();
  if (!std::isfinite(h.energy_before)) in.fail("non-finite energy");
  if (!std::isfinite(h.integrator_created) || !finite_non_negative(h.energy_scale))
    in.fail("non-finite energy guard record");
  h.damping_dissipated = in.get<double>();
  if (!std::isfinite(h.damping_dissipated)) in.fail("non-finite damping record");

  state_out = std::move(state);
  history_out = std::move(h);
}

void save_simulation(CheckpointWriter& out, const Simulation& simulation) {
  write_step_checkpoint(out, simulation.state(), simulation.history());
}

void restore_simulation(CheckpointReader& in, Simulation& simulation) {
  const Model& model = simulation.model();
  const StepCheckpointShape shape{model.num_dofs(), model.num_vertices, simulation.num_joints(),
                                  static_cast<int64_t>(simulation.kinematic().vertices().size()),
                                  simulation.has_contact(), static_cast<int32_t>(model.bodies.size())};
  State state;
  StepHistory history;
  read_step_checkpoint(in, shape, state, history);
  simulation.adopt(state, history);
}

void save_simulation(CheckpointWriter& out, const MpmSimulation& simulation) {
  const MpmState& s = simulation.state();
  out.put_string(kMpmCheckpointTag);
  out.put(s.step);
  out.put(s.time);
  out.put(simulation.previous_total());
  out.put_vector(s.particles.x);
  out.put_vector(s.particles.v);
  out.put_vector(s.particles.F);
  out.put_vector(s.particles.C);
  out.put_vector(s.history.a_bar);
}

void restore_simulation(CheckpointReader& in, MpmSimulation& simulation) {
  if (in.get_string() != kMpmCheckpointTag) in.fail("not an MPM state of this version");
  const Particles& initial = simulation.model().initial;
  const int64_t n = initial.size();
  MpmState s;
  s.particles = initial;
  s.step = in.get<int64_t>();
  s.time = in.get<double>();
  const double total = in.get<double>();
  s.particles.x = in.get_vector<double>(3 * n);
  s.particles.v = in.get_vector<double>(3 * n);
  s.particles.F = in.get_vector<double>(9 * n);
  s.particles.C = in.get_vector<double>(9 * n);
  s.history.a_bar = in.get_vector<double>(3 * n);
  if (s.step < 0 || !std::isfinite(s.time)) in.fail("negative step, or non-finite time");
  if (!std::isfinite(total)) in.fail("non-finite energy");
  for (const std::vector<double>* field : {&s.particles.x, &s.particles.v, &s.particles.F, &s.particles.C,
                                           &s.history.a_bar})
    if (!all_finite(*field)) in.fail("non-finite particle positions, velocities, deformations or accelerations");
  simulation.adopt(s, total);
}

}  // namespace nexdyn

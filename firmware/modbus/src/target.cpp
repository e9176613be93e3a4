#include "zerog/modbus/target.hpp"

#include <algorithm>

namespace zerog::modbus {

void fill_from_cycle(const loop::Cycle& cycle, SupervisorSnapshot& s) noexcept {
  const loop::CycleRecord& r = cycle.last();
  s.cycle = r.cycle;
  s.state = cycle.state_machine().state();
  s.fault = cycle.state_machine().fault();
  s.flags = r.flags;
  s.ready = cycle.ready();
  s.contact_sensor = r.contact;
  s.datagrams_lost = cycle.counters().datagrams_lost;
  s.commands_refused = cycle.counters().commands_refused;
  s.poses_from_joints = cycle.counters().poses_from_joints;
  s.pose_disagreements = cycle.counters().pose_disagreements;
  s.poses_missing = cycle.counters().poses_missing;
}

void fill_model_identity(const infer::DeployedModel& model, std::uint32_t file_crc32,
                         SupervisorSnapshot& s) {
  s.model_crc32 = file_crc32;
  s.model_effects = model.physics.effects.bits();
  if (!model.network) return;
  const model::NetworkShape& shape = model.network->shape;
  s.network_inputs = static_cast<std::uint16_t>(shape.width.front());
  s.network_outputs = static_cast<std::uint16_t>(shape.width.back());
  s.network_layers = static_cast<std::uint16_t>(shape.num_layers());
  int widest = 0;
  for (std::size_t l = 1; l + 1 < shape.width.size(); ++l)
    widest = std::max(widest, shape.width[l]);
  s.network_width = static_cast<std::uint16_t>(widest);
}

}  // namespace zerog::modbus

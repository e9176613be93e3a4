#include "zerog/modbus/target.hpp"

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
}

}  // namespace zerog::modbus

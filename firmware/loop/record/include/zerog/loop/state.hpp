#pragma once
// The operating states of zerog-rt and the faults that stop the cycle (proto/states.md), with
// their names as the records, logs and telemetry spell them. Part of zerog::cycle_record (what a
// cycle did, readable without the cycle); the state machine that moves between them is
// zerog::loop's (zerog/loop/state_machine.hpp).
#include <cstdint>

namespace zerog::loop {

enum class State : std::uint8_t { idle, collecting, zero_g, fault };
const char* state_name(State s);

/// Why the loop faulted. The loop answers every robot datagram with a zero correction while in
/// fault, until a reset in idle conditions.
enum class Fault : std::uint8_t {
  none,
  ft_stale,            ///< no valid F/T sample for too many cycles
  ft_critical,         ///< the F/T sensor reported a critical status bit
  ft_saturated,        ///< the F/T sensor's gauges stayed saturated
  imu_stale,           ///< no valid IMU sample for too many cycles
  robot_late,          ///< robot datagrams late or missing for too many cycles
  contact_over_limit,  ///< contact force or torque above its limit
  model_invalid,       ///< the model could not be evaluated (bad input, saturation)
};
const char* fault_name(Fault f);

}  // namespace zerog::loop

#include "zerog/loop/state.hpp"

namespace zerog::loop {

const char* state_name(State s) {
  switch (s) {
    case State::idle:
      return "idle";
    case State::collecting:
      return "collecting";
    case State::zero_g:
      return "zero_g";
    case State::fault:
      return "fault";
  }
  return "?";
}

const char* fault_name(Fault f) {
  switch (f) {
    case Fault::none:
      return "none";
    case Fault::ft_stale:
      return "ft_stale";
    case Fault::ft_critical:
      return "ft_critical";
    case Fault::ft_saturated:
      return "ft_saturated";
    case Fault::imu_stale:
      return "imu_stale";
    case Fault::robot_late:
      return "robot_late";
    case Fault::contact_over_limit:
      return "contact_over_limit";
    case Fault::model_invalid:
      return "model_invalid";
  }
  return "?";
}

}  // namespace zerog::loop

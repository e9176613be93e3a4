#include "zerog/loop/state_machine.hpp"

namespace zerog::loop {

const char* command_name(Command c) {
  switch (c) {
    case Command::enable_zero_g:
      return "enable_zero_g";
    case Command::start_collection:
      return "start_collection";
    case Command::stop:
      return "stop";
    case Command::reset_fault:
      return "reset_fault";
  }
  return "?";
}

bool StateMachine::command(Command c, std::uint64_t cycle) {
  State to = state_;
  switch (c) {
    case Command::enable_zero_g:
      if (state_ != State::idle) return false;
      to = State::zero_g;
      break;
    case Command::start_collection:
      if (state_ != State::idle) return false;
      to = State::collecting;
      break;
    case Command::stop:
      if (state_ != State::collecting && state_ != State::zero_g) return false;
      to = State::idle;
      break;
    case Command::reset_fault:
      if (state_ != State::fault) return false;
      to = State::idle;
      fault_ = Fault::none;
      break;
  }
  record({cycle, state_, to, c, Fault::none, false});
  state_ = to;
  return true;
}

void StateMachine::raise(Fault f, std::uint64_t cycle) {
  if (state_ == State::fault || f == Fault::none) return;
  record({cycle, state_, State::fault, Command::stop, f, true});
  state_ = State::fault;
  fault_ = f;
}

void StateMachine::record(const Transition& t) {
  log_[total_ % kLogCapacity] = t;
  ++total_;
}

const Transition& StateMachine::log_at(std::size_t i) const {
  const std::size_t first = total_ < kLogCapacity ? 0 : total_ % kLogCapacity;
  return log_[(first + i) % kLogCapacity];
}

}  // namespace zerog::loop

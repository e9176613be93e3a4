#pragma once
// The transitions between the operating states of zerog-rt (zerog/loop/state.hpp,
// proto/states.md). Transitions are requested by commands (Modbus coils, the CLI) or by faults
// from the cycle; each one is recorded in a fixed-size log with the cycle number and the reason.
// Real-time safe: no allocation, no exceptions, no locks.
#include <array>
#include <cstddef>
#include <cstdint>

#include "zerog/loop/state.hpp"

namespace zerog::loop {

enum class Command : std::uint8_t { enable_zero_g, start_collection, stop, reset_fault };
const char* command_name(Command c);

struct Transition {
  std::uint64_t cycle = 0;
  State from = State::idle, to = State::idle;
  Command command = Command::stop;  ///< valid if !by_fault
  Fault fault = Fault::none;        ///< valid if by_fault
  bool by_fault = false;
};

class StateMachine {
 public:
  static constexpr std::size_t kLogCapacity = 64;

  State state() const { return state_; }
  Fault fault() const { return fault_; }

  /// Applies a command; returns false (and changes nothing) if it is not allowed in the current
  /// state: enable_zero_g and start_collection only from idle; reset_fault only from fault;
  /// stop from collecting or zero_g (to idle).
  bool command(Command c, std::uint64_t cycle);
  /// Enters fault from any state (the first fault is kept until reset).
  void raise(Fault f, std::uint64_t cycle);

  /// Transitions so far (oldest first), at most kLogCapacity; `total` counts all of them.
  std::size_t log_size() const { return total_ < kLogCapacity ? total_ : kLogCapacity; }
  const Transition& log_at(std::size_t i) const;  ///< 0 = oldest kept
  std::uint64_t total_transitions() const { return total_; }

 private:
  void record(const Transition& t);
  State state_ = State::idle;
  Fault fault_ = Fault::none;
  std::array<Transition, kLogCapacity> log_{};
  std::uint64_t total_ = 0;
};

}  // namespace zerog::loop

#pragma once
// What the Modbus server sees of zerog-rt: a small interface (docs/STYLE.md habit 1) that
// zerog-rt's Runtime implements over its lock-free paths (Cycle::request, Cycle::propose, a
// LatestValue of the snapshot), and tests implement over a real loop::Cycle stepped by a test
// thread.
#include <array>
#include <cstdint>

#include "zerog/infer/deploy_model.hpp"
#include "zerog/loop/cycle.hpp"

namespace zerog::modbus {

/// What the input registers and discrete inputs show (proto/modbus.md), published by the cycle
/// thread after every cycle. Fixed size and trivially copyable, so it fits handover::LatestValue.
/// SI units; counters count from the start of the run.
struct SupervisorSnapshot {
  std::uint64_t cycle = 0;  ///< robot messages handled
  loop::State state = loop::State::idle;
  loop::Fault fault = loop::Fault::none;
  bool ready = false;       ///< last record without kNotReady, kFtHeld, kImuHeld
  std::uint32_t flags = 0;  ///< loop::CycleFlags of the last record
  /// Contact wrench of the last record: sensor frame S, torque about the sensor origin
  /// (Fx, Fy, Fz in N; Mx, My, Mz in N·m).
  std::array<double, 6> contact_sensor{};
  double compute_last_s = 0.0;         ///< time of the last Cycle::step()
  double compute_p99_s = 0.0;          ///< over the last second
  double period_last_s = 0.0;          ///< between the last two cycle starts
  double jitter_max_s = 0.0;           ///< largest |period − nominal| over the last second
  std::uint64_t robot_lost = 0;        ///< timeouts + malformed + receive errors
  std::uint64_t datagrams_lost = 0;    ///< loop::CycleCounters::datagrams_lost
  std::uint64_t commands_refused = 0;  ///< loop::CycleCounters::commands_refused
  /// The sensor pose's sources (loop::CycleCounters): messages without RIst posed by the robot's
  /// kinematics, RIst and the kinematics disagreeing (a wrong tool or base frame shows here
  /// first), messages without RIst and no robot to pose them.
  std::uint64_t poses_from_joints = 0;
  std::uint64_t pose_disagreements = 0;
  std::uint64_t poses_missing = 0;
  std::uint64_t telemetry_dropped = 0;
  std::uint64_t records_dropped = 0;
  // Model identity.
  std::uint32_t model_crc32 = 0;    ///< CRC-32 of the deploy file's bytes (infer::crc32)
  std::uint32_t model_effects = 0;  ///< bit k: model::Effect k is in the physics part
  std::uint16_t network_inputs = 0;
  std::uint16_t network_layers = 0;  ///< weight layers (0: physics only)
  std::uint16_t network_width = 0;   ///< widest hidden layer
  std::uint16_t network_outputs = 0;
};

/// The fields a loop::Cycle knows (cycle, state, fault, ready, flags, contact, datagrams_lost,
/// commands_refused, the pose counters), from its last record and counters; the program adds the
/// rest (times, robot lost, drops, model identity). Call it on the cycle's thread after
/// step()/robot_lost(). Real-time safe.
void fill_from_cycle(const loop::Cycle& cycle, SupervisorSnapshot& s) noexcept;

/// The model identity registers (model_crc32 … network_outputs) from the deployed model and the
/// deploy file's CRC-32. Start-up (before the cycle takes the model).
void fill_model_identity(const infer::DeployedModel& model, std::uint32_t file_crc32,
                         SupervisorSnapshot& s);

/// The server's only way into the cycle. Every call is made from the server's thread and must
/// not block the cycle: lock-free (or wait-free) underneath.
class SupervisorTarget {
 public:
  virtual ~SupervisorTarget() = default;
  /// The newest published snapshot (any thread).
  virtual SupervisorSnapshot snapshot() const = 0;
  /// Cycle::request: the command's ticket, 0 if a command is already pending.
  virtual std::uint64_t request(loop::Command c) = 0;
  /// Cycle::command_outcome of a ticket request() returned.
  virtual loop::CommandOutcome command_outcome(std::uint64_t ticket) const = 0;
  /// Cycle::propose: false if a proposal is already pending.
  virtual bool propose(const loop::Tunables& t) = 0;
  virtual loop::ProposalStatus proposal_status() const = 0;
  virtual bool withdraw_proposal() = 0;
  /// The tunables in use when the server starts (called once, by ModbusServer::start()). After
  /// that the server is the only proposer and keeps its own copy of what the cycle accepted.
  virtual loop::Tunables tunables() const = 0;
};

}  // namespace zerog::modbus

#pragma once
// The scenario file of zerog-emu (TOML, proto/emulator.md): the robot's cycle and servo, the
// payload's truth (host/sim configuration), the F/T board's counts, scripted pushes and injected
// faults. Read strictly: an unknown key, a wrong type or an out-of-range value is an
// formats::InputError naming the file, line, column, key and reason.
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "zerog/emu/physics.hpp"
#include "zerog/sim/robot.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::emu {

enum class FaultKind : std::uint8_t {
  robot_drop,       ///< send nothing for `cycles` cycles
  robot_late,       ///< send `cycles` datagrams `delay_ms` late
  robot_malformed,  ///< send `cycles` malformed datagrams instead of good ones
  robot_duplicate,  ///< send each of `cycles` datagrams twice
  robot_reorder,    ///< swap `cycles` pairs of datagrams (n after n + 1)
  robot_foreign,    ///< `cycles` extra datagrams from another source port
  ft_silent,        ///< the F/T board answers nothing for `duration_s`
  ft_slow,          ///< the F/T board answers `response_delay_ms` late for `duration_s`
  ft_critical,      ///< status word with a critical bit for `duration_s`
  ft_saturated,     ///< gauge SG0 at its rail for `duration_s`
  /// the F/T board leaves its thermistor reads (opcode 0x9) unanswered for `duration_s`
  ft_thermistor_silent,
  imu_garbage,  ///< random bytes instead of datagrams for `duration_s`
  imu_crc,      ///< datagrams with a wrong CRC for `duration_s`
  imu_gaps,     ///< every other datagram left out for `duration_s`
  imu_silent,   ///< no datagrams for `duration_s`
  imu_unplug,   ///< the pty closes; re-plugged after `duration_s` if given
};
inline constexpr int kFaultKindCount = 16;

struct FaultKindInfo {
  FaultKind kind;
  const char* name;
  bool robot;  ///< counted in cycles (robot loop), else timed (devices)
  const char* description;
};
const std::array<FaultKindInfo, kFaultKindCount>& fault_kind_infos();
const FaultKindInfo& info(FaultKind kind);

struct Fault {
  FaultKind kind = FaultKind::robot_drop;
  double start_s = 0.0;
  int cycles = 0;                  ///< robot faults
  double duration_s = 0.0;         ///< device faults (imu_unplug: 0 = stays unplugged)
  double delay_ms = 0.0;           ///< robot_late
  double response_delay_ms = 0.0;  ///< ft_slow
};

/// The robot cycles a robot fault changes, first and last (inclusive): from the first cycle
/// starting at or after start_s; robot_reorder spans 2 · cycles − 1 cycles (it holds every
/// other datagram). For a device fault: {-1, -1}.
std::pair<std::int64_t, std::int64_t> robot_fault_cycles(const Fault& fault, double cycle_s);

struct RobotSettings {
  int cycle_ms = 12;  ///< 4 or 12
  double servo_bandwidth_hz = 8.0;
  double physics_rate_hz = 2000.0;
  sim::JointVector start_joints_rad{};  ///< default: default_start_joints()
};

/// The emulated NETCANOEM board's calibration counts. The defaults keep every gauge below about
/// 27,000 of its ±32,767 counts for any 1,200 N with any 400 N·m (AtiBoard's default matrix);
/// one count is then at most 0.2 / 0.24 / 1.2 N and 0.11 / 0.17 / 0.11 N·m (worst-case sums,
/// AtiBoard::count_resolution_si). AtiBoard's own defaults reach only tens of N.
struct FtSettings {
  std::uint32_t counts_per_force = 15'000;
  std::uint32_t counts_per_torque = 600;
  std::uint8_t base_id = 0x20;
};

struct Scenario {
  std::filesystem::path source;  ///< empty for a built-in default
  RobotSettings robot;
  sim::SimConfig sim;  ///< default_sim_config(seed), effects and `set` applied
  FtSettings ft;
  std::vector<Push> pushes;
  std::vector<Fault> faults;
  double cycle_s() const { return robot.cycle_ms * 1e-3; }
};

/// The scenario of an empty file: default robot, seed 1, the sim's default effects, no pushes
/// and no faults.
Scenario default_scenario();

/// Reads and validates a scenario file. Throws formats::InputError (file:line:column: why) naming
/// the key; std::runtime_error if the file cannot be read.
Scenario read_scenario(const std::filesystem::path& file);
/// The same from text; `file` names it in messages.
Scenario parse_scenario(std::string_view toml_text, const std::filesystem::path& file);

}  // namespace zerog::emu

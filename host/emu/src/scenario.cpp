#include "zerog/emu/scenario.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "toml_table.hpp"  // zerog::io's strict TOML reader (host/io/src)
#include "zerog/emu/robot.hpp"
#include "zerog/io/log.hpp"

namespace zerog::emu {
namespace {

using io::detail::number_text;
using io::detail::throw_at;
using io::detail::TomlTable;
namespace fs = std::filesystem;

constexpr double kDeg = 3.14159265358979323846 / 180.0;

const std::array<FaultKindInfo, kFaultKindCount> kFaults = {{
    {FaultKind::robot_drop, "robot_drop", true, "send nothing for `cycles` cycles"},
    {FaultKind::robot_late, "robot_late", true,
     "send `cycles` datagrams `delay_ms` after their cycle start"},
    {FaultKind::robot_malformed, "robot_malformed", true,
     "send `cycles` malformed datagrams instead of good ones"},
    {FaultKind::robot_duplicate, "robot_duplicate", true, "send each of `cycles` datagrams twice"},
    {FaultKind::robot_reorder, "robot_reorder", true,
     "swap `cycles` pairs of datagrams: hold one, send it after the next one"},
    {FaultKind::robot_foreign, "robot_foreign", true,
     "for `cycles` cycles, also send a datagram from another source port"},
    {FaultKind::ft_silent, "ft_silent", false, "the F/T board answers nothing for `duration_s`"},
    {FaultKind::ft_slow, "ft_slow", false,
     "the F/T board answers each sample request `response_delay_ms` late for `duration_s`"},
    {FaultKind::ft_critical, "ft_critical", false,
     "F/T status word with a critical bit for `duration_s`"},
    {FaultKind::ft_saturated, "ft_saturated", false, "F/T gauge SG0 at its rail for `duration_s`"},
    {FaultKind::imu_garbage, "imu_garbage", false,
     "random bytes instead of IMU datagrams for `duration_s`"},
    {FaultKind::imu_crc, "imu_crc", false, "IMU datagrams with a wrong CRC for `duration_s`"},
    {FaultKind::imu_gaps, "imu_gaps", false,
     "every other IMU datagram left out (counter gaps) for `duration_s`"},
    {FaultKind::imu_silent, "imu_silent", false, "no IMU datagrams for `duration_s`"},
    {FaultKind::imu_unplug, "imu_unplug", false,
     "the IMU's pty closes (hang-up); re-plugged after `duration_s` if given"},
}};

// A number in [lo, hi] (either bound open when the flag says so).
double ranged(const TomlTable& t, const toml::node& node, std::string_view key, double lo,
              bool lo_open, double hi, bool hi_open) {
  const double v = t.number(node, key);
  const bool below = lo_open ? v <= lo : v < lo;
  const bool above = hi_open ? v >= hi : v > hi;
  if (below || above) {
    throw_at(t.file(), node.source(),
             "'" + t.name(key) + "' must be in " + (lo_open ? "(" : "[") + number_text(lo) + ", " +
                 number_text(hi) + (hi_open ? ")" : "]") + ", is " + number_text(v));
  }
  return v;
}

double ranged(const TomlTable& t, std::string_view key, double lo, bool lo_open, double hi,
              bool hi_open) {
  return ranged(t, t.require(key), key, lo, lo_open, hi, hi_open);
}

std::int64_t ranged_integer(const TomlTable& t, std::string_view key, std::int64_t lo,
                            std::int64_t hi) {
  const std::int64_t v = t.integer(key);
  if (v < lo || v > hi) {
    throw_at(t.file(), t.require(key).source(),
             "'" + t.name(key) + "' must be an integer in [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "], is " + std::to_string(v));
  }
  return v;
}

// A list of 3 numbers, each finite and of magnitude ≤ `limit` (the vector's norm).
Eigen::Vector3d vector3(const TomlTable& t, std::string_view key, double limit, const char* unit) {
  const std::vector<double> v = t.numbers(key, 3);
  const Eigen::Vector3d out(v[0], v[1], v[2]);
  if (out.norm() > limit) {
    throw_at(t.file(), t.require(key).source(),
             "'" + t.name(key) + "' has magnitude " + number_text(out.norm()) + " " + unit +
                 ", more than the " + number_text(limit) + " " + unit + " allowed");
  }
  return out;
}

std::string degrees(double rad) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", rad / kDeg);
  return buf;
}

void read_robot(const toml::table& table, const fs::path& file, RobotSettings& r) {
  const TomlTable t(table, file, "robot.",
                    {"cycle_ms", "servo_bandwidth_hz", "physics_rate_hz", "start_joints_deg"});
  if (t.find("cycle_ms")) {
    const std::int64_t c = t.integer("cycle_ms");
    if (c != 4 && c != 12)
      throw_at(file, t.require("cycle_ms").source(),
               "'robot.cycle_ms' must be 4 or 12 (the RSI interpolation cycles), is " +
                   std::to_string(c));
    r.cycle_ms = static_cast<int>(c);
  }
  if (t.find("physics_rate_hz"))
    r.physics_rate_hz = ranged(t, "physics_rate_hz", 500.0, false, 20000.0, false);
  if (t.find("servo_bandwidth_hz"))
    r.servo_bandwidth_hz =
        ranged(t, "servo_bandwidth_hz", 0.0, true, r.physics_rate_hz / 10.0, false);
  if (t.find("start_joints_deg")) {
    const std::vector<double> q = t.numbers("start_joints_deg", 6);
    const sim::JointLimits lim = emulator_joint_limits();
    for (int i = 0; i < 6; ++i) {
      const double rad = q[i] * kDeg;
      if (rad < lim.lower_rad[i] - 1e-12 || rad > lim.upper_rad[i] + 1e-12) {
        const toml::node& element = *t.require("start_joints_deg").as_array()->get(i);
        throw_at(file, element.source(),
                 "'robot.start_joints_deg' A" + std::to_string(i + 1) + " = " + number_text(q[i]) +
                     " deg is outside its range [" + degrees(lim.lower_rad[i]) + ", " +
                     degrees(lim.upper_rad[i]) + "] deg");
      }
      r.start_joints_rad[i] = rad;
    }
  }
}

// `set` keys are host/sim's set_config_value names, e.g. gravity.mass: written dotted (nested
// tables) or quoted ("gravity.mass"), both work.
void apply_set(const toml::table& table, const fs::path& file, const std::string& prefix,
               sim::SimConfig& sim) {
  for (const auto& [key, value] : table) {
    const std::string name = prefix + std::string(key.str());
    if (const toml::table* nested = value.as_table()) {
      apply_set(*nested, file, name + ".", sim);
      continue;
    }
    if (!value.is_number())
      throw_at(file, value.source(), "'payload.set." + name + "' must be a number");
    try {
      sim::set_config_value(sim, name, *value.value<double>());
    } catch (const std::invalid_argument& e) {
      throw_at(file, key.source(), "'payload.set." + name + "': " + e.what());
    }
  }
}

void read_payload(const toml::table& table, const fs::path& file, sim::SimConfig& sim) {
  const TomlTable t(table, file, "payload.", {"seed", "effects", "set"});
  std::uint64_t seed = 1;
  if (t.find("seed"))
    seed = static_cast<std::uint64_t>(ranged_integer(t, "seed", 0, (std::int64_t{1} << 53)));
  sim = sim::default_sim_config(seed);
  if (const toml::node* node = t.find("effects")) {
    const toml::array* list = node->as_array();
    if (list == nullptr)
      throw_at(file, node->source(), "'payload.effects' must be a list of effect names");
    for (const toml::node& element : *list) {
      if (!element.is_string())
        throw_at(file, element.source(), "'payload.effects' must be a list of effect names");
      try {
        sim.effects =
            sim::parse_sim_effects(std::string(*element.value<std::string_view>()), sim.effects);
      } catch (const std::invalid_argument& e) {
        throw_at(file, element.source(), std::string("'payload.effects': ") + e.what());
      }
    }
  }
  if (const toml::node* node = t.find("set")) {
    const toml::table* set = node->as_table();
    if (set == nullptr)
      throw_at(file, node->source(), "'payload.set' must be a table of key = number");
    apply_set(*set, file, "", sim);
  }
}

void read_ft(const toml::table& table, const fs::path& file, FtSettings& ft) {
  const TomlTable t(table, file, "ft.", {"counts_per_force", "counts_per_torque", "base_id"});
  constexpr std::int64_t kMaxCounts = 0x7FFFFFFF;
  if (t.find("counts_per_force"))
    ft.counts_per_force =
        static_cast<std::uint32_t>(ranged_integer(t, "counts_per_force", 1, kMaxCounts));
  if (t.find("counts_per_torque"))
    ft.counts_per_torque =
        static_cast<std::uint32_t>(ranged_integer(t, "counts_per_torque", 1, kMaxCounts));
  if (t.find("base_id"))
    ft.base_id = static_cast<std::uint8_t>(ranged_integer(t, "base_id", 0, 127));
}

const toml::array& array_of_tables(const toml::node& node, const fs::path& file,
                                   const std::string& key) {
  const toml::array* a = node.as_array();
  if (a == nullptr || !a->is_array_of_tables())
    throw_at(file, node.source(), "'" + key + "' must be an array of tables ([[" + key + "]])");
  return *a;
}

Push read_push(const toml::table& table, const fs::path& file, std::size_t index) {
  const TomlTable t(
      table, file, "push[" + std::to_string(index + 1) + "].",
      {"start_s", "duration_s", "force_world_N", "torque_world_Nm", "point_sensor_m", "profile"});
  Push p;
  p.start_s = ranged(t, "start_s", 0.0, false, 1e6, false);
  p.duration_s = ranged(t, "duration_s", 0.0, true, 60.0, false);
  p.force_world_N = vector3(t, "force_world_N", 5000.0, "N");
  if (t.find("torque_world_Nm")) p.torque_world_Nm = vector3(t, "torque_world_Nm", 1000.0, "N*m");
  if (t.find("point_sensor_m")) p.point_sensor_m = vector3(t, "point_sensor_m", 3.0, "m");
  const std::string profile = t.optional_string("profile", "half_sine");
  if (profile == "half_sine") {
    p.profile = PushProfile::half_sine;
  } else if (profile == "constant") {
    p.profile = PushProfile::constant;
  } else {
    throw_at(file, t.require("profile").source(),
             "'" + t.name("profile") + "' must be \"half_sine\" or \"constant\", is \"" + profile +
                 "\"");
  }
  return p;
}

Fault read_fault(const toml::table& table, const fs::path& file, std::size_t index) {
  const TomlTable t(table, file, "fault[" + std::to_string(index + 1) + "].",
                    {"kind", "start_s", "cycles", "duration_s", "delay_ms", "response_delay_ms"});
  const std::string kind = t.string("kind");
  const FaultKindInfo* fi = nullptr;
  for (const FaultKindInfo& i : kFaults)
    if (kind == i.name) fi = &i;
  if (fi == nullptr) {
    std::string known;
    for (const FaultKindInfo& i : kFaults) known += std::string(known.empty() ? "" : ", ") + i.name;
    throw_at(file, t.require("kind").source(),
             "'" + t.name("kind") + "' is \"" + kind + "\", not a fault kind (" + known + ")");
  }
  Fault f;
  f.kind = fi->kind;
  f.start_s = ranged(t, "start_s", 0.0, false, 1e6, false);
  // Each key only where it means something for this kind.
  auto refuse = [&](std::string_view key, const std::string& why) {
    if (const toml::node* node = t.find(key))
      throw_at(file, node->source(),
               "'" + t.name(key) + "' does not apply to kind '" + kind + "' (" + why + ")");
  };
  if (fi->robot) {
    f.cycles = static_cast<int>(ranged_integer(t, "cycles", 1, 1'000'000));
    refuse("duration_s", "robot faults count cycles");
  } else {
    refuse("cycles", "device faults last duration_s");
    if (f.kind != FaultKind::imu_unplug || t.find("duration_s"))
      f.duration_s = ranged(t, "duration_s", 0.0, true, 1e6, false);
  }
  if (f.kind == FaultKind::robot_late) {
    f.delay_ms = ranged(t, "delay_ms", 0.0, true, 1000.0, false);
  } else {
    refuse("delay_ms", "only robot_late has it");
  }
  if (f.kind == FaultKind::ft_slow) {
    f.response_delay_ms = ranged(t, "response_delay_ms", 0.0, true, 1000.0, false);
  } else {
    refuse("response_delay_ms", "only ft_slow has it");
  }
  return f;
}

Scenario from_table(const toml::table& root, const fs::path& file) {
  const TomlTable top(root, file, "", {"robot", "payload", "ft", "push", "fault"});
  Scenario s = default_scenario();
  s.source = file;
  if (top.find("robot")) read_robot(top.table("robot"), file, s.robot);
  if (top.find("payload")) read_payload(top.table("payload"), file, s.sim);
  if (top.find("ft")) read_ft(top.table("ft"), file, s.ft);
  if (const toml::node* node = top.find("push")) {
    const toml::array& pushes = array_of_tables(*node, file, "push");
    if (pushes.size() > kMaxPushes)
      throw_at(file, node->source(),
               "at most " + std::to_string(kMaxPushes) + " [[push]] tables, got " +
                   std::to_string(pushes.size()));
    for (std::size_t k = 0; k < pushes.size(); ++k)
      s.pushes.push_back(read_push(*pushes.get(k)->as_table(), file, k));
  }
  if (const toml::node* node = top.find("fault")) {
    const toml::array& faults = array_of_tables(*node, file, "fault");
    for (std::size_t k = 0; k < faults.size(); ++k)
      s.faults.push_back(read_fault(*faults.get(k)->as_table(), file, k));
    // One fault at a time per group (robot, F/T board, IMU): each would undo the other.
    auto group = [](FaultKind k) {
      return info(k).robot ? 0 : k <= FaultKind::ft_saturated ? 1 : 2;
    };
    auto window = [&](const Fault& f) -> std::pair<double, double> {
      if (info(f.kind).robot) {
        const auto [first, last] = robot_fault_cycles(f, s.cycle_s());
        return {static_cast<double>(first) * s.cycle_s(),
                static_cast<double>(last + 1) * s.cycle_s()};
      }
      return {f.start_s, f.duration_s > 0.0 ? f.start_s + f.duration_s : 1e300};
    };
    for (std::size_t k = 0; k < s.faults.size(); ++k) {
      for (std::size_t j = 0; j < k; ++j) {
        if (group(s.faults[j].kind) != group(s.faults[k].kind)) continue;
        const auto a = window(s.faults[j]);
        const auto b = window(s.faults[k]);
        if (a.first < b.second && b.first < a.second) {
          const toml::table& t = *faults.get(k)->as_table();
          throw_at(file, t.get("start_s")->source(),
                   "'fault[" + std::to_string(k + 1) + "]' (" + info(s.faults[k].kind).name +
                       ") overlaps 'fault[" + std::to_string(j + 1) + "]' (" +
                       info(s.faults[j].kind).name + "): faults of the same " +
                       (group(s.faults[k].kind) == 0   ? "robot"
                        : group(s.faults[k].kind) == 1 ? "F/T board"
                                                       : "IMU") +
                       " must not overlap");
        }
      }
    }
  }
  return s;
}

}  // namespace

const std::array<FaultKindInfo, kFaultKindCount>& fault_kind_infos() { return kFaults; }

std::pair<std::int64_t, std::int64_t> robot_fault_cycles(const Fault& fault, double cycle_s) {
  if (!info(fault.kind).robot) return {-1, -1};
  const auto first = static_cast<std::int64_t>(std::ceil(fault.start_s / cycle_s - 1e-9));
  const std::int64_t span =
      fault.kind == FaultKind::robot_reorder ? 2 * std::int64_t{fault.cycles} - 1 : fault.cycles;
  return {first, first + span - 1};
}
const FaultKindInfo& info(FaultKind kind) { return kFaults[static_cast<int>(kind)]; }

Scenario default_scenario() {
  Scenario s;
  s.robot.start_joints_rad = default_start_joints();
  s.sim = sim::default_sim_config(1);
  return s;
}

Scenario parse_scenario(std::string_view toml_text, const fs::path& file) {
  toml::table root;
  try {
    root = toml::parse(toml_text, file.string());
  } catch (const toml::parse_error& e) {
    throw io::InputError(file, static_cast<int>(e.source().begin.line),
                         static_cast<int>(e.source().begin.column),
                         "TOML syntax: " + std::string(e.description()));
  }
  return from_table(root, file);
}

Scenario read_scenario(const fs::path& file) {
  return from_table(io::detail::parse_toml_file(file), file);
}

}  // namespace zerog::emu

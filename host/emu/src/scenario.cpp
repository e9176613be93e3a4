#include "zerog/emu/scenario.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "zerog/emu/robot.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/formats/toml_table.hpp"

namespace zerog::emu {
namespace {

using formats::number_text;
using formats::throw_at;
using formats::TomlTable;
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
    {FaultKind::ft_thermistor_silent, "ft_thermistor_silent", false,
     "the F/T board leaves its thermistor reads (opcode 0x9) unanswered for `duration_s`; the "
     "samples go on"},
    {FaultKind::imu_garbage, "imu_garbage", false,
     "random bytes instead of IMU datagrams for `duration_s`"},
    {FaultKind::imu_crc, "imu_crc", false, "IMU datagrams with a wrong CRC for `duration_s`"},
    {FaultKind::imu_gaps, "imu_gaps", false,
     "every other IMU datagram left out (counter gaps) for `duration_s`"},
    {FaultKind::imu_silent, "imu_silent", false, "no IMU datagrams for `duration_s`"},
    {FaultKind::imu_unplug, "imu_unplug", false,
     "the IMU's pty closes (hang-up); re-plugged after `duration_s` if given"},
}};

// A list of 3 numbers, each finite and of magnitude ≤ `limit` (the vector's norm).
Eigen::Vector3d vector3(const TomlTable& t, std::string_view key, double limit, const char* unit) {
  const Eigen::Vector3d out = t.vector3(key);
  if (out.norm() > limit) {
    t.fail(key, "has magnitude " + number_text(out.norm()) + " " + unit + ", more than the " +
                    number_text(limit) + " " + unit + " allowed");
  }
  return out;
}

std::string degrees(double rad) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", rad / kDeg);
  return buf;
}

void read_robot(const TomlTable& top, RobotSettings& r) {
  const TomlTable t = top.sub_table(
      "robot", {"cycle_ms", "servo_bandwidth_hz", "physics_rate_hz", "start_joints_deg"});
  if (t.find("cycle_ms")) {
    const std::int64_t c = t.integer("cycle_ms");
    if (c != 4 && c != 12)
      t.fail("cycle_ms", "must be 4 or 12 (the RSI interpolation cycles), is " + std::to_string(c));
    r.cycle_ms = static_cast<int>(c);
  }
  r.physics_rate_hz =
      t.optional_number("physics_rate_hz", r.physics_rate_hz, {500.0, false, 20000.0, false});
  r.servo_bandwidth_hz = t.optional_number("servo_bandwidth_hz", r.servo_bandwidth_hz,
                                           {0.0, true, r.physics_rate_hz / 10.0, false});
  if (t.find("start_joints_deg")) {
    const std::vector<double> q = t.numbers("start_joints_deg", 6);
    const sim::JointLimits lim = emulator_joint_limits();
    for (int i = 0; i < 6; ++i) {
      const double rad = q[i] * kDeg;
      if (rad < lim.lower_rad[i] - 1e-12 || rad > lim.upper_rad[i] + 1e-12) {
        const toml::node& element = *t.require("start_joints_deg").as_array()->get(i);
        t.fail("start_joints_deg", element.source(),
               "A" + std::to_string(i + 1) + " = " + number_text(q[i]) +
                   " deg is outside its range [" + degrees(lim.lower_rad[i]) + ", " +
                   degrees(lim.upper_rad[i]) + "] deg");
      }
      r.start_joints_rad[i] = rad;
    }
  }
}

// `set` keys are host/sim's set_config_value names, e.g. gravity.mass: written dotted (nested
// tables) or quoted ("gravity.mass"), both work.
void apply_set(const toml::table& table, const TomlTable& payload, const std::string& prefix,
               sim::SimConfig& sim) {
  for (const auto& [key, value] : table) {
    const std::string name = prefix + std::string(key.str());
    if (const toml::table* nested = value.as_table()) {
      apply_set(*nested, payload, name + ".", sim);
      continue;
    }
    if (!value.is_number()) payload.fail("set." + name, value.source(), "must be a number");
    try {
      sim::set_config_value(sim, name, *value.value<double>());
    } catch (const std::invalid_argument& e) {
      throw_at(payload.file(), key.source(), "'payload.set." + name + "': " + e.what());
    }
  }
}

void read_payload(const TomlTable& top, sim::SimConfig& sim) {
  const TomlTable t = top.sub_table("payload", {"seed", "effects", "set"});
  if (!t.present()) return;
  const auto seed =
      static_cast<std::uint64_t>(t.optional_integer("seed", 1, 0, std::int64_t{1} << 53));
  sim = sim::default_sim_config(seed);
  if (const toml::node* node = t.find("effects")) {
    const toml::array* list = node->as_array();
    if (list == nullptr) t.fail("effects", "must be a list of effect names");
    for (const toml::node& element : *list) {
      if (!element.is_string())
        t.fail("effects", element.source(), "must be a list of effect names");
      try {
        sim.effects =
            sim::parse_sim_effects(std::string(*element.value<std::string_view>()), sim.effects);
      } catch (const std::invalid_argument& e) {
        throw_at(t.file(), element.source(), std::string("'payload.effects': ") + e.what());
      }
    }
  }
  if (const toml::node* node = t.find("set")) {
    const toml::table* set = node->as_table();
    if (set == nullptr) t.fail("set", "must be a table of key = number");
    apply_set(*set, t, "", sim);
  }
}

void read_ft(const TomlTable& top, FtSettings& ft) {
  const TomlTable t = top.sub_table("ft", {"counts_per_force", "counts_per_torque", "base_id"});
  constexpr std::int64_t kMaxCounts = 0x7FFFFFFF;
  ft.counts_per_force = static_cast<std::uint32_t>(
      t.optional_integer("counts_per_force", ft.counts_per_force, 1, kMaxCounts));
  ft.counts_per_torque = static_cast<std::uint32_t>(
      t.optional_integer("counts_per_torque", ft.counts_per_torque, 1, kMaxCounts));
  ft.base_id = static_cast<std::uint8_t>(t.optional_integer("base_id", ft.base_id, 0, 127));
}

// The [[key]] tables of the file (none if `key` is not there).
const toml::array* array_of_tables(const TomlTable& top, std::string_view key) {
  const toml::node* node = top.find(key);
  if (node == nullptr) return nullptr;
  const toml::array* a = node->as_array();
  if (a == nullptr || !a->is_array_of_tables())
    top.fail(key, "must be an array of tables ([[" + std::string(key) + "]])");
  return a;
}

Push read_push(const toml::table& table, const fs::path& file, std::size_t index) {
  const TomlTable t(
      table, file, "push[" + std::to_string(index + 1) + "].",
      {"start_s", "duration_s", "force_world_N", "torque_world_Nm", "point_sensor_m", "profile"});
  Push p;
  p.start_s = t.number("start_s", {0.0, false, 1e6, false});
  p.duration_s = t.number("duration_s", {0.0, true, 60.0, false});
  p.force_world_N = vector3(t, "force_world_N", 5000.0, "N");
  if (t.find("torque_world_Nm")) p.torque_world_Nm = vector3(t, "torque_world_Nm", 1000.0, "N*m");
  if (t.find("point_sensor_m")) p.point_sensor_m = vector3(t, "point_sensor_m", 3.0, "m");
  const std::string profile = t.optional_string("profile", "half_sine");
  if (profile == "half_sine") {
    p.profile = PushProfile::half_sine;
  } else if (profile == "constant") {
    p.profile = PushProfile::constant;
  } else {
    t.fail("profile", "must be \"half_sine\" or \"constant\", is \"" + profile + "\"");
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
    t.fail("kind", "is \"" + kind + "\", not a fault kind (" + known + ")");
  }
  Fault f;
  f.kind = fi->kind;
  f.start_s = t.number("start_s", {0.0, false, 1e6, false});
  // Each key only where it means something for this kind.
  auto refuse = [&](std::string_view key, const std::string& why) {
    if (t.find(key) != nullptr) t.fail(key, "does not apply to kind '" + kind + "' (" + why + ")");
  };
  if (fi->robot) {
    f.cycles = static_cast<int>(t.integer("cycles", 1, 1'000'000));
    refuse("duration_s", "robot faults count cycles");
  } else {
    refuse("cycles", "device faults last duration_s");
    if (f.kind != FaultKind::imu_unplug || t.find("duration_s"))
      f.duration_s = t.number("duration_s", {0.0, true, 1e6, false});
  }
  if (f.kind == FaultKind::robot_late) {
    f.delay_ms = t.number("delay_ms", {0.0, true, 1000.0, false});
  } else {
    refuse("delay_ms", "only robot_late has it");
  }
  if (f.kind == FaultKind::ft_slow) {
    f.response_delay_ms = t.number("response_delay_ms", {0.0, true, 1000.0, false});
  } else {
    refuse("response_delay_ms", "only ft_slow has it");
  }
  return f;
}

Scenario from_table(const toml::table& root, const fs::path& file) {
  const TomlTable top(root, file, "", {"robot", "payload", "ft", "push", "fault"});
  Scenario s = default_scenario();
  s.source = file;
  read_robot(top, s.robot);
  read_payload(top, s.sim);
  read_ft(top, s.ft);
  if (const toml::array* pushes = array_of_tables(top, "push")) {
    if (pushes->size() > kMaxPushes)
      throw_at(file, pushes->source(),
               "at most " + std::to_string(kMaxPushes) + " [[push]] tables, got " +
                   std::to_string(pushes->size()));
    for (std::size_t k = 0; k < pushes->size(); ++k)
      s.pushes.push_back(read_push(*pushes->get(k)->as_table(), file, k));
  }
  if (const toml::array* list = array_of_tables(top, "fault")) {
    const toml::array& faults = *list;
    for (std::size_t k = 0; k < faults.size(); ++k)
      s.faults.push_back(read_fault(*faults.get(k)->as_table(), file, k));
    // One fault at a time per group (robot, F/T board, IMU): each would undo the other.
    auto group = [](FaultKind k) {
      return info(k).robot ? 0 : k <= FaultKind::ft_thermistor_silent ? 1 : 2;
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
  return from_table(formats::parse_toml(toml_text, file), file);
}

Scenario read_scenario(const fs::path& file) {
  return from_table(formats::parse_toml_file(file), file);
}

}  // namespace zerog::emu

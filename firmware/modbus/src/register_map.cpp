#include "zerog/modbus/register_map.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

namespace zerog::modbus {
namespace {

using loop::Tunables;
using S = StatusInputs;

constexpr double kNs = 1e9;  // raw units per second for times (ns)

// Row constructors: one line per register below.
constexpr RegisterDef coil(std::uint16_t a, std::string_view name, CoilAction action,
                           double (*get)(const S&), std::string_view description) {
  return {Table::coil, a,           name,    ValueType::bit, 1.0, "",    0.0,
          1.0,         description, nullptr, nullptr,        get, action};
}
constexpr RegisterDef discrete(std::uint16_t a, std::string_view name, double (*get)(const S&),
                               std::string_view description) {
  return {Table::discrete_input,
          a,
          name,
          ValueType::bit,
          1.0,
          "",
          0.0,
          1.0,
          description,
          nullptr,
          nullptr,
          get,
          CoilAction::none};
}
constexpr RegisterDef input(std::uint16_t a, std::string_view name, ValueType type,
                            double raw_per_unit, std::string_view unit, double (*get)(const S&),
                            std::string_view description) {
  return {Table::input_register, a,       name,    type, raw_per_unit,    unit, 0.0, 0.0,
          description,           nullptr, nullptr, get,  CoilAction::none};
}
constexpr RegisterDef holding(std::uint16_t a, std::string_view name, double raw_per_unit,
                              std::string_view unit, double min, double max,
                              double (*get)(const Tunables&), void (*set)(Tunables&, double),
                              std::string_view description) {
  return {Table::holding_register,
          a,
          name,
          ValueType::int32,
          raw_per_unit,
          unit,
          min,
          max,
          description,
          get,
          set,
          nullptr,
          CoilAction::none};
}

double state_is(const S& s, loop::State st) { return s.target.state == st ? 1.0 : 0.0; }
double as_double(std::uint64_t v) { return static_cast<double>(v & 0xFFFFFFFFu); }

// clang-format off
constexpr std::array kMap{
  // --- coils (read/write) ----------------------------------------------------------------------
  coil(0, "zero_g", CoilAction::zero_g, +[](const S& s) { return state_is(s, loop::State::zero_g); },
       "write 1: enable_zero_g (from idle, when ready); write 0: stop (if in zero_g, else nothing). Reads 1 in zero_g"),
  coil(1, "collect", CoilAction::collect, +[](const S& s) { return state_is(s, loop::State::collecting); },
       "write 1: start_collection (from idle, needs --collect); write 0: stop (if collecting, else nothing). Reads 1 while collecting"),
  coil(2, "reset_fault", CoilAction::reset, +[](const S&) { return 0.0; },
       "write 1: reset_fault (from fault); write 0: nothing. Reads 0 (a push button)"),
  // --- discrete inputs (read) ------------------------------------------------------------------
  discrete(0, "ready", +[](const S& s) { return s.target.ready ? 1.0 : 0.0; },
           "both sensors deliver and the model has its rows: enable_zero_g can be accepted"),
  discrete(1, "fault_latched", +[](const S& s) { return state_is(s, loop::State::fault); },
           "state is fault (zero corrections until reset_fault)"),
  discrete(2, "proposal_pending", +[](const S& s) { return s.proposal == loop::ProposalStatus::pending ? 1.0 : 0.0; },
           "a parameter write waits for the cycle"),
  // --- input registers (read) ------------------------------------------------------------------
  input(0, "map_version", ValueType::uint16, 1, "", +[](const S&) { return static_cast<double>(kRegisterMapVersion); },
        "version of this register map (2)"),
  input(1, "state", ValueType::uint16, 1, "", +[](const S& s) { return double(static_cast<int>(s.target.state)); },
        "0 idle, 1 collecting, 2 zero_g, 3 fault (states.md)"),
  input(2, "fault", ValueType::uint16, 1, "", +[](const S& s) { return double(static_cast<int>(s.target.fault)); },
        "0 none, 1 ft_stale, 2 ft_critical, 3 ft_saturated, 4 imu_stale, 5 robot_late, 6 contact_over_limit, 7 model_invalid"),
  input(3, "ready", ValueType::uint16, 1, "", +[](const S& s) { return s.target.ready ? 1.0 : 0.0; },
        "as discrete input 0"),
  input(4, "proposal_status", ValueType::uint16, 1, "", +[](const S& s) { return double(static_cast<int>(s.proposal)); },
        "fate of the last parameter write: 0 none, 1 pending, 2 accepted, 3 refused_state, 4 refused_invalid"),
  input(5, "modbus_clients", ValueType::uint16, 1, "", +[](const S& s) { return static_cast<double>(s.clients_connected); },
        "Modbus clients connected now"),
  input(6, "cycle", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.cycle); },
        "robot messages handled (modulo 2^32)"),
  input(8, "cycle_flags", ValueType::uint32, 1, "", +[](const S& s) { return static_cast<double>(s.target.flags); },
        "loop::CycleFlags of the last cycle (loop.md, record CSV `flags`)"),
  input(10, "contact_Fx_sensor_N", ValueType::int32, 1000, "N", +[](const S& s) { return s.target.contact_sensor[0]; },
        "contact force, sensor frame S"),
  input(12, "contact_Fy_sensor_N", ValueType::int32, 1000, "N", +[](const S& s) { return s.target.contact_sensor[1]; },
        "contact force, sensor frame S"),
  input(14, "contact_Fz_sensor_N", ValueType::int32, 1000, "N", +[](const S& s) { return s.target.contact_sensor[2]; },
        "contact force, sensor frame S"),
  input(16, "contact_Mx_sensor_Nm", ValueType::int32, 10000, "N·m", +[](const S& s) { return s.target.contact_sensor[3]; },
        "contact torque about the sensor origin, sensor frame S"),
  input(18, "contact_My_sensor_Nm", ValueType::int32, 10000, "N·m", +[](const S& s) { return s.target.contact_sensor[4]; },
        "contact torque about the sensor origin, sensor frame S"),
  input(20, "contact_Mz_sensor_Nm", ValueType::int32, 10000, "N·m", +[](const S& s) { return s.target.contact_sensor[5]; },
        "contact torque about the sensor origin, sensor frame S"),
  input(22, "compute_last_s", ValueType::uint32, kNs, "s", +[](const S& s) { return s.target.compute_last_s; },
        "time of the last cycle's step()"),
  input(24, "compute_p99_s", ValueType::uint32, kNs, "s", +[](const S& s) { return s.target.compute_p99_s; },
        "99th percentile of step() over the last second"),
  input(26, "period_last_s", ValueType::uint32, kNs, "s", +[](const S& s) { return s.target.period_last_s; },
        "time between the last two cycle starts"),
  input(28, "jitter_max_s", ValueType::uint32, kNs, "s", +[](const S& s) { return s.target.jitter_max_s; },
        "largest deviation of a period from the nominal one over the last second"),
  input(30, "robot_lost", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.robot_lost); },
        "robot cycles lost (timeouts, malformed, receive errors), modulo 2^32"),
  input(32, "datagrams_lost", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.datagrams_lost); },
        "datagrams lost in IPOC gaps, modulo 2^32"),
  input(34, "commands_refused", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.commands_refused); },
        "commands the state machine refused, modulo 2^32"),
  input(36, "telemetry_dropped", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.telemetry_dropped); },
        "telemetry samples dropped, modulo 2^32"),
  input(38, "records_dropped", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.records_dropped); },
        "cycle records the recorder could not take, modulo 2^32"),
  input(40, "model_crc32", ValueType::uint32, 1, "", +[](const S& s) { return static_cast<double>(s.target.model_crc32); },
        "CRC-32 of the deployed model file (deploy_format.md)"),
  input(42, "model_effects", ValueType::uint32, 1, "", +[](const S& s) { return static_cast<double>(s.target.model_effects); },
        "bit k set: effect k of effects.md is in the model's physics"),
  input(44, "network_inputs", ValueType::uint16, 1, "", +[](const S& s) { return static_cast<double>(s.target.network_inputs); },
        "residual network inputs (0: physics only)"),
  input(45, "network_layers", ValueType::uint16, 1, "", +[](const S& s) { return static_cast<double>(s.target.network_layers); },
        "residual network weight layers"),
  input(46, "network_width", ValueType::uint16, 1, "", +[](const S& s) { return static_cast<double>(s.target.network_width); },
        "widest hidden layer"),
  input(47, "network_outputs", ValueType::uint16, 1, "", +[](const S& s) { return static_cast<double>(s.target.network_outputs); },
        "residual network outputs"),
  input(48, "modbus_requests", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.requests); },
        "Modbus requests handled, modulo 2^32"),
  input(50, "modbus_exceptions", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.exceptions); },
        "exception replies sent, modulo 2^32"),
  input(52, "modbus_writes_refused", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.writes_refused); },
        "register and coil writes refused (any exception), modulo 2^32"),
  input(54, "modbus_clients_refused", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.clients_refused); },
        "connections closed at once (allowlist, client limit), modulo 2^32"),
  input(56, "pose_disagreements", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.pose_disagreements); },
        "messages whose RIst disagreed with the pose from the robot's kinematics (robot_kinematics.md; a wrong tool or base frame), modulo 2^32"),
  input(58, "poses_from_joints", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.poses_from_joints); },
        "messages without RIst, posed by the robot's kinematics from AIPos, modulo 2^32"),
  input(60, "poses_missing", ValueType::uint32, 1, "", +[](const S& s) { return as_double(s.target.poses_missing); },
        "messages without RIst and no robot kinematics to pose them, modulo 2^32"),
  // --- holding registers (read/write; every one int32, idle only) ------------------------------
  holding(0, "mass_kg", 1000, "kg", 1.0, 2000.0,
          +[](const Tunables& t) { return t.body.mass_kg; },
          +[](Tunables& t, double v) { t.body.mass_kg = v; },
          "virtual body mass"),
  holding(2, "inertia_xx_kgm2", 10000, "kg·m²", 0.001, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(0, 0); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(0, 0) = v; },
          "inertia tensor about the virtual centre of mass, body axes (= sensor axes at enable), element xx"),
  holding(4, "inertia_yy_kgm2", 10000, "kg·m²", 0.001, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(1, 1); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(1, 1) = v; },
          "element yy"),
  holding(6, "inertia_zz_kgm2", 10000, "kg·m²", 0.001, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(2, 2); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(2, 2) = v; },
          "element zz"),
  holding(8, "inertia_xy_kgm2", 10000, "kg·m²", -1000.0, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(0, 1); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(0, 1) = t.body.inertia_body_kgm2(1, 0) = v; },
          "element xy = yx (the tensor's element, i.e. minus the product of inertia)"),
  holding(10, "inertia_xz_kgm2", 10000, "kg·m²", -1000.0, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(0, 2); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(0, 2) = t.body.inertia_body_kgm2(2, 0) = v; },
          "element xz = zx"),
  holding(12, "inertia_yz_kgm2", 10000, "kg·m²", -1000.0, 1000.0,
          +[](const Tunables& t) { return t.body.inertia_body_kgm2(1, 2); },
          +[](Tunables& t, double v) { t.body.inertia_body_kgm2(1, 2) = t.body.inertia_body_kgm2(2, 1) = v; },
          "element yz = zy"),
  holding(14, "com_x_sensor_m", 100000, "m", -2.0, 2.0,
          +[](const Tunables& t) { return t.p_sensor_com_m.x(); },
          +[](Tunables& t, double v) { t.p_sensor_com_m.x() = v; },
          "virtual centre of mass, sensor frame S"),
  holding(16, "com_y_sensor_m", 100000, "m", -2.0, 2.0,
          +[](const Tunables& t) { return t.p_sensor_com_m.y(); },
          +[](Tunables& t, double v) { t.p_sensor_com_m.y() = v; },
          "virtual centre of mass, sensor frame S"),
  holding(18, "com_z_sensor_m", 100000, "m", -2.0, 2.0,
          +[](const Tunables& t) { return t.p_sensor_com_m.z(); },
          +[](Tunables& t, double v) { t.p_sensor_com_m.z() = v; },
          "virtual centre of mass, sensor frame S"),
  holding(20, "linear_damping_per_s", 1000, "1/s", 0.0, 20.0,
          +[](const Tunables& t) { return t.limits.linear_damping_per_s; },
          +[](Tunables& t, double v) { t.limits.linear_damping_per_s = v; },
          "velocity decays as e^(−c·t) when nothing pushes (0: free body)"),
  holding(22, "angular_damping_per_s", 1000, "1/s", 0.0, 20.0,
          +[](const Tunables& t) { return t.limits.angular_damping_per_s; },
          +[](Tunables& t, double v) { t.limits.angular_damping_per_s = v; },
          "angular momentum decays as e^(−c·t) when nothing pushes"),
  holding(24, "force_deadband_N", 1000, "N", 0.0, 100.0,
          +[](const Tunables& t) { return t.limits.force_deadband_N; },
          +[](Tunables& t, double v) { t.limits.force_deadband_N = v; },
          "contact gate threshold on the force (0: no gate); below max_contact_force_N"),
  holding(26, "torque_deadband_Nm", 1000, "N·m", 0.0, 20.0,
          +[](const Tunables& t) { return t.limits.torque_deadband_Nm; },
          +[](Tunables& t, double v) { t.limits.torque_deadband_Nm = v; },
          "contact gate threshold on the torque (judged as control::torque_gate_input)"),
  holding(28, "contact_confirm_cycles", 1, "", 1.0, 100.0,
          +[](const Tunables& t) { return double(t.limits.contact_confirm_cycles); },
          +[](Tunables& t, double v) { t.limits.contact_confirm_cycles = static_cast<int>(std::lround(v)); },
          "cycles above the threshold that confirm a contact"),
  holding(30, "contact_release_fraction", 1000, "", 0.0, 1.0,
          +[](const Tunables& t) { return t.limits.contact_release_fraction; },
          +[](Tunables& t, double v) { t.limits.contact_release_fraction = v; },
          "an open gate closes below this fraction of the threshold"),
  holding(32, "max_contact_force_N", 100, "N", 1.0, 2000.0,
          +[](const Tunables& t) { return t.limits.max_contact_force_N; },
          +[](Tunables& t, double v) { t.limits.max_contact_force_N = v; },
          "above this: fault contact_over_limit"),
  holding(34, "max_contact_torque_Nm", 1000, "N·m", 0.1, 500.0,
          +[](const Tunables& t) { return t.limits.max_contact_torque_Nm; },
          +[](Tunables& t, double v) { t.limits.max_contact_torque_Nm = v; },
          "above this: fault contact_over_limit"),
  holding(36, "max_speed_mps", 100000, "m/s", 0.001, 2.0,
          +[](const Tunables& t) { return t.limits.max_speed_mps; },
          +[](Tunables& t, double v) { t.limits.max_speed_mps = v; },
          "speed limit of the centre of mass"),
  holding(38, "max_angular_speed_radps", 100000, "rad/s", 0.001, 3.0,
          +[](const Tunables& t) { return t.limits.max_angular_speed_radps; },
          +[](Tunables& t, double v) { t.limits.max_angular_speed_radps = v; },
          "angular speed limit"),
  holding(40, "max_accel_mps2", 10000, "m/s²", 0.01, 20.0,
          +[](const Tunables& t) { return t.limits.max_accel_mps2; },
          +[](Tunables& t, double v) { t.limits.max_accel_mps2 = v; },
          "commanded change of velocity per second"),
  holding(42, "max_angular_accel_radps2", 10000, "rad/s²", 0.01, 50.0,
          +[](const Tunables& t) { return t.limits.max_angular_accel_radps2; },
          +[](Tunables& t, double v) { t.limits.max_angular_accel_radps2 = v; },
          "commanded change of angular velocity per second"),
  holding(44, "workspace_min_x_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_min_m.x(); },
          +[](Tunables& t, double v) { t.limits.workspace_min_m.x() = v; },
          "workspace box of the centre of mass, robot base frame B; below workspace_max"),
  holding(46, "workspace_min_y_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_min_m.y(); },
          +[](Tunables& t, double v) { t.limits.workspace_min_m.y() = v; },
          "robot base frame B"),
  holding(48, "workspace_min_z_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_min_m.z(); },
          +[](Tunables& t, double v) { t.limits.workspace_min_m.z() = v; },
          "robot base frame B"),
  holding(50, "workspace_max_x_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_max_m.x(); },
          +[](Tunables& t, double v) { t.limits.workspace_max_m.x() = v; },
          "robot base frame B"),
  holding(52, "workspace_max_y_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_max_m.y(); },
          +[](Tunables& t, double v) { t.limits.workspace_max_m.y() = v; },
          "robot base frame B"),
  holding(54, "workspace_max_z_base_m", 100000, "m", -5.0, 5.0,
          +[](const Tunables& t) { return t.limits.workspace_max_m.z(); },
          +[](Tunables& t, double v) { t.limits.workspace_max_m.z() = v; },
          "robot base frame B"),
};
// clang-format on

// The map's shape, checked at compile time: sorted by (table, address), no overlaps.
constexpr bool well_formed() {
  for (std::size_t i = 1; i < kMap.size(); ++i) {
    const RegisterDef& a = kMap[i - 1];
    const RegisterDef& b = kMap[i];
    if (a.table > b.table) return false;
    if (a.table == b.table && a.address + word_count(a.type) > b.address) return false;
  }
  return true;
}
static_assert(well_formed(), "register map must be sorted by table and address, no overlaps");

std::string format_number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

/// "0.001 kg" for raw_per_unit 1000: the value of one raw unit.
std::string format_resolution(const RegisterDef& r) {
  if (r.type == ValueType::bit) return "—";
  const double digits = std::log10(r.raw_per_unit);
  const std::string unit = r.unit.empty() ? "" : " " + std::string(r.unit);
  if (std::abs(digits - std::round(digits)) < 1e-12) {
    const int n = static_cast<int>(std::round(digits));
    if (n == 0) return "1" + unit;
    if (n <= 5) return "0." + std::string(static_cast<std::size_t>(n - 1), '0') + "1" + unit;
    return "1e-" + std::to_string(n) + unit;
  }
  return format_number(1.0 / r.raw_per_unit) + unit;
}

}  // namespace

const char* table_name(Table t) {
  switch (t) {
    case Table::coil:
      return "coil";
    case Table::discrete_input:
      return "discrete input";
    case Table::input_register:
      return "input register";
    case Table::holding_register:
      return "holding register";
  }
  return "?";
}

const char* value_type_name(ValueType t) {
  switch (t) {
    case ValueType::bit:
      return "bit";
    case ValueType::uint16:
      return "uint16";
    case ValueType::int16:
      return "int16";
    case ValueType::uint32:
      return "uint32";
    case ValueType::int32:
      return "int32";
  }
  return "?";
}

std::int64_t RegisterDef::raw_lo() const { return std::llround(min * raw_per_unit); }
std::int64_t RegisterDef::raw_hi() const { return std::llround(max * raw_per_unit); }

std::span<const RegisterDef> registers() { return kMap; }

const RegisterDef* find_register(Table table, std::uint16_t address) {
  for (const RegisterDef& r : kMap) {
    if (r.table == table && r.address == address) return &r;
  }
  return nullptr;
}

std::uint16_t table_extent(Table table) {
  std::uint16_t end = 0;
  for (const RegisterDef& r : kMap) {
    if (r.table == table) end = std::max(end, static_cast<std::uint16_t>(r.address + r.words()));
  }
  return end;
}

std::int64_t to_raw(const RegisterDef& r, double value) {
  if (std::isnan(value)) return 0;
  const double scaled = std::round(value * r.raw_per_unit);
  const auto lo = static_cast<double>(raw_min(r.type));
  const auto hi = static_cast<double>(raw_max(r.type));
  if (scaled <= lo) return raw_min(r.type);
  if (scaled >= hi) return raw_max(r.type);
  return static_cast<std::int64_t>(scaled);
}

double from_raw(const RegisterDef& r, std::int64_t raw) {
  return static_cast<double>(raw) / r.raw_per_unit;
}

void put_words(ValueType t, std::int64_t raw, std::uint16_t* words) {
  const auto u = static_cast<std::uint64_t>(raw);
  if (word_count(t) == 2) {
    words[0] = static_cast<std::uint16_t>((u >> 16) & 0xFFFFu);
    words[1] = static_cast<std::uint16_t>(u & 0xFFFFu);
  } else {
    words[0] = static_cast<std::uint16_t>(u & 0xFFFFu);
  }
}

std::int64_t get_words(ValueType t, const std::uint16_t* words) {
  switch (t) {
    case ValueType::bit:
      return words[0] != 0 ? 1 : 0;
    case ValueType::uint16:
      return words[0];
    case ValueType::int16:
      return static_cast<std::int16_t>(words[0]);
    case ValueType::uint32:
      return (static_cast<std::int64_t>(words[0]) << 16) | static_cast<std::int64_t>(words[1]);
    case ValueType::int32:
      return static_cast<std::int32_t>((static_cast<std::uint32_t>(words[0]) << 16) |
                                       static_cast<std::uint32_t>(words[1]));
  }
  return 0;
}

void fill_holding(const loop::Tunables& t, std::span<std::uint16_t> regs) {
  std::fill(regs.begin(), regs.end(), std::uint16_t{0});
  for (const RegisterDef& r : kMap) {
    if (r.table != Table::holding_register) continue;
    if (static_cast<std::size_t>(r.address + r.words()) > regs.size()) continue;
    put_words(r.type, to_raw(r, r.get_tunable(t)), &regs[r.address]);
  }
}

void fill_input(const StatusInputs& s, std::span<std::uint16_t> regs) {
  std::fill(regs.begin(), regs.end(), std::uint16_t{0});
  for (const RegisterDef& r : kMap) {
    if (r.table != Table::input_register) continue;
    if (static_cast<std::size_t>(r.address + r.words()) > regs.size()) continue;
    put_words(r.type, to_raw(r, r.get_status(s)), &regs[r.address]);
  }
}

void fill_bits(Table table, const StatusInputs& s, std::span<std::uint8_t> bits) {
  std::fill(bits.begin(), bits.end(), std::uint8_t{0});
  for (const RegisterDef& r : kMap) {
    if (r.table != table || r.address >= bits.size()) continue;
    bits[r.address] = r.get_status(s) != 0.0 ? 1 : 0;
  }
}

std::string register_map_markdown() {
  std::string out;
  const struct {
    Table table;
    const char* title;
  } sections[] = {
      {Table::coil, "Coils (read/write: FC 01, 05, 15)"},
      {Table::discrete_input, "Discrete inputs (read: FC 02)"},
      {Table::input_register, "Input registers (read: FC 04)"},
      {Table::holding_register, "Holding registers (read: FC 03; write: FC 16, idle only)"},
  };
  for (const auto& section : sections) {
    out += "### " + std::string(section.title) + "\n\n";
    const bool holding = section.table == Table::holding_register;
    out += "| address | mbpoll `-r` | name | type | 1 raw = | ";
    out += holding ? "range (SI) | raw range | " : "";
    out += "meaning |\n|---|---|---|---|---|";
    out += holding ? "---|---|" : "";
    out += "---|\n";
    for (const RegisterDef& r : kMap) {
      if (r.table != section.table) continue;
      const std::string unit = r.unit.empty() ? "" : " " + std::string(r.unit);
      std::string address = std::to_string(r.address);
      std::string ref = std::to_string(r.address + 1);
      if (r.words() == 2) {
        address += "–" + std::to_string(r.address + 1);
      }
      out += "| " + address + " | " + ref + " | `" + std::string(r.name) + "` | " +
             value_type_name(r.type) + " | " + format_resolution(r) + " | ";
      if (holding) {
        out += format_number(r.min) + " … " + format_number(r.max) + unit + " | " +
               std::to_string(r.raw_lo()) + " … " + std::to_string(r.raw_hi()) + " | ";
      }
      out += std::string(r.description) + " |\n";
    }
    out += "\n";
  }
  return out;
}

}  // namespace zerog::modbus

#include "zerog/rt/config.hpp"

#include <arpa/inet.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string_view>
#include <system_error>
#include <utility>

#include "zerog/formats/toml_table.hpp"
#include "zerog/rtio/local_can_bus.hpp"
#include "zerog/rtio/serial_port.hpp"
#include "zerog/status.hpp"

namespace zerog::rt {

namespace fs = std::filesystem;
using formats::number_text;
using formats::TomlTable;

namespace {

void check_ipv4(const TomlTable& t, std::string_view key, const std::string& value) {
  in_addr address{};
  if (::inet_pton(AF_INET, value.c_str(), &address) != 1) {
    t.fail(key, "must be an IPv4 address in dotted-quad form (e.g. \"192.168.1.10\"), is \"" +
                    value + "\"");
  }
}

// [ft] transport and the key of the bus it names: interface (socketcan) or local_path (local).
void read_ft_bus(const TomlTable& ft, FtSection& out) {
  const std::string transport = ft.optional_string("transport", "socketcan");
  if (transport == "socketcan") {
    out.transport = CanTransport::socketcan;
  } else if (transport == "local") {
    out.transport = CanTransport::local;
  } else {
    ft.fail("transport",
            "must be \"socketcan\" (a CAN interface) or \"local\" (zerog-emu's bus "
            "socket), is \"" +
                transport + "\"");
  }
  // The other transport's key would be ignored: say so rather than run on the wrong bus.
  const char* unused = out.transport == CanTransport::socketcan ? "local_path" : "interface";
  if (ft.find(unused) != nullptr) {
    ft.fail(unused, std::string("applies only to transport = \"") +
                        (out.transport == CanTransport::socketcan ? "local" : "socketcan") +
                        "\" (transport is \"" + transport + "\")");
  }
  if (out.transport == CanTransport::socketcan) {
    if (ft.present() && ft.find("interface") == nullptr) {  // absent [ft]: string() says so
      ft.fail("interface",
              "is required with transport = \"socketcan\" (the default): the CAN interface "
              "(e.g. \"can0\")");
    }
    out.interface = ft.string("interface");
    if (out.interface.empty() || out.interface.size() > 15)
      ft.fail("interface", "must be a network interface name of 1..15 characters (e.g. \"can0\")");
    return;
  }
  if (ft.find("local_path") == nullptr) {
    ft.fail("local_path",
            "is required with transport = \"local\": the path of the bus socket zerog-emu "
            "serves (--can-local PATH)");
  }
  if (ft.string("local_path").empty()) {
    ft.fail("local_path",
            "must be the path of the bus socket zerog-emu --can-local serves (e.g. "
            "\"/run/zerog/can.sock\"), is empty");
  }
  // Relative to the configuration's folder, like every path in it (proto/paths.md).
  const std::string local_path = ft.path("local_path").string();
  if (local_path.size() > rtio::LocalCanBus::kMaxPathBytes) {
    ft.fail("local_path",
            "must be at most " + std::to_string(rtio::LocalCanBus::kMaxPathBytes) +
                " bytes (an AF_UNIX socket's sun_path), is " + std::to_string(local_path.size()) +
                (local_path == ft.string("local_path")
                     ? std::string()
                     : " as resolved against the configuration's folder: \"" + local_path + "\""));
  }
  out.local_path = local_path;
}

// The keys of the tables loop::check_config's settings come from (check_cycle reopens them).
const std::vector<std::string_view> kModelKeys{"file", "temperature_C"};
const std::vector<std::string_view> kRobotKeys{
    "bind_address", "bind_port",          "address",       "port",          "sensor_type",
    "cycle_ms",     "receive_timeout_ms", "pose_check_mm", "pose_check_deg"};
const std::vector<std::string_view> kBodyKeys{"mass_kg", "inertia_kgm2", "com_sensor_m"};
const std::vector<std::string_view> kLimitsKeys{
    "force_deadband_N",       "torque_deadband_Nm",
    "contact_confirm_cycles", "contact_release_fraction",
    "max_contact_force_N",    "max_contact_torque_Nm",
    "max_speed_mps",          "max_angular_speed_radps",
    "max_accel_mps2",         "max_angular_accel_radps2",
    "linear_damping_per_s",   "angular_damping_per_s",
    "contact_lowpass_hz",     "workspace_min_m",
    "workspace_max_m"};
const std::vector<std::string_view> kWatchdogKeys{"ft_fault_cycles", "imu_fault_cycles",
                                                  "robot_fault_cycles", "robot_late_cycles",
                                                  "model_fault_cycles"};
const std::vector<std::string_view> kFilterKeys{
    "angular_accel_order", "motion",         "crossover_hz", "load_bandwidth_hz",
    "excitation_hz",       "ft_delay_s",     "imu_delay_s",  "ringing_radps",
    "mode_gain",           "ringing_hold_s", "servo_hz",     "tare_s"};
const std::vector<std::string_view> kCollectionKeys{"speed_fraction", "dwell_s",
                                                    "max_axis_step_rad", "approach_speed_radps",
                                                    "approach_accel_radps2"};

// [model]: the deployed model and the temperature fed to it.
void read_model(const TomlTable& file, RtConfig& c) {
  const TomlTable model = file.sub_table("model", kModelKeys);
  c.model_file = model.path("file");
  c.temperature_C = model.optional_number("temperature_C", 25.0, {-50.0, false, 150.0, false});
}

// [rig]: the running rig's file.
fs::path read_rig(const TomlTable& file) {
  const TomlTable rig = file.sub_table("rig", {"file"});
  return rig.path("file");
}

// <Sen Type="…">: what the robot's RSI configuration may name (proto/rsi.md).
bool valid_sensor_type(const std::string& type) {
  return !type.empty() && type.size() <= 32 && std::all_of(type.begin(), type.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) != 0 || ch == '_' || ch == '.' || ch == '-';
  });
}

// [robot]: the RSI endpoint and the RSI cycle.
RobotSection read_robot(const TomlTable& file) {
  const TomlTable robot = file.sub_table("robot", kRobotKeys);
  RobotSection r;
  r.bind_address = robot.optional_string("bind_address", r.bind_address);
  if (robot.find("bind_address") != nullptr) check_ipv4(robot, "bind_address", r.bind_address);
  r.bind_port = static_cast<std::uint16_t>(robot.optional_integer("bind_port", 49152, 0, 65535));
  r.address = robot.optional_string("address", r.address);
  if (robot.find("address") != nullptr) check_ipv4(robot, "address", r.address);
  r.port = static_cast<std::uint16_t>(robot.optional_integer("port", 0, 0, 65535));
  r.sensor_type = robot.optional_string("sensor_type", r.sensor_type);
  if (!valid_sensor_type(r.sensor_type)) {
    robot.fail("sensor_type",
               "must be 1..32 characters of [A-Za-z0-9_.-] (the Type of the robot's RSI "
               "sensor object), is \"" +
                   r.sensor_type + "\"");
  }
  const std::int64_t ms = robot.integer("cycle_ms", 1, 1000);
  if (ms != 4 && ms != 12)
    robot.fail("cycle_ms",
               "must be 4 or 12 (the RSI interpolation cycles), is " + std::to_string(ms));
  r.cycle_ms = static_cast<int>(ms);
  r.receive_timeout_ms =
      robot.optional_number("receive_timeout_ms", 1.5 * r.cycle_ms, {0.0, true, 1000.0, false});
  r.pose_check_mm = robot.optional_number("pose_check_mm", 1.0, {0.0, true, 1000.0, false});
  r.pose_check_deg = robot.optional_number("pose_check_deg", 0.1, {0.0, true, 180.0, false});
  return r;
}

// [ft]: the F/T board's bus (read_ft_bus) and its NETCANOEM settings.
FtSection read_ft(const TomlTable& file) {
  const TomlTable ft = file.sub_table(
      "ft", {"transport", "interface", "local_path", "base_id", "calibration", "rate_hz",
             "sample_timeout_ms", "thermistor_period_s", "thermistor_max_age_s",
             "thermistor_C_at_zero_counts", "thermistor_C_per_count"});
  FtSection f;
  read_ft_bus(ft, f);
  f.base_id = static_cast<int>(ft.optional_integer("base_id", 0x20, 0, 127));
  f.calibration = static_cast<int>(ft.optional_integer("calibration", 0, 0, 15));
  f.rate_hz = ft.optional_number("rate_hz", 500.0, {0.0, true, 2000.0, false});
  f.sample_timeout_ms = ft.optional_number("sample_timeout_ms", std::min(2.0, 1000.0 / f.rate_hz),
                                           {0.0, true, 1000.0 / f.rate_hz, false});
  f.thermistor_period_s = ft.optional_number("thermistor_period_s", 1.0, {0.0, false, 3600.0});
  // A held reading expires: a board that stops answering 0x9 must not leave the model with a
  // temperature of any age. Longer than the period (one late answer is not stale).
  f.thermistor_max_age_s = ft.optional_number(
      "thermistor_max_age_s", f.thermistor_period_s > 0.0 ? 3.0 * f.thermistor_period_s : 3.0,
      {0.0, true, 3.0 * 3600.0});
  if (f.thermistor_period_s > 0.0 && f.thermistor_max_age_s <= f.thermistor_period_s) {
    ft.fail("thermistor_max_age_s",
            "must be more than ft.thermistor_period_s (" + number_text(f.thermistor_period_s) +
                " s): every reading would expire before the next one is due");
  }
  // The conversion has no default (no datasheet fact): both numbers, or neither.
  const bool at_zero = ft.find("thermistor_C_at_zero_counts") != nullptr;
  const bool per_count = ft.find("thermistor_C_per_count") != nullptr;
  if (at_zero != per_count) {
    const char* missing = at_zero ? "thermistor_C_per_count" : "thermistor_C_at_zero_counts";
    ft.fail(at_zero ? "thermistor_C_at_zero_counts" : "thermistor_C_per_count",
            std::string("needs ft.") + missing +
                " too: the thermistor conversion is °C = C_at_zero_counts + C_per_count * counts "
                "(proto/netcanoem.md, \"Thermistor\")");
  }
  if (at_zero) {
    proto::netcanoem::ThermistorConversion c;
    c.celsius_at_zero_counts = ft.number("thermistor_C_at_zero_counts", formats::NumberRange{});
    c.celsius_per_count = ft.number("thermistor_C_per_count", formats::NumberRange{});
    if (c.celsius_per_count == 0.0) {
      ft.fail("thermistor_C_per_count", "must not be 0 (every reading would be the same °C)");
    }
    f.thermistor = c;
  }
  return f;
}

// [imu]: the STIM300's tty and datagram.
ImuSection read_imu(const TomlTable& file) {
  const TomlTable imu = file.sub_table("imu", {"device", "baud", "identifier", "accel_range_g"});
  ImuSection i;
  if (imu.string("device").empty()) imu.fail("device", "must name a tty");
  i.device = imu.path("device").string();  // relative: to this file's folder (proto/paths.md)
  i.baud = static_cast<std::uint32_t>(imu.optional_integer("baud", 921600, 1200, 4000000));
  if (rtio::baud_to_speed(i.baud) == 0) {
    imu.fail("baud",
             "must be a standard serial rate (e.g. 460800, 921600), is " + std::to_string(i.baud));
  }
  i.identifier = static_cast<int>(imu.optional_integer("identifier", 0x93, 0, 255));
  i.accel_range_g = static_cast<int>(imu.optional_integer("accel_range_g", 10, 5, 80));
  if (i.accel_range_g != 5 && i.accel_range_g != 10 && i.accel_range_g != 30 &&
      i.accel_range_g != 80) {
    imu.fail("accel_range_g", "must be 5, 10, 30 or 80 (the STIM300's accelerometer range), is " +
                                  std::to_string(i.accel_range_g));
  }
  return i;
}

// [body]: the virtual body's mass properties.
void read_body(const TomlTable& file, RtConfig& c) {
  const TomlTable body = file.sub_table("body", kBodyKeys);
  c.body.mass_kg = body.number("mass_kg", {0.0, true, 10000.0, false});
  const Eigen::Matrix3d I = body.matrix3(
      "inertia_kgm2",
      " (kg·m², about the centre of mass, body axes = sensor axes), e.g. [[4, 0, 0], [0, 5, 0], "
      "[0, 0, 6]]");
  if ((I - I.transpose()).norm() > 1e-9 * I.norm()) body.fail("inertia_kgm2", "must be symmetric");
  const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(I).eigenvalues()[0];
  if (!(smallest > 0.0)) {
    body.fail("inertia_kgm2", "must be positive definite (smallest eigenvalue " +
                                  number_text(smallest) + " kg·m²)");
  }
  c.body.inertia_body_kgm2 = I;
  c.com_sensor_m = body.optional_vector3("com_sensor_m", Eigen::Vector3d::Zero());
}

// [limits]: the motion limits; defaults are control::MotionLimits'.
control::MotionLimits read_limits(const TomlTable& file) {
  const TomlTable limits = file.sub_table("limits", kLimitsKeys);
  const formats::NumberRange at_least_zero{0.0, false};
  const formats::NumberRange positive{0.0, true};
  control::MotionLimits l;
  l.force_deadband_N =
      limits.optional_number("force_deadband_N", l.force_deadband_N, at_least_zero);
  l.torque_deadband_Nm =
      limits.optional_number("torque_deadband_Nm", l.torque_deadband_Nm, at_least_zero);
  l.contact_confirm_cycles = static_cast<int>(
      limits.optional_integer("contact_confirm_cycles", l.contact_confirm_cycles, 1, 100));
  l.contact_release_fraction = limits.optional_number(
      "contact_release_fraction", l.contact_release_fraction, {0.0, false, 1.0, false});
  l.max_contact_force_N =
      limits.optional_number("max_contact_force_N", l.max_contact_force_N, positive);
  l.max_contact_torque_Nm =
      limits.optional_number("max_contact_torque_Nm", l.max_contact_torque_Nm, positive);
  l.max_speed_mps = limits.optional_number("max_speed_mps", l.max_speed_mps, positive);
  l.max_angular_speed_radps =
      limits.optional_number("max_angular_speed_radps", l.max_angular_speed_radps, positive);
  l.max_accel_mps2 = limits.optional_number("max_accel_mps2", l.max_accel_mps2, positive);
  l.max_angular_accel_radps2 =
      limits.optional_number("max_angular_accel_radps2", l.max_angular_accel_radps2, positive);
  l.linear_damping_per_s = limits.optional_number("linear_damping_per_s", l.linear_damping_per_s,
                                                  {0.0, false, 100.0, false});
  l.angular_damping_per_s = limits.optional_number("angular_damping_per_s", l.angular_damping_per_s,
                                                   {0.0, false, 100.0, false});
  l.contact_lowpass_hz = limits.optional_number("contact_lowpass_hz", l.contact_lowpass_hz,
                                                {0.0, false, 100.0, false});
  l.workspace_min_m = limits.optional_vector3("workspace_min_m", l.workspace_min_m);
  l.workspace_max_m = limits.optional_vector3("workspace_max_m", l.workspace_max_m);
  // Deadbands below the contact limits: the loop's own rule (check_cycle).
  constexpr const char* kAxes[] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    if (!(l.workspace_min_m[k] < l.workspace_max_m[k])) {
      limits.fail(limits.find("workspace_max_m") != nullptr ? "workspace_max_m" : "workspace_min_m",
                  std::string("workspace_min_m must be below workspace_max_m on every axis (") +
                      kAxes[k] + ": " + number_text(l.workspace_min_m[k]) + " m, " +
                      number_text(l.workspace_max_m[k]) + " m)");
    }
  }
  return l;
}

// [watchdog]: cycles before each fault; defaults are loop::WatchdogConfig's.
loop::WatchdogConfig read_watchdog(const TomlTable& file) {
  const TomlTable watchdog = file.sub_table("watchdog", kWatchdogKeys);
  loop::WatchdogConfig w;
  for (auto [key, cycles] : {std::pair{"ft_fault_cycles", &w.ft_fault_cycles},
                             std::pair{"imu_fault_cycles", &w.imu_fault_cycles},
                             std::pair{"robot_fault_cycles", &w.robot_fault_cycles},
                             std::pair{"robot_late_cycles", &w.robot_late_cycles},
                             std::pair{"model_fault_cycles", &w.model_fault_cycles}}) {
    *cycles = static_cast<int>(watchdog.optional_integer(key, *cycles, 1, 1000));
  }
  return w;
}

// [filter]: the angular-acceleration difference's order and the payload's motion
// (loop/motion_estimator.hpp; proto/rt_config.md, "[filter]").
void read_filter(const TomlTable& file, RtConfig& c) {
  const TomlTable filter = file.sub_table("filter", kFilterKeys);
  const auto order = static_cast<int>(filter.optional_integer("angular_accel_order", 4, 2, 4));
  if (order == 3) {
    filter.fail("angular_accel_order",
                "must be 4 (5-point difference, 2 rows late) or 2 (3-point, 1 row late), is 3");
  }
  c.angular_accel_order = order;
  loop::MotionEstimatorConfig& m = c.motion;
  const std::string source = filter.optional_string("motion", "imu");
  if (source == "fused") {
    m.source = loop::MotionSource::fused;
  } else if (source == "imu") {
    m.source = loop::MotionSource::imu;
  } else {
    filter.fail("motion",
                "must be \"fused\" (the robot's poses and joints with the IMU below "
                "crossover_hz) or \"imu\" (the IMU as it comes), is \"" +
                    source + "\"");
  }
  m.crossover_hz = filter.optional_number("crossover_hz", m.crossover_hz, {0.0, true, 10.0, false});
  m.load_bandwidth_hz =
      filter.optional_number("load_bandwidth_hz", m.load_bandwidth_hz, {0.0, true, 100.0, false});
  m.excitation_hz =
      filter.optional_number("excitation_hz", m.excitation_hz, {0.0, true, 100.0, false});
  m.servo_hz = filter.optional_number("servo_hz", m.servo_hz, {0.0, false, 1000.0, false});
  m.ringing_radps =
      filter.optional_number("ringing_radps", m.ringing_radps, {0.0, false, 0.1, false});
  m.mode_gain = filter.optional_number("mode_gain", m.mode_gain, {0.0, false, 1.0, false});
  m.ringing_hold_s =
      filter.optional_number("ringing_hold_s", m.ringing_hold_s, {0.0, false, 3600.0, false});
  m.ft_delay_s = filter.optional_number("ft_delay_s", m.ft_delay_s, {0.0, false, 0.1, false});
  m.imu_delay_s = filter.optional_number("imu_delay_s", m.imu_delay_s, {0.0, false, 0.1, false});
  c.tare_s = filter.optional_number("tare_s", c.tare_s, {0.0, false, 60.0, false});
}

// [realtime]: memory locking, the cycle thread's priority and CPU.
RealtimeSection read_realtime(const TomlTable& file) {
  const TomlTable realtime = file.sub_table("realtime", {"lock_memory", "priority", "cpu"});
  RealtimeSection r;
  r.lock_memory = realtime.optional_boolean("lock_memory", true);
  r.priority = static_cast<int>(realtime.optional_integer("priority", 80, 0, 99));
  r.cpu = static_cast<int>(realtime.optional_integer("cpu", -1, -1, 1023));
  return r;
}

// [collection]: the design path's speed and dwell, the approach to its first point.
CollectionSection read_collection(const TomlTable& file) {
  const TomlTable collection = file.sub_table("collection", kCollectionKeys);
  CollectionSection col;
  col.speed_fraction = collection.optional_number("speed_fraction", 0.3, {0.0, true, 1.0, false});
  col.dwell_s = collection.optional_number("dwell_s", 2.0, {0.0, false, 3600.0, false});
  col.max_axis_step_rad =
      collection.optional_number("max_axis_step_rad", 0.01, {0.0, true, 0.1, false});
  col.approach_speed_radps =
      collection.optional_number("approach_speed_radps", 0.2, {0.0, true, 2.0, false});
  col.approach_accel_radps2 =
      collection.optional_number("approach_accel_radps2", 0.5, {0.0, true, 10.0, false});
  return col;
}

// [record]: the folder recordings go to, one per run or not.
void read_record(const TomlTable& file, RtConfig& c) {
  const TomlTable record = file.sub_table("record", {"dir", "per_run"});
  if (record.find("dir") != nullptr) c.record_dir = record.path("dir");
  c.record_per_run = record.optional_boolean("per_run", false);
  if (c.record_per_run && !c.record_dir) {
    record.fail("per_run", "needs [record] dir (the folder the runs go into)");
  }
}

// A setting the module's own check refused: the TOML error at that key (the status names the
// field, e.g. "allow[1]"; its position is that of the key, "allow").
[[noreturn]] void fail_setting(const TomlTable& table, const Status& st) {
  const std::string& setting = st.setting();
  table.fail(setting, table.where(setting.substr(0, setting.find('['))), st.message());
}

// [modbus]: absent, no server (proto/modbus.md, "Connecting", documents the keys). Checked with
// modbus::check_server_config, the server's own rules.
std::optional<modbus::ServerConfig> read_modbus(const TomlTable& file) {
  const TomlTable mb =
      file.sub_table("modbus", {"bind_address", "port", "allow", "max_clients", "request_timeout_s",
                                "idle_timeout_s", "proposal_timeout_s"});
  if (!mb.present()) return std::nullopt;
  modbus::ServerConfig m;
  m.bind_address = mb.string("bind_address");
  m.port = static_cast<int>(mb.optional_integer("port", m.port, 0, 65535));
  if (const toml::node* allow = mb.find("allow")) {
    const toml::array* list = allow->as_array();
    if (list == nullptr || !list->empty()) m.allow = mb.strings("allow", 0);
  }
  m.max_clients = static_cast<int>(mb.optional_integer("max_clients", m.max_clients, 1, 64));
  m.request_timeout_s =
      mb.optional_number("request_timeout_s", m.request_timeout_s, {0.0, true, 10.0, false});
  m.idle_timeout_s =
      mb.optional_number("idle_timeout_s", m.idle_timeout_s, {0.0, false, 86400.0, false});
  m.proposal_timeout_s =
      mb.optional_number("proposal_timeout_s", m.proposal_timeout_s, {0.0, true, 5.0, false});
  if (const Status st = modbus::check_server_config(m); !st.ok()) fail_setting(mb, st);
  return m;
}

// [telemetry]: absent, none (proto/telemetry.md, "Configuration"). Checked with
// telemetry::check_config, the channel's own rules.
std::optional<telemetry::TelemetryConfig> read_telemetry(const TomlTable& file) {
  const TomlTable tel =
      file.sub_table("telemetry", {"domain_id", "interface", "peers", "allow_multicast",
                                   "topic_prefix", "health_period_s", "ros2", "ros_namespace",
                                   "base_frame", "sensor_frame", "imu_frame", "joint_names"});
  if (!tel.present()) return std::nullopt;
  telemetry::TelemetryConfig t;
  t.domain_id = static_cast<int>(tel.optional_integer("domain_id", t.domain_id, 0, 232));
  // Required, as [modbus] bind_address is: the operator names the network telemetry goes to.
  if (tel.find("interface") == nullptr) {
    tel.fail("interface",
             "is required: the network interface DDS announces and sends on (\"eth1\", "
             "\"lo\"); note that Cyclone DDS binds its discovery and data ports on every "
             "address (proto/telemetry.md, \"Network\")");
  }
  t.interface = tel.string("interface");
  if (const toml::node* peers = tel.find("peers")) {
    const toml::array* list = peers->as_array();
    if (list == nullptr || !list->empty()) t.peers = tel.strings("peers", 0);
  }
  t.allow_multicast = tel.optional_boolean("allow_multicast", t.allow_multicast);
  t.topic_prefix = tel.optional_string("topic_prefix", t.topic_prefix);
  t.health_period_s =
      tel.optional_number("health_period_s", t.health_period_s, {0.0, true, 60.0, false});
  // The ROS 2 topics (proto/telemetry.md, "ROS 2 topics").
  t.ros2 = tel.optional_boolean("ros2", t.ros2);
  t.ros_namespace = tel.optional_string("ros_namespace", t.ros_namespace);
  t.base_frame = tel.optional_string("base_frame", t.base_frame);
  t.sensor_frame = tel.optional_string("sensor_frame", t.sensor_frame);
  t.imu_frame = tel.optional_string("imu_frame", t.imu_frame);
  if (tel.find("joint_names") != nullptr) t.joint_names = tel.strings("joint_names", 6);
  if (const Status st = telemetry::check_config(t); !st.ok()) fail_setting(tel, st);
  return t;
}

// config_key() as {table, key}; {"", ""} for a field the file does not set. The reverse of
// cycle_config().
std::pair<std::string_view, std::string_view> file_key(std::string_view setting) {
  static constexpr std::pair<std::string_view, std::pair<std::string_view, std::string_view>>
      kRenamed[] = {
          {"period_s", {"robot", "cycle_ms"}},
          {"temperature_C", {"model", "temperature_C"}},
          {"angular_accel_order", {"filter", "angular_accel_order"}},
          {"tare_s", {"filter", "tare_s"}},
          {"motion.crossover_hz", {"filter", "crossover_hz"}},
          {"motion.load_bandwidth_hz", {"filter", "load_bandwidth_hz"}},
          {"motion.excitation_hz", {"filter", "excitation_hz"}},
          {"motion.servo_hz", {"filter", "servo_hz"}},
          {"motion.ft_delay_s", {"filter", "ft_delay_s"}},
          {"motion.ringing_radps", {"filter", "ringing_radps"}},
          {"motion.mode_gain", {"filter", "mode_gain"}},
          {"motion.ringing_hold_s", {"filter", "ringing_hold_s"}},
          {"motion.imu_delay_s", {"filter", "imu_delay_s"}},
          {"motion.ft_rate_hz", {"ft", "rate_hz"}},
          {"body.mass_kg", {"body", "mass_kg"}},
          {"body.inertia_body_kgm2", {"body", "inertia_kgm2"}},
          {"p_sensor_com_m", {"body", "com_sensor_m"}},
          {"max_axis_step_rad", {"collection", "max_axis_step_rad"}},
          {"approach_speed_radps", {"collection", "approach_speed_radps"}},
          {"approach_accel_radps2", {"collection", "approach_accel_radps2"}},
          {"pose_check_position_m", {"robot", "pose_check_mm"}},
          {"pose_check_angle_rad", {"robot", "pose_check_deg"}},
      };
  for (const auto& [field, key] : kRenamed) {
    if (setting == field) return key;
  }
  // [limits] and [watchdog] keys are MotionLimits' and WatchdogConfig's field names.
  for (std::string_view table : {"limits", "watchdog"}) {
    if (setting.size() > table.size() && setting.starts_with(table) && setting[table.size()] == '.')
      return {table, setting.substr(table.size() + 1)};
  }
  return {};
}

const std::vector<std::string_view>& table_keys(std::string_view table) {
  static const std::vector<std::string_view> none;
  for (const auto& [name, keys] :
       {std::pair{"model", &kModelKeys}, std::pair{"robot", &kRobotKeys},
        std::pair{"body", &kBodyKeys}, std::pair{"limits", &kLimitsKeys},
        std::pair{"watchdog", &kWatchdogKeys}, std::pair{"filter", &kFilterKeys},
        std::pair{"collection", &kCollectionKeys}}) {
    if (table == name) return *keys;
  }
  return none;
}

// The loop's own rules (loop::check_config) on the configuration read so far: a refused field
// is reported at the file key that set it ("limits.force_deadband_N" at its line and column),
// as the [modbus] and [telemetry] checks are (fail_setting). The robot is the rig file's and
// is checked with it (load_setup).
void check_cycle(const TomlTable& file, const RtConfig& c) {
  const Status st = loop::check_config(cycle_config(c));
  if (st.ok()) return;
  const auto [table, key] = file_key(st.setting());
  if (table.empty()) file.fail(st.setting(), file.where(), st.message());
  const TomlTable section = file.sub_table(table, table_keys(table));
  section.fail(key, st.message());
}

// The file, table by table (in this order: the first error found is the one reported); then
// the loop's rules across tables (check_cycle).
RtConfig read_tables(const toml::table& root, const fs::path& path) {
  RtConfig c;
  c.file = path;
  const TomlTable file(root, path, "",
                       {"model", "rig", "robot", "ft", "imu", "body", "limits", "watchdog",
                        "filter", "realtime", "collection", "record", "modbus", "telemetry"},
                       "proto/rt_config.md");
  read_model(file, c);
  c.rig_file = read_rig(file);
  c.robot = read_robot(file);
  c.ft = read_ft(file);
  c.imu = read_imu(file);
  read_body(file, c);
  c.limits = read_limits(file);
  c.watchdog = read_watchdog(file);
  read_filter(file, c);
  c.realtime = read_realtime(file);
  c.collection = read_collection(file);
  read_record(file, c);
  c.modbus = read_modbus(file);
  c.telemetry = read_telemetry(file);
  check_cycle(file, c);
  return c;
}

}  // namespace

const char* can_transport_name(CanTransport transport) {
  switch (transport) {
    case CanTransport::socketcan:
      return "socketcan";
    case CanTransport::local:
      return "local";
  }
  return "?";
}

ConfigError::ConfigError(fs::path file, std::string key, int line, int column,
                         const std::string& why)
    : formats::InputError(std::move(file), line, column, (key.empty() ? "" : key + ": ") + why),
      key_(std::move(key)) {}

RtConfig parse_config(const std::string& text, const fs::path& path) {
  try {
    return read_tables(formats::parse_toml(text, path), path);
  } catch (const formats::TomlError& e) {
    throw ConfigError(path, e.key(), e.line(), e.column(), e.reason());
  }
}

RtConfig read_config(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw ConfigError(path, "", 0, 0,
                      "cannot open the configuration file for reading (" +
                          std::string(std::error_code(errno, std::generic_category()).message()) +
                          ")");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return parse_config(text.str(), path);
}

std::string config_key(std::string_view cycle_setting) {
  const auto [table, key] = file_key(cycle_setting);
  return table.empty() ? std::string() : std::string(table) + "." + std::string(key);
}

loop::CycleConfig cycle_config(const RtConfig& c) {
  loop::CycleConfig out;
  out.period_s = c.robot.cycle_s();
  out.ipoc_unit_s = 0.001;
  out.angular_accel_order = c.angular_accel_order;
  out.motion = c.motion;
  out.motion.ft_rate_hz = c.ft.rate_hz;  // the rig's IMU rate: setup.cpp
  out.temperature_C = c.temperature_C;
  out.tare_s = c.tare_s;
  out.watchdog = c.watchdog;
  out.body = c.body;
  out.limits = c.limits;
  out.p_sensor_com_m = c.com_sensor_m;
  out.max_axis_step_rad = c.collection.max_axis_step_rad;
  out.approach_speed_radps = c.collection.approach_speed_radps;
  out.approach_accel_radps2 = c.collection.approach_accel_radps2;
  out.pose_check_position_m = c.robot.pose_check_mm * 1e-3;
  out.pose_check_angle_rad = c.robot.pose_check_deg * proto::rsi::kRadPerDeg;
  return out;
}

namespace {

std::chrono::nanoseconds from_ms(double ms) {
  return std::chrono::nanoseconds(static_cast<std::int64_t>(ms * 1e6 + 0.5));
}

proto::stim300::AccelRange accel_range(int g) {
  switch (g) {
    case 5:
      return proto::stim300::AccelRange::g5;
    case 30:
      return proto::stim300::AccelRange::g30;
    case 80:
      return proto::stim300::AccelRange::g80;
    default:
      return proto::stim300::AccelRange::g10;
  }
}

}  // namespace

rtio::NetcanoemConfig netcanoem_config(const FtSection& ft) {
  rtio::NetcanoemConfig out;
  out.base_id = static_cast<std::uint8_t>(ft.base_id);
  out.calibration_index = static_cast<std::uint8_t>(ft.calibration);
  out.sample_timeout = from_ms(ft.sample_timeout_ms);
  // Every N-th sample request reads the thermistor: N = period × rate, at least 1.
  out.thermistor_every_polls =
      ft.thermistor_period_s > 0.0
          ? static_cast<int>(std::max(1.0, std::round(ft.thermistor_period_s * ft.rate_hz)))
          : 0;
  out.thermistor = ft.thermistor;
  // The maximum age in sample requests, more than the period's (read_ft checked the seconds).
  out.thermistor_max_age_polls =
      static_cast<int>(std::max(static_cast<double>(out.thermistor_every_polls) + 1.0,
                                std::round(ft.thermistor_max_age_s * ft.rate_hz)));
  return out;
}

rtio::Stim300Config stim300_config(const ImuSection& imu) {
  rtio::Stim300Config out;
  out.path = imu.device;
  out.serial.baud = imu.baud;
  out.stream.identifier = static_cast<std::uint8_t>(imu.identifier);
  out.stream.scale.accel_range = accel_range(imu.accel_range_g);
  return out;
}

rtio::RsiEndpointConfig rsi_endpoint_config(const RobotSection& robot) {
  rtio::RsiEndpointConfig out;
  out.bind_address = robot.bind_address;
  out.bind_port = robot.bind_port;
  out.robot_address = robot.address;
  out.robot_port = robot.port;
  out.sensor_type = robot.sensor_type;
  out.receive_timeout = from_ms(robot.receive_timeout_ms);
  return out;
}

}  // namespace zerog::rt

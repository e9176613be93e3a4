#pragma once
// zerog-rt's configuration: one TOML file (proto/rt_config.md documents every key, its unit and
// default). Read and checked at start-up only (allocates, throws ConfigError). Unknown keys,
// wrong types and out-of-range values are errors that name the file, the key (dotted path), the
// line and column, and why.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "zerog/control/motion.hpp"
#include "zerog/control/virtual_body.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/modbus/server.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"
#include "zerog/rtio/stim300_imu.hpp"
#include "zerog/telemetry/config.hpp"

namespace zerog::rt {

/// A configuration error. what() reads `FILE:LINE:COLUMN: KEY: why` (`FILE: KEY: why` when the
/// position is unknown, e.g. the file cannot be read). A missing key names its table's position.
/// file(), line() (1-based; 0 = unknown) and column() come from formats::InputError.
class ConfigError : public formats::InputError {
 public:
  ConfigError(std::filesystem::path file, std::string key, int line, int column,
              const std::string& why);
  const std::string& key() const { return key_; }  ///< dotted path, e.g. "robot.cycle_ms"

 private:
  std::string key_;
};

struct RobotSection {
  std::string bind_address = "127.0.0.1";  ///< local IPv4 address the RSI endpoint binds
  std::uint16_t bind_port = 49152;         ///< 0: any free port (tests)
  std::string address = "127.0.0.1";       ///< the robot controller: the only sender accepted
  std::uint16_t port = 0;                  ///< the controller's source port; 0 = any
  std::string sensor_type = "zerog";       ///< <Sen Type="…">, as in the robot's RSI config
  int cycle_ms = 12;                       ///< RSI interpolation cycle: 4 or 12 (required)
  double receive_timeout_ms = 18.0;        ///< default 1.5 cycles
  /// RIst against the rig's robot kinematics: further apart than this disagrees (counted).
  double pose_check_mm = 1.0;
  double pose_check_deg = 0.1;
  double cycle_s() const { return cycle_ms * 1e-3; }
};

/// How zerog-rt reaches the F/T board's CAN bus ([ft] transport).
enum class CanTransport : std::uint8_t {
  socketcan,  ///< a SocketCAN interface (rtio::CanSocket on [ft] interface): the real bus
  local,      ///< zerog-emu's bus socket (rtio::LocalCanBus client of [ft] local_path)
};
const char* can_transport_name(CanTransport transport);

struct FtSection {
  CanTransport transport = CanTransport::socketcan;
  std::string interface = "can0";    ///< SocketCAN interface (transport socketcan)
  std::filesystem::path local_path;  ///< absolute path of the bus socket (transport local)
  int base_id = 0x20;                ///< NETCANOEM board base id, 0..127
  int calibration = 0;               ///< active calibration, 0..15
  double rate_hz = 500.0;            ///< sample requests per second
  double sample_timeout_ms = 2.0;    ///< request → both response frames
  /// Thermistor reads (opcode 0x9, index 2) between the sample requests, s; 0: none.
  double thermistor_period_s = 1.0;
  /// A reading older than this (or none this long after start-up) is stale: the model gets
  /// [model] temperature_C again, flagged and counted (proto/rt_config.md). s; default three
  /// periods; more than thermistor_period_s.
  double thermistor_max_age_s = 3.0;
  /// thermistor_C_at_zero_counts and thermistor_C_per_count (both or neither). UNVERIFIED: no
  /// datasheet default. Empty: raw counts only, the model gets [model] temperature_C.
  std::optional<proto::netcanoem::ThermistorConversion> thermistor;
};

struct ImuSection {
  std::string device = "/dev/ttyUSB0";  ///< tty of the STIM300
  std::uint32_t baud = 921600;
  int identifier = 0x93;   ///< datagram identifier accepted; 0 = any of the content table
  int accel_range_g = 10;  ///< accelerometer range of the unit (ordering code): 5, 10, 30, 80
};

struct RealtimeSection {
  bool lock_memory = true;  ///< mlockall(MCL_CURRENT | MCL_FUTURE)
  int priority = 80;        ///< SCHED_FIFO priority of the cycle thread; 0 = SCHED_OTHER
  int cpu = -1;             ///< CPU the cycle thread is pinned to; -1 = any
};

struct CollectionSection {
  double speed_fraction = 0.3;         ///< PTP override, design path (robot::kr210_ptp_limits)
  double dwell_s = 2.0;                ///< dwell at each path point
  double max_axis_step_rad = 0.01;     ///< largest axis correction per cycle
  double approach_speed_radps = 0.2;   ///< per axis, to the path's first point
  double approach_accel_radps2 = 0.5;  ///< per axis
};

/// The whole file, with relative paths resolved against the configuration file's folder.
struct RtConfig {
  std::filesystem::path file;        ///< the configuration file itself
  std::filesystem::path model_file;  ///< [model] file: the deployed model (proto/deploy_format.md)
  double temperature_C = 25.0;       ///< [model] temperature_C fed to the model
  std::filesystem::path rig_file;    ///< [rig] file: the running rig (.rig.toml)
  RobotSection robot;
  FtSection ft;
  ImuSection imu;
  control::BodyParams body;                                ///< [body] mass_kg, inertia_kgm2
  Eigen::Vector3d com_sensor_m = Eigen::Vector3d::Zero();  ///< [body] com_sensor_m
  control::MotionLimits limits;                            ///< [limits]
  loop::WatchdogConfig watchdog;                           ///< [watchdog]
  int angular_accel_order = 4;                             ///< [filter]
  double tare_s = 0.0;                                     ///< [filter] tare_s (0: off)
  loop::MotionEstimatorConfig
      motion;  ///< [filter] motion, crossover_hz, load_bandwidth_hz, excitation_hz
  RealtimeSection realtime;
  CollectionSection collection;
  std::optional<std::filesystem::path> record_dir;  ///< [record] dir
  /// [record] per_run: each start records into dir/run-<UTC start time> (a service restarts).
  bool record_per_run = false;
  /// [modbus]: the supervisory interface for the cell PLC (proto/modbus.md); absent: none.
  std::optional<modbus::ServerConfig> modbus;
  /// [telemetry]: live telemetry over DDS (proto/telemetry.md); absent: none.
  std::optional<telemetry::TelemetryConfig> telemetry;
};

/// Reads and checks `path`. Throws ConfigError (naming file, key, line:column, why).
RtConfig read_config(const std::filesystem::path& path);
/// Same, from text (`path` names it in messages and anchors relative paths).
RtConfig parse_config(const std::string& text, const std::filesystem::path& path);

/// The loop's configuration from the file's settings.
loop::CycleConfig cycle_config(const RtConfig& config);
/// The file's key ("limits.force_deadband_N", "body.com_sensor_m", "robot.cycle_ms") of the
/// CycleConfig field `cycle_setting` as loop::check_config names it ("limits.force_deadband_N",
/// "p_sensor_com_m", "period_s"); "" for a field the file does not set (ipoc_unit_s; robot.*,
/// which is the rig file's). read_config reports the loop's refusals at that key.
std::string config_key(std::string_view cycle_setting);

/// The devices' settings from their tables (units converted: ms → ns, g → the STIM300's range).
rtio::NetcanoemConfig netcanoem_config(const FtSection& ft);
rtio::Stim300Config stim300_config(const ImuSection& imu);
rtio::RsiEndpointConfig rsi_endpoint_config(const RobotSection& robot);

}  // namespace zerog::rt

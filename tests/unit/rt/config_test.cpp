// zerog-rt's configuration: the sample file passes (read, model and rig loaded, and the program's
// --check-config exits 0 against a model and rig made here); each kind of error names the file,
// the dotted key, line:column and why; start-up failures exit 2 naming the file; [ft] transport
// "local" reaches an emulated board (emu::AtiBoard) on a LocalCanBus.
#include "zerog/rt/config.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <atomic>
#include <cstdlib>
#include <string>
#include <thread>

#include "rt_fixtures.hpp"
#include "zerog/emu/ati_board.hpp"
#include "zerog/rt/setup.hpp"
#include "zerog/rtio/local_can_bus.hpp"
#include "zerog/sim/design.hpp"

namespace zerog::rt {
namespace {

namespace fs = std::filesystem;

const fs::path kSample = fs::path(ZEROG_SOURCE_DIR) / "firmware/rt/zerog-rt.sample.toml";

std::string sample_text() { return test::read_text(kSample); }

/// 1-based line of the first line of `text` that starts with `prefix`.
int line_of(const std::string& text, const std::string& prefix) {
  int line = 1;
  std::size_t at = 0;
  while (at < text.size()) {
    if (text.compare(at, prefix.size(), prefix) == 0) return line;
    at = text.find('\n', at);
    if (at == std::string::npos) break;
    ++at;
    ++line;
  }
  return -1;
}

/// The sample with the line starting `old_start` replaced by `replacement` (which may be "").
std::string with_line(std::string text, const std::string& old_start,
                      const std::string& replacement) {
  const int line = line_of(text, old_start);
  EXPECT_GT(line, 0) << old_start;
  std::size_t at = 0;
  for (int i = 1; i < line; ++i) at = text.find('\n', at) + 1;
  const std::size_t end = text.find('\n', at);
  text.replace(at, end - at, replacement);
  return text;
}

struct Expected {
  std::string key;
  int line;
  int column;
  std::string why;
};

void expect_error(const std::string& text, const Expected& e,
                  const fs::path& file = "/etc/zerog/zerog-rt.toml") {
  try {
    parse_config(text, file);
    ADD_FAILURE() << "no error; expected one at " << e.key;
  } catch (const ConfigError& error) {
    const std::string what = error.what();
    EXPECT_EQ(error.file(), file);
    EXPECT_EQ(error.key(), e.key) << what;
    EXPECT_EQ(error.line(), e.line) << what;
    if (e.column > 0) {
      EXPECT_EQ(error.column(), e.column) << what;
    }
    EXPECT_NE(what.find(e.why), std::string::npos) << what;
    EXPECT_EQ(what.rfind(file.string() + ":" + std::to_string(e.line) + ":", 0), 0u) << what;
    EXPECT_NE(what.find(e.key), std::string::npos) << what;
  }
}

TEST(RtConfig, TheSampleReadsWithItsValuesAndRelativePathsFromItsFolder) {
  const RtConfig c = parse_config(sample_text(), "/etc/zerog/zerog-rt.toml");
  EXPECT_EQ(c.model_file, fs::path("/etc/zerog/deploy.zgm"));
  EXPECT_EQ(c.rig_file, fs::path("/etc/zerog/rig.rig.toml"));
  EXPECT_EQ(c.robot.cycle_ms, 12);
  EXPECT_EQ(c.robot.address, "192.168.1.10");
  EXPECT_DOUBLE_EQ(c.robot.receive_timeout_ms, 18.0);
  EXPECT_EQ(c.ft.base_id, 0x20);
  EXPECT_EQ(c.imu.identifier, 0x93);
  EXPECT_DOUBLE_EQ(c.body.inertia_body_kgm2(2, 2), 6.0);
  EXPECT_DOUBLE_EQ(c.com_sensor_m.z(), 0.25);
  EXPECT_DOUBLE_EQ(c.limits.workspace_max_m.z(), 2.2);
  EXPECT_EQ(c.watchdog.ft_fault_cycles, 5);
  EXPECT_EQ(c.limits.contact_confirm_cycles, 3);
  EXPECT_DOUBLE_EQ(c.limits.contact_release_fraction, 0.5);
  EXPECT_DOUBLE_EQ(c.limits.contact_lowpass_hz, 2.0);
  EXPECT_EQ(c.realtime.priority, 80);
  EXPECT_FALSE(c.record_dir.has_value());
  const loop::CycleConfig cc = cycle_config(c);
  EXPECT_DOUBLE_EQ(cc.period_s, 0.012);
  EXPECT_EQ(cc.angular_accel_order, 4);
}

TEST(RtConfig, DefaultsApplyToOptionalKeys) {
  const std::string minimal =
      "[model]\nfile = \"m.zgm\"\n[rig]\nfile = \"r.rig.toml\"\n[robot]\ncycle_ms = 4\n"
      "[ft]\ninterface = \"vcan0\"\n[imu]\ndevice = \"/dev/pts/3\"\n"
      "[body]\nmass_kg = 60\ninertia_kgm2 = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]\n";
  const RtConfig c = parse_config(minimal, "rt.toml");
  EXPECT_DOUBLE_EQ(c.robot.receive_timeout_ms, 6.0);  // 1.5 cycles
  EXPECT_EQ(c.robot.bind_address, "127.0.0.1");
  EXPECT_EQ(c.robot.bind_port, 49152);
  EXPECT_DOUBLE_EQ(c.ft.rate_hz, 500.0);
  EXPECT_EQ(c.imu.baud, 921600u);
  EXPECT_EQ(c.angular_accel_order, 4);
  EXPECT_TRUE(c.realtime.lock_memory);
  EXPECT_EQ(c.realtime.priority, 80);
  EXPECT_EQ(c.realtime.cpu, -1);
  EXPECT_DOUBLE_EQ(c.limits.max_contact_force_N, control::MotionLimits{}.max_contact_force_N);
  EXPECT_EQ(c.watchdog.robot_fault_cycles, loop::WatchdogConfig{}.robot_fault_cycles);
  EXPECT_EQ(c.tare_s, 0.0) << "no tare unless asked for";
  EXPECT_EQ(cycle_config(parse_config(minimal + "[filter]\ntare_s = 1.5\n", "rt.toml")).tare_s,
            1.5);
}

// The check of RIst against the rig's robot kinematics (issue 15): defaults 1 mm and 0.1°,
// given in mm and degrees, SI in the loop's configuration; out of range is an error.
TEST(RtConfig, PoseCheckTolerancesAreReadInMillimetresAndDegrees) {
  const std::string base =
      "[model]\nfile = \"m.zgm\"\n[rig]\nfile = \"r.rig.toml\"\n[robot]\ncycle_ms = 4\n"
      "[ft]\ninterface = \"vcan0\"\n[imu]\ndevice = \"/dev/pts/3\"\n"
      "[body]\nmass_kg = 60\ninertia_kgm2 = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]\n";
  const RtConfig defaults = parse_config(base, "rt.toml");
  EXPECT_DOUBLE_EQ(cycle_config(defaults).pose_check_position_m, 1e-3);
  EXPECT_NEAR(cycle_config(defaults).pose_check_angle_rad, 0.1 * proto::rsi::kRadPerDeg, 1e-15);
  const std::string given =
      with_line(base, "cycle_ms = 4", "cycle_ms = 4\npose_check_mm = 2.5\npose_check_deg = 0.5");
  const loop::CycleConfig cc = cycle_config(parse_config(given, "rt.toml"));
  EXPECT_DOUBLE_EQ(cc.pose_check_position_m, 2.5e-3);
  EXPECT_NEAR(cc.pose_check_angle_rad, 0.5 * proto::rsi::kRadPerDeg, 1e-15);
  EXPECT_FALSE(cc.robot.has_value());  // the robot comes from the rig (load_setup)
  expect_error(with_line(base, "cycle_ms = 4", "cycle_ms = 4\npose_check_mm = 0"),
               {"robot.pose_check_mm", 7, 17, ""});
}

TEST(RtConfig, EachErrorNamesFileKeyPositionAndWhy) {
  const std::string s = sample_text();
  // Unknown key (a typo), with the suggestion.
  expect_error(with_line(s, "cycle_ms = 12", "cylce_ms = 12"),
               {"robot.cylce_ms", line_of(s, "cycle_ms = 12"), 1,
                "unknown key (did you mean 'robot.cycle_ms'?)"});
  // Unknown table.
  expect_error(with_line(s, "# [record]", "[recorder]"),
               {"recorder", line_of(s, "# [record]"), 2, "unknown key"});
  // Wrong type.
  expect_error(with_line(s, "cycle_ms = 12", "cycle_ms = \"12\""),
               {"robot.cycle_ms", line_of(s, "cycle_ms = 12"), 12, "must be an integer"});
  expect_error(
      with_line(s, "lock_memory = true", "lock_memory = 1"),
      {"realtime.lock_memory", line_of(s, "lock_memory = true"), 15, "must be true or false"});
  // Out of range.
  expect_error(with_line(s, "cycle_ms = 12", "cycle_ms = 8"),
               {"robot.cycle_ms", line_of(s, "cycle_ms = 12"), 12, "must be 4 or 12"});
  expect_error(with_line(s, "# tare_s = 1.5", "tare_s = 61"),
               {"filter.tare_s", line_of(s, "# tare_s = 1.5"), 10, "must be in [0, 60], is 61"});
  expect_error(with_line(s, "rate_hz = 500.0", "rate_hz = -5.0"),
               {"ft.rate_hz", line_of(s, "rate_hz = 500.0"), 11, "must be in (0, 2000], is -5"});
  expect_error(
      with_line(s, "base_id = 32", "base_id = 200"),
      {"ft.base_id", line_of(s, "base_id = 32"), 11, "must be an integer in [0, 127], is 200"});
  expect_error(
      with_line(s, "priority = 80", "priority = 120"),
      {"realtime.priority", line_of(s, "priority = 80"), 12, "must be an integer in [0, 99]"});
  expect_error(with_line(s, "angular_accel_order = 4", "angular_accel_order = 3"),
               {"filter.angular_accel_order", line_of(s, "angular_accel_order = 4"), 23,
                "must be 4 (5-point"});
  expect_error(with_line(s, "baud = 921600", "baud = 100000"),
               {"imu.baud", line_of(s, "baud = 921600"), 8, "standard serial rate"});
  expect_error(with_line(s, "address = \"192.168.1.10\"", "address = \"robot.local\""),
               {"robot.address", line_of(s, "address = \"192.168.1.10\""), 11, "IPv4 address"});
  expect_error(with_line(s, "contact_confirm_cycles = 3", "contact_confirm_cycles = 0"),
               {"limits.contact_confirm_cycles", line_of(s, "contact_confirm_cycles = 3"), 26,
                "must be an integer in [1, 100], is 0"});
  expect_error(with_line(s, "max_speed_mps = 0.25", "max_speed_mps = 0"),
               {"limits.max_speed_mps", line_of(s, "max_speed_mps = 0.25"), 17, "must be > 0"});
  expect_error(with_line(s, "workspace_max_m", "workspace_max_m = [2.5, 1.5, 0.2]"),
               {"limits.workspace_max_m", line_of(s, "workspace_max_m"), 19,
                "workspace_min_m must be below workspace_max_m on every axis (z"});
  expect_error(with_line(s, "max_speed_mps = 0.25", "linear_damping_per_s = -0.1"),
               {"limits.linear_damping_per_s", line_of(s, "max_speed_mps = 0.25"), 24,
                "must be in [0, 100], is -0.1"});
  expect_error(with_line(s, "contact_lowpass_hz = 2.0", "contact_lowpass_hz = -1"),
               {"limits.contact_lowpass_hz", line_of(s, "contact_lowpass_hz = 2.0"), 22,
                "must be in [0, 100], is -1"});
  expect_error(with_line(s, "# [record]", "[record]\nper_run = true"),
               {"record.per_run", line_of(s, "# [record]") + 1, 11, "needs [record] dir"});
  // A matrix of the wrong shape, and one that is no inertia.
  expect_error(with_line(s, "                [0.0, 0.0, 6.0]]", "                [0.0, 0.0]]"),
               {"body.inertia_kgm2[2]", line_of(s, "                [0.0, 0.0, 6.0]]"), 17,
                "must be a row of 3 numbers"});
  expect_error(
      with_line(s, "inertia_kgm2 = [[4.0", "inertia_kgm2 = [[-4.0, 0.0, 0.0],"),
      {"body.inertia_kgm2", line_of(s, "inertia_kgm2 = [[4.0"), 16, "must be positive definite"});
  // A missing required key names its table's position; a missing table the file's start.
  expect_error(with_line(s, "mass_kg = 100.0", ""),
               {"body.mass_kg", line_of(s, "[body]"), 1, "missing required key in [body]"});
  std::string no_imu = s;
  for (const char* line : {"[imu]", "device = ", "baud = ", "identifier = ", "accel_range_g = "})
    no_imu = with_line(no_imu, line, "");
  expect_error(no_imu, {"imu.device", 1, 1, "missing: the file has no [imu] table"});
  // TOML syntax.
  expect_error(with_line(s, "port = 0", "port = = 0"),
               {"", line_of(s, "port = 0"), 0, "TOML syntax"});
}

/// The sample with [ft] on zerog-emu's bus socket instead of a CAN interface.
std::string with_local_transport(const std::string& text) {
  return with_line(with_line(text, "transport = ", "transport = \"local\""),
                   "interface = ", "local_path = \"/run/zerog/can.sock\"");
}

// The thermistor (opcode 0x9): read about once a second by default, no conversion unless both
// numbers are given (no datasheet default), each error naming its key.
TEST(RtConfig, FtThermistorConversionIsBothNumbersOrNeither) {
  const std::string s = sample_text();
  const RtConfig defaults = parse_config(s, "rt.toml");
  EXPECT_FALSE(defaults.ft.thermistor.has_value());
  EXPECT_EQ(netcanoem_config(defaults.ft).thermistor_every_polls, 500);  // 1 s at 500 Hz
  EXPECT_FALSE(netcanoem_config(defaults.ft).thermistor.has_value());
  const RtConfig given =
      parse_config(with_line(s, "thermistor_period_s = 1.0",
                             "thermistor_period_s = 0.5\n"
                             "thermistor_C_at_zero_counts = -50.0\nthermistor_C_per_count = 0.005"),
                   "rt.toml");
  ASSERT_TRUE(given.ft.thermistor.has_value());
  EXPECT_DOUBLE_EQ(given.ft.thermistor->celsius_at_zero_counts, -50.0);
  EXPECT_DOUBLE_EQ(given.ft.thermistor->celsius_per_count, 0.005);
  const rtio::NetcanoemConfig nc = netcanoem_config(given.ft);
  EXPECT_EQ(nc.thermistor_every_polls, 250);
  ASSERT_TRUE(nc.thermistor.has_value());
  const RtConfig off =
      parse_config(with_line(s, "thermistor_period_s = 1.0", "thermistor_period_s = 0"), "rt.toml");
  EXPECT_EQ(netcanoem_config(off.ft).thermistor_every_polls, 0);
  const int line = line_of(s, "thermistor_period_s = 1.0");
  expect_error(
      with_line(s, "thermistor_period_s = 1.0",
                "thermistor_period_s = 1.0\nthermistor_C_per_count = 0.005"),
      {"ft.thermistor_C_per_count", line + 1, 0, "needs ft.thermistor_C_at_zero_counts too"});
  expect_error(with_line(s, "thermistor_period_s = 1.0",
                         "thermistor_period_s = 1.0\nthermistor_C_at_zero_counts = 1.0\n"
                         "thermistor_C_per_count = 0.0"),
               {"ft.thermistor_C_per_count", line + 2, 0, "must not be 0"});
  expect_error(with_line(s, "thermistor_period_s = 1.0", "thermistor_period_s = -1"),
               {"ft.thermistor_period_s", line, 0, "in [0, 3600]"});
}

// The thermistor reading's maximum age: three periods by default, in sample requests for the
// sensor; not more than the period is refused (every reading would expire before the next).
TEST(RtConfig, FtThermistorMaxAgeIsThreePeriodsByDefaultAndMoreThanOne) {
  const std::string s = sample_text();
  const RtConfig defaults = parse_config(s, "rt.toml");
  EXPECT_DOUBLE_EQ(defaults.ft.thermistor_max_age_s, 3.0);
  EXPECT_EQ(netcanoem_config(defaults.ft).thermistor_max_age_polls, 1500);  // 3 s at 500 Hz
  const RtConfig half = parse_config(
      with_line(s, "thermistor_period_s = 1.0", "thermistor_period_s = 0.5"), "rt.toml");
  EXPECT_DOUBLE_EQ(half.ft.thermistor_max_age_s, 1.5);
  const RtConfig given =
      parse_config(with_line(s, "thermistor_period_s = 1.0",
                             "thermistor_period_s = 1.0\nthermistor_max_age_s = 2.5"),
                   "rt.toml");
  EXPECT_DOUBLE_EQ(given.ft.thermistor_max_age_s, 2.5);
  EXPECT_EQ(netcanoem_config(given.ft).thermistor_max_age_polls, 1250);
  const RtConfig off =
      parse_config(with_line(s, "thermistor_period_s = 1.0", "thermistor_period_s = 0"), "rt.toml");
  EXPECT_GT(netcanoem_config(off.ft).thermistor_max_age_polls, 0);
  const int line = line_of(s, "thermistor_period_s = 1.0");
  expect_error(
      with_line(s, "thermistor_period_s = 1.0",
                "thermistor_period_s = 1.0\nthermistor_max_age_s = 1.0"),
      {"ft.thermistor_max_age_s", line + 1, 0, "must be more than ft.thermistor_period_s"});
  expect_error(with_line(s, "thermistor_period_s = 1.0",
                         "thermistor_period_s = 1.0\nthermistor_max_age_s = 0"),
               {"ft.thermistor_max_age_s", line + 1, 0, "in (0, 10800]"});
}

TEST(RtConfig, FtTransportIsSocketCanByDefaultOrTheLocalBusSocket) {
  const std::string s = sample_text();
  const RtConfig sample = parse_config(s, "rt.toml");
  EXPECT_EQ(sample.ft.transport, CanTransport::socketcan);
  EXPECT_EQ(sample.ft.interface, "can0");
  // Without the key (every configuration written before it): SocketCAN.
  const RtConfig old = parse_config(with_line(s, "transport = ", ""), "rt.toml");
  EXPECT_EQ(old.ft.transport, CanTransport::socketcan);
  EXPECT_EQ(old.ft.interface, "can0");
  EXPECT_TRUE(old.ft.local_path.empty());

  const std::string local = with_local_transport(s);
  const RtConfig c = parse_config(local, "/etc/zerog/zerog-rt.toml");
  EXPECT_EQ(c.ft.transport, CanTransport::local);
  EXPECT_EQ(c.ft.local_path, fs::path("/run/zerog/can.sock"));
  EXPECT_STREQ(can_transport_name(c.ft.transport), "local");
  EXPECT_EQ(c.ft.base_id, 0x20);  // the rest of [ft] as before
  EXPECT_DOUBLE_EQ(c.ft.rate_hz, 500.0);
}

// One rule for paths in files (proto/paths.md): relative to the file's folder.
TEST(RtConfig, FtLocalPathIsRelativeToTheConfigurationsFolder) {
  const std::string local = with_line(with_local_transport(sample_text()),
                                      "local_path = ", "local_path = \"run/can.sock\"");
  EXPECT_EQ(parse_config(local, "/etc/zerog/zerog-rt.toml").ft.local_path,
            fs::path("/etc/zerog/run/can.sock"));
  EXPECT_EQ(parse_config(local, "cell/zerog-rt.toml").ft.local_path, fs::path("cell/run/can.sock"));
  // Resolved, it may pass sun_path's 107 bytes: the error says what it was resolved to.
  const std::string deep = "/" + std::string(100, 'd') + "/zerog-rt.toml";
  expect_error(local,
               {"ft.local_path", line_of(local, "local_path = "), 14,
                "must be at most 107 bytes (an AF_UNIX socket's sun_path), is 114 as "
                "resolved against the configuration's folder"},
               deep);
}

TEST(RtConfig, FtTransportErrorsNameTheKeyAndWhy) {
  const std::string s = sample_text();
  const std::string local = with_local_transport(s);
  const int ft = line_of(s, "[ft]");
  // Unknown transport: both choices listed.
  expect_error(with_line(s, "transport = ", "transport = \"vcan\""),
               {"ft.transport", line_of(s, "transport = "), 13,
                "must be \"socketcan\" (a CAN interface) or \"local\" (zerog-emu's bus socket), "
                "is \"vcan\""});
  expect_error(with_line(s, "transport = ", "transport = 1"),
               {"ft.transport", line_of(s, "transport = "), 13, "must be a string"});
  // local: local_path required, not empty, short enough for sun_path (a relative one is resolved
  // against the configuration's folder: RtConfig.FtLocalPathIsRelativeToTheConfigurationsFolder).
  expect_error(with_line(local, "local_path = ", ""),
               {"ft.local_path", ft, 1, "is required with transport = \"local\""});
  expect_error(with_line(local, "local_path = ", "local_path = \"\""),
               {"ft.local_path", line_of(local, "local_path = "), 14,
                "must be the path of the bus socket zerog-emu --can-local serves"});
  expect_error(with_line(local, "local_path = ", "local_path = \"/" + std::string(107, 'x') + "\""),
               {"ft.local_path", line_of(local, "local_path = "), 14,
                "must be at most 107 bytes (an AF_UNIX socket's sun_path), is 108"});
  // socketcan: interface required.
  expect_error(with_line(s, "interface = ", ""),
               {"ft.interface", ft, 1, "is required with transport = \"socketcan\" (the default)"});
  expect_error(with_line(with_line(s, "transport = ", ""), "interface = ", ""),
               {"ft.interface", ft, 1, "is required with transport = \"socketcan\""});
  // The other transport's key is an error, not silently ignored.
  expect_error(with_line(local, "local_path = ", "local_path = \"/x.sock\"\ninterface = \"can0\""),
               {"ft.interface", line_of(local, "local_path = ") + 1, 13,
                "applies only to transport = \"socketcan\" (transport is \"local\")"});
  expect_error(with_line(s, "interface = ", "interface = \"can0\"\nlocal_path = \"/x.sock\""),
               {"ft.local_path", line_of(s, "interface = ") + 1, 14,
                "applies only to transport = \"local\" (transport is \"socketcan\")"});
}

/// The sample with its commented-out [modbus] and [telemetry] tables switched on.
std::string with_supervision(std::string text) {
  for (const char* key :
       {"[modbus]", "bind_address = \"192.168.2", "port = 502", "allow = ", "max_clients",
        "[telemetry]", "domain_id", "interface = \"eth1", "peers = []", "allow_multicast"}) {
    const std::string commented = std::string("# ") + key;
    const int line = line_of(text, commented);
    EXPECT_GT(line, 0) << key;
    std::size_t at = 0;
    for (int i = 1; i < line; ++i) at = text.find('\n', at) + 1;
    text.erase(at, 2);
  }
  return text;
}

TEST(RtConfig, ModbusAndTelemetryTablesAreReadAndCheckedKeyByKey) {
  const RtConfig none = parse_config(sample_text(), "rt.toml");
  EXPECT_FALSE(none.modbus.has_value()) << "no [modbus]: no server";
  EXPECT_FALSE(none.telemetry.has_value());
  const std::string s = with_supervision(sample_text());
  const RtConfig c = parse_config(s, "rt.toml");
  ASSERT_TRUE(c.modbus.has_value());
  EXPECT_EQ(c.modbus->bind_address, "192.168.2.100");
  EXPECT_EQ(c.modbus->port, 502);
  EXPECT_EQ(c.modbus->allow, std::vector<std::string>{"192.168.2.10"});
  EXPECT_EQ(c.modbus->max_clients, 4);
  ASSERT_TRUE(c.telemetry.has_value());
  EXPECT_EQ(c.telemetry->interface, "eth1");
  EXPECT_TRUE(c.telemetry->peers.empty());
  EXPECT_TRUE(c.telemetry->allow_multicast);
  // Errors name the key, its position and why.
  expect_error(with_line(s, "allow = ", "allow = [\"192.168.2.10\", \"10.0.0.5/24\"]"),
               {"modbus.allow[1]", line_of(s, "allow = "), 9, "host bits"});
  expect_error(with_line(s, "bind_address = \"192.168.2", "bind_adress = \"192.168.2.100\""),
               {"modbus.bind_adress", line_of(s, "bind_address = \"192.168.2"), 1, "unknown key"});
  expect_error(with_line(s, "max_clients", "max_clients = 1000"),
               {"modbus.max_clients", line_of(s, "max_clients"), 15, "[1, 64]"});
  expect_error(with_line(s, "domain_id", "domain_id = 300"),
               {"telemetry.domain_id", line_of(s, "domain_id"), 13, "[0, 232]"});
  expect_error(with_line(s, "interface = \"eth1", "# no interface"),
               {"telemetry.interface", line_of(s, "[telemetry]"), 1, "is required"});
  expect_error(with_line(s, "allow_multicast", "allow_multicast = false"),
               {"telemetry.peers", line_of(s, "peers = []"), 0, "needs at least one unicast peer"});
}

// The [modbus] and [telemetry] values the server's and the channel's own checks refuse
// (modbus::check_server_config, telemetry::check_config): the key comes from the status's field,
// at its value's position, and the message reads `KEY: why` once (no key parsed out of text).
TEST(RtConfig, ModuleChecksNameTheKeyFromTheStatusField) {
  const std::string s = with_supervision(sample_text());
  const int bind_line = line_of(s, "bind_address = \"192.168.2");
  expect_error(with_line(s, "bind_address = \"192.168.2", "bind_address = \"localhost\""),
               {"modbus.bind_address", bind_line, 16, "'localhost' is not an IPv4 address"});
  expect_error(with_line(s, "allow = ", "allow = [\"10.0.0.0/33\"]"),
               {"modbus.allow[0]", line_of(s, "allow = "), 9, "prefix length that is not 0..32"});
  expect_error(with_line(s, "allow = ", "allow = [\"10.0.0.0/8\", \"ten\"]"),
               {"modbus.allow[1]", line_of(s, "allow = "), 9, "'ten' is not an IPv4 address"});
  expect_error(with_line(s, "interface = \"eth1", "interface = \"an-interface-too-long\""),
               {"telemetry.interface", line_of(s, "interface = \"eth1"), 13,
                "is longer than 15 characters"});
  expect_error(with_line(s, "peers = []", "peers = [\"bad<peer\"]"),
               {"telemetry.peers", line_of(s, "peers = []"), 9,
                "\"bad<peer\" is not an address or host name"});
  expect_error(with_line(s, "allow_multicast", "allow_multicast = true\ntopic_prefix = \"zerog.\""),
               {"telemetry.topic_prefix", line_of(s, "allow_multicast") + 1, 16,
                "may hold only letters, digits"});
  try {
    parse_config(with_line(s, "bind_address = \"192.168.2", "bind_address = \"localhost\""),
                 "rt.toml");
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "rt.toml:" + std::to_string(bind_line) +
                                         ":16: modbus.bind_address: 'localhost' is not an IPv4 "
                                         "address");
  }
}

// The loop's own rules across keys (loop::check_config, the cycle's check): its status names the
// CycleConfig field, reported at the file key that set it, at that key's value, `KEY: why`.
TEST(RtConfig, LoopChecksNameTheFileKeyAtItsPosition) {
  const std::string s = sample_text();
  const int force_line = line_of(s, "force_deadband_N");
  expect_error(with_line(s, "force_deadband_N", "force_deadband_N = 400.0"),
               {"limits.force_deadband_N", force_line, 20, "must be below max_contact_force_N"});
  expect_error(with_line(s, "torque_deadband_Nm", "torque_deadband_Nm = 90"),
               {"limits.torque_deadband_Nm", line_of(s, "torque_deadband_Nm"), 22,
                "must be below max_contact_torque_Nm"});
  try {
    parse_config(with_line(s, "force_deadband_N", "force_deadband_N = 400.0"), "rt.toml");
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "rt.toml:" + std::to_string(force_line) +
                  ":20: limits.force_deadband_N: must be below max_contact_force_N");
  }
}

// Every CycleConfig field the file sets maps to the key that sets it (and back: cycle_config).
TEST(RtConfig, ConfigKeyIsTheFileKeyOfACycleConfigField) {
  EXPECT_EQ(config_key("period_s"), "robot.cycle_ms");
  EXPECT_EQ(config_key("angular_accel_order"), "filter.angular_accel_order");
  EXPECT_EQ(config_key("tare_s"), "filter.tare_s");
  EXPECT_EQ(config_key("temperature_C"), "model.temperature_C");
  EXPECT_EQ(config_key("body.mass_kg"), "body.mass_kg");
  EXPECT_EQ(config_key("body.inertia_body_kgm2"), "body.inertia_kgm2");
  EXPECT_EQ(config_key("p_sensor_com_m"), "body.com_sensor_m");
  EXPECT_EQ(config_key("limits.max_speed_mps"), "limits.max_speed_mps");
  EXPECT_EQ(config_key("limits.workspace_max_m"), "limits.workspace_max_m");
  EXPECT_EQ(config_key("watchdog.robot_late_cycles"), "watchdog.robot_late_cycles");
  EXPECT_EQ(config_key("max_axis_step_rad"), "collection.max_axis_step_rad");
  EXPECT_EQ(config_key("approach_speed_radps"), "collection.approach_speed_radps");
  EXPECT_EQ(config_key("approach_accel_radps2"), "collection.approach_accel_radps2");
  EXPECT_EQ(config_key("pose_check_position_m"), "robot.pose_check_mm");
  EXPECT_EQ(config_key("pose_check_angle_rad"), "robot.pose_check_deg");
  EXPECT_EQ(config_key("ipoc_unit_s"), "");
  EXPECT_EQ(config_key("robot.joint_count"), "");
  EXPECT_EQ(config_key("limits"), "");
  // Each key named is one the file may have: a value there that the loop refuses is reported
  // by read_config at that key (the [limits] deadband rule is the one the reader leaves to it).
  const std::string s = sample_text();
  for (const char* field : {"limits.force_deadband_N", "limits.torque_deadband_Nm"}) {
    const std::string key = config_key(field);
    const std::string name = key.substr(key.find('.') + 1);
    const std::string bad = with_line(s, name, name + " = 1000");
    try {
      parse_config(bad, "rt.toml");
      ADD_FAILURE() << field;
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
      EXPECT_EQ(e.line(), line_of(s, name)) << e.what();
    }
  }
}

// --- the program ---------------------------------------------------------------------------

struct ProgramRun {
  int code;
  std::string out, err;
};

ProgramRun run_rt(const fs::path& dir, const std::string& args) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string command = std::string(ZEROG_RT_EXE) + " " + args + " > " + out.string() +
                              " 2> " + err.string() + " < /dev/null";
  const int status = std::system(command.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, test::read_text(out), test::read_text(err)};
}

TEST(ZerogRt, TheSampleConfigurationPassesCheckConfigAgainstAGeneratedModelAndRig) {
  test::TempDir dir;
  test::write_text(dir.path() / "zerog-rt.toml", sample_text());
  test::write_model_and_rig(dir.path());
  const rt::Setup setup = load_setup(read_config(dir.path() / "zerog-rt.toml"));
  EXPECT_EQ(setup.rig.name, test::test_rig().name);
  EXPECT_DOUBLE_EQ(setup.rig.sample_period_s, 0.012);
  const ProgramRun r =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() + " --check-config");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find(": OK: model"), std::string::npos) << r.out;

  // With a design for --collect (zerog design's format): its PTP path is checked too.
  sim::DesignOptions options;
  options.kind = sim::DesignKind::random;
  options.points = 5;
  sim::write_design(sim::make_design(options), dir.path() / "design.csv");
  const ProgramRun c =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() +
                             " --check-config --collect " + (dir.path() / "design.csv").string());
  EXPECT_EQ(c.code, 0) << c.err;
  EXPECT_NE(c.out.find("(5 points, "), std::string::npos) << c.out;
  test::write_text(dir.path() / "bad.csv", "# zerog-design 1\nq1_rad,q2_rad\n");
  const ProgramRun bad =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() +
                             " --check-config --collect " + (dir.path() / "bad.csv").string());
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.err.find("bad.csv:2:"), std::string::npos) << bad.err;
}

TEST(ZerogRt, AMissingModelFailsCheckConfigWithOneAndStartUpWithTwoNamingThePath) {
  test::TempDir dir;
  test::write_text(dir.path() / "zerog-rt.toml", sample_text());
  test::write_model_and_rig(dir.path());
  fs::remove(dir.path() / "deploy.zgm");
  const std::string config = "--config " + (dir.path() / "zerog-rt.toml").string();
  ProgramRun r = run_rt(dir.path(), config + " --check-config");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find((dir.path() / "deploy.zgm").string() + ": no such file ([model] file in"),
            std::string::npos)
      << r.err;
  r = run_rt(dir.path(), config + " --duration 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find((dir.path() / "deploy.zgm").string()), std::string::npos) << r.err;
  // A configuration error, likewise: the file, the key, the position.
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(sample_text(), "cycle_ms", "cycle_ms = 5"));
  r = run_rt(dir.path(), config + " --check-config");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.err.find("zerog-rt.toml:" + std::to_string(line_of(sample_text(), "cycle_ms")) +
                       ":12: robot.cycle_ms: must be 4 or 12"),
            std::string::npos)
      << r.err;
  // A value the loop's own check refuses (loop::check_config), likewise: the file's key.
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(sample_text(), "torque_deadband_Nm", "torque_deadband_Nm = 90"));
  r = run_rt(dir.path(), config + " --check-config");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(
      r.err.find("zerog-rt.toml:" + std::to_string(line_of(sample_text(), "torque_deadband_Nm")) +
                 ":22: limits.torque_deadband_Nm: must be below max_contact_torque_Nm"),
      std::string::npos)
      << r.err;
}

TEST(ZerogRt, StartUpFailsWithTwoWhenTheFtSensorCannotBeOpened) {
  test::TempDir dir;
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(sample_text(), "interface = ", "interface = \"zerogcan9\""));
  test::write_model_and_rig(dir.path());
  const ProgramRun r =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() + " --duration 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("zerog-rt: F/T sensor: cannot open CAN interface 'zerogcan9'"),
            std::string::npos)
      << r.err;
}

TEST(ZerogRt, StartUpFailsWithTwoWhenNobodyServesTheLocalCanBus) {
  test::TempDir dir;
  const fs::path bus = dir.path() / "can.sock";
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(with_local_transport(sample_text()),
                             "local_path = ", "local_path = \"" + bus.string() + "\""));
  test::write_model_and_rig(dir.path());
  const ProgramRun r =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() + " --duration 1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("zerog-rt: F/T sensor: cannot connect to the local CAN bus '" +
                       bus.string() + "': connect_failed (connect: No such file or directory)"),
            std::string::npos)
      << r.err;
}

// zerog-rt's F/T sensor on zerog-emu's board over the local bus: the calibration is read (the
// start-up gets as far as the IMU, which this test does not provide).
TEST(ZerogRt, TheFtSensorStartsOnTheLocalCanBus) {
  test::TempDir dir;
  const fs::path bus = dir.path() / "can.sock";
  emu::AtiBoard board;
  rtio::LocalCanBus server;
  ASSERT_TRUE(server.open_server(bus.string()).ok());
  std::atomic<bool> stop{false};
  std::thread serving([&] { board.serve(server, stop); });
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(with_line(with_local_transport(sample_text()),
                                       "local_path = ", "local_path = \"" + bus.string() + "\""),
                             "device = ", "device = \"" + (dir.path() / "no-imu").string() + "\""));
  test::write_model_and_rig(dir.path());
  const ProgramRun r =
      run_rt(dir.path(), "--config " + (dir.path() / "zerog-rt.toml").string() + " --duration 1");
  stop.store(true);
  serving.join();
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.find("F/T sensor"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("zerog-rt: IMU on " + (dir.path() / "no-imu").string()), std::string::npos)
      << r.err;
  const emu::AtiBoard::Counters counters = board.counters();
  EXPECT_GE(counters.requests, 10u);  // calibration, firmware, serial, 6 rows, counts, units
  EXPECT_EQ(counters.tx_failed, 0u);
}

TEST(ZerogRt, AModelFittedAtTwelveMillisecondRowsIsRefusedAtAFourMillisecondCycle) {
  test::TempDir dir;
  test::write_text(dir.path() / "zerog-rt.toml",
                   with_line(with_line(sample_text(), "cycle_ms", "cycle_ms = 4"),
                             "receive_timeout_ms", "receive_timeout_ms = 6.0"));
  test::write_model_and_rig(dir.path());
  try {
    load_setup(read_config(dir.path() / "zerog-rt.toml"));
    ADD_FAILURE() << "accepted";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("wrong rig"), std::string::npos) << what;
    EXPECT_NE(what.find("sample period"), std::string::npos) << what;
    EXPECT_NE(what.find("cycle_ms = 4"), std::string::npos) << what;
  }
  // Another rig (the IMU moved) is refused naming the running rig's file.
  formats::Rig moved = test::test_rig();
  moved.sensor_imu.p_m.z() += 0.002;
  test::write_text(dir.path() / "zerog-rt.toml", sample_text());
  formats::write_rig(moved, dir.path() / "rig.rig.toml");
  try {
    load_setup(read_config(dir.path() / "zerog-rt.toml"));
    ADD_FAILURE() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("rig.rig.toml"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace zerog::rt

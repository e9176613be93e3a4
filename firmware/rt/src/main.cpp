// zerog-rt: the cabinet-PC program. Wires the configuration, the devices and the runtime's
// threads (zerog/rt/runtime.hpp); everything else lives in the zerog::rt library.
// Usage and files: proto/rt_config.md.
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "zerog/formats/log.hpp"
#include "zerog/rt/config.hpp"
#include "zerog/rt/runtime.hpp"
#include "zerog/rt/setup.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/local_can_bus.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"
#include "zerog/rtio/stim300_imu.hpp"

namespace {

using namespace zerog;
namespace fs = std::filesystem;

constexpr int kExitOk = 0;
constexpr int kExitOutputFailed = 1;  // the run finished, an output could not be written
constexpr int kExitStartup = 2;

void print_err(const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); }
void print_out(const std::string& line) {
  std::fprintf(stdout, "%s\n", line.c_str());
  std::fflush(stdout);
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

std::string errno_text(int error) { return error != 0 ? std::strerror(error) : "no errno"; }

// Applies one command line from --commands stdin. Returns false on `quit`.
bool handle_command(std::string_view line, rt::Runtime& runtime) {
  const rt::CommandLine c = rt::parse_command_line(line);
  switch (c.kind) {
    case rt::CommandLine::Kind::none:
      return true;
    case rt::CommandLine::Kind::quit:
      return false;
    case rt::CommandLine::Kind::unknown:
      print_err("zerog-rt: unknown command '" + std::string(line) +
                "' (commands: enable, stop, reset, collect, quit)");
      return true;
    case rt::CommandLine::Kind::command:
      if (!runtime.request(c.command)) {
        print_err("zerog-rt: a command is still pending; '" + std::string(line) + "' ignored");
      }
      return true;
  }
  return true;
}

struct Options {
  std::string config;
  bool enable_zero_g = false;
  std::string collect;
  std::string record;
  double duration_s = 0.0;
  std::string summary_out;
  std::string commands;
  bool check_config = false;
  std::string lockstep;     // the emulator's lockstep socket (proto/lockstep.md)
  std::string test_mutant;  // a deliberately broken zerog-rt, for the HIL tests' own test
};

/// Test-only mutants (tests/hil/CMakeLists.txt: the HIL checks must fail on each).
void apply_mutant(const std::string& name, loop::CycleConfig& cycle) {
  if (name == "gate_never_opens") {
    cycle.limits.contact_confirm_cycles = 1'000'000;  // no push is ever confirmed
  } else if (name == "watchdog_doubled") {
    for (int* w : {&cycle.watchdog.ft_fault_cycles, &cycle.watchdog.imu_fault_cycles,
                   &cycle.watchdog.robot_fault_cycles, &cycle.watchdog.robot_late_cycles})
      *w *= 2;
  }
}

/// [record] per_run: run-YYYYmmddTHHMMSSZ (UTC), so a restarted service never meets its last run.
std::string run_folder_name(std::chrono::system_clock::time_point now) {
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm utc{};
  ::gmtime_r(&t, &utc);
  char text[32];
  std::strftime(text, sizeof text, "run-%Y%m%dT%H%M%SZ", &utc);
  return text;
}

int run(const Options& opt) {
  const int failure = opt.check_config ? 1 : kExitStartup;
  rt::RtConfig config;
  try {
    config = rt::read_config(opt.config);
  } catch (const rt::ConfigError& e) {
    print_err(std::string("zerog-rt: ") + e.what());
    return failure;
  }
  if (!opt.record.empty()) config.record_dir = fs::path(opt.record);
  if (config.record_dir && config.record_per_run) {
    config.record_dir = *config.record_dir / run_folder_name(std::chrono::system_clock::now());
  }
  rt::Setup setup;
  std::unique_ptr<rt::PtpJointPath> path;
  try {
    setup = rt::load_setup(config);
    if (!opt.collect.empty()) path = rt::load_collection_path(opt.collect, config.collection);
  } catch (const std::exception& e) {
    print_err(std::string("zerog-rt: ") + e.what());
    return failure;
  }
  if (opt.check_config) {
    std::string effects;
    for (model::Effect e : model::kAllEffects) {
      if (setup.model.physics.effects.has(e))
        effects += (effects.empty() ? "" : ",") + std::string(model::info(e).name);
    }
    print_out("zerog-rt: " + opt.config + ": OK: model " + config.model_file.string() + " (" +
              effects + (setup.model.network ? " + network" : "") + "), rig '" + setup.rig.name +
              "', RSI cycle " + std::to_string(config.robot.cycle_ms) + " ms" +
              (setup.cycle.robot ? ", pose from RIst or the rig's robot kinematics"
                                 : ", pose from RIst only (the rig describes no robot)") +
              (path ? ", design " + opt.collect + " (" + std::to_string(path->num_points()) +
                          " points, " + std::to_string(path->duration_s()) + " s)"
                    : std::string()));
    return kExitOk;
  }
  if (!opt.test_mutant.empty()) {
    apply_mutant(opt.test_mutant, setup.cycle);
    print_err("zerog-rt: WARNING: test mutant '" + opt.test_mutant +
              "': this zerog-rt is broken on purpose (HIL tests only)");
  }
  if (opt.enable_zero_g && path) {
    print_err("zerog-rt: --enable-zero-g and --collect exclude each other: choose one");
    return kExitStartup;
  }

  // Signals go to the main thread only (signalfd); every thread inherits the mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  ::pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  const int signal_fd = ::signalfd(-1, &signals, SFD_CLOEXEC);

  // Devices (start-up: may block, bounded by their timeouts). The F/T board's bus: a SocketCAN
  // interface, or zerog-emu's bus socket ([ft] transport); everything above it is the same.
  const rtio::CanSocketConfig can_config =
      rtio::NetcanoemSensor::socket_config(static_cast<std::uint8_t>(config.ft.base_id));
  rtio::CanSocket can_socket;
  rtio::LocalCanBus can_local;
  rtio::CanBus* can = &can_socket;
  // Names the bus in messages: "can0", or "local:/run/zerog/can.sock".
  std::string ft_bus = config.ft.interface;
  if (config.ft.transport == rt::CanTransport::local) {
    ft_bus = "local:" + config.ft.local_path.string();
    const rtio::CanOpenResult opened =
        can_local.open_client(config.ft.local_path.string(), can_config);
    if (!opened.ok()) {
      print_err("zerog-rt: F/T sensor: cannot connect to the local CAN bus '" +
                config.ft.local_path.string() + "': " + rtio::can_open_status_name(opened.status) +
                " (" + opened.what + ": " + errno_text(opened.error_number) +
                "); start zerog-emu --can-local first");
      return kExitStartup;
    }
    can = &can_local;
  } else {
    const rtio::CanOpenResult opened = can_socket.open(config.ft.interface, can_config);
    if (!opened.ok()) {
      print_err("zerog-rt: F/T sensor: cannot open CAN interface '" + config.ft.interface +
                "': " + rtio::can_open_status_name(opened.status) + " (" + opened.what + ": " +
                errno_text(opened.error_number) + ")");
      return kExitStartup;
    }
    if (can_socket.receive_buffer_capped()) {
      print_err("zerog-rt: WARNING: the CAN receive buffer was capped by net.core.rmem_max (" +
                std::to_string(can_socket.receive_buffer_bytes()) + " bytes)");
    }
  }
  rtio::NetcanoemConfig ft_config;
  ft_config.base_id = static_cast<std::uint8_t>(config.ft.base_id);
  ft_config.calibration_index = static_cast<std::uint8_t>(config.ft.calibration);
  ft_config.sample_timeout =
      std::chrono::nanoseconds(static_cast<std::int64_t>(config.ft.sample_timeout_ms * 1e6 + 0.5));
  rtio::NetcanoemSensor ft(*can, ft_config);
  if (const rtio::FtStartStatus st = ft.start(); st != rtio::FtStartStatus::ok) {
    print_err("zerog-rt: F/T sensor on " + ft_bus + " (base id " +
              std::to_string(config.ft.base_id) +
              "): start failed: " + rtio::ft_start_status_name(st));
    return kExitStartup;
  }
  rtio::Stim300Config imu_config;
  imu_config.path = config.imu.device;
  imu_config.serial.baud = config.imu.baud;
  imu_config.stream.identifier = static_cast<std::uint8_t>(config.imu.identifier);
  imu_config.stream.scale.accel_range = accel_range(config.imu.accel_range_g);
  rtio::Stim300Imu imu(imu_config);
  if (const rtio::ImuStartStatus st = imu.start(); st != rtio::ImuStartStatus::ok) {
    print_err("zerog-rt: IMU on " + config.imu.device + ": " + rtio::imu_start_status_name(st) +
              " (" + errno_text(imu.last_errno()) + ")");
    return kExitStartup;
  }
  rtio::RsiEndpointConfig robot_config;
  robot_config.bind_address = config.robot.bind_address;
  robot_config.bind_port = config.robot.bind_port;
  robot_config.robot_address = config.robot.address;
  robot_config.robot_port = config.robot.port;
  robot_config.sensor_type = config.robot.sensor_type;
  robot_config.receive_timeout = std::chrono::nanoseconds(
      static_cast<std::int64_t>(config.robot.receive_timeout_ms * 1e6 + 0.5));
  rtio::RsiEndpoint robot(robot_config);
  if (const rtio::RobotStartStatus st = robot.start(); st != rtio::RobotStartStatus::ok) {
    print_err("zerog-rt: RSI endpoint " + config.robot.bind_address + ":" +
              std::to_string(config.robot.bind_port) + ": " + rtio::robot_start_status_name(st) +
              " (" + errno_text(robot.last_errno()) + ")");
    return kExitStartup;
  }

  rtio::LockstepClient lockstep;
  if (!opt.lockstep.empty()) {
    if (const char* why = lockstep.open(opt.lockstep); *why != '\0') {
      print_err("zerog-rt: --lockstep " + opt.lockstep + ": " + why + " (" +
                errno_text(lockstep.last_errno()) + "); start zerog-emu --lockstep first");
      return kExitStartup;
    }
  }

  rt::RuntimeOptions options;
  options.ft_rate_hz = config.ft.rate_hz;
  options.realtime = config.realtime;
  if (!opt.lockstep.empty() && options.realtime.priority > 0) {
    // The emulator is the clock; real-time threads polling for its events would only take the
    // CPU from it.
    print_err("zerog-rt: lockstep: [realtime] priority ignored (threads run SCHED_OTHER)");
    options.realtime.priority = 0;
  }
  options.auto_enable_zero_g = opt.enable_zero_g;
  options.auto_collect = path != nullptr;
  options.recorder.dir = config.record_dir;
  options.recorder.rig = setup.rig;
  options.model_file_crc32 = setup.model_file_crc32;
  options.modbus = config.modbus;
  options.telemetry = config.telemetry;
  options.model_file_name = config.model_file.filename().string();
  rt::Runtime runtime(
      options, rt::RuntimeDevices{&robot, &ft, &imu, opt.lockstep.empty() ? nullptr : &lockstep});
  if (std::string why = runtime.configure(setup.cycle, std::move(setup.model), path.get());
      !why.empty()) {
    print_err("zerog-rt: " + config.file.string() + ": the loop refuses the configuration: " + why);
    return kExitStartup;
  }
  std::vector<std::string> warnings;
  const std::string started = runtime.start(warnings);
  for (const std::string& w : warnings) print_err(w);
  if (!started.empty()) {
    print_err("zerog-rt: " + started);
    return kExitStartup;
  }
  // Lockstep: hello once the threads wait for the emulator's events (start() dropped what had
  // queued on the RSI socket before).
  if (!opt.lockstep.empty() &&
      lockstep.hello(robot_config.receive_timeout, config.ft.rate_hz, ft_config.sample_timeout) !=
          rtio::LockstepStatus::ok) {
    print_err("zerog-rt: --lockstep " + opt.lockstep + ": cannot send hello (" +
              errno_text(lockstep.last_errno()) + ")");
    runtime.stop();
    return kExitStartup;
  }
  print_err(
      "zerog-rt: running: RSI on " + config.robot.bind_address + ":" +
      std::to_string(robot.local_port()) + " for " + config.robot.address + ", cycle " +
      std::to_string(config.robot.cycle_ms) + " ms; F/T " + ft_bus + " at " +
      std::to_string(static_cast<int>(config.ft.rate_hz)) + " Hz; IMU " + config.imu.device +
      (config.record_dir ? "; recording to " + config.record_dir->string() : std::string()) +
      (config.telemetry ? "; telemetry on DDS domain " + std::to_string(config.telemetry->domain_id)
                        : std::string()) +
      (runtime.modbus_server() != nullptr ? "; Modbus on " + config.modbus->bind_address + ":" +
                                                std::to_string(runtime.modbus_server()->port())
                                          : std::string()));

  // Main loop: signals, commands, supervision, status once a second.
  const bool commands = opt.commands == "stdin";
  pollfd fds[2] = {{signal_fd, POLLIN, 0}, {commands ? STDIN_FILENO : -1, POLLIN, 0}};
  const auto t_start = std::chrono::steady_clock::now();
  auto next_status = t_start + std::chrono::seconds(1);
  std::string input;
  bool quit = false;
  while (!quit) {
    ::poll(fds, 2, 10);
    if ((fds[0].revents & POLLIN) != 0) {
      signalfd_siginfo info{};
      if (::read(signal_fd, &info, sizeof info) == static_cast<ssize_t>(sizeof info)) {
        print_err(std::string("zerog-rt: ") + (info.ssi_signo == SIGINT ? "SIGINT" : "SIGTERM") +
                  ": stopping");
      }
      quit = true;
    }
    if (fds[1].fd >= 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
      char buffer[512];
      const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
      if (n <= 0) {
        fds[1].fd = -1;  // end of input: keep running until quit, a signal or --duration
      } else {
        input.append(buffer, static_cast<std::size_t>(n));
        std::size_t eol;
        while (!quit && (eol = input.find('\n')) != std::string::npos) {
          quit = !handle_command(std::string_view(input).substr(0, eol), runtime);
          input.erase(0, eol + 1);
        }
      }
    }
    const rt::SupervisorEvents events = runtime.supervise();
    for (const std::string& line : events.out) print_out(line);
    for (const std::string& line : events.err) print_err(line);
    if (runtime.collection_finished()) quit = true;
    if (runtime.lockstep_finished()) quit = true;  // the emulator ended the run (or failed)
    const auto now = std::chrono::steady_clock::now();
    if (opt.duration_s > 0.0 && now - t_start >= std::chrono::duration<double>(opt.duration_s))
      quit = true;
    if (now >= next_status) {
      print_err(runtime.status_line());
      next_status += std::chrono::seconds(1);
      if (next_status < now) next_status = now + std::chrono::seconds(1);
    }
  }

  int code = kExitOk;
  if (std::string error = runtime.stop(); !error.empty()) {
    print_err("zerog-rt: " + error);
    code = kExitOutputFailed;
  }
  print_err(runtime.status_line());
  if (config.record_dir && runtime.recorder() != nullptr) {
    const rt::RecorderCounters& rc = runtime.recorder()->counters();
    print_err("zerog-rt: recorded " + std::to_string(rc.log_rows) + " log rows to " +
              runtime.recorder()->log_path().string() + " (" + std::to_string(rc.records) +
              " cycles in " + runtime.recorder()->cycles_path().string() + ", " +
              std::to_string(runtime.record_ring().dropped()) + " records dropped)");
  }
  if (!opt.summary_out.empty()) {
    try {
      io::write_file_atomic(opt.summary_out, runtime.summary_json(), {}, rt::kRecordFileMode);
    } catch (const std::exception& e) {
      print_err(std::string("zerog-rt: cannot write the summary: ") + e.what());
      code = kExitOutputFailed;
    }
  }
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "zerog-rt: the cabinet-PC program of zerog. Answers the robot's RSI datagrams every cycle, "
      "predicts the payload's wrench from the deployed model and moves the part as if it floated "
      "(zero-g), or drives a calibration path (collection). Files and keys: proto/rt_config.md."};
  Options opt;
  app.add_option("--config", opt.config, "the configuration file (TOML, proto/rt_config.md)")
      ->required();
  app.add_flag("--enable-zero-g", opt.enable_zero_g,
               "request zero-g as soon as the model has its rows and both sensors deliver");
  app.add_option("--collect", opt.collect,
                 "drive the robot through this design (zerog design, proto/design_format.md) and "
                 "stop at its end");
  app.add_option("--record", opt.record,
                 "record the run into this folder: run.csv + run.rig.toml (the log format) and "
                 "cycles.csv (overrides [record] dir)");
  app.add_option("--duration", opt.duration_s,
                 "stop after this many seconds (0: run until "
                 "SIGINT/SIGTERM or quit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--summary-out", opt.summary_out, "write the run's summary (JSON) here at exit");
  app.add_option("--commands", opt.commands,
                 "read commands (enable, stop, reset, collect, quit), one per line")
      ->check(CLI::IsMember({"stdin"}));
  app.add_option("--lockstep", opt.lockstep,
                 "run in lockstep with zerog-emu --lockstep at this socket: the emulator is the "
                 "clock (acceptance tests; proto/lockstep.md)");
  app.add_option("--test-mutant", opt.test_mutant,
                 "TEST ONLY: run a deliberately broken zerog-rt (gate_never_opens: no push is "
                 "confirmed; watchdog_doubled: every watchdog threshold doubled)")
      ->check(CLI::IsMember({"gate_never_opens", "watchdog_doubled"}));
  app.add_flag("--check-config", opt.check_config,
               "check the configuration, the model and the rig (and --collect's design), then "
               "exit 0 (all good) or 1");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : kExitStartup;
  }
  try {
    return run(opt);
  } catch (const std::exception& e) {
    print_err(std::string("zerog-rt: ") + e.what());
    return kExitStartup;
  }
}

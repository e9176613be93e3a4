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
#include "zerog/status.hpp"

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
  } else if (name == "estimator_without_imu") {  // the fused motion without the IMU's share
    cycle.motion.mutant_without_imu = true;
  } else if (name == "estimator_without_joints") {  // the IMU alone: the raw path
    cycle.motion.source = loop::MotionSource::imu;
  } else if (name == "estimator_one_row_late") {  // the estimate of the row before the model's
    cycle.motion.mutant_one_row_late = true;
  } else if (name == "estimator_ringing_unguarded") {
    // Both guards against the elastic arm's ringing closing a loop through the virtual body
    // gone: step 4 dropped, and the wrench's ringing loading the modes again (proto/loop.md,
    // "The joints' load": either guard alone keeps the loop open).
    cycle.motion.mutant_without_ringing = true;
    cycle.motion.load_bandwidth_hz = 3.0;
  } else if (name == "estimator_settled_at_once") {  // a push confirmed on its first rows
    cycle.motion.mutant_settled_at_once = true;
  } else if (name == "contact_lowpass_off") {  // the gates' output drives the body directly
    cycle.limits.contact_lowpass_hz = 0.0;
  } else if (name == "tare_unguarded") {  // a hand on the part while the tare is taken kept
    cycle.mutant_tare_unguarded = true;
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

// What zerog-rt reads before any device opens: the configuration (with --record applied), the
// rig, the model and the loop's configuration, and --collect's design.
struct Loaded {
  rt::RtConfig config;
  rt::Setup setup;
  std::unique_ptr<rt::PtpJointPath> path;
};

// Reads everything; false (the reason printed) on any error.
bool load(const Options& opt, Loaded& out) {
  try {
    out.config = rt::read_config(opt.config);
  } catch (const rt::ConfigError& e) {
    print_err(std::string("zerog-rt: ") + e.what());
    return false;
  }
  rt::RtConfig& config = out.config;
  if (!opt.record.empty()) config.record_dir = fs::path(opt.record);
  if (config.record_dir && config.record_per_run) {
    config.record_dir = *config.record_dir / run_folder_name(std::chrono::system_clock::now());
  }
  try {
    out.setup = rt::load_setup(config);
    if (!opt.collect.empty()) out.path = rt::load_collection_path(opt.collect, config.collection);
  } catch (const std::exception& e) {
    print_err(std::string("zerog-rt: ") + e.what());
    return false;
  }
  return true;
}

// --check-config's answer: what was read and checked.
std::string check_config_line(const Options& opt, const Loaded& loaded) {
  const rt::Setup& setup = loaded.setup;
  std::string effects;
  for (model::Effect e : model::kAllEffects) {
    if (setup.model.physics.effects.has(e))
      effects += (effects.empty() ? "" : ",") + std::string(model::info(e).name);
  }
  const rt::PtpJointPath* path = loaded.path.get();
  return "zerog-rt: " + opt.config + ": OK: model " + loaded.config.model_file.string() + " (" +
         effects + (setup.model.network ? " + network" : "") + "), rig '" + setup.rig.name +
         "', RSI cycle " + std::to_string(loaded.config.robot.cycle_ms) + " ms" +
         (setup.cycle.robot ? ", pose from RIst or the rig's robot kinematics"
                            : ", pose from RIst only (the rig describes no robot)") +
         (path ? ", design " + opt.collect + " (" + std::to_string(path->num_points()) +
                     " points, " + std::to_string(path->duration_s()) + " s)"
               : std::string());
}

// Signals go to the main thread only (signalfd); every thread started later inherits the mask.
int block_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  ::pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return ::signalfd(-1, &signals, SFD_CLOEXEC);
}

// The F/T board's bus: a SocketCAN interface, or zerog-emu's bus socket ([ft] transport);
// everything above it is the same.
struct FtBus {
  rtio::CanSocket socket;
  rtio::LocalCanBus local;
  rtio::CanBus* bus = nullptr;
  std::string name;  // in messages: "can0", or "local:/run/zerog/can.sock"
};

bool open_ft_bus(const rt::FtSection& ft, FtBus& out) {
  const rtio::CanSocketConfig can_config =
      rtio::NetcanoemSensor::socket_config(static_cast<std::uint8_t>(ft.base_id));
  if (ft.transport == rt::CanTransport::local) {
    out.name = "local:" + ft.local_path.string();
    const rtio::CanOpenResult opened = out.local.open_client(ft.local_path.string(), can_config);
    if (!opened.ok()) {
      print_err("zerog-rt: F/T sensor: cannot connect to the local CAN bus '" +
                ft.local_path.string() + "': " + rtio::can_open_status_name(opened.status) + " (" +
                opened.what + ": " + errno_text(opened.error_number) +
                "); start zerog-emu --can-local first");
      return false;
    }
    out.bus = &out.local;
    return true;
  }
  out.name = ft.interface;
  const rtio::CanOpenResult opened = out.socket.open(ft.interface, can_config);
  if (!opened.ok()) {
    print_err("zerog-rt: F/T sensor: cannot open CAN interface '" + ft.interface +
              "': " + rtio::can_open_status_name(opened.status) + " (" + opened.what + ": " +
              errno_text(opened.error_number) + ")");
    return false;
  }
  if (out.socket.receive_buffer().capped) {
    print_err("zerog-rt: WARNING: the CAN receive buffer was capped by net.core.rmem_max (" +
              std::to_string(out.socket.receive_buffer().bytes) + " bytes)");
  }
  out.bus = &out.socket;
  return true;
}

// Each device's start(); false (the reason printed) if it failed.
bool start_ft(rtio::NetcanoemSensor& ft, const FtBus& bus, const rt::FtSection& section) {
  const rtio::FtStartStatus st = ft.start();
  if (st == rtio::FtStartStatus::ok) return true;
  print_err("zerog-rt: F/T sensor on " + bus.name + " (base id " + std::to_string(section.base_id) +
            "): start failed: " + rtio::ft_start_status_name(st));
  return false;
}

bool start_imu(rtio::Stim300Imu& imu, const rt::ImuSection& section) {
  const rtio::ImuStartStatus st = imu.start();
  if (st == rtio::ImuStartStatus::ok) return true;
  print_err("zerog-rt: IMU on " + section.device + ": " + rtio::imu_start_status_name(st) + " (" +
            errno_text(imu.last_errno()) + ")");
  return false;
}

bool start_robot(rtio::RsiEndpoint& robot, const rt::RobotSection& section) {
  const rtio::RobotStartStatus st = robot.start();
  if (st == rtio::RobotStartStatus::ok) return true;
  print_err("zerog-rt: RSI endpoint " + section.bind_address + ":" +
            std::to_string(section.bind_port) + ": " + rtio::robot_start_status_name(st) + " (" +
            errno_text(robot.last_errno()) + ")");
  return false;
}

bool open_lockstep(rtio::LockstepClient& lockstep, const std::string& socket_path) {
  if (const Status st = lockstep.open(socket_path); !st.ok()) {
    print_err("zerog-rt: --lockstep " + socket_path + ": " + st.text() +
              (st.code() == StatusCode::system_error ? "; start zerog-emu --lockstep first" : ""));
    return false;
  }
  return true;
}

// The runtime's options from the configuration and the command line.
rt::RuntimeOptions runtime_options(const Options& opt, const Loaded& loaded) {
  const rt::RtConfig& config = loaded.config;
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
  options.auto_collect = loaded.path != nullptr;
  options.recorder.dir = config.record_dir;
  options.recorder.rig = loaded.setup.rig;
  options.recorder.temperature = config.ft.thermistor.has_value();
  options.model_file_crc32 = loaded.setup.model_file_crc32;
  options.modbus = config.modbus;
  options.telemetry = config.telemetry;
  options.model_file_name = config.model_file.filename().string();
  return options;
}

// The announcement once everything runs.
std::string running_line(const rt::RtConfig& config, const rtio::RsiEndpoint& robot,
                         const FtBus& ft_bus, const rt::Runtime& runtime) {
  return "zerog-rt: running: RSI on " + config.robot.bind_address + ":" +
         std::to_string(robot.local_port()) + " for " + config.robot.address + ", cycle " +
         std::to_string(config.robot.cycle_ms) + " ms; F/T " + ft_bus.name + " at " +
         std::to_string(static_cast<int>(config.ft.rate_hz)) + " Hz; IMU " + config.imu.device +
         (config.record_dir ? "; recording to " + config.record_dir->string() : std::string()) +
         (config.telemetry
              ? "; telemetry on DDS domain " + std::to_string(config.telemetry->domain_id)
              : std::string()) +
         (runtime.modbus_server() != nullptr ? "; Modbus on " + config.modbus->bind_address + ":" +
                                                   std::to_string(runtime.modbus_server()->port())
                                             : std::string());
}

// Main loop: signals, commands, supervision, status once a second, until a signal, `quit`, the
// end of --collect's path, the emulator's end of the run or --duration.
void supervise_until_done(const Options& opt, int signal_fd, rt::Runtime& runtime) {
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
}

// Stops the runtime and writes what the run leaves: the recording's line, the summary. The exit
// code: kExitOk, or kExitOutputFailed when an output could not be written.
int finish(const Options& opt, const rt::RtConfig& config, rt::Runtime& runtime) {
  int code = kExitOk;
  if (const Status st = runtime.stop(); !st.ok()) {
    print_err("zerog-rt: " + st.text());
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
      formats::write_file_atomic(opt.summary_out, runtime.summary_json(), {}, rt::kRecordFileMode);
    } catch (const std::exception& e) {
      print_err(std::string("zerog-rt: cannot write the summary: ") + e.what());
      code = kExitOutputFailed;
    }
  }
  return code;
}

int run(const Options& opt) {
  Loaded loaded;
  if (!load(opt, loaded)) return opt.check_config ? 1 : kExitStartup;
  const rt::RtConfig& config = loaded.config;
  if (opt.check_config) {
    print_out(check_config_line(opt, loaded));
    return kExitOk;
  }
  if (!opt.test_mutant.empty()) {
    apply_mutant(opt.test_mutant, loaded.setup.cycle);
    print_err("zerog-rt: WARNING: test mutant '" + opt.test_mutant +
              "': this zerog-rt is broken on purpose (HIL tests only)");
    if (opt.test_mutant == "exit_at_start") {
      // As a start-up error would (a file the configuration names is missing): the HIL runner
      // must stop the emulator and fail at once (tests/hil/CMakeLists.txt, hil_runner_stops).
      print_err("zerog-rt: test mutant exit_at_start: exiting before the devices open");
      return kExitStartup;
    }
  }
  if (opt.enable_zero_g && loaded.path) {
    print_err("zerog-rt: --enable-zero-g and --collect exclude each other: choose one");
    return kExitStartup;
  }
  const int signal_fd = block_signals();

  // Devices (start-up: may block, bounded by their timeouts).
  FtBus ft_bus;
  if (!open_ft_bus(config.ft, ft_bus)) return kExitStartup;
  const rtio::NetcanoemConfig ft_config = rt::netcanoem_config(config.ft);
  rtio::NetcanoemSensor ft(*ft_bus.bus, ft_config);
  if (!start_ft(ft, ft_bus, config.ft)) return kExitStartup;
  rtio::Stim300Imu imu(rt::stim300_config(config.imu));
  if (!start_imu(imu, config.imu)) return kExitStartup;
  const rtio::RsiEndpointConfig robot_config = rt::rsi_endpoint_config(config.robot);
  rtio::RsiEndpoint robot(robot_config);
  if (!start_robot(robot, config.robot)) return kExitStartup;
  rtio::LockstepClient lockstep;
  const bool lockstepped = !opt.lockstep.empty();
  if (lockstepped && !open_lockstep(lockstep, opt.lockstep)) return kExitStartup;

  rt::Runtime runtime(runtime_options(opt, loaded),
                      rt::RuntimeDevices{&robot, &ft, &imu, lockstepped ? &lockstep : nullptr});
  if (const Status st =
          runtime.configure(loaded.setup.cycle, std::move(loaded.setup.model), loaded.path.get());
      !st.ok()) {
    print_err("zerog-rt: " + config.file.string() +
              ": the loop refuses the configuration: " + st.text());
    return kExitStartup;
  }
  std::vector<Status> warnings;
  const Status started = runtime.start(warnings);
  for (const Status& w : warnings) print_err("zerog-rt: WARNING: " + w.text());
  if (!started.ok()) {
    print_err("zerog-rt: " + started.text());
    return kExitStartup;
  }
  // Lockstep: hello once the threads wait for the emulator's events (start() dropped what had
  // queued on the RSI socket before).
  if (lockstepped && lockstep.hello(robot_config.receive_timeout, config.ft.rate_hz,
                                    ft_config.sample_timeout) != rtio::LockstepStatus::ok) {
    print_err("zerog-rt: --lockstep " + opt.lockstep + ": cannot send hello (" +
              errno_text(lockstep.last_errno()) + ")");
    (void)runtime.stop();
    return kExitStartup;
  }
  print_err(running_line(config, robot, ft_bus, runtime));
  supervise_until_done(opt, signal_fd, runtime);
  return finish(opt, config, runtime);
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
                 "confirmed; watchdog_doubled: every watchdog threshold doubled; exit_at_start: "
                 "exits with a start-up error before the devices open; estimator_without_imu, "
                 "estimator_without_joints, estimator_one_row_late, estimator_ringing_unguarded, "
                 "estimator_settled_at_once: the motion estimator without the IMU's share, the "
                 "IMU alone, the estimate one row late, the ringing arm's step left out and the "
                 "wrench's ringing in the joints' load, its first rows trusted; "
                 "contact_lowpass_off: [limits] contact_lowpass_hz ignored; tare_unguarded: "
                 "a push held while [filter] tare_s is taken becomes the contact's zero)")
      ->check(CLI::IsMember(
          {"gate_never_opens", "watchdog_doubled", "exit_at_start", "estimator_without_imu",
           "estimator_without_joints", "estimator_one_row_late", "estimator_ringing_unguarded",
           "estimator_settled_at_once", "contact_lowpass_off", "tare_unguarded"}));
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

// zerog-emu — the rig for zerog-rt's hardware-in-the-loop tests (proto/emulator.md): the robot
// controller on RSI/UDP with servo lag, the payload's physics with scripted pushes, the ATI
// NETCANOEM board on a CAN bus and the STIM300 on a pty, faults on a schedule.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "zerog/emu/ati_board.hpp"
#include "zerog/emu/rig_emulator.hpp"
#include "zerog/emu/scenario.hpp"
#include "zerog/emu/stim300_emulator.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/local_can_bus.hpp"

namespace {

namespace fs = std::filesystem;
using namespace zerog;

std::atomic<bool> g_stop{false};
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

extern "C" void on_signal(int) { g_stop.store(true); }

void install_signal_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

struct Args {
  std::string scenario, can, can_local, imu_link;
  std::string robot_bind = "127.0.0.1:49153", rt_address = "127.0.0.1:49152";
  double duration_s = 20.0;
  std::string truth_out, summary_out, write_model, write_rig;
  bool list_faults = false;
  bool write_only = false;
  std::string lockstep;
  bool lockstep_paced = false;
};

void list_faults() {
  std::printf("%-16s  %-8s  %s\n", "kind", "counted", "what it does");
  for (const emu::FaultKindInfo& i : emu::fault_kind_infos())
    std::printf("%-16s  %-8s  %s\n", i.name, i.robot ? "cycles" : "seconds", i.description);
}

// --can-local PATH: a socket file nobody serves (left by a zerog-emu that was killed) is removed;
// a socket someone serves, or anything that is not a socket, is refused.
void clear_stale_can_socket(const std::string& path) {
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(path, ec);
  if (status.type() == fs::file_type::not_found) return;
  if (ec) throw std::runtime_error("--can-local " + path + ": " + ec.message());
  if (status.type() != fs::file_type::socket)
    throw std::runtime_error("--can-local " + path +
                             ": exists and is not a socket; refusing to replace it");
  rtio::LocalCanBus probe;
  if (probe.open_client(path).ok())
    throw std::runtime_error("--can-local " + path +
                             ": another process serves this socket (a zerog-emu still running?)");
  if (!fs::remove(path, ec) && ec)
    throw std::runtime_error("--can-local " + path +
                             ": cannot remove the stale socket: " + ec.message());
}

// Every output path distinct, none the scenario.
void check_outputs(const Args& a) {
  std::vector<std::pair<std::string, std::string>> outs;
  for (const auto& [flag, path] :
       {std::pair<const char*, const std::string*>{"--truth-out", &a.truth_out},
        {"--summary-out", &a.summary_out},
        {"--write-model", &a.write_model},
        {"--write-rig", &a.write_rig}}) {
    if (path->empty()) continue;
    std::error_code ec;
    if (fs::equivalent(*path, a.scenario, ec))
      throw std::invalid_argument(std::string(flag) + " " + *path + " is the scenario file");
    for (const auto& [other_flag, other] : outs)
      if (fs::weakly_canonical(other) == fs::weakly_canonical(*path))
        throw std::invalid_argument(std::string(flag) + " and " + other_flag +
                                    " name the same file: " + *path);
    outs.emplace_back(flag, *path);
  }
}

int run(const Args& a) {
  emu::Scenario scenario = emu::read_scenario(a.scenario);
  check_outputs(a);
  const std::vector<fs::path> inputs = {a.scenario};

  emu::RigEmulatorOptions options;
  options.robot_bind = a.robot_bind;
  options.rt_address = a.rt_address;
  options.duration_s = a.duration_s;
  options.imu_link = a.imu_link;
  options.lockstep_path = a.lockstep;
  options.lockstep_paced = a.lockstep_paced;
  std::unique_ptr<emu::AtiBoard> board;
  if (!a.can.empty() || !a.can_local.empty()) {
    emu::AtiBoardConfig c;
    c.base_id = scenario.ft.base_id;
    c.counts_per_force = scenario.ft.counts_per_force;
    c.counts_per_torque = scenario.ft.counts_per_torque;
    c.seed = scenario.sim.seed;
    board = std::make_unique<emu::AtiBoard>(c);
  }
  std::unique_ptr<emu::Stim300Emulator> imu;
  if (!a.imu_link.empty()) {
    emu::Stim300EmulatorConfig c;
    c.seed = scenario.sim.seed;
    // The scenario's noise.gyro_bias / accel_bias / imu_bias_tau (proto/sim_robot.md).
    c.gyro_bias_radps = scenario.sim.noise.gyro_bias_radps;
    c.accel_bias_mps2 = scenario.sim.noise.accel_bias_mps2;
    c.bias_tau_s = scenario.sim.noise.imu_bias_tau_s;
    imu = std::make_unique<emu::Stim300Emulator>(c);
  }
  emu::RigEmulator emulator(scenario, options, board.get(), imu.get());

  if (!a.write_model.empty())
    io::write_model(emu::emulator_truth(scenario, emulator.physics().simulator()), a.write_model,
                    inputs);
  if (!a.write_rig.empty())
    formats::write_rig(emu::emulator_rig(scenario, emulator.physics().simulator()), a.write_rig,
                       inputs);
  if (a.write_only) return 0;

  // Devices ready before the first datagram. The board's bus: a SocketCAN interface (--can) or
  // a LocalCanBus server at --can-local PATH, unlinked again when can_local closes (at exit).
  rtio::CanSocket can;
  rtio::LocalCanBus can_local;
  rtio::CanBus* can_bus = &can;
  if (board) {
    std::string where = a.can;
    if (!a.can_local.empty()) {
      clear_stale_can_socket(a.can_local);
      const rtio::CanOpenResult r = can_local.open_server(a.can_local);
      if (!r.ok())
        throw std::runtime_error("--can-local " + a.can_local + ": " +
                                 rtio::can_open_status_name(r.status) + " (" + r.what + ": " +
                                 std::strerror(r.error_number) + ")");
      can_bus = &can_local;
      where = "local:" + a.can_local;
    } else {
      const rtio::CanOpenResult r = can.open(a.can);
      if (!r.ok())
        throw std::runtime_error("--can " + a.can + ": " + rtio::can_open_status_name(r.status) +
                                 " (" + r.what + ": " + std::strerror(r.error_number) + ")");
    }
    const std::array<double, 6> range = board->full_scale_si();
    std::fprintf(stderr, "zerog-emu: F/T board 0x%02x on %s, range +-%.0f N, +-%.0f N*m\n",
                 scenario.ft.base_id, where.c_str(), std::min({range[0], range[1], range[2]}),
                 std::min({range[3], range[4], range[5]}));
  }
  if (imu) {
    if (const Status st = imu->open(a.imu_link); !st.ok())
      throw std::runtime_error("--imu-link: " + st.message());
    std::fprintf(stderr, "zerog-emu: STIM300 on %s -> %s\n", a.imu_link.c_str(),
                 imu->slave_path().c_str());
  }
  emulator.bind();
  std::atomic<bool> devices_stop{false};
  std::thread can_thread;
  if (board) can_thread = std::thread([&] { board->serve(*can_bus, devices_stop); });

  install_signal_handlers();
  std::printf("zerog-emu: ready\n");
  std::fflush(stdout);
  std::exception_ptr error;
  try {
    emulator.run(g_stop);
  } catch (...) {
    error = std::current_exception();
  }
  devices_stop = true;
  if (can_thread.joinable()) can_thread.join();
  can_local.close();  // unlinks --can-local's socket
  if (error) std::rethrow_exception(error);

  if (!a.truth_out.empty()) formats::write_file_atomic(a.truth_out, emulator.truth_csv(), inputs);
  const nlohmann::json summary = emulator.summary();
  if (!a.summary_out.empty())
    formats::write_file_atomic(a.summary_out, summary.dump(2) + "\n", inputs);
  const nlohmann::json& r = summary["replies"];
  std::fprintf(stderr,
               "zerog-emu: %zu cycles, replies ok %llu, late %llu, missing %llu, wrong IPOC %llu, "
               "malformed %llu; physics worst lag %.1f ms\n",
               emulator.cycles().size(), r["ok"].get<unsigned long long>(),
               r["late"].get<unsigned long long>(), r["missing"].get<unsigned long long>(),
               r["wrong_ipoc"].get<unsigned long long>(), r["malformed"].get<unsigned long long>(),
               summary["physics"]["worst_lag_s"].get<double>() * 1e3);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "zerog-emu: the rig for zerog-rt's hardware-in-the-loop tests: robot controller (RSI over "
      "UDP), payload physics with pushes, ATI NETCANOEM board on CAN, STIM300 on a pty, faults"};
  Args a;
  app.add_option("--scenario", a.scenario, "Scenario file (TOML, proto/emulator.md)")
      ->check(CLI::ExistingFile);
  CLI::Option* can = app.add_option("--can", a.can,
                                    "CAN interface for the F/T board (e.g. vcan0); none: no board");
  app.add_option("--can-local", a.can_local,
                 "Serve the F/T board on a local CAN bus socket at this path instead (no kernel "
                 "CAN needed; zerog-rt [ft] transport = \"local\", local_path = this path)")
      ->excludes(can);
  app.add_option("--imu-link", a.imu_link,
                 "Symlink to create to the STIM300's pty (e.g. /tmp/zerog/imu); none: no IMU");
  app.add_option("--robot-bind", a.robot_bind, "The controller's UDP address:port")
      ->capture_default_str();
  app.add_option("--rt-address", a.rt_address, "zerog-rt's UDP address:port")
      ->capture_default_str();
  app.add_option("--duration", a.duration_s, "Run length in s; 0: until SIGINT/SIGTERM")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--truth-out", a.truth_out, "Truth CSV, one row per robot cycle");
  app.add_option("--summary-out", a.summary_out, "Summary JSON");
  app.add_option("--write-model", a.write_model,
                 "Also write the payload's truth model file (JSON, what zerog export reads)");
  app.add_option("--write-rig", a.write_rig, "Also write the rig (.rig.toml) zerog-rt runs on");
  app.add_option(
      "--lockstep", a.lockstep,
      "Run in lockstep with zerog-rt --lockstep over this unix socket: emulated time, "
      "one robot cycle per exchange, independent of the host's load (proto/lockstep.md)");
  app.add_flag("--lockstep-paced", a.lockstep_paced,
               "With --lockstep: emulated time never runs ahead of the wall clock (peers that "
               "act on the wall clock: the cell PLC, fault_peer.py)")
      ->needs("--lockstep");
  app.add_flag("--write-only", a.write_only,
               "Write --write-model and --write-rig, then exit without running (so zerog export "
               "can run before the timed run starts)");
  app.add_flag("--list-faults", a.list_faults, "List the fault kinds of [[fault]] and exit");
  try {
    app.parse(argc, argv);
    if (a.list_faults) {
      list_faults();
      return 0;
    }
    if (a.scenario.empty()) throw CLI::RequiredError("--scenario");
    return run(a);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const formats::InputError& e) {
    std::fprintf(stderr, "zerog-emu: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "zerog-emu: error: %s\n", e.what());
    return 1;
  }
}

// What a Modbus client costs the cycle: one zerog-rt cycle (a real loop::Cycle step with a robot
// standing still, then the snapshot published wait-free for the server, as zerog-rt does) timed
// with no server, with a server and a client flooding it (reads of every input register and,
// every 10th request, a mass write the cycle accepts), and with a client stalled on half a
// request while another polls. Compare the per-cycle times (mean, p99, max) across the three;
// nothing is asserted (speed is measured, never asserted).
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "loop_fixtures.hpp"
#include "zerog/handover/latest_value.hpp"
#include "zerog/modbus/server.hpp"

namespace {

using namespace zerog;

/// The target as zerog-rt has it: the snapshot through a LatestValue (wait-free), commands and
/// proposals straight into the cycle (lock-free).
class LatestValueTarget : public modbus::SupervisorTarget {
 public:
  explicit LatestValueTarget(loop::Cycle& cycle) : cycle_(cycle), initial_(cycle.tunables()) {}
  /// The cycle thread, after each step.
  void publish() {
    modbus::fill_from_cycle(cycle_, scratch_);
    box_.publish(scratch_);
  }
  modbus::SupervisorSnapshot snapshot() const override {
    box_.read(last_);  // the server thread is the only reader
    return last_;
  }
  std::uint64_t request(loop::Command c) override { return cycle_.request(c); }
  loop::CommandOutcome command_outcome(std::uint64_t ticket) const override {
    return cycle_.command_outcome(ticket);
  }
  bool propose(const loop::Tunables& t) override { return cycle_.propose(t); }
  loop::ProposalStatus proposal_status() const override { return cycle_.proposal_status(); }
  bool withdraw_proposal() override { return cycle_.withdraw_proposal(); }
  loop::Tunables tunables() const override { return initial_; }

 private:
  loop::Cycle& cycle_;
  loop::Tunables initial_;
  modbus::SupervisorSnapshot scratch_;
  mutable handover::LatestValue<modbus::SupervisorSnapshot> box_;
  mutable modbus::SupervisorSnapshot last_;
};

enum class Load { none, flood, stall };

void run_cycles(benchmark::State& state, Load load) {
  loop::Cycle cycle;
  if (!cycle.configure(loop::test::test_cycle_config(), loop::test::payload_model()).ok()) {
    state.SkipWithError("cycle configuration failed");
    return;
  }
  loop::test::StaticRobot robot;
  LatestValueTarget target(cycle);
  for (int i = 0; i < 10; ++i) {
    robot.quiet(cycle);
    target.publish();
  }

  modbus::ServerConfig config;
  config.bind_address = "127.0.0.1";
  config.port = 0;
  config.request_timeout_s = 10.0;  // the stalled client stays for the whole run
  modbus::ModbusServer server(config, target);
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> requests{0};
  std::vector<std::thread> clients;
  int stalled_fd = -1;
  if (load != Load::none) {
    if (!server.start().ok()) {
      state.SkipWithError("server did not start");
      return;
    }
    const int port = server.port();
    if (load == Load::stall) {
      stalled_fd = ::socket(AF_INET, SOCK_STREAM, 0);
      sockaddr_in a{};
      a.sin_family = AF_INET;
      a.sin_port = htons(static_cast<std::uint16_t>(port));
      inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
      const std::uint8_t half[] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04};
      if (::connect(stalled_fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0 ||
          ::send(stalled_fd, half, sizeof half, 0) < 0) {
        state.SkipWithError("stalled client could not connect");
        return;
      }
    }
    clients.emplace_back([&, port] {
      modbus_t* ctx = modbus_new_tcp("127.0.0.1", port);
      modbus_set_response_timeout(ctx, 1, 0);
      if (modbus_connect(ctx) != 0) return;
      std::uint16_t regs[56];
      std::uint64_t n = 0;
      while (!stop.load(std::memory_order_relaxed)) {
        if (load == Load::flood && n % 10 == 9) {
          const std::uint16_t mass[2] = {0x0001, static_cast<std::uint16_t>(0x86A0 + n % 2)};
          modbus_write_registers(ctx, 0, 2, mass);
        } else {
          modbus_read_input_registers(ctx, 0, 56, regs);
        }
        ++n;
        requests.fetch_add(1, std::memory_order_relaxed);
        // The stall case: a well-behaved PLC polling at 100 Hz next to the stalled one.
        if (load == Load::stall) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      modbus_close(ctx);
      modbus_free(ctx);
    });
  }

  std::vector<double> ns;
  ns.reserve(1 << 20);
  const auto t0 = std::chrono::steady_clock::now();
  for (auto _ : state) {
    const auto a = std::chrono::steady_clock::now();
    robot.quiet(cycle);
    target.publish();
    const auto b = std::chrono::steady_clock::now();
    ns.push_back(
        static_cast<double>(std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count()));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stop = true;
  for (std::thread& t : clients) t.join();
  if (stalled_fd >= 0) ::close(stalled_fd);
  server.stop();

  std::sort(ns.begin(), ns.end());
  const auto at = [&](double q) {
    return ns.empty() ? 0.0 : ns[static_cast<std::size_t>(q * static_cast<double>(ns.size() - 1))];
  };
  state.counters["p50_us"] = at(0.50) / 1e3;
  state.counters["p99_us"] = at(0.99) / 1e3;
  state.counters["max_us"] = ns.empty() ? 0.0 : ns.back() / 1e3;
  state.counters["modbus_req_per_s"] = static_cast<double>(requests.load()) / seconds;
  const modbus::ServerCounters c = server.counters();
  state.counters["writes_accepted"] = static_cast<double>(c.writes_accepted);
  state.counters["exceptions"] = static_cast<double>(c.exceptions_total());
}

void BM_CycleNoServer(benchmark::State& s) { run_cycles(s, Load::none); }
void BM_CycleModbusFlood(benchmark::State& s) { run_cycles(s, Load::flood); }
void BM_CycleModbusStalledClient(benchmark::State& s) { run_cycles(s, Load::stall); }

BENCHMARK(BM_CycleNoServer)->MinTime(2.0)->UseRealTime();
BENCHMARK(BM_CycleModbusFlood)->MinTime(2.0)->UseRealTime();
BENCHMARK(BM_CycleModbusStalledClient)->MinTime(2.0)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

// RSI round trip on loopback UDP: datagram in → parsed (RsiEndpoint::receive) → reply out
// (RsiEndpoint::reply), against a bare UDP echo (recvfrom → sendto of the same bytes) measured
// the same way in the same run. A client socket plays the robot; the server runs in a thread.
// BM_ZerogRtRoundTrip times zerog-rt's whole cycle thread (zerog::rt::Runtime: receive, hand-over
// of the sensor samples, Cycle::step in zero-g, reply) the same way.
// Its argument adds what issue 5 says must not change the cycle's timing: 0 nothing, 1 DDS
// telemetry with no subscriber, 2 telemetry with a slow subscriber (keep-last readers of every
// per-cycle topic, best-effort like the writers, taking one sample every 100 ms), 3 the Modbus
// server with a client that sends half a request and stalls (reconnecting whenever the server
// closes it) and a second client that connected and says nothing, 4 both 2 and 3. ratio_plain
// compares with argument 0. Reported per benchmark: p50, p99, p99.9 and max round trip in µs; the
// RSI benchmark also reports its ratio to the echo at the median and the 99.9th percentile. Speed
// is measured, never asserted (tests/bench/CMakeLists.txt).
#include <benchmark/benchmark.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include <arpa/inet.h>
#include <dds/dds.h>
#include <netinet/in.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "rt_fixtures.hpp"
#include "telemetry.h"
#include "udp.hpp"
#include "zerog/rt/runtime.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"

namespace {

using namespace std::chrono_literals;
using zerog::rtio::test::UdpPeer;

constexpr std::int64_t kRoundTrips = 20'000;

struct Percentiles {
  double p50_us = 0, p99_us = 0, p999_us = 0, max_us = 0;
};
Percentiles g_echo;  // from BM_BareUdpEcho, for the ratio in BM_RsiEndpointRoundTrip

Percentiles percentiles(std::vector<double>& us) {
  std::sort(us.begin(), us.end());
  auto at = [&](double q) {
    return us[std::min(us.size() - 1,
                       static_cast<std::size_t>(q * static_cast<double>(us.size())))];
  };
  return {at(0.5), at(0.99), at(0.999), us.back()};
}

void report(benchmark::State& state, const Percentiles& p) {
  state.counters["p50_us"] = p.p50_us;
  state.counters["p99_us"] = p.p99_us;
  state.counters["p999_us"] = p.p999_us;
  state.counters["max_us"] = p.max_us;
}

// Sends one robot message per iteration and waits for the answer; returns the round trips (µs).
// `before` runs before each message, outside the timed part, and may replace the message.
std::vector<double> run_client(
    benchmark::State& state, std::uint16_t server_port,
    const std::function<std::string_view(std::span<char>, std::uint64_t)>& make_message = {},
    const std::function<void()>& before = {}) {
  UdpPeer robot("127.0.0.1", 0);
  std::vector<double> round_trips_us;
  round_trips_us.reserve(static_cast<std::size_t>(kRoundTrips));
  std::array<char, 1024> out{};
  std::array<char, 1024> in{};
  std::uint64_t ipoc = 1;
  for (auto _ : state) {
    if (before) before();
    const std::string_view message =
        make_message ? make_message(out, ipoc) : zerog::rtio::test::robot_message(out, ipoc);
    ++ipoc;
    const auto start = std::chrono::steady_clock::now();
    robot.send_to(server_port, message);
    const long n = robot.receive(in, 1000);
    const auto stop = std::chrono::steady_clock::now();
    if (n <= 0) {
      state.SkipWithError("no reply within 1 s");
      break;
    }
    round_trips_us.push_back(std::chrono::duration<double, std::micro>(stop - start).count());
  }
  return round_trips_us;
}

void BM_BareUdpEcho(benchmark::State& state) {
  UdpPeer server("127.0.0.1", 0);
  std::atomic<bool> stop{false};
  std::thread echo([&] {
    std::array<char, 4096> buffer{};
    while (!stop.load(std::memory_order_relaxed)) {
      pollfd pfd{server.fd(), POLLIN, 0};
      if (::poll(&pfd, 1, 20) != 1) continue;
      sockaddr_in from{};
      socklen_t length = sizeof from;
      const ssize_t n = ::recvfrom(server.fd(), buffer.data(), buffer.size(), 0,
                                   reinterpret_cast<sockaddr*>(&from), &length);
      if (n > 0) {
        ::sendto(server.fd(), buffer.data(), static_cast<std::size_t>(n), 0,
                 reinterpret_cast<sockaddr*>(&from), length);
      }
    }
  });
  std::vector<double> us = run_client(state, server.port());
  stop.store(true);
  echo.join();
  if (us.empty()) return;
  g_echo = percentiles(us);
  report(state, g_echo);
}

void BM_RsiEndpointRoundTrip(benchmark::State& state) {
  zerog::rtio::RsiEndpointConfig config;
  config.bind_port = 0;
  config.robot_port = 0;  // any port of 127.0.0.1: the client binds after the server
  config.receive_timeout = 20ms;
  zerog::rtio::RsiEndpoint endpoint(config);
  if (endpoint.start() != zerog::rtio::RobotStartStatus::ok) {
    state.SkipWithError("RsiEndpoint::start failed");
    return;
  }
  std::atomic<bool> stop{false};
  std::thread server([&] {
    zerog::proto::rsi::RobotMessage message;
    const auto correction = zerog::proto::rsi::correction_from_si({1e-4, -2e-4, 0}, {0, 0, 1e-3});
    while (!stop.load(std::memory_order_relaxed)) {
      if (endpoint.receive(message) == zerog::rtio::RobotReceiveStatus::message) {
        endpoint.reply(correction, message.ipoc);
      }
    }
  });
  std::vector<double> us = run_client(state, endpoint.local_port());
  stop.store(true);
  server.join();
  if (us.empty()) return;
  const Percentiles p = percentiles(us);
  report(state, p);
  if (g_echo.p50_us > 0) {
    state.counters["ratio_p50"] = p.p50_us / g_echo.p50_us;
    state.counters["ratio_p999"] = p.p999_us / g_echo.p999_us;
  }
  state.counters["malformed"] = static_cast<double>(endpoint.counters().malformed);
}

Percentiles g_plain;  // BM_ZerogRtRoundTrip/0's own times, for the plain_* ratios

constexpr int kBenchDomain = 231;

// A subscriber that reads slowly: keep-last readers of the per-cycle topics (best-effort, as
// their writers; a reliable reader would not match) in a participant of its own, taking one
// sample of each every 100 ms.
class SlowSubscriber {
 public:
  SlowSubscriber() {
    participant_ = dds_create_participant(kBenchDomain, nullptr, nullptr);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 8);
    const std::pair<const dds_topic_descriptor_t*, const char*> topics[] = {
        {&zerog_telemetry_WrenchSample_desc, "zerog/wrench"},
        {&zerog_telemetry_ImuSample_desc, "zerog/imu"},
        {&zerog_telemetry_RobotSample_desc, "zerog/robot"},
        {&zerog_telemetry_CommandSample_desc, "zerog/command"},
        {&zerog_telemetry_BodySample_desc, "zerog/body"},
        {&zerog_telemetry_TimingSample_desc, "zerog/timing"}};
    for (const auto& [desc, name] : topics) {
      const dds_entity_t topic = dds_create_topic(participant_, desc, name, nullptr, nullptr);
      readers_.push_back(dds_create_reader(participant_, topic, q, nullptr));
    }
    dds_delete_qos(q);
    thread_ = std::thread([this] {
      while (!stop_.load()) {
        for (const dds_entity_t r : readers_) {
          void* sample[1] = {};
          dds_sample_info_t info;
          if (dds_take(r, sample, &info, 1, 1) > 0) {
            ++taken_;
            dds_return_loan(r, sample, 1);
          }
        }
        std::this_thread::sleep_for(100ms);
      }
    });
  }
  ~SlowSubscriber() {
    stop_ = true;
    thread_.join();
    dds_delete(participant_);
  }
  std::uint64_t taken() const { return taken_; }

 private:
  dds_entity_t participant_ = 0;
  std::vector<dds_entity_t> readers_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> taken_{0};
};

// Modbus clients that never finish a request: one sends the first 3 bytes of a 12-byte read and
// waits (reconnecting when the server drops it after request_timeout_s); one connects and is
// silent.
class StalledModbusClients {
 public:
  explicit StalledModbusClients(int port) : port_(port) {
    silent_ = connect_once();
    thread_ = std::thread([this] {
      while (!stop_.load()) {
        const int fd = connect_once();
        if (fd < 0) {
          std::this_thread::sleep_for(10ms);
          continue;
        }
        const unsigned char half[3] = {0x00, 0x01, 0x00};
        if (::send(fd, half, sizeof half, MSG_NOSIGNAL) == 3) ++stalls_;
        pollfd pfd{fd, POLLIN, 0};
        while (!stop_.load() && ::poll(&pfd, 1, 20) == 0) {
        }
        ::close(fd);
      }
    });
  }
  ~StalledModbusClients() {
    stop_ = true;
    thread_.join();
    if (silent_ >= 0) ::close(silent_);
  }
  std::uint64_t stalls() const { return stalls_; }

 private:
  int connect_once() const {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port_));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) return fd;
    if (fd >= 0) ::close(fd);
    return -1;
  }
  int port_;
  int silent_ = -1;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> stalls_{0};
};

void BM_ZerogRtRoundTrip(benchmark::State& state) {
  namespace rt = zerog::rt;
  const auto mode = state.range(0);
  const bool telemetry = mode == 1 || mode == 2 || mode == 4;
  const bool slow_subscriber = mode == 2 || mode == 4;
  const bool modbus = mode == 3 || mode == 4;
  zerog::rtio::RsiEndpointConfig config;
  config.bind_port = 0;
  config.robot_port = 0;
  config.receive_timeout = 20ms;
  zerog::rtio::RsiEndpoint endpoint(config);
  if (endpoint.start() != zerog::rtio::RobotStartStatus::ok) {
    state.SkipWithError("RsiEndpoint::start failed");
    return;
  }
  rt::RuntimeOptions options;
  options.auto_enable_zero_g = true;
  if (telemetry) {
    zerog::telemetry::TelemetryConfig t;
    t.domain_id = kBenchDomain;
    t.interface = "lo";
    t.peers = {"127.0.0.1"};
    t.allow_multicast = false;
    options.telemetry = t;
  }
  if (modbus) {
    zerog::modbus::ServerConfig m;
    m.bind_address = "127.0.0.1";
    m.port = 0;
    options.modbus = m;
  }
  rt::Runtime runtime(options, rt::RuntimeDevices{&endpoint});
  if (!runtime.configure(rt::test::test_cycle_config(), rt::test::payload_model()).ok()) {
    state.SkipWithError("Runtime::configure failed");
    return;
  }
  std::vector<zerog::Status> warnings;
  if (!runtime.start(warnings).ok()) {
    state.SkipWithError("Runtime::start failed");
    return;
  }
  std::unique_ptr<SlowSubscriber> subscriber;
  if (slow_subscriber) subscriber = std::make_unique<SlowSubscriber>();
  std::unique_ptr<StalledModbusClients> stalled;
  if (modbus) stalled = std::make_unique<StalledModbusClients>(runtime.modbus_server()->port());
  rt::test::StaticRobot rig;
  std::int64_t n = 0;
  // Per cycle, as at 12 ms: 4 F/T and 24 IMU samples handed over by the "sensor threads" (here
  // the client, outside the timed part), a slow push back and forth so the body moves.
  auto before = [&] {
    const double push = (n / 50) % 2 == 0 ? 0.0 : ((n / 100) % 2 ? 20.0 : -20.0);
    for (int i = 0; i < 4; ++i) runtime.ft_ring().try_push(rig.ft(rt::test::push(push, 0, 0)));
    for (int i = 0; i < 24; ++i) runtime.imu_ring().try_push(rig.imu_sample);
    if (n % 64 == 0) runtime.supervise();  // --enable-zero-g
    ++n;
  };
  auto make_message = [&](std::span<char> out, std::uint64_t ipoc) {
    rig.message.ipoc = 1'000'000 + 12 * ipoc;
    const zerog::proto::rsi::FormatResult f =
        zerog::proto::rsi::format_robot_message(rig.message, out);
    return std::string_view(out.data(), f.size);
  };
  std::vector<double> us = run_client(state, endpoint.local_port(), make_message, before);
  if (subscriber) state.counters["subscriber_taken"] = static_cast<double>(subscriber->taken());
  if (stalled) state.counters["modbus_stalls"] = static_cast<double>(stalled->stalls());
  stalled.reset();
  if (const zerog::Status st = runtime.stop(); !st.ok()) state.SkipWithError(st.text().c_str());
  subscriber.reset();
  if (const auto* t = runtime.telemetry()) {
    state.counters["dds_published"] = static_cast<double>(t->counters().records_published);
    state.counters["dds_dropped"] = static_cast<double>(t->counters().telemetry_drops);
  }
  const std::string summary = runtime.summary_json();
  if (summary.find("\"state\": \"zero_g\"") == std::string::npos) {
    state.SkipWithError("the cycle was not in zero-g at the end");
    return;
  }
  if (us.empty()) return;
  const Percentiles p = percentiles(us);
  report(state, p);
  if (g_echo.p50_us > 0) {
    state.counters["ratio_p50"] = p.p50_us / g_echo.p50_us;
    state.counters["ratio_p999"] = p.p999_us / g_echo.p999_us;
  }
  const nlohmann::json j = nlohmann::json::parse(summary);
  Percentiles own;  // the cycle's own times, µs: reply median / p99, compute median / p99
  own.p50_us = j["reply_latency_ns"]["median"].get<double>() / 1e3;
  own.p99_us = j["reply_latency_ns"]["p99"].get<double>() / 1e3;
  own.p999_us = j["compute_ns"]["median"].get<double>() / 1e3;
  own.max_us = j["compute_ns"]["p99"].get<double>() / 1e3;
  state.counters["reply_p50_us"] = own.p50_us;
  state.counters["reply_p99_us"] = own.p99_us;
  state.counters["compute_p50_us"] = own.p999_us;
  state.counters["compute_p99_us"] = own.max_us;
  if (mode == 0) {
    g_plain = own;
  } else if (g_plain.p50_us > 0) {
    state.counters["plain_reply_p50"] = own.p50_us / g_plain.p50_us;
    state.counters["plain_reply_p99"] = own.p99_us / g_plain.p99_us;
    state.counters["plain_compute_p99"] = own.max_us / g_plain.max_us;
  }
}

// Registered in this order: the echo runs first, so the RSI runs can report their ratio.
BENCHMARK(BM_BareUdpEcho)->Iterations(kRoundTrips)->Unit(benchmark::kMicrosecond)->UseRealTime();
BENCHMARK(BM_RsiEndpointRoundTrip)
    ->Iterations(kRoundTrips)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();
BENCHMARK(BM_ZerogRtRoundTrip)
    ->DenseRange(0, 4)
    ->Iterations(kRoundTrips)
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();

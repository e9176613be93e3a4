// The device emulators against the real device classes: AtiBoard answering rtio::NetcanoemSensor
// (FakeCanBus, and a thread-safe in-memory bus for serve()), Stim300Emulator writing into a real
// pty read by rtio::Stim300Imu.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "alloc_count.hpp"
#include "zerog/emu/ati_board.hpp"
#include "zerog/emu/stim300_emulator.hpp"
#include "zerog/proto/netcanoem.hpp"
#include "zerog/rtio/fake_can_bus.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"
#include "zerog/rtio/stim300_imu.hpp"

namespace zerog::emu {
namespace {

using namespace std::chrono_literals;
namespace netcanoem = proto::netcanoem;
using Clock = std::chrono::steady_clock;

constexpr double kNewtonPerLbf = 4.4482216152605;
constexpr double kNewtonMetrePerLbfIn = 4.4482216152605 * 0.0254;

// ---------------------------------------------------------------------------------------------
// AtiBoard

// Half a gauge count on every gauge, in the worst sign combination, as a wrench: 0.5 Σ_j |A_ij|
// with A_ij = scale_i · float32(C_ij) / counts_i (ATI 9610-05-1030), computed here from the
// configuration alone.
std::array<double, 6> quantisation_bound(const AtiBoardConfig& c, double n_per_unit,
                                         double nm_per_unit) {
  std::array<double, 6> bound{};
  for (int i = 0; i < 6; ++i) {
    double sum = 0.0;
    for (int j = 0; j < 6; ++j)
      sum += std::abs(static_cast<double>(static_cast<float>(c.matrix[i][j])));
    bound[i] =
        0.5 * sum * (i < 3 ? n_per_unit / c.counts_per_force : nm_per_unit / c.counts_per_torque);
  }
  return bound;
}

class AtiBoardTest : public ::testing::Test {
 protected:
  void make(const AtiBoardConfig& config) {
    board_ = std::make_unique<AtiBoard>(config);
    responder_ = std::make_unique<AtiBoardResponder>(*board_);
    bus_.set_responder(responder_.get());
    rtio::NetcanoemConfig c;
    c.base_id = config.base_id;
    // FakeCanBus answers at once or times out at once; a long timeout only keeps a slow
    // (sanitizer) build or a busy machine from timing out between request and read.
    c.sample_timeout = 1s;
    for (int j = 0; j < 6; ++j) c.bias_gauges[j] = config.gauge_bias[j];
    sensor_ = std::make_unique<rtio::NetcanoemSensor>(bus_, c);
    ASSERT_EQ(sensor_->start(), rtio::FtStartStatus::ok);
  }

  rtio::FakeCanBus bus_;
  std::unique_ptr<AtiBoard> board_;
  std::unique_ptr<AtiBoardResponder> responder_;
  std::unique_ptr<rtio::NetcanoemSensor> sensor_;
};

TEST_F(AtiBoardTest, SensorReproducesASetWrenchToTheGaugeQuantisation) {
  struct Case {
    AtiBoardConfig config;
    double n_per_unit;
    double nm_per_unit;
  };
  std::vector<Case> cases(3);
  cases[0].n_per_unit = cases[0].nm_per_unit = 1.0;  // the default board: N, N·m, 1e6 counts
  cases[1].config.gauge_bias = {1200, -800, 2500, 640, -1800, 90};
  cases[1].config.counts_per_force = 40'000;  // a range for a 100 kg payload
  cases[1].config.counts_per_torque = 2'000;
  cases[1].n_per_unit = cases[1].nm_per_unit = 1.0;
  cases[2].config.base_id = 0x31;  // lbf and lbf·in on the wire
  cases[2].config.force_unit = 1;
  cases[2].config.torque_unit = 1;
  cases[2].config.counts_per_torque = 1000;
  cases[2].config.gauge_bias = {-5, 7, 0, 3, 100, -2};
  cases[2].n_per_unit = kNewtonPerLbf;
  cases[2].nm_per_unit = kNewtonMetrePerLbfIn;

  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (std::size_t k = 0; k < cases.size(); ++k) {
    SCOPED_TRACE(k);
    make(cases[k].config);
    const std::array<double, 6> bound =
        quantisation_bound(cases[k].config, cases[k].n_per_unit, cases[k].nm_per_unit);
    const std::array<double, 6> resolution = board_->count_resolution_si();
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(0.5 * resolution[i], bound[i], 1e-12 * bound[i]);
    const std::array<double, 6> full_scale = board_->full_scale_si();
    double worst = 0.0;  // largest error in units of the bound
    for (int n = 0; n < 200; ++n) {
      // 0.15 of each axis' full scale: the six together stay within 0.9 of every gauge's range.
      std::array<double, 6> wrench{};
      for (int i = 0; i < 6; ++i) wrench[i] = 0.15 * full_scale[i] * unit(rng);
      board_->set_wrench(wrench);
      rtio::FtSample s;
      ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
      ASSERT_EQ(s.status, rtio::FtSampleStatus::ok);
      for (int i = 0; i < 6; ++i) {
        EXPECT_NEAR(s.wrench_si[i], wrench[i], bound[i] * (1 + 1e-9)) << n << " axis " << i;
        worst = std::max(worst, std::abs(s.wrench_si[i] - wrench[i]) / bound[i]);
      }
    }
    EXPECT_GT(worst, 0.01);  // the gauges are quantised: not an exact copy
    // Zero wrench: the gauges are the bias, the sensor reads zero.
    board_->set_wrench({});
    EXPECT_EQ(board_->gauges(), cases[k].config.gauge_bias);
  }
}

TEST_F(AtiBoardTest, FullScaleIsWhereTheGaugesSaturate) {
  AtiBoardConfig config;
  config.gauge_bias = {300, -200, 0, 0, 50, 0};
  make(config);
  const std::array<double, 6> full_scale = board_->full_scale_si();
  std::uint64_t saturated = 0;
  for (int i = 0; i < 6; ++i) {
    SCOPED_TRACE(i);
    EXPECT_GT(full_scale[i], 0.0);
    int saturated_signs = 0;  // the bias gives one sign more room than the other
    for (double sign : {-1.0, 1.0}) {
      std::array<double, 6> wrench{};
      wrench[i] = sign * 0.999 * full_scale[i];
      board_->set_wrench(wrench);
      rtio::FtSample s;
      ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
      EXPECT_EQ(s.status, rtio::FtSampleStatus::ok);
      wrench[i] = sign * 1.01 * full_scale[i];
      board_->set_wrench(wrench);
      ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
      if (s.status == rtio::FtSampleStatus::saturated) {  // clamped at a rail
        ++saturated_signs;
        EXPECT_FALSE(s.valid);
        EXPECT_NE(s.saturated_mask, 0u);
      } else {
        EXPECT_EQ(s.status, rtio::FtSampleStatus::ok);
      }
    }
    EXPECT_GE(saturated_signs, 1);
    saturated += static_cast<std::uint64_t>(saturated_signs);
  }
  EXPECT_EQ(board_->counters().saturated_samples, saturated);
}

TEST_F(AtiBoardTest, FaultsGiveTheSensorsStatuses) {
  make({});
  const std::array<double, 6> wrench{12.0, -30.0, 200.0, 0.4, -0.3, 0.2};
  const std::array<double, 6> bound = quantisation_bound({}, 1.0, 1.0);
  board_->set_wrench(wrench);
  rtio::FtSample s;

  board_->set_fault(FtFault::saturated);
  ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_EQ(s.status, rtio::FtSampleStatus::saturated);
  EXPECT_EQ(s.saturated_mask, 1u);  // SG0
  EXPECT_EQ(s.gauges[0], 32767);
  EXPECT_FALSE(s.valid);

  board_->set_fault(FtFault::critical);
  ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_EQ(s.status, rtio::FtSampleStatus::critical);
  EXPECT_EQ(s.status_word, (1u << 1) | (1u << 15));
  EXPECT_FALSE(s.valid);

  board_->set_fault(FtFault::bus_error_bit);
  ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_EQ(s.status, rtio::FtSampleStatus::warning);
  EXPECT_EQ(s.status_word, (1u << 14) | (1u << 15));
  EXPECT_TRUE(s.valid);  // a warning: the data stay usable
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.wrench_si[i], wrench[i], bound[i]) << i;

  board_->set_fault(FtFault::silent);
  EXPECT_EQ(board_->fault(), FtFault::silent);
  EXPECT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::timeout);
  EXPECT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::timeout);
  EXPECT_EQ(sensor_->counters().timeouts, 2u);

  board_->set_fault(FtFault::none);
  ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_EQ(s.status, rtio::FtSampleStatus::ok);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.wrench_si[i], wrench[i], bound[i]) << i;

  const AtiBoard::Counters c = board_->counters();
  EXPECT_EQ(c.sample_requests, 6u);
  EXPECT_EQ(c.samples_sent, 4u);
  EXPECT_EQ(c.ignored, 2u);
  EXPECT_EQ(c.sample_requests_ignored, 2u);
  EXPECT_EQ(c.critical_samples, 1u);
  EXPECT_EQ(c.saturated_samples, 1u);
  // + the start-up read-out (calibration, version, serial, 6 matrix rows, counts, units) + the
  // thermistor read that goes with the first poll (rtio::NetcanoemConfig::thermistor_every_polls)
  EXPECT_EQ(c.requests, 6u + 11u + 1u);
  EXPECT_EQ(c.thermistor_reads, 1u);
  EXPECT_EQ(std::string(ft_fault_name(FtFault::bus_error_bit)), "bus_error_bit");
}

TEST_F(AtiBoardTest, SilentBoardFailsStartUp) {
  AtiBoard board;
  board.set_fault(FtFault::silent);
  AtiBoardResponder responder(board);
  rtio::FakeCanBus bus;
  bus.set_responder(&responder);
  rtio::NetcanoemConfig c;
  c.startup_attempts = 2;
  rtio::NetcanoemSensor sensor(bus, c);
  EXPECT_EQ(sensor.start(), rtio::FtStartStatus::no_response);
  EXPECT_EQ(board.counters().ignored, 2u);
}

TEST_F(AtiBoardTest, GaugeNoiseHasTheConfiguredSigmaAndRepeatsWithTheSeed) {
  AtiBoardConfig config;
  config.gauge_noise_counts = 4.0;
  config.seed = 99;
  config.gauge_bias = {100, 200, 300, 400, 500, 600};
  make(config);
  AtiBoard twin(config);
  const proto::CanFrame request = netcanoem::request_sample(config.base_id).value();
  constexpr int kSamples = 4000;
  std::array<double, 6> sum{}, sum2{};
  for (int n = 0; n < kSamples; ++n) {
    rtio::FtSample s;
    ASSERT_EQ(sensor_->read_sample(s), rtio::FtReadStatus::sample);
    AtiBoard::Response out{};
    ASSERT_EQ(twin.respond(request, out), 2u);
    netcanoem::SampleAssembler assembler(config.base_id);
    netcanoem::GaugeSample g;
    assembler.feed(out[0], g);
    ASSERT_EQ(assembler.feed(out[1], g), netcanoem::FeedResult::sample);
    EXPECT_EQ(g.gauges, s.gauges);  // same seed, same noise
    for (int j = 0; j < 6; ++j) {
      const double d = s.gauges[j] - config.gauge_bias[j];
      sum[j] += d;
      sum2[j] += d * d;
    }
  }
  for (int j = 0; j < 6; ++j) {
    const double mean = sum[j] / kSamples;
    // Rounding adds 1/12 count² of variance.
    const double sigma = std::sqrt(sum2[j] / kSamples - mean * mean - 1.0 / 12.0);
    EXPECT_NEAR(mean, 0.0, 4 * 4.0 / std::sqrt(kSamples)) << j;
    EXPECT_NEAR(sigma, 4.0, 0.4) << j;
  }
}

TEST_F(AtiBoardTest, BadConfigurationsAreRefusedWithTheirReason) {
  auto message = [](const AtiBoardConfig& c) -> std::string {
    try {
      AtiBoard board(c);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  AtiBoardConfig c;
  c.base_id = 128;
  EXPECT_NE(message(c).find("base_id 128"), std::string::npos) << message(c);
  c = {};
  c.matrix[5] = c.matrix[4];
  EXPECT_NE(message(c).find("singular"), std::string::npos) << message(c);
  c = {};
  c.matrix[2][3] = std::nan("");
  EXPECT_NE(message(c).find("matrix row 2"), std::string::npos) << message(c);
  c = {};
  c.counts_per_torque = 0;
  EXPECT_NE(message(c).find("counts_per_"), std::string::npos) << message(c);
  c = {};
  c.gauge_noise_counts = -1;
  EXPECT_NE(message(c).find("gauge_noise_counts"), std::string::npos) << message(c);

  c = {};
  c.torque_unit = 42;  // accepted (a sensor must refuse it), but no SI conversion
  AtiBoard unknown_units(c);
  EXPECT_THROW(unknown_units.set_wrench({}), std::logic_error);
  AtiBoard board;
  EXPECT_THROW(board.set_wrench({0, 0, std::nan(""), 0, 0, 0}), std::invalid_argument);
  AtiBoardQuirks q;
  q.before_sample_count = 5;
  EXPECT_THROW(board.set_quirks(q), std::invalid_argument);

  c = {};
  c.thermistor.celsius_per_count = 0.0;
  EXPECT_NE(message(c).find("thermistor"), std::string::npos) << message(c);
  c = {};
  c.temperature_C = 1000.0;  // beyond 65535 counts of the default conversion
  EXPECT_NE(message(c).find("1000"), std::string::npos) << message(c);
  EXPECT_THROW(board.set_temperature(std::nan("")), std::invalid_argument);
}

// The thermistor channel (0x9, index 2) answers the temperature through the inverse of the
// board's conversion; the other channels answer too, an index above 5 gets no answer.
TEST_F(AtiBoardTest, ThermistorChannelAnswersTheTemperature) {
  AtiBoard board;
  AtiBoard::Response out{};
  board.set_temperature(37.25);
  const auto thermistor =
      netcanoem::request_diagnostic_adc(0x20, netcanoem::DiagnosticIndex::thermistor).value();
  ASSERT_EQ(board.respond(thermistor, out), 1u);
  std::uint16_t counts = 0;
  ASSERT_EQ(netcanoem::decode_diagnostic_adc(out[0], 0x20, counts), netcanoem::DecodeStatus::ok);
  EXPECT_EQ(counts, board.thermistor_counts());
  EXPECT_NEAR(netcanoem::thermistor_celsius(board.config().thermistor, counts), 37.25,
              0.5 * board.config().thermistor.celsius_per_count);
  const auto power =
      netcanoem::request_diagnostic_adc(0x20, netcanoem::DiagnosticIndex::power).value();
  EXPECT_EQ(board.respond(power, out), 1u);
  proto::CanFrame bad_index = thermistor;
  bad_index.data[0] = 6;
  EXPECT_EQ(board.respond(bad_index, out), 0u);
  const AtiBoard::Counters c = board.counters();
  EXPECT_EQ(c.diagnostic_reads, 2u);
  EXPECT_EQ(c.thermistor_reads, 1u);
  EXPECT_EQ(c.ignored, 1u);
}

// End to end with the real sensor class: the board's temperature reaches the sample in °C.
TEST_F(AtiBoardTest, SensorReadsTheBoardsTemperature) {
  AtiBoardConfig config;
  config.temperature_C = 18.0;
  board_ = std::make_unique<AtiBoard>(config);
  responder_ = std::make_unique<AtiBoardResponder>(*board_, 5);
  bus_.set_responder(responder_.get());
  rtio::NetcanoemConfig c;
  c.sample_timeout = 1s;
  c.thermistor_every_polls = 2;
  c.thermistor = config.thermistor;
  rtio::NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), rtio::FtStartStatus::ok);
  rtio::FtSample s;
  ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample);
  ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample);
  ASSERT_TRUE(s.temperature_valid);
  EXPECT_NEAR(s.temperature_C, 18.0, 0.5 * config.thermistor.celsius_per_count);
  board_->set_temperature(55.5);
  for (int i = 0; i < 2; ++i) ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_NEAR(s.temperature_C, 55.5, 0.5 * config.thermistor.celsius_per_count);
  EXPECT_EQ(board_->counters().thermistor_reads, 2u);
  EXPECT_EQ(sensor.counters().thermistor_readings, 2u);
}

TEST_F(AtiBoardTest, RespondIgnoresWhatIsNotItsRequest) {
  AtiBoard board;
  AtiBoard::Response out{};
  proto::CanFrame other = netcanoem::request_sample(0x21).value();  // another board
  EXPECT_EQ(board.respond(other, out), 0u);
  proto::CanFrame response = netcanoem::encode_units(0x20, 2, 3).value();  // a response
  EXPECT_EQ(board.respond(response, out), 0u);
  proto::CanFrame extended = netcanoem::request_sample(0x20).value();
  extended.id |= proto::kCanExtendedFlag;
  EXPECT_EQ(board.respond(extended, out), 0u);
  proto::CanFrame row = netcanoem::request_matrix_row(0x20, 1).value();
  ASSERT_EQ(board.respond(row, out), 3u);
  std::array<double, 2> pair{};
  ASSERT_EQ(netcanoem::decode_matrix_part(out[1], 0x20, 1, pair), netcanoem::DecodeStatus::ok);
  EXPECT_EQ(pair[0], AtiBoardConfig{}.matrix[1][2]);
  const AtiBoard::Counters c = board.counters();
  EXPECT_EQ(c.other_frames, 3u);
  EXPECT_EQ(c.requests, 1u);
}

// Two ends of one in-memory bus, like two raw sockets on vcan: what one end writes, the other
// reads. Thread-safe, and read() really waits, unlike FakeCanBus. Test code (allocates).
class BusLink {
 public:
  class End final : public rtio::CanBus {
   public:
    End(BusLink& link, int side) : link_(link), side_(side) {}
    rtio::CanReadStatus read(rtio::CanRxFrame& out, std::chrono::nanoseconds timeout) override {
      std::unique_lock lock(link_.mutex_);
      std::deque<proto::CanFrame>& queue = link_.queues_[side_];
      if (!link_.cv_.wait_for(lock, timeout, [&] { return !queue.empty(); })) {
        return rtio::CanReadStatus::timeout;
      }
      out = rtio::CanRxFrame{queue.front(), 0};
      queue.pop_front();
      ++counters_.frames_received;
      return rtio::CanReadStatus::frame;
    }
    rtio::CanWriteStatus write(const proto::CanFrame& frame) override {
      {
        const std::lock_guard lock(link_.mutex_);
        link_.queues_[1 - side_].push_back(frame);
      }
      link_.cv_.notify_all();
      ++counters_.frames_sent;
      return rtio::CanWriteStatus::ok;
    }
    const rtio::CanBusCounters& counters() const override { return counters_; }

   private:
    BusLink& link_;
    int side_;
    rtio::CanBusCounters counters_;
  };
  End& end(int side) { return side == 0 ? a_ : b_; }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::array<std::deque<proto::CanFrame>, 2> queues_;
  End a_{*this, 0};
  End b_{*this, 1};
};

TEST(AtiBoardServe, AnswersASensorInAnotherThreadAndASlowBoardTimesOut) {
  AtiBoard board;
  BusLink link;
  std::atomic<bool> stop{false};
  std::thread server([&] { board.serve(link.end(1), stop); });
  rtio::NetcanoemConfig c;
  c.sample_timeout = 20ms;
  rtio::NetcanoemSensor sensor(link.end(0), c);
  ASSERT_EQ(sensor.start(), rtio::FtStartStatus::ok);
  const std::array<double, 6> wrench{1.0, 2.0, -50.0, 0.1, 0.2, -0.05};
  board.set_wrench(wrench);
  const std::array<double, 6> bound = quantisation_bound({}, 1.0, 1.0);
  rtio::FtSample s;
  for (int n = 0; n < 20; ++n) {
    ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample) << n;
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.wrench_si[i], wrench[i], bound[i]) << i;
  }

  board.set_response_delay(5ms);  // slow, but within the 20 ms timeout
  auto before = Clock::now();
  ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_GE(Clock::now() - before, 5ms);
  board.set_response_delay(60ms);  // slower than the timeout
  EXPECT_EQ(sensor.read_sample(s), rtio::FtReadStatus::timeout);
  std::this_thread::sleep_for(80ms);  // the late pair arrives and waits in the queue
  board.set_response_delay(0ms);
  ASSERT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample);
  EXPECT_EQ(sensor.counters().stale_frames, 2u);  // drained, not taken for the answer

  // A long delay does not keep serve() from noticing stop.
  board.set_response_delay(10s);
  ASSERT_EQ(link.end(0).write(netcanoem::request_sample(0x20).value()), rtio::CanWriteStatus::ok);
  std::this_thread::sleep_for(20ms);
  before = Clock::now();
  stop.store(true);
  server.join();
  EXPECT_LT(Clock::now() - before, 100ms);
  const AtiBoard::Counters counters = board.counters();
  EXPECT_EQ(counters.sample_requests, 24u);
  EXPECT_EQ(counters.samples_sent, 24u);  // counted when made; the last one was never sent
  EXPECT_EQ(counters.tx_failed, 0u);
}

TEST(AtiBoardServe, ServesAFakeCanBusAndCountsRefusedWrites) {
  AtiBoard board;
  rtio::FakeCanBus bus;
  // Serves in short sessions until `done` holds (checked between sessions, when the server thread
  // is the bus's only user no more) or 5 s have passed: a loaded machine may need more than one
  // session to answer, and a fixed sleep then counted too early.
  auto serve_until = [&](auto done) {
    const auto deadline = std::chrono::steady_clock::now() + 5s;
    while (!done() && std::chrono::steady_clock::now() < deadline) {
      std::atomic<bool> stop{false};
      std::thread server([&] { board.serve(bus, stop); });  // the only user of `bus` until joined
      std::this_thread::sleep_for(30ms);
      stop.store(true);
      server.join();
    }
  };
  ASSERT_TRUE(bus.inject(netcanoem::request_firmware_version(0x20).value()));
  ASSERT_TRUE(bus.inject(netcanoem::request_sample(0x20).value()));
  serve_until([&] { return bus.written_count() >= 3; });
  ASSERT_EQ(bus.written_count(), 3u);
  netcanoem::FirmwareVersion version;
  EXPECT_EQ(netcanoem::decode_firmware_version(bus.written(0), 0x20, version),
            netcanoem::DecodeStatus::ok);
  EXPECT_EQ(version.build, 1201);
  EXPECT_EQ(bus.written(1).len, netcanoem::kSampleALength);
  EXPECT_EQ(bus.written(2).len, netcanoem::kSampleBLength);

  bus.fail_writes(rtio::CanWriteStatus::would_block);
  ASSERT_TRUE(bus.inject(netcanoem::request_units(0x20).value()));
  serve_until([&] { return board.counters().tx_failed >= 1; });
  EXPECT_EQ(board.counters().tx_failed, 1u);
  EXPECT_EQ(bus.written_count(), 3u);  // the refused write is counted, not written
}

// ---------------------------------------------------------------------------------------------
// Stim300Emulator

// One LSB of each quantity (datasheet TS1524): rate 2^-14 °/s, acc 2^-19 g (±10 g), incl 2^-22 g.
constexpr double kRateLsb = 3.14159265358979323846 / 180.0 / 16384.0;
constexpr double kAccelLsb = 9.80665 / 524288.0;
constexpr double kInclLsb = 9.80665 / 4194304.0;
constexpr double kSlack = 1.000001;  // for the floating-point rounding of the bound itself

Stim300EmulatorConfig noiseless() {
  Stim300EmulatorConfig c;
  c.gyro_noise_radps = c.accel_noise_mps2 = c.incl_noise_mps2 = 0.0;
  return c;
}

ImuTruthSample truth(int k) {
  ImuTruthSample t;
  const double x = 0.01 * k;
  t.rate_imu_radps = {0.3 * std::sin(x), -0.2 + x, 1.5 * std::cos(3 * x)};
  t.specific_force_imu_mps2 = {0.5 - x, -9.80665 + 0.1 * std::sin(x), 2.0 * std::cos(x)};
  return t;
}

rtio::Stim300Config reader_config(const std::string& path,
                                  std::chrono::nanoseconds timeout = 200ms) {
  rtio::Stim300Config c;
  c.path = path;
  c.read_timeout = timeout;
  return c;
}

// A fresh empty directory under TMPDIR (or /tmp), removed with its entries by the destructor.
class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string pattern =
        std::string(base != nullptr && *base != '\0' ? base : "/tmp") + "/zerog_emu_test_XXXXXX";
    path_ = ::mkdtemp(pattern.data()) != nullptr ? pattern : std::string();
  }
  ~TempDir() {
    for (const std::string& entry : entries_) ::unlink((path_ + "/" + entry).c_str());
    if (!path_.empty()) ::rmdir(path_.c_str());
  }
  std::string file(const std::string& name) {
    entries_.push_back(name);
    return path_ + "/" + name;
  }
  bool ok() const { return !path_.empty(); }

 private:
  std::string path_;
  std::vector<std::string> entries_;
};

std::string link_target(const std::string& path) {
  std::array<char, 256> buf{};
  const ssize_t n = ::readlink(path.c_str(), buf.data(), buf.size() - 1);
  return n > 0 ? std::string(buf.data(), static_cast<std::size_t>(n)) : std::string();
}

TEST(Stim300Emulator, ValuesRoundTripWithinOneLsb) {
  for (const bool crlf : {false, true}) {
    SCOPED_TRACE(crlf);
    Stim300EmulatorConfig config = noiseless();
    config.crlf = crlf;
    Stim300Emulator emulator(config);
    ASSERT_EQ(emulator.open().text(), "");
    ASSERT_FALSE(emulator.slave_path().empty());
    rtio::Stim300Imu imu(reader_config(emulator.slave_path()));
    ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
    for (int k = 0; k < 300; ++k) {
      ASSERT_TRUE(emulator.write_sample(truth(k)));
      rtio::ImuSample s;
      ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample) << k;
      const ImuTruthSample t = truth(k);
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(s.rate_rad_s[i], t.rate_imu_radps[i], 0.5 * kRateLsb * kSlack) << k;
        EXPECT_NEAR(s.accel_m_s2[i], t.specific_force_imu_mps2[i], 0.5 * kAccelLsb * kSlack) << k;
        EXPECT_NEAR(s.incl_m_s2[i], t.specific_force_imu_mps2[i], 0.5 * kInclLsb * kSlack) << k;
      }
      EXPECT_TRUE(s.rate_valid && s.accel_valid && s.incl_valid);
      EXPECT_EQ(s.counter, static_cast<std::uint8_t>(k));  // wraps at 256
      EXPECT_EQ(s.missed_before, 0);
      EXPECT_NEAR(s.latency_s, 400e-6, 1e-12);
    }
    const rtio::ImuCounters c = imu.counters();
    EXPECT_EQ(c.samples, 300u);
    EXPECT_EQ(c.bytes_skipped, 0u);
    EXPECT_EQ(c.counter_gaps, 0u);
    EXPECT_EQ(c.bytes_read, 300u * (38u + (crlf ? 2u : 0u)));
    EXPECT_EQ(emulator.counters().written, 300u);
    EXPECT_EQ(emulator.counters().dropped, 0u);
  }
}

// Issue 15 acceptance: a byte stream of every datagram identifier of the TS1524 rev.31 table
// (0x90–0x94, 0xA5–0xA7, 0xF0–0xF7), as the emulator sends them, with and without CR LF, decodes
// completely: every datagram recovered in order with its CRC checked, every group it carries.
TEST(Stim300Emulator, StreamOfEveryRev31IdentifierDecodesCompletely) {
  namespace stim300 = proto::stim300;
  constexpr double kTemperatureC = 31.25;  // a multiple of the 2^-8 °C LSB: exact
  constexpr std::uint32_t kPps = 0xABCDEF;
  constexpr int kRounds = 3;
  for (const bool crlf : {false, true}) {
    SCOPED_TRACE(crlf);
    Stim300EmulatorConfig config = noiseless();
    config.crlf = crlf;
    config.temperature_c = kTemperatureC;
    config.pps_raw = kPps;
    Stim300Emulator emulator(config);
    std::vector<std::uint8_t> stream;
    std::vector<std::size_t> starts;  // byte offset of each datagram
    std::vector<std::uint8_t> ids;
    std::array<std::uint8_t, stim300::kMaxDatagramLength + 2> buf{};
    for (int round = 0; round < kRounds; ++round) {
      for (const stim300::DatagramContent& c : stim300::kDatagramTable) {
        const int k = static_cast<int>(ids.size());
        const std::size_t n = emulator.encode_next(truth(k), c.identifier, buf);
        ASSERT_EQ(n, stim300::datagram_length(c) + (crlf ? 2u : 0u)) << int{c.identifier};
        starts.push_back(stream.size());
        stream.insert(stream.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(n));
        ids.push_back(c.identifier);
      }
    }
    ASSERT_EQ(ids.size(), 16u * kRounds);

    auto decode = [](const std::vector<std::uint8_t>& bytes, std::size_t chunk,
                     stim300::StreamDecoder& decoder) {
      std::vector<stim300::Sample> got;
      for (std::size_t i = 0; i < bytes.size(); i += chunk) {
        const std::size_t n = std::min(chunk, bytes.size() - i);
        decoder.feed(std::span<const std::uint8_t>(bytes.data() + i, n),
                     [&](const stim300::Sample& s) { got.push_back(s); });
      }
      return got;
    };
    for (const std::size_t chunk :
         {std::size_t{1}, std::size_t{7}, std::size_t{64}, stream.size()}) {
      SCOPED_TRACE(chunk);
      stim300::StreamDecoder decoder;  // identifier 0: any identifier of the table
      const std::vector<stim300::Sample> got = decode(stream, chunk, decoder);
      ASSERT_EQ(got.size(), ids.size());
      for (std::size_t k = 0; k < got.size(); ++k) {
        const stim300::Sample& s = got[k];
        const stim300::DatagramContent& c = *stim300::find_content(ids[k]);
        const ImuTruthSample t = truth(static_cast<int>(k));
        ASSERT_EQ(s.raw.identifier, ids[k]) << k;
        EXPECT_EQ(s.raw.counter, static_cast<std::uint8_t>(k));
        EXPECT_TRUE(s.rate_valid);
        EXPECT_EQ(s.accel_valid, c.accel) << k;
        EXPECT_EQ(s.incl_valid, c.incl) << k;
        EXPECT_EQ(s.rate_temperature_valid, c.temperature) << k;
        EXPECT_EQ(s.accel_temperature_valid, c.temperature && c.accel) << k;
        EXPECT_EQ(s.incl_temperature_valid, c.temperature && c.incl) << k;
        EXPECT_EQ(s.pps_valid, c.pps) << k;
        for (int i = 0; i < 3; ++i) {
          EXPECT_NEAR(s.rate_rad_s[i], t.rate_imu_radps[i], 0.5 * kRateLsb * kSlack) << k;
          if (c.accel) {
            EXPECT_NEAR(s.accel_m_s2[i], t.specific_force_imu_mps2[i], 0.5 * kAccelLsb * kSlack);
          }
          if (c.incl) {
            EXPECT_NEAR(s.incl_m_s2[i], t.specific_force_imu_mps2[i], 0.5 * kInclLsb * kSlack);
          }
          if (c.temperature) {
            EXPECT_EQ(s.rate_temperature_c[i], kTemperatureC) << k;
            EXPECT_EQ(s.accel_temperature_c[i], c.accel ? kTemperatureC : 0.0) << k;
            EXPECT_EQ(s.incl_temperature_c[i], c.incl ? kTemperatureC : 0.0) << k;
          }
        }
        EXPECT_EQ(s.raw.pps, c.pps ? kPps : 0u) << k;
        EXPECT_NEAR(s.latency_s, 400e-6, 1e-12);
      }
      const stim300::StreamCounters& n = decoder.counters();
      EXPECT_EQ(n.datagrams, ids.size());
      EXPECT_EQ(n.bytes_skipped, 0u);
      EXPECT_EQ(n.crc_failures, 0u);
      EXPECT_EQ(n.sync_losses, 0u);
      EXPECT_EQ(n.counter_gaps, 0u);
      EXPECT_EQ(n.invalid_samples, 0u);
    }

    // The CRC is checked on every identifier: one flipped bit in datagram j loses exactly j.
    for (std::size_t j = 0; j < 16; ++j) {
      std::vector<std::uint8_t> bad = stream;
      bad[starts[j] + 2] ^= 0x10;  // a rate byte
      stim300::StreamDecoder decoder;
      const std::vector<stim300::Sample> got = decode(bad, 64, decoder);
      ASSERT_EQ(got.size(), ids.size() - 1) << int{ids[j]};
      EXPECT_EQ(decoder.counters().crc_failures, j == 0 ? 0u : 1u) << int{ids[j]};
      for (std::size_t k = 0; k < got.size(); ++k)
        EXPECT_EQ(got[k].raw.counter, static_cast<std::uint8_t>(k < j ? k : k + 1));
    }
  }
}

TEST(Stim300Emulator, NoiseHasTheConfiguredSigmaAndRepeatsWithTheSeed) {
  Stim300EmulatorConfig config;  // the default σ: 9e-4 rad/s, 0.024 m/s²
  config.seed = 5;
  Stim300Emulator emulator(config);
  Stim300Emulator twin(config);
  ASSERT_EQ(emulator.open().text(), "");
  ASSERT_EQ(twin.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path()));
  rtio::Stim300Imu twin_imu(reader_config(twin.slave_path()));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  ASSERT_EQ(twin_imu.start(), rtio::ImuStartStatus::ok);
  const ImuTruthSample t = truth(10);
  constexpr int kSamples = 4000;
  std::array<double, 9> sum{}, sum2{};
  for (int k = 0; k < kSamples; ++k) {
    ASSERT_TRUE(emulator.write_sample(t));
    ASSERT_TRUE(twin.write_sample(t));
    rtio::ImuSample s, u;
    ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample) << k;
    ASSERT_EQ(twin_imu.read_sample(u), rtio::ImuReadStatus::sample) << k;
    ASSERT_EQ(s.rate_rad_s, u.rate_rad_s);  // same seed, same noise
    ASSERT_EQ(s.accel_m_s2, u.accel_m_s2);
    for (int i = 0; i < 3; ++i) {
      const std::array<double, 3> d{s.rate_rad_s[i] - t.rate_imu_radps[i],
                                    s.accel_m_s2[i] - t.specific_force_imu_mps2[i],
                                    s.incl_m_s2[i] - t.specific_force_imu_mps2[i]};
      for (int q = 0; q < 3; ++q) {
        sum[3 * q + i] += d[q];
        sum2[3 * q + i] += d[q] * d[q];
      }
    }
  }
  const std::array<double, 3> sigma{config.gyro_noise_radps, config.accel_noise_mps2,
                                    config.incl_noise_mps2};
  for (int q = 0; q < 3; ++q) {
    for (int i = 0; i < 3; ++i) {
      const double mean = sum[3 * q + i] / kSamples;
      const double sd = std::sqrt(sum2[3 * q + i] / kSamples - mean * mean);
      EXPECT_NEAR(sd, sigma[q], 0.1 * sigma[q]) << "quantity " << q << " axis " << i;
      EXPECT_NEAR(mean, 0.0, 4 * sigma[q] / std::sqrt(kSamples)) << q << " " << i;
    }
  }
}

TEST(Stim300Emulator, BiasInstabilityIsACorrelatedProcessOfTheConfiguredSigma) {
  // No white noise; a bias of σ with a correlation time of 50 ms (so that 4 s hold 80 of them):
  // the error's spread is σ and neighbouring datagrams agree (lag-1 correlation exp(−0.5/50)).
  Stim300EmulatorConfig config = noiseless();
  config.gyro_bias_radps = 2e-3;
  config.accel_bias_mps2 = 0.05;
  config.bias_tau_s = 0.05;
  config.seed = 9;
  Stim300Emulator emulator(config);
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path()));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  const ImuTruthSample t = truth(10);
  constexpr int kSamples = 8000;
  std::vector<double> gyro, accel;
  for (int k = 0; k < kSamples; ++k) {
    ASSERT_TRUE(emulator.write_sample(t));
    rtio::ImuSample s;
    ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample) << k;
    gyro.push_back(s.rate_rad_s[0] - t.rate_imu_radps[0]);
    accel.push_back(s.accel_m_s2[1] - t.specific_force_imu_mps2[1]);
  }
  for (const auto& [e, sigma] : {std::pair{&gyro, 2e-3}, std::pair{&accel, 0.05}}) {
    double m = 0.0, v = 0.0, c = 0.0;
    for (double x : *e) m += x / kSamples;
    for (std::size_t k = 0; k < e->size(); ++k) {
      v += ((*e)[k] - m) * ((*e)[k] - m);
      if (k > 0) c += ((*e)[k] - m) * ((*e)[k - 1] - m);
    }
    EXPECT_NEAR(std::sqrt(v / kSamples), sigma, 0.3 * sigma);
    EXPECT_GT(c / v, 0.98);  // a white error of the same σ gives about 0
  }
}

TEST(Stim300Emulator, CounterGapsAreSeenByTheReader) {
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path(), 50ms));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  emulator.set_fault(ImuFault::counter_gaps);
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(emulator.write_sample(truth(k)));
  for (int n = 0; n < 10; ++n) {
    rtio::ImuSample s;
    ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
    EXPECT_EQ(s.counter, 2 * n);
    EXPECT_EQ(s.missed_before, n == 0 ? 0 : 1);
  }
  rtio::ImuSample s;
  EXPECT_EQ(imu.read_sample(s), rtio::ImuReadStatus::timeout);
  EXPECT_EQ(imu.counters().counter_gaps, 9u);
  EXPECT_EQ(imu.counters().datagrams_missed, 9u);
  EXPECT_EQ(emulator.counters().skipped, 10u);
  EXPECT_EQ(emulator.counters().written, 10u);
}

TEST(Stim300Emulator, GarbageAndBadCrcsAreCountedAndTheReaderRecovers) {
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path(), 50ms));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  int k = 0;
  auto write = [&](ImuFault fault, int n) {
    emulator.set_fault(fault);
    for (int i = 0; i < n; ++i) ASSERT_TRUE(emulator.write_sample(truth(k++)));
  };
  write(ImuFault::none, 5);
  write(ImuFault::crc_errors, 3);
  write(ImuFault::none, 5);
  write(ImuFault::garbage, 4);
  write(ImuFault::none, 5);
  std::vector<int> counters;
  rtio::ImuSample s;
  while (imu.read_sample(s) == rtio::ImuReadStatus::sample) counters.push_back(s.counter);
  const std::vector<int> expected{0, 1, 2, 3, 4, 8, 9, 10, 11, 12, 17, 18, 19, 20, 21};
  EXPECT_EQ(counters, expected);
  const rtio::ImuCounters c = imu.counters();
  EXPECT_EQ(c.samples, 15u);
  EXPECT_GE(c.crc_failures, 1u);  // the first bad CRC, where a datagram was due
  EXPECT_GE(c.sync_losses, 2u);   // at the bad CRC and at the garbage
  EXPECT_GE(c.bytes_skipped, 3u * 38u + 4u * 38u);
  EXPECT_EQ(c.counter_gaps, 2u);
  EXPECT_EQ(c.datagrams_missed, 7u);
  const Stim300Emulator::Counters e = emulator.counters();
  EXPECT_EQ(e.bad_crc, 3u);
  EXPECT_EQ(e.garbage_bytes, 4u * 38u);
  EXPECT_EQ(e.written, 18u);  // the bad-CRC ones included
}

TEST(Stim300Emulator, StatusBitsInvalidateTheRate) {
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path()));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  emulator.set_fault(ImuFault::status_bits);
  ASSERT_TRUE(emulator.write_sample(truth(1)));
  rtio::ImuSample s;
  ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
  EXPECT_FALSE(s.rate_valid);
  EXPECT_EQ(s.rate_status, Stim300Emulator::kFaultRateStatus);
  EXPECT_TRUE(s.accel_valid);
  EXPECT_TRUE(s.incl_valid);
  EXPECT_EQ(imu.counters().invalid_samples, 1u);
  EXPECT_STREQ(imu_fault_name(ImuFault::status_bits), "status_bits");
}

TEST(Stim300Emulator, SilentGivesTimeoutsAndTheCounterKeepsRunning) {
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path(), 30ms));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  emulator.set_fault(ImuFault::silent);
  for (int k = 0; k < 5; ++k) EXPECT_TRUE(emulator.write_sample(truth(k)));
  rtio::ImuSample s;
  EXPECT_EQ(imu.read_sample(s), rtio::ImuReadStatus::timeout);
  EXPECT_EQ(imu.read_sample(s), rtio::ImuReadStatus::timeout);
  EXPECT_EQ(imu.counters().timeouts, 2u);
  EXPECT_EQ(imu.counters().bytes_read, 0u);
  emulator.set_fault(ImuFault::none);
  ASSERT_TRUE(emulator.write_sample(truth(5)));
  ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
  EXPECT_EQ(s.counter, 5);
}

TEST(Stim300Emulator, UnplugIsAHangUpAndOpenPlugsItBackIn) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string link = dir.file("stim300");
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open(link).text(), "");
  rtio::Stim300Imu imu(reader_config(link));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  ASSERT_TRUE(emulator.write_sample(truth(0)));
  rtio::ImuSample s;
  ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);

  emulator.unplug();
  EXPECT_EQ(imu.read_sample(s), rtio::ImuReadStatus::disconnected);
  EXPECT_EQ(imu.counters().disconnects, 1u);
  EXPECT_FALSE(emulator.write_sample(truth(1)));
  EXPECT_EQ(emulator.counters().dropped, 1u);

  ASSERT_EQ(emulator.open(link).text(), "");  // plugged back in: a new pty behind the same link
  EXPECT_EQ(link_target(link), emulator.slave_path());
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  ASSERT_TRUE(emulator.write_sample(truth(2)));
  ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
  EXPECT_EQ(s.counter, 2);
}

TEST(Stim300Emulator, SymlinkIsReplacedAtomicallyButNothingElse) {
  TempDir dir;
  ASSERT_TRUE(dir.ok());
  const std::string link = dir.file("imu");
  {
    Stim300Emulator first(noiseless());
    ASSERT_EQ(first.open(link).text(), "");
    EXPECT_EQ(link_target(link), first.slave_path());
    EXPECT_EQ(first.link_path(), link);
    {
      Stim300Emulator second(noiseless());
      ASSERT_EQ(second.open(link).text(), "");  // an existing symlink is replaced
      EXPECT_EQ(link_target(link), second.slave_path());
      EXPECT_NE(second.slave_path(), first.slave_path());
    }  // removes the link: it pointed to its pty
    struct stat st {};
    EXPECT_NE(::lstat(link.c_str(), &st), 0);
  }  // `first` leaves alone what is no longer its link

  const std::string file = dir.file("regular");
  { std::ofstream(file) << "keep me\n"; }
  Stim300Emulator emulator(noiseless());
  const Status refused = emulator.open(file);
  EXPECT_EQ(refused.code(), StatusCode::invalid_setting);
  EXPECT_EQ(refused.setting(), "link_path");
  const std::string& error = refused.message();
  EXPECT_NE(error.find(file), std::string::npos) << error;
  EXPECT_NE(error.find("not a symlink"), std::string::npos) << error;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "keep me");
  EXPECT_TRUE(emulator.slave_path().empty());
  EXPECT_FALSE(emulator.write_sample(truth(0)));  // not open

  const std::string missing = dir.file("no_such_dir") + "/imu";
  const Status failed = emulator.open(missing);
  EXPECT_EQ(failed.code(), StatusCode::system_error);
  EXPECT_EQ(failed.setting(), "link_path");
  const std::string& error2 = failed.message();
  EXPECT_NE(error2.find("no_such_dir"), std::string::npos) << error2;
  EXPECT_NE(error2.find("No such file or directory"), std::string::npos) << error2;
}

TEST(Stim300Emulator, WithoutAReaderDatagramsAreDroppedWholeAndNothingBlocks) {
  Stim300Emulator emulator(noiseless());
  ASSERT_EQ(emulator.open().text(), "");
  int accepted = 0;
  int dropped = 0;
  const auto before = Clock::now();
  for (int k = 0; k < 20000 && dropped < 100; ++k) {
    if (emulator.write_sample(truth(k))) {
      ++accepted;
    } else {
      ++dropped;
    }
  }
  EXPECT_LT(Clock::now() - before, 2s);
  ASSERT_EQ(dropped, 100) << "the pty took " << accepted << " datagrams";
  EXPECT_EQ(emulator.counters().dropped, 100u);
  EXPECT_EQ(emulator.counters().written, static_cast<std::uint64_t>(accepted));

  // What the pty holds is whole datagrams: a reader that keeps the buffer decodes every one.
  rtio::Stim300Config c = reader_config(emulator.slave_path(), 50ms);
  c.serial.flush_on_open = false;
  rtio::Stim300Imu imu(c);
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  rtio::ImuSample s;
  int read = 0;
  while (imu.read_sample(s) == rtio::ImuReadStatus::sample) ++read;
  ASSERT_TRUE(emulator.write_sample(truth(1)));  // room again; a partial rest went first
  while (imu.read_sample(s) == rtio::ImuReadStatus::sample) ++read;
  EXPECT_EQ(imu.counters().bytes_skipped, 0u);
  EXPECT_EQ(imu.counters().crc_failures, 0u);
  EXPECT_EQ(read, accepted + 1);
  std::printf("pty buffer took %d datagrams (%d bytes) without a reader\n", accepted,
              accepted * 38);
}

TEST(Stim300Emulator, WriteSampleDoesNotAllocate) {
  Stim300Emulator emulator;
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Imu imu(reader_config(emulator.slave_path(), 5ms));
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  constexpr std::array<ImuFault, 5> kFaults{ImuFault::none, ImuFault::garbage, ImuFault::crc_errors,
                                            ImuFault::counter_gaps, ImuFault::status_bits};
  rtio::ImuSample s;
  int samples = 0;
  const std::size_t before = zerog::test::allocation_count();
  for (int k = 0; k < 500; ++k) {
    emulator.set_fault(kFaults[static_cast<std::size_t>(k / 20) % kFaults.size()]);
    emulator.write_sample(truth(k));
    if (imu.read_sample(s) == rtio::ImuReadStatus::sample) ++samples;
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_GT(samples, 200);
  EXPECT_GT(emulator.counters().garbage_bytes, 0u);
}

TEST(Stim300Emulator, BadConfigurationsAreRefused) {
  Stim300EmulatorConfig c;
  c.identifier = 0x42;
  EXPECT_THROW(Stim300Emulator{c}, std::invalid_argument);
  c = {};
  c.accel_noise_mps2 = -0.1;
  EXPECT_THROW(Stim300Emulator{c}, std::invalid_argument);
  c = {};
  c.identifier = 0x91;  // rate and acceleration only: what a reader set to 0x91 decodes
  Stim300Emulator emulator(c);
  ASSERT_EQ(emulator.open().text(), "");
  rtio::Stim300Config r = reader_config(emulator.slave_path());
  r.stream.identifier = 0x91;
  rtio::Stim300Imu imu(r);
  ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  ASSERT_TRUE(emulator.write_sample(truth(3)));
  rtio::ImuSample s;
  ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
  EXPECT_TRUE(s.accel_valid);
  EXPECT_FALSE(s.incl_valid);
}

}  // namespace
}  // namespace zerog::emu

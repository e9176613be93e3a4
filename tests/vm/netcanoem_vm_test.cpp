// NetcanoemSensor on real SocketCAN (vcan0, inside the qemu VM of run_in_vm.sh): the emulated ATI
// board (zerog::emu::AtiBoard::serve) answers on its own raw socket in a thread, using the
// codec's response encoders with a known calibration matrix and gauge values. Checked: start-up and
// calibration readout, SI wrenches (computed independently here), error frames counted by class, a
// silent sensor, a critical status bit, stray frames, wrong-length frames, kernel filtering,
// timestamps, the SO_RXQ_OVFL drop counter, a slow board (response delay), set wrenches reproduced
// to the gauge quantisation, and no allocation per sample on the real socket. Natively (this host's
// kernel has no CAN) it skips; in the VM (ZEROG_IN_VM=1) a missing interface is a failure.
#include <gtest/gtest.h>

#include <net/if.h>
#include <time.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>

#include "alloc_count.hpp"
#include "netcanoem_board.hpp"
#include "zerog/emu/ati_board.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"

namespace zerog::rtio {
namespace {

namespace netcanoem = proto::netcanoem;
using namespace std::chrono_literals;
constexpr std::array<std::int16_t, 6> kGauges{1200, -800, 2500, 640, -1800, 90};

std::string can_iface() {
  const char* env = std::getenv("ZEROG_CAN_IFACE");
  return (env != nullptr && *env != '\0') ? std::string(env) : std::string("vcan0");
}

bool in_vm() {
  const char* env = std::getenv("ZEROG_IN_VM");
  return env != nullptr && std::string(env) == "1";
}

std::int64_t monotonic_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// The board: emu::AtiBoard serving its own raw socket on the interface in a thread until
// destroyed. Its setters are thread-safe: tests change gauges, status and quirks between
// requests.
class EmulatedBoard {
 public:
  EmulatedBoard(const std::string& iface, const emu::AtiBoardConfig& config) : board_(config) {
    board_.set_gauges(kGauges);
    CanSocketConfig socket_config;
    socket_config.filters[0] = netcanoem::filter_for(config.base_id);
    socket_config.error_mask = 0;
    opened_ = socket_.open(iface, socket_config);
    if (opened_.ok()) thread_ = std::thread([this] { board_.serve(socket_, stop_); });
  }
  ~EmulatedBoard() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  EmulatedBoard(const EmulatedBoard&) = delete;
  EmulatedBoard& operator=(const EmulatedBoard&) = delete;

  const CanOpenResult& opened() const { return opened_; }
  emu::AtiBoard& board() { return board_; }
  const emu::AtiBoardConfig& config() const { return board_.config(); }

 private:
  emu::AtiBoard board_;
  CanSocket socket_;
  CanOpenResult opened_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

class NetcanoemVm : public ::testing::Test {
 protected:
  void SetUp() override {
    iface_ = can_iface();
    if (::if_nametoindex(iface_.c_str()) == 0) {
      if (in_vm()) {
        FAIL() << "ZEROG_IN_VM=1 but CAN interface '" << iface_
               << "' does not exist: the VM harness did not set it up";
      }
      GTEST_SKIP() << "no CAN interface '" << iface_
                   << "' on this kernel (it has no vcan support); run this test through "
                      "tests/vm/run_in_vm.sh, e.g. ctest -L vm";
    }
    start_board({});
    if (HasFatalFailure()) return;
    const CanOpenResult r =
        socket_.open(iface_, NetcanoemSensor::socket_config(board_->config().base_id));
    ASSERT_TRUE(r.ok()) << can_open_status_name(r.status) << " " << r.what << ": "
                        << std::strerror(r.error_number);
    config_.base_id = board_->config().base_id;
    config_.calibration_index = 3;
    // Generous for TCG emulation on a busy host; the board answers in microseconds.
    config_.sample_timeout = 100ms;
    config_.startup_timeout = 300ms;
    config_.bias_gauges = {12.0, -3.0, 0.0, 7.5, -1.0, 2.0};
  }

  // (Re)starts the board with `config` (the board's configuration is fixed while it serves).
  void start_board(const emu::AtiBoardConfig& config) {
    board_.reset();
    board_ = std::make_unique<EmulatedBoard>(iface_, config);
    ASSERT_TRUE(board_->opened().ok()) << "board socket: " << board_->opened().what;
  }
  emu::AtiBoard& board() { return board_->board(); }

  // A raw socket for frames that come from neither the board nor the sensor.
  CanSocket& injector() {
    if (!injector_.is_open()) {
      CanSocketConfig config;
      config.filter_count = 0;  // receives nothing
      config.error_mask = 0;
      EXPECT_TRUE(injector_.open(iface_, config).ok());
    }
    return injector_;
  }

  static void expect_wrench(const std::array<double, 6>& got, const std::array<double, 6>& want) {
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(got[i], want[i], 1e-9 * (1 + std::abs(want[i]))) << i;
  }

  std::string iface_;
  std::unique_ptr<EmulatedBoard> board_;
  CanSocket socket_;
  CanSocket injector_;
  NetcanoemConfig config_;
};

TEST_F(NetcanoemVm, StartsUpReadsTheCalibrationAndConvertsSamples) {
  emu::AtiBoardConfig board_config;
  board_config.counts_per_force = 1'000'000;
  board_config.counts_per_torque = 1000;  // N·mm-ish counts, N·m unit
  board_config.force_unit = 2;
  board_config.torque_unit = 3;
  start_board(board_config);
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok) << "retries " << sensor.startup_retries();
  const netcanoem::Calibration& cal = sensor.calibration();
  EXPECT_EQ(cal.active_calibration, 3);
  EXPECT_STREQ(cal.serial_number.data(), "FT42007A");
  EXPECT_EQ(cal.firmware.minor, 8);
  EXPECT_TRUE(cal.counts_from_device);
  EXPECT_EQ(cal.counts_per_torque, 1000u);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) {
      EXPECT_EQ(cal.matrix[r][c], board_config.matrix[r][c]) << r << "," << c;
    }
  // Root in the VM: SO_RCVBUFFORCE gets the whole 256 frames' worth (doubled by the kernel).
  EXPECT_GE(socket_.receive_buffer().bytes, 2 * 256 * 1024);
  EXPECT_FALSE(socket_.receive_buffer().capped);

  FtSample s;
  std::int64_t last_timestamp = 0;
  for (int k = 0; k < 50; ++k) {
    const std::array<std::int16_t, 6> gauges{static_cast<std::int16_t>(100 * k - 2500),
                                             800,
                                             static_cast<std::int16_t>(-37 * k),
                                             4000,
                                             -1200,
                                             static_cast<std::int16_t>(k)};
    board().set_gauges(gauges);
    const std::int64_t before = monotonic_ns();
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << k;
    const std::int64_t after = monotonic_ns();
    EXPECT_EQ(s.gauges, gauges);
    EXPECT_TRUE(s.valid);
    EXPECT_EQ(s.status, FtSampleStatus::ok);
    expect_wrench(s.wrench_si,
                  test::expected_wrench_si(board_config, gauges, config_.bias_gauges, 1.0, 1.0));
    // Kernel receive timestamp (SO_TIMESTAMPNS on CLOCK_MONOTONIC), between request and return.
    EXPECT_GE(s.arrived_ns, before);
    EXPECT_LE(s.arrived_ns, after);
    EXPECT_GT(s.arrived_ns, last_timestamp);
    last_timestamp = s.arrived_ns;
  }
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.samples, 50u);
  EXPECT_EQ(c.requests, 50u);
  EXPECT_EQ(c.timeouts, 0u);
  EXPECT_EQ(c.kernel_drops, 0u);
  EXPECT_EQ(c.stray_frames, 0u);
}

TEST_F(NetcanoemVm, FirmwareBefore37UsesTheDefaultCounts) {
  emu::AtiBoardConfig board_config;
  board_config.firmware = {3, 5, 0};
  start_board(board_config);
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  EXPECT_FALSE(sensor.calibration().counts_from_device);
  EXPECT_EQ(sensor.calibration().counts_per_force, netcanoem::kDefaultCounts);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  expect_wrench(s.wrench_si,
                test::expected_wrench_si(board_config, kGauges, config_.bias_gauges, 1, 1));
}

TEST_F(NetcanoemVm, ErrorFramesAreCountedByClass) {
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  proto::CanFrame bus_off;
  bus_off.id = proto::kCanErrorFlag | 0x040u;  // CAN_ERR_BUSOFF
  bus_off.len = 8;
  proto::CanFrame controller;
  controller.id = proto::kCanErrorFlag | 0x004u | 0x080u;  // CAN_ERR_CRTL | CAN_ERR_BUSERROR
  controller.len = 8;
  controller.data[1] = 0x04;  // CAN_ERR_CRTL_RX_WARNING
  emu::AtiBoardQuirks quirks;
  quirks.before_sample = {bus_off, controller, controller};
  quirks.before_sample_count = 3;
  board().set_quirks(quirks);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);  // error frames are counted, the sample still comes
  const CanBusCounters& bus = socket_.counters();
  EXPECT_EQ(bus.error_frames, 3u);
  EXPECT_EQ(bus.error_classes[static_cast<int>(CanErrorClass::bus_off)], 1u);
  EXPECT_EQ(bus.error_classes[static_cast<int>(CanErrorClass::controller)], 2u);
  EXPECT_EQ(bus.error_classes[static_cast<int>(CanErrorClass::bus_error)], 2u);
  EXPECT_EQ(bus.error_classes[static_cast<int>(CanErrorClass::no_ack)], 0u);
  EXPECT_EQ(sensor.counters().error_frames, 3u);
}

TEST_F(NetcanoemVm, SilentSensorTimesOutAndIsCounted) {
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  board().set_fault(emu::FtFault::silent);
  FtSample s;
  const auto before = std::chrono::steady_clock::now();
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 90ms);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(sensor.counters().timeouts, 2u);
  board().set_fault(emu::FtFault::none);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // recovers by itself

  board().set_fault(emu::FtFault::silent);
  NetcanoemConfig c = config_;
  c.startup_timeout = 50ms;
  c.startup_attempts = 2;
  NetcanoemSensor silent(socket_, c);
  EXPECT_EQ(silent.start(), FtStartStatus::no_response);
  EXPECT_EQ(silent.startup_retries(), 1u);
}

TEST_F(NetcanoemVm, CriticalStatusBitMakesTheSampleInvalid) {
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  board().set_status_word((1u << 11) | netcanoem::kStatusAnyError);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_FALSE(s.valid);
  EXPECT_EQ(s.status, FtSampleStatus::critical);
  EXPECT_EQ(s.status_word, (1u << 11) | netcanoem::kStatusAnyError);

  board().set_status_word(netcanoem::kStatusCanBusError);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.status, FtSampleStatus::warning);
  EXPECT_EQ(sensor.counters().samples_critical, 1u);
  EXPECT_EQ(sensor.counters().samples_warning, 1u);
}

TEST_F(NetcanoemVm, StrayAndWrongLengthFramesAreCountedAndSkipped) {
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const std::uint8_t base = board_->config().base_id;
  proto::CanFrame stray;  // the board's serial-number id in the middle of the sample stream
  stray.id = netcanoem::can_id(base, netcanoem::Opcode::serial_number);
  stray.len = 8;
  proto::CanFrame short_a;  // a first half with 3 bytes instead of 8
  short_a.id = netcanoem::can_id(base, netcanoem::Opcode::sample_a);
  short_a.len = 3;
  proto::CanFrame long_b;  // a second half with 8 bytes instead of 6
  long_b.id = netcanoem::can_id(base, netcanoem::Opcode::sample_b);
  long_b.len = 8;
  emu::AtiBoardQuirks quirks;
  quirks.before_sample = {stray, short_a, long_b};
  quirks.before_sample_count = 3;
  board().set_quirks(quirks);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.gauges, kGauges);
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.stray_frames, 1u);
  EXPECT_EQ(c.wrong_length, 2u);

  // Frames of other ids never reach the sensor's socket: the kernel filter drops them.
  board().set_quirks({});
  proto::CanFrame other;
  other.id = netcanoem::can_id(static_cast<std::uint8_t>(base + 1), netcanoem::Opcode::sample_a);
  other.len = 8;
  proto::CanFrame extended;
  extended.id = proto::kCanExtendedFlag | (static_cast<std::uint32_t>(base) << 4);
  extended.len = 2;
  const std::uint64_t received_before = socket_.counters().frames_received;
  for (int i = 0; i < 10; ++i) {
    ASSERT_EQ(injector().write(other), CanWriteStatus::ok);
    ASSERT_EQ(injector().write(extended), CanWriteStatus::ok);
  }
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  const FtCounters after = sensor.counters();
  EXPECT_EQ(after.stray_frames, 1u);
  EXPECT_EQ(after.stale_frames, 0u);
  // Just the answer, and the thermistor's answer to the first poll's read (0x9, taken here; the
  // board sent it before this poll's pair).
  EXPECT_EQ(socket_.counters().frames_received - received_before, 3u);
  EXPECT_EQ(after.thermistor_readings, 1u);
}

TEST_F(NetcanoemVm, KernelDropsAreCountedFromSoRxqOvfl) {
  CanSocket small;
  CanSocketConfig config;
  config.receive_buffer_bytes = 1;  // the kernel's minimum: a handful of frames
  ASSERT_TRUE(small.open(iface_, config).ok());
  proto::CanFrame frame;
  frame.id = 0x7AB;  // outside the board's and the sensor's filters
  frame.len = 8;
  constexpr int kSent = 1000;
  for (int i = 0; i < kSent; ++i) {
    frame.data[0] = static_cast<std::uint8_t>(i);
    ASSERT_EQ(injector().write(frame), CanWriteStatus::ok) << i;
  }
  CanRxFrame rx;
  while (small.read(rx, 50ms) == CanReadStatus::frame) {
  }
  // The kernel reports its running drop count with the frames queued after the drops.
  ASSERT_EQ(injector().write(frame), CanWriteStatus::ok);
  ASSERT_EQ(small.read(rx, 1s), CanReadStatus::frame);
  const CanBusCounters& c = small.counters();
  EXPECT_GT(c.kernel_drops, 0u);
  EXPECT_EQ(c.frames_received + c.kernel_drops, static_cast<std::uint64_t>(kSent + 1));
  EXPECT_EQ(c.control_truncated, 0u);
}

TEST_F(NetcanoemVm, SetWrenchIsReproducedAndASlowBoardIsCounted) {
  emu::AtiBoardConfig board_config;
  board_config.counts_per_torque = 10'000;  // a wider torque range than the default
  board_config.gauge_bias = {12, -3, 0, 8, -1, 2};
  start_board(board_config);
  NetcanoemConfig c = config_;
  for (int j = 0; j < 6; ++j) c.bias_gauges[j] = board_config.gauge_bias[j];
  NetcanoemSensor sensor(socket_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  // Half a count on each gauge, in the worst sign combination.
  const std::array<double, 6> resolution = board().count_resolution_si();
  const std::array<double, 6> wrench{10.0, -20.0, 150.0, 0.5, -0.25, 0.1};
  board().set_wrench(wrench);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.wrench_si[i], wrench[i], 0.5 * resolution[i]) << i;

  // Slow, within the sensor's timeout (100 ms here): late but answered.
  board().set_response_delay(30ms);
  auto before = std::chrono::steady_clock::now();
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 30ms);
  // Slower than the timeout: a timeout, and the late pair is drained as stale next time.
  board().set_response_delay(150ms);
  before = std::chrono::steady_clock::now();
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 90ms);
  std::this_thread::sleep_for(150ms);  // the late answer arrives meanwhile
  board().set_response_delay(0ms);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(sensor.counters().timeouts, 1u);
  EXPECT_EQ(sensor.counters().stale_frames, 2u);
  const emu::AtiBoard::Counters bc = board().counters();
  EXPECT_EQ(bc.sample_requests, 4u);
  EXPECT_EQ(bc.samples_sent, 4u);
  EXPECT_EQ(bc.tx_failed, 0u);
}

TEST_F(NetcanoemVm, SampleReadDoesNotAllocateOnTheRealSocket) {
  NetcanoemSensor sensor(socket_, config_);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // warm-up
  int samples = 0;
  const std::size_t before = zerog::test::allocation_count();
  for (int i = 0; i < 200; ++i) {
    if (sensor.read_sample(s) == FtReadStatus::sample) ++samples;
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_EQ(samples, 200);
}

}  // namespace
}  // namespace zerog::rtio

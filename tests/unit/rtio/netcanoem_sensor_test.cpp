// NetcanoemSensor on a FakeCanBus with an emulated board: start-up, conversion to SI, status
// classification and every counted drop. The same device on real SocketCAN: tests/vm/.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>

#include "netcanoem_board.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/fake_can_bus.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"

namespace zerog::rtio {
namespace {

using test::BoardState;
namespace netcanoem = proto::netcanoem;

constexpr double kNewtonPerLbf = 4.4482216152605;
constexpr double kNewtonMetrePerLbfIn = 4.4482216152605 * 0.0254;

class BoardResponder final : public CanResponder {
 public:
  void on_write(const proto::CanFrame& frame, FakeCanBus& bus) override {
    std::array<proto::CanFrame, test::kMaxBoardFrames> frames{};
    const std::size_t n = test::board_respond(board, frame, frames);
    for (std::size_t i = 0; i < n; ++i)
      bus.inject(CanRxFrame{frames[i], 1000 + static_cast<std::int64_t>(i)});
  }
  BoardState board;
};

class NetcanoemSensorTest : public ::testing::Test {
 protected:
  NetcanoemSensorTest() { bus_.set_responder(&responder_); }

  NetcanoemConfig config() const {
    NetcanoemConfig c;
    c.base_id = responder_.board.base_id;
    return c;
  }

  static void expect_wrench(const std::array<double, 6>& got, const std::array<double, 6>& want) {
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(got[i], want[i], 1e-9 * (1 + std::abs(want[i]))) << i;
  }

  // How many frames with `opcode` the sensor has written.
  std::size_t written_with(netcanoem::Opcode opcode) const {
    std::size_t n = 0;
    for (std::uint64_t i = 0; i < bus_.written_count(); ++i) {
      if (netcanoem::opcode_of(bus_.written(i).id) == static_cast<std::uint8_t>(opcode)) ++n;
    }
    return n;
  }

  FakeCanBus bus_;
  BoardResponder responder_;
};

TEST_F(NetcanoemSensorTest, StartUpReadsTheCalibration) {
  NetcanoemConfig c = config();
  c.calibration_index = 2;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const netcanoem::Calibration& cal = sensor.calibration();
  EXPECT_EQ(cal.active_calibration, 2);
  EXPECT_EQ(cal.firmware.major, 3);
  EXPECT_EQ(cal.firmware.minor, 8);
  EXPECT_EQ(cal.firmware.build, 1201);
  EXPECT_STREQ(cal.serial_number.data(), "FT42007A");
  for (int r = 0; r < 6; ++r)
    for (int col = 0; col < 6; ++col)
      EXPECT_EQ(cal.matrix[r][col], responder_.board.matrix[r][col]);
  EXPECT_TRUE(cal.counts_from_device);
  EXPECT_EQ(cal.counts_per_force, 1'000'000u);
  EXPECT_EQ(cal.force_unit, 2);
  EXPECT_EQ(cal.torque_unit, 3);
  EXPECT_EQ(written_with(netcanoem::Opcode::matrix_sg01), 6u);
  EXPECT_EQ(written_with(netcanoem::Opcode::counts), 1u);
  EXPECT_TRUE(sensor.started());
}

TEST_F(NetcanoemSensorTest, FirmwareBefore37UsesTheDefaultCounts) {
  responder_.board.firmware = {3, 6, 7};
  responder_.board.counts_per_force = 123;  // must not be used (and is never asked for)
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  EXPECT_FALSE(sensor.calibration().counts_from_device);
  EXPECT_EQ(sensor.calibration().counts_per_force, netcanoem::kDefaultCounts);
  EXPECT_EQ(sensor.calibration().counts_per_torque, netcanoem::kDefaultCounts);
  EXPECT_EQ(written_with(netcanoem::Opcode::counts), 0u);
}

TEST_F(NetcanoemSensorTest, SampleBecomesAnSiWrench) {
  BoardState& b = responder_.board;
  b.counts_per_force = 1'000'000;
  b.counts_per_torque = 1000;
  b.force_unit = 1;   // lbf
  b.torque_unit = 1;  // lbf·in
  NetcanoemConfig c = config();
  c.bias_gauges = {10.0, -4.0, 0.5, 0.0, 20.0, -7.25};
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);

  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.status, FtSampleStatus::ok);
  EXPECT_EQ(s.gauges, b.gauges);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(s.timestamp_ns, 1001);  // of the second (completing) frame
  expect_wrench(s.wrench_si,
                test::expected_wrench_si(b, c.bias_gauges, kNewtonPerLbf, kNewtonMetrePerLbfIn));

  b.gauges = {-30000, 15000, 0, 1, -1, 32000};
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.sequence, 2u);
  expect_wrench(s.wrench_si,
                test::expected_wrench_si(b, c.bias_gauges, kNewtonPerLbf, kNewtonMetrePerLbfIn));
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.requests, 2u);
  EXPECT_EQ(counters.samples, 2u);
  EXPECT_EQ(counters.timeouts, 0u);
}

TEST_F(NetcanoemSensorTest, StatusClassification) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;

  responder_.board.status = netcanoem::kStatusCanBusError | netcanoem::kStatusAnyError;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::warning);  // bus error: warn, keep using it
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.status_word, responder_.board.status);

  responder_.board.status = (1u << 3) | netcanoem::kStatusAnyError;  // a critical bit
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::critical);
  EXPECT_FALSE(s.valid);

  responder_.board.status = 0;
  responder_.board.gauges[4] = -32768;  // rail
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::saturated);
  EXPECT_EQ(s.saturated_mask, 1u << 4);
  EXPECT_FALSE(s.valid);

  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.samples, 3u);
  EXPECT_EQ(c.samples_warning, 1u);
  EXPECT_EQ(c.samples_critical, 1u);
  EXPECT_EQ(c.samples_saturated, 1u);
}

TEST_F(NetcanoemSensorTest, StrayWrongLengthAndErrorFramesAreCountedAndWaitedPast) {
  BoardState& b = responder_.board;
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);

  proto::CanFrame stray;  // another opcode of the board
  stray.id = netcanoem::can_id(b.base_id, netcanoem::Opcode::serial_number);
  stray.len = 8;
  proto::CanFrame short_a;  // a 0x0 response cut to 5 bytes
  short_a.id = netcanoem::can_id(b.base_id, netcanoem::Opcode::sample_a);
  short_a.len = 5;
  proto::CanFrame error;  // bus error frame: no ACK + bus error
  error.id = proto::kCanErrorFlag | 0x020u | 0x080u;
  error.len = 8;
  b.before_sample = {stray, short_a, error, stray};
  b.before_sample_count = 4;

  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.stray_frames, 2u);
  EXPECT_EQ(c.wrong_length, 1u);
  EXPECT_EQ(c.error_frames, 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::no_ack)], 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::bus_error)], 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::bus_off)], 0u);
}

TEST_F(NetcanoemSensorTest, SilentSensorTimesOutAndIsCounted) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  responder_.board.silent = true;
  FtSample s;
  s.sequence = 77;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(s.sequence, 77u);  // untouched
  EXPECT_EQ(sensor.counters().timeouts, 2u);
  EXPECT_EQ(sensor.counters().requests, 2u);
  responder_.board.silent = false;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::sample);
}

TEST_F(NetcanoemSensorTest, HalfResponseTimesOutAndLateFramesAreDrainedAsStale) {
  BoardState& b = responder_.board;
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  // Only the first half arrives: the sample is incomplete when the wait ends.
  const auto frames = netcanoem::encode_sample(b.base_id, b.gauges, 0).value();
  b.before_sample[0] = frames[0];
  b.before_sample_count = 1;
  b.no_sample_response = true;
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  // Its second half comes late, with a whole old pair: drained before the next request.
  bus_.inject(frames[1]);
  bus_.inject(frames[0]);
  bus_.inject(frames[1]);
  b.before_sample_count = 0;
  b.no_sample_response = false;
  b.gauges = {1, 2, 3, 4, 5, 6};
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, b.gauges);  // the fresh answer, not the stale pair
  EXPECT_EQ(sensor.counters().stale_frames, 3u);
  EXPECT_EQ(sensor.counters().timeouts, 1u);
}

TEST_F(NetcanoemSensorTest, FullTxQueueIsCounted) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  bus_.fail_writes(CanWriteStatus::would_block);
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::tx_failed);
  EXPECT_EQ(sensor.counters().tx_would_block, 1u);
  EXPECT_EQ(bus_.counters().tx_would_block, 1u);
  bus_.fail_writes(CanWriteStatus::io_error);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::io_error);
  EXPECT_EQ(sensor.counters().io_errors, 1u);
}

TEST_F(NetcanoemSensorTest, NotStartedBeforeStart) {
  NetcanoemSensor sensor(bus_, config());
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::not_started);
  EXPECT_EQ(bus_.written_count(), 0u);
}

TEST_F(NetcanoemSensorTest, StartUpRetriesEachRequest) {
  responder_.board.ignore_requests = 2;
  NetcanoemConfig c = config();
  c.startup_attempts = 3;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  EXPECT_EQ(sensor.startup_retries(), 2u);
}

TEST_F(NetcanoemSensorTest, SilentSensorFailsStartUpAfterTheAttempts) {
  responder_.board.silent = true;
  NetcanoemConfig c = config();
  c.startup_attempts = 3;
  NetcanoemSensor sensor(bus_, c);
  EXPECT_EQ(sensor.start(), FtStartStatus::no_response);
  EXPECT_EQ(bus_.written_count(), 3u);  // the set-calibration request, three times
  EXPECT_FALSE(sensor.started());
}

TEST_F(NetcanoemSensorTest, EchoMismatchFailsStartUp) {
  responder_.board.wrong_echo = true;
  NetcanoemSensor sensor(bus_, config());
  EXPECT_EQ(sensor.start(), FtStartStatus::readout_failed);
  EXPECT_EQ(sensor.readout_error(), netcanoem::ReadoutError::echo_mismatch);
}

TEST_F(NetcanoemSensorTest, UnknownUnitsFailStartUp) {
  responder_.board.torque_unit = 42;
  NetcanoemSensor sensor(bus_, config());
  EXPECT_EQ(sensor.start(), FtStartStatus::unknown_units);
}

TEST_F(NetcanoemSensorTest, BadConfig) {
  NetcanoemConfig c = config();
  c.calibration_index = 16;
  NetcanoemSensor sensor(bus_, c);
  EXPECT_EQ(sensor.start(), FtStartStatus::bad_config);
}

TEST(NetcanoemSocketConfig, FiltersTheBoardsIdsAndAllErrors) {
  const CanSocketConfig c = NetcanoemSensor::socket_config(0x21, 128);
  ASSERT_EQ(c.filter_count, 1u);
  proto::CanFrame f;
  f.id = 0x215;
  EXPECT_TRUE(c.filters[0].matches(f));
  f.id = 0x225;
  EXPECT_FALSE(c.filters[0].matches(f));
  f.id = 0x215 | proto::kCanExtendedFlag;
  EXPECT_FALSE(c.filters[0].matches(f));
  EXPECT_EQ(c.error_mask, kCanAllErrors);
  EXPECT_EQ(c.receive_buffer_bytes, 128 * 1024);
  EXPECT_TRUE(c.timestamps);
}

TEST(FakeFtSensor, ReturnsTheScriptAndCounts) {
  FakeFtSensor fake;
  FtSample s;
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::not_started);
  ASSERT_EQ(fake.start(), FtStartStatus::ok);
  FtSample critical;
  critical.status = FtSampleStatus::critical;
  fake.push(FtReadStatus::sample, critical);
  fake.push(FtReadStatus::timeout);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::critical);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::timeout);  // script empty
  EXPECT_EQ(fake.counters().samples_critical, 1u);
  EXPECT_EQ(fake.counters().timeouts, 2u);
}

// Natively this kernel has no CAN: opening fails cleanly with a status, never an exception.
TEST(CanSocket, OpenFailuresAreReportedAsStatus) {
  CanSocket socket;
  EXPECT_EQ(socket.open("").status, CanOpenStatus::bad_argument);
  EXPECT_EQ(socket.open("a_name_far_too_long_for_ifnamsiz").status, CanOpenStatus::bad_argument);
  const CanOpenResult r = socket.open("zgnoif0");
  EXPECT_TRUE(r.status == CanOpenStatus::socket_failed ||
              r.status == CanOpenStatus::no_such_interface)
      << can_open_status_name(r.status);
  EXPECT_FALSE(socket.is_open());
  CanRxFrame rx;
  EXPECT_EQ(socket.read(rx, std::chrono::nanoseconds(0)), CanReadStatus::not_open);
  EXPECT_EQ(socket.write(proto::CanFrame{}), CanWriteStatus::not_open);
}

}  // namespace
}  // namespace zerog::rtio

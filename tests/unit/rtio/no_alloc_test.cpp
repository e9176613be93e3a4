// The per-sample paths do not allocate (docs/STYLE.md habit 4): NetcanoemSensor::read_sample on a
// FakeCanBus with an emulated board, Stim300Imu::read_sample on a pty, RsiEndpoint receive +
// reply on loopback UDP, and the handover primitives. Start-up (which may allocate) happens
// before the count is taken.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstdint>

#include "alloc_count.hpp"
#include "netcanoem_board.hpp"
#include "pty.hpp"
#include "udp.hpp"
#include "zerog/handover/latest_value.hpp"
#include "zerog/handover/spsc_ring.hpp"
#include "zerog/proto/stim300.hpp"
#include "zerog/rtio/fake_can_bus.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"
#include "zerog/rtio/stim300_imu.hpp"

namespace zerog::rtio {
namespace {

using namespace std::chrono_literals;
namespace netcanoem = proto::netcanoem;

class Board final : public CanResponder {
 public:
  void on_write(const proto::CanFrame& frame, FakeCanBus& bus) override {
    std::array<proto::CanFrame, test::kMaxBoardFrames> frames{};
    const std::size_t n = test::board_respond(state, frame, frames);
    for (std::size_t i = 0; i < n; ++i) bus.inject(frames[i]);
  }
  test::BoardState state;
};

TEST(NoAllocation, NetcanoemSensorReadSample) {
  FakeCanBus bus;
  Board board;
  bus.set_responder(&board);
  NetcanoemConfig config;
  config.base_id = board.state.base_id;
  config.thermistor_every_polls = 7;  // thermistor reads interleaved (0x9)
  config.thermistor = board.state.board.config().thermistor;
  NetcanoemSensor sensor(bus, config);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  // Exercise the counted paths too: a stray, an error frame, a wrong-length frame.
  proto::CanFrame stray;
  stray.id = netcanoem::can_id(board.state.base_id, netcanoem::Opcode::units);
  stray.len = 2;
  proto::CanFrame error;
  error.id = proto::kCanErrorFlag | 0x004u;
  error.len = 8;
  proto::CanFrame short_b;
  short_b.id = netcanoem::can_id(board.state.base_id, netcanoem::Opcode::sample_b);
  short_b.len = 2;
  proto::CanFrame long_diagnostic;  // a 0x9 frame of a wrong length (counted)
  long_diagnostic.id = netcanoem::can_id(board.state.base_id, netcanoem::Opcode::diagnostic_adc);
  long_diagnostic.len = 4;

  const std::size_t before = zerog::test::allocation_count();
  FtSample s;
  std::uint64_t samples = 0;
  for (int i = 0; i < 2000; ++i) {
    board.state.gauges[0] = static_cast<std::int16_t>(i);
    board.state.status = (i % 7 == 0) ? 0x4008 : 0;
    board.state.before_sample = {stray, error, short_b, long_diagnostic};
    board.state.before_sample_count = static_cast<std::size_t>(i % 5);
    board.state.silent = (i % 11 == 0);  // timeouts too
    if (sensor.read_sample(s) == FtReadStatus::sample) ++samples;
  }
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_GT(samples, 1500u);
  EXPECT_GT(counters.timeouts, 0u);
  EXPECT_GT(counters.stray_frames, 0u);
  EXPECT_GT(counters.thermistor_readings, 0u);
  EXPECT_GT(counters.thermistor_wrong_length, 0u);
}

TEST(NoAllocation, Stim300ImuReadSampleOnAPty) {
  test::Pty pty;
  ASSERT_TRUE(pty.ok());
  Stim300Config config;
  config.path = pty.slave_path();
  config.read_timeout = 500ms;
  Stim300Imu imu(config);
  ASSERT_EQ(imu.start(), ImuStartStatus::ok);

  namespace stim300 = proto::stim300;
  std::array<std::uint8_t, stim300::kMaxDatagramLength + 2> buffer{};
  stim300::RawDatagram raw;
  raw.identifier = 0x93;
  const std::size_t before = zerog::test::allocation_count();
  ImuSample s;
  int samples = 0;
  for (int i = 0; i < 500; ++i) {
    raw.counter = static_cast<std::uint8_t>(i);
    raw.rate.counts = {i, -i, 2 * i};
    const stim300::EncodeResult r = stim300::encode_datagram(raw, true, buffer);
    const std::array<std::uint8_t, 3> garbage{0x01, 0x93, 0x02};
    if (i % 10 == 0) pty.write(garbage);
    pty.write(std::span(buffer).first(r.size));
    if (imu.read_sample(s) == ImuReadStatus::sample && s.counter == raw.counter) ++samples;
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_EQ(samples, 500);
  EXPECT_GT(imu.counters().bytes_skipped, 0u);
}

TEST(NoAllocation, RsiEndpointReceiveAndReply) {
  test::UdpPeer robot;
  ASSERT_TRUE(robot.ok());
  RsiEndpointConfig config;
  config.bind_port = 0;
  config.robot_port = robot.port();
  config.receive_timeout = 500ms;
  RsiEndpoint endpoint(config);
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  test::UdpPeer stranger("127.0.0.2");
  ASSERT_TRUE(stranger.ok());

  std::array<char, 1024> out{};
  std::array<char, 1024> in{};
  proto::rsi::RobotMessage m;
  int answered = 0;
  const std::size_t before = zerog::test::allocation_count();
  for (std::uint64_t ipoc = 1; ipoc <= 500; ++ipoc) {
    if (ipoc % 10 == 0) stranger.send_to(endpoint.local_port(), "<Rob/>");
    if (ipoc % 25 == 0) robot.send_to(endpoint.local_port(), "<Rob><RIst");
    robot.send_to(endpoint.local_port(), test::robot_message(out, ipoc));
    RobotReceiveStatus status;
    while ((status = endpoint.receive(m)) == RobotReceiveStatus::malformed) {
    }
    if (status != RobotReceiveStatus::message) continue;
    endpoint.reply(proto::rsi::Correction{0.1, 0, 0, 0, 0, 0.01}, m.ipoc);
    const long n = robot.receive(in, 500);
    if (n > 0 && test::reply_ipoc({in.data(), static_cast<std::size_t>(n)}) ==
                     static_cast<long long>(ipoc)) {
      ++answered;
    }
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_EQ(answered, 500);
  EXPECT_EQ(endpoint.counters().foreign, 50u);
  EXPECT_EQ(endpoint.counters().malformed, 20u);
}

TEST(NoAllocation, HandoverPrimitives) {
  struct Sample {
    std::array<double, 6> wrench{};
    std::uint64_t seq = 0;
  };
  static handover::SpscRing<Sample, 256> ring;
  static handover::LatestValue<Sample> box;
  Sample s;
  const std::size_t before = zerog::test::allocation_count();
  for (std::uint64_t i = 0; i < 1000; ++i) {
    s.seq = i;
    ring.try_push(s);
    box.publish(s);
    ring.try_pop(s);
    box.read(s);
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
}

void* volatile g_sink = nullptr;

TEST(NoAllocation, TheCounterSeesAllocations) {
  const std::size_t before = zerog::test::allocation_count();
  g_sink = ::operator new(64);  // a direct call: not elidable like a new-expression
  ::operator delete(g_sink);
  EXPECT_EQ(zerog::test::allocation_count(), before + 1);
}

}  // namespace
}  // namespace zerog::rtio

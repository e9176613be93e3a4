// RsiEndpoint on real loopback UDP: a client socket plays the robot; every datagram is answered
// with its IPOC, foreign senders are ignored and counted, malformed datagrams are counted.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <string_view>

#include "alloc_count.hpp"
#include "udp.hpp"
#include "zerog/rtio/fake_robot_link.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"

namespace zerog::rtio {
namespace {

namespace rsi = proto::rsi;
using namespace std::chrono_literals;

class RsiEndpointTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(robot_.ok()); }

  RsiEndpointConfig config() const {
    RsiEndpointConfig c;
    c.bind_port = 0;  // any free port
    c.robot_address = "127.0.0.1";
    c.robot_port = robot_.port();
    c.receive_timeout = 500ms;
    return c;
  }

  // The robot sends a message with `ipoc` and expects the reply with the same IPOC.
  void exchange(RsiEndpoint& endpoint, std::uint64_t ipoc) {
    std::array<char, 1024> buffer{};
    ASSERT_TRUE(robot_.send_to(endpoint.local_port(), test::robot_message(buffer, ipoc)));
    rsi::RobotMessage m;
    ASSERT_EQ(endpoint.receive(m), RobotReceiveStatus::message);
    EXPECT_EQ(m.ipoc, ipoc);
    EXPECT_DOUBLE_EQ(m.actual_pose.x_mm, 445.5);
    EXPECT_DOUBLE_EQ(m.joints_deg[5], -12.25);
    ASSERT_EQ(endpoint.reply(rsi::correction_from_si({1e-4, 0, -2e-4}, {0, 0, 0}), m.ipoc),
              RobotReplyStatus::ok);
    std::uint16_t from_port = 0;
    const long n = robot_.receive(buffer, 1000, &from_port);
    ASSERT_GT(n, 0) << "no reply";
    const std::string_view reply(buffer.data(), static_cast<std::size_t>(n));
    EXPECT_EQ(test::reply_ipoc(reply), static_cast<long long>(ipoc)) << reply;
    EXPECT_EQ(reply.substr(0, 17), "<Sen Type=\"zerog\"");
    EXPECT_NE(reply.find("X=\"0.1000\""), std::string_view::npos) << reply;
    EXPECT_EQ(from_port, endpoint.local_port());
  }

  test::UdpPeer robot_;
};

TEST_F(RsiEndpointTest, DefaultsToLoopback) {
  const RsiEndpointConfig c;
  EXPECT_EQ(c.bind_address, "127.0.0.1");
  EXPECT_EQ(c.robot_address, "127.0.0.1");
}

TEST_F(RsiEndpointTest, EveryDatagramIsAnsweredWithItsIpoc) {
  RsiEndpoint endpoint(config());
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  ASSERT_NE(endpoint.local_port(), 0);
  for (std::uint64_t ipoc = 4208157; ipoc < 4208157 + 200; ++ipoc) exchange(endpoint, ipoc);
  EXPECT_EQ(endpoint.counters().messages, 200u);
  EXPECT_EQ(endpoint.counters().replies, 200u);
  EXPECT_EQ(endpoint.counters().foreign, 0u);
  EXPECT_EQ(endpoint.counters().malformed, 0u);
}

TEST_F(RsiEndpointTest, DatagramsQueuedBeforeTheCycleStartsAreDiscardedAndCounted) {
  RsiEndpoint endpoint(config());
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  std::array<char, 1024> buffer{};
  for (std::uint64_t ipoc = 1; ipoc <= 5; ++ipoc)
    ASSERT_TRUE(robot_.send_to(endpoint.local_port(), test::robot_message(buffer, ipoc)));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(endpoint.discard_queued(), 5u);
  EXPECT_EQ(endpoint.counters().discarded, 5u);
  EXPECT_EQ(endpoint.counters().messages, 0u);
  exchange(endpoint, 6);  // the next one is the first handled
  EXPECT_EQ(endpoint.counters().messages, 1u);
}

TEST_F(RsiEndpointTest, ForeignSendersAreIgnoredAndCounted) {
  RsiEndpoint endpoint(config());
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  test::UdpPeer other_port("127.0.0.1");  // right address, wrong port
  test::UdpPeer other_host("127.0.0.2");  // another address (all of 127/8 is loopback)
  ASSERT_TRUE(other_port.ok());
  ASSERT_TRUE(other_host.ok());
  std::array<char, 1024> buffer{};
  ASSERT_TRUE(other_port.send_to(endpoint.local_port(), test::robot_message(buffer, 1)));
  ASSERT_TRUE(other_host.send_to(endpoint.local_port(), test::robot_message(buffer, 2)));
  exchange(endpoint, 3);  // the robot's message is the one taken and answered
  EXPECT_EQ(endpoint.counters().foreign, 2u);
  EXPECT_EQ(endpoint.counters().datagrams, 3u);
  EXPECT_EQ(other_port.receive(buffer, 50), -1);  // no reply to strangers
  EXPECT_EQ(other_host.receive(buffer, 50), -1);

  ASSERT_TRUE(other_host.send_to(endpoint.local_port(), test::robot_message(buffer, 4)));
  rsi::RobotMessage m;
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::timeout);  // only foreign traffic
  EXPECT_EQ(endpoint.counters().foreign, 3u);
}

TEST_F(RsiEndpointTest, AnySourcePortOfTheRobotWhenUnset) {
  RsiEndpointConfig c = config();
  c.robot_port = 0;
  RsiEndpoint endpoint(c);
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  exchange(endpoint, 11);
  test::UdpPeer other_port("127.0.0.1");
  std::array<char, 1024> buffer{};
  ASSERT_TRUE(other_port.send_to(endpoint.local_port(), test::robot_message(buffer, 12)));
  rsi::RobotMessage m;
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::message);
  EXPECT_EQ(endpoint.counters().foreign, 0u);
}

TEST_F(RsiEndpointTest, MalformedDatagramsAreCountedAndNeverStopTheEndpoint) {
  RsiEndpoint endpoint(config());
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  rsi::RobotMessage m;

  ASSERT_TRUE(robot_.send_to(endpoint.local_port(), "<Rob Type=\"KUKA\"><RIst X=\"1\""));
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::malformed);
  EXPECT_EQ(endpoint.last_parse().status, rsi::ParseStatus::truncated);

  ASSERT_TRUE(robot_.send_to(endpoint.local_port(), "<Sen/>"));
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::malformed);
  EXPECT_EQ(endpoint.last_parse().status, rsi::ParseStatus::wrong_root);

  const std::string huge(6000, ' ');  // larger than rsi::kMaxMessageBytes
  ASSERT_TRUE(robot_.send_to(endpoint.local_port(), huge));
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::malformed);
  EXPECT_EQ(endpoint.last_parse().status, rsi::ParseStatus::too_long);

  ASSERT_TRUE(robot_.send_to(endpoint.local_port(), ""));  // empty datagram
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::malformed);

  exchange(endpoint, 99);  // still working
  const RobotLinkCounters& c = endpoint.counters();
  EXPECT_EQ(c.malformed, 4u);
  EXPECT_EQ(c.malformed_by_status[static_cast<int>(rsi::ParseStatus::truncated)], 2u);
  EXPECT_EQ(c.malformed_by_status[static_cast<int>(rsi::ParseStatus::wrong_root)], 1u);
  EXPECT_EQ(c.malformed_by_status[static_cast<int>(rsi::ParseStatus::too_long)], 1u);
  EXPECT_EQ(c.messages, 1u);
  EXPECT_EQ(c.replies, 1u);
}

TEST_F(RsiEndpointTest, TimeoutNoPeerAndBadCorrection) {
  RsiEndpointConfig c = config();
  c.receive_timeout = 20ms;
  RsiEndpoint endpoint(c);
  rsi::RobotMessage m;
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::not_started);
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  const auto before = std::chrono::steady_clock::now();
  EXPECT_EQ(endpoint.receive(m), RobotReceiveStatus::timeout);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 15ms);
  EXPECT_EQ(endpoint.counters().timeouts, 1u);
  EXPECT_EQ(endpoint.reply({}, 1), RobotReplyStatus::no_peer);

  exchange(endpoint, 5);
  rsi::Correction nan;
  nan.x_mm = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(endpoint.reply(nan, 6), RobotReplyStatus::bad_correction);  // never sent
  EXPECT_EQ(endpoint.counters().bad_corrections, 1u);
  std::array<char, 256> buffer{};
  EXPECT_EQ(robot_.receive(buffer, 50), -1);
}

TEST_F(RsiEndpointTest, AxisRepliesCarryAKorrInDegreesAndTheIpoc) {
  RsiEndpoint endpoint(config());
  const std::array<double, 6> akorr{0.01, -0.02, 0.0, 0.5, -0.125, 0.00005};
  EXPECT_EQ(endpoint.reply_axes(akorr, 1), RobotReplyStatus::not_started);
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  EXPECT_EQ(endpoint.reply_axes(akorr, 1), RobotReplyStatus::no_peer);
  std::array<char, 1024> buffer{};
  for (std::uint64_t ipoc = 700; ipoc < 720; ++ipoc) {
    ASSERT_TRUE(robot_.send_to(endpoint.local_port(), test::robot_message(buffer, ipoc)));
    rsi::RobotMessage m;
    ASSERT_EQ(endpoint.receive(m), RobotReceiveStatus::message);
    const std::size_t before = zerog::test::allocation_count();
    const RobotReplyStatus status = endpoint.reply_axes(akorr, m.ipoc);
    EXPECT_EQ(zerog::test::allocation_count() - before, 0u);
    ASSERT_EQ(status, RobotReplyStatus::ok);
    const long n = robot_.receive(buffer, 1000);
    ASSERT_GT(n, 0) << "no reply";
    const std::string_view text(buffer.data(), static_cast<std::size_t>(n));
    rsi::Reply reply;
    ASSERT_TRUE(rsi::parse_reply(text, reply).ok()) << text;
    EXPECT_EQ(reply.ipoc, ipoc);
    EXPECT_TRUE(reply.has_akorr);
    EXPECT_FALSE(reply.has_rkorr);
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(reply.akorr_deg[k], akorr[k], 0.5e-4) << text;
    EXPECT_EQ(text.substr(0, 17), "<Sen Type=\"zerog\"");
  }
  EXPECT_EQ(endpoint.counters().replies, 20u);
  std::array<double, 6> bad = akorr;
  bad[3] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(endpoint.reply_axes(bad, 721), RobotReplyStatus::bad_correction);  // never sent
  EXPECT_EQ(endpoint.counters().bad_corrections, 1u);
  EXPECT_EQ(robot_.receive(buffer, 50), -1);
}

TEST_F(RsiEndpointTest, BadConfigurationIsRefused) {
  RsiEndpointConfig c = config();
  c.robot_address = "robot.local";  // addresses only, no name lookup
  EXPECT_EQ(RsiEndpoint(c).start(), RobotStartStatus::bad_config);
  c = config();
  c.sensor_type = "bad type";
  EXPECT_EQ(RsiEndpoint(c).start(), RobotStartStatus::bad_config);
  c = config();
  c.bind_address = "192.0.2.1";  // TEST-NET: not an address of this host
  EXPECT_EQ(RsiEndpoint(c).start(), RobotStartStatus::bind_failed);
}

// SI at the border: the endpoint hands the cycle m, rad and a rotation matrix, and writes the
// cycle's SI correction in KUKA units.
TEST_F(RsiEndpointTest, ReceivesInSiAndAnswersSiCorrectionsInKukaUnits) {
  RsiEndpoint endpoint(config());
  ASSERT_EQ(endpoint.start(), RobotStartStatus::ok);
  std::array<char, 1024> buffer{};
  ASSERT_TRUE(robot_.send_to(endpoint.local_port(), test::robot_message(buffer, 77)));
  samples::RobotSample s;
  ASSERT_EQ(endpoint.receive_sample(s), RobotReceiveStatus::message);
  EXPECT_EQ(s.ipoc, 77u);
  EXPECT_TRUE(s.has_delay);
  EXPECT_EQ(s.delay, 0u);
  EXPECT_TRUE(s.has_pose);
  // RIst X=445.5 Y=-0.25 Z=900.0 (mm) A=180 B=0.5 C=-179.9 (degrees); A5=45.5°, A6=-12.25°.
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[0], 0.4455);
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[1], -0.25e-3);
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[2], 0.9);
  EXPECT_NEAR(s.joints_rad[4], 45.5 * std::numbers::pi / 180, 1e-15);
  EXPECT_NEAR(s.joints_rad[5], -12.25 * std::numbers::pi / 180, 1e-15);
  // A = 180°, B ≈ 0, C ≈ −180°: T's x axis is −x of B (R(0,0) = cos A cos B ≈ −1), its z
  // axis about −z of B (R(2,2) = cos B cos C ≈ −1).
  EXPECT_NEAR(s.R_base_tcp[0], -std::cos(0.5 * std::numbers::pi / 180), 1e-12);
  EXPECT_NEAR(s.R_base_tcp[8],
              std::cos(0.5 * std::numbers::pi / 180) * std::cos(-179.9 * std::numbers::pi / 180),
              1e-12);

  samples::RobotCorrection c;
  c.ipoc = s.ipoc;
  c.kind = samples::RobotCorrection::Kind::cartesian;
  c.translation_m = {1e-4, 0.0, -2e-4};
  const double a = 0.5 * std::numbers::pi / 180;  // 0.5° about z of B
  c.R_correction = {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
  ASSERT_EQ(endpoint.send_correction(c), RobotReplyStatus::ok);
  const long n = robot_.receive(buffer, 1000, nullptr);
  ASSERT_GT(n, 0) << "no reply";
  rsi::Reply reply;
  ASSERT_TRUE(
      rsi::parse_reply(std::string_view(buffer.data(), static_cast<std::size_t>(n)), reply).ok());
  EXPECT_EQ(reply.ipoc, 77u);
  ASSERT_TRUE(reply.has_rkorr);
  EXPECT_FALSE(reply.has_akorr);
  EXPECT_DOUBLE_EQ(reply.rkorr.x_mm, 0.1);
  EXPECT_DOUBLE_EQ(reply.rkorr.z_mm, -0.2);
  EXPECT_DOUBLE_EQ(reply.rkorr.a_deg, 0.5);
  EXPECT_DOUBLE_EQ(reply.rkorr.b_deg, 0.0);

  c.kind = samples::RobotCorrection::Kind::axes;
  c.axes_rad = {std::numbers::pi / 180, 0, 0, 0, 0, -0.5 * std::numbers::pi / 180};
  ASSERT_EQ(endpoint.send_correction(c), RobotReplyStatus::ok);
  const long m = robot_.receive(buffer, 1000, nullptr);
  ASSERT_GT(m, 0) << "no reply";
  ASSERT_TRUE(
      rsi::parse_reply(std::string_view(buffer.data(), static_cast<std::size_t>(m)), reply).ok());
  EXPECT_FALSE(reply.has_rkorr);
  ASSERT_TRUE(reply.has_akorr);
  EXPECT_DOUBLE_EQ(reply.akorr_deg[0], 1.0);
  EXPECT_DOUBLE_EQ(reply.akorr_deg[5], -0.5);
}

TEST(FakeRobotLink, SiCallsConvertAtTheBorder) {
  FakeRobotLink fake;
  ASSERT_EQ(fake.start(), RobotStartStatus::ok);
  rsi::RobotMessage m;
  m.ipoc = 5;
  m.has_actual_pose = false;
  m.joints_deg = {90, 0, 0, 0, 0, -45};
  fake.push(m);
  samples::RobotSample s;
  s.has_pose = true;
  ASSERT_EQ(fake.receive_sample(s), RobotReceiveStatus::message);
  EXPECT_EQ(s.ipoc, 5u);
  EXPECT_FALSE(s.has_pose);
  EXPECT_DOUBLE_EQ(s.joints_rad[0], std::numbers::pi / 2);
  EXPECT_DOUBLE_EQ(s.joints_rad[5], -std::numbers::pi / 4);
  samples::RobotSample untouched;
  untouched.ipoc = 99;
  EXPECT_EQ(fake.receive_sample(untouched), RobotReceiveStatus::timeout);
  EXPECT_EQ(untouched.ipoc, 99u);  // written only when a message came

  samples::RobotCorrection none;  // Kind::none: an RKorr of zeros
  none.ipoc = 5;
  ASSERT_EQ(fake.send_correction(none), RobotReplyStatus::ok);
  ASSERT_EQ(fake.reply_count(), 1u);
  EXPECT_FALSE(fake.reply_at(0).axis);
  EXPECT_EQ(fake.reply_at(0).ipoc, 5u);
  EXPECT_FALSE(std::signbit(fake.reply_at(0).correction.b_deg));  // +0, not −0
  samples::RobotCorrection axes;
  axes.kind = samples::RobotCorrection::Kind::axes;
  axes.axes_rad[1] = -std::numbers::pi / 180;
  ASSERT_EQ(fake.send_correction(axes), RobotReplyStatus::ok);
  EXPECT_TRUE(fake.reply_at(1).axis);
  EXPECT_DOUBLE_EQ(fake.reply_at(1).akorr_deg[1], -1.0);
}

TEST(FakeRobotLink, RecordsReplies) {
  FakeRobotLink fake;
  rsi::RobotMessage m;
  EXPECT_EQ(fake.receive(m), RobotReceiveStatus::not_started);
  ASSERT_EQ(fake.start(), RobotStartStatus::ok);
  EXPECT_EQ(fake.reply({}, 1), RobotReplyStatus::no_peer);
  m.ipoc = 42;
  fake.push(m);
  rsi::RobotMessage got;
  ASSERT_EQ(fake.receive(got), RobotReceiveStatus::message);
  EXPECT_EQ(fake.reply({}, got.ipoc), RobotReplyStatus::ok);
  ASSERT_EQ(fake.reply_count(), 1u);
  EXPECT_EQ(fake.reply_at(0).ipoc, 42u);
  EXPECT_EQ(fake.receive(got), RobotReceiveStatus::timeout);
  EXPECT_FALSE(fake.reply_at(0).axis);
  const std::array<double, 6> akorr{0.1, 0, 0, 0, 0, -0.2};
  EXPECT_EQ(fake.reply_axes(akorr, 43), RobotReplyStatus::ok);
  ASSERT_EQ(fake.reply_count(), 2u);
  EXPECT_TRUE(fake.reply_at(1).axis);
  EXPECT_EQ(fake.reply_at(1).ipoc, 43u);
  EXPECT_EQ(fake.reply_at(1).akorr_deg, akorr);
  std::array<double, 6> nan = akorr;
  nan[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(fake.reply_axes(nan, 44), RobotReplyStatus::bad_correction);
  EXPECT_EQ(fake.reply_count(), 2u);
  EXPECT_EQ(fake.counters().bad_corrections, 1u);
}

}  // namespace
}  // namespace zerog::rtio
